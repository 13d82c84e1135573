//! `splatbridge compare`: Render every renderer and profile against native splatting and report parity.

#[derive(clap::Args)]
pub struct Args {
    /// Arguments of this command (not wired yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("compare is not implemented yet")
}
