//! `splatbridge accuracy`: Sweep the accuracy knobs one at a time and plot error against time.

#[derive(clap::Args)]
pub struct Args {
    /// Arguments of this command (not wired yet).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub rest: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("accuracy is not implemented yet")
}
