//! `splatbridge demo`: Run the whole pipeline on the built-in street scene and write a report.

#[derive(clap::Args)]
pub struct Args {
    /// Arguments of this command (not wired yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("demo is not implemented yet")
}
