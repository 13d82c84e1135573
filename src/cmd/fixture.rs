//! `splatbridge fixture`: generate deterministic synthetic scenes.

use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// street, large or hard.
    pub name: String,
    /// Output directory.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Number of Gaussians (large).
    #[arg(long, default_value_t = 1_000_000)]
    pub count: usize,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::bail!("fixture {} is not implemented yet", args.name)
}
