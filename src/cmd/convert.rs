//! `splatbridge convert`: Convert Gaussians to triangle meshes (GLB/glTF/OBJ/PLY) or native glTF splats.

#[derive(clap::Args)]
pub struct Args {
    /// Arguments of this command (not wired yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("convert is not implemented yet")
}
