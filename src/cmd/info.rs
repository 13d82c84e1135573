//! `splatbridge info`: describe a PLY or manifest.

use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A 3DGS PLY or a splatbridge-scene/1 manifest.
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Drop invalid Gaussians (NaN, zero quaternion) with a counted warning instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::bail!("{}: info is not implemented yet", args.file.display())
}
