//! `splatbridge trace`: Ray-trace an exported file (or a scene converted in memory) with a BVH.

#[derive(clap::Args)]
pub struct Args {
    /// Arguments of this command (not wired yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("trace is not implemented yet")
}
