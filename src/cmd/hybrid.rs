//! `splatbridge hybrid`: Render with the GES-style hybrid: opaque surfels, then unsorted Gaussians.

#[derive(clap::Args)]
pub struct Args {
    /// Arguments of this command (not wired yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("hybrid is not implemented yet")
}
