//! `splatbridge bench hybrid`.

#[derive(clap::Args)]
pub struct Args {
    /// Arguments of this benchmark (not wired yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("bench hybrid is not implemented yet")
}
