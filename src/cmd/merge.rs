//! `splatbridge merge SHARD_DIR... -o OUT`: join the folders of a sharded `compare` or
//! `accuracy` run (`--shard I/N`) into what the unsharded run writes (`splatbridge::batch::merge`).

use std::path::PathBuf;

use splatbridge::batch::merge;

#[derive(clap::Args)]
pub struct Args {
    /// The shards' output folders (every shard of one run, in any order).
    #[arg(required = true, value_name = "SHARD_DIR")]
    pub shards: Vec<PathBuf>,
    /// Output folder for the merged run.
    #[arg(short, long, alias = "output")]
    pub out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let merged = merge::gather(&args.shards)?;
    let written = merge::write_report(&merged, &args.out)?;
    let peak = merged.peaks.iter().copied().max().unwrap_or(0);
    println!(
        "merged {} shards of `{}`: {} records, {} files; largest shard peak memory {:.1} MB",
        merged.peaks.len(),
        merged.first.command,
        merged.records.len(),
        merged.files.len(),
        peak as f64 / 1e6
    );
    println!("wrote {}", args.out.join(written).display());
    Ok(())
}
