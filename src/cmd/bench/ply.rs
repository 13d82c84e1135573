//! `splatbridge bench ply`: PLY load throughput and peak memory.
//!
//! One untimed load warms the page cache, then `--repeat` timed loads; reported: the median
//! wall time, file MB/s at the median (MB = 10⁶ bytes), and the process's peak resident memory
//! (`VmHWM` from `/proc/self/status`) above its resident size before the first load, relative
//! to the size of the loaded cloud's arrays. Each cloud is dropped before the next load, so
//! the peak is one load's.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use splatbridge_scene::ply::{read_ply, ReadOptions};
use splatbridge_scene::GaussianCloud;

#[derive(clap::Args)]
pub struct Args {
    /// A 3DGS PLY file.
    pub file: PathBuf,
    /// Timed loads (after one warm-up load).
    #[arg(long, alias = "repeats", default_value_t = 10)]
    pub repeat: usize,
    /// Drop invalid Gaussians instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// A `kB` field of `/proc/self/status`, in bytes (None off Linux).
fn proc_status_bytes(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line[field.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}

/// Bytes held by the cloud's arrays (its "Gaussian data").
pub fn cloud_bytes(c: &GaussianCloud) -> u64 {
    use std::mem::size_of_val;
    (size_of_val(c.means.as_slice())
        + size_of_val(c.log_scales.as_slice())
        + size_of_val(c.rotations.as_slice())
        + size_of_val(c.opacity_logits.as_slice())
        + size_of_val(c.sh.as_slice())
        + c.object_ids
            .as_ref()
            .map_or(0, |v| size_of_val(v.as_slice()))) as u64
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = ReadOptions {
        drop_invalid: args.drop_invalid,
    };
    let file_bytes = std::fs::metadata(&args.file)
        .with_context(|| args.file.display().to_string())?
        .len();
    let rss_before = proc_status_bytes("VmRSS:");
    let (cloud, _) = read_ply(&args.file, &opts)?;
    let (n, degree, data) = (cloud.len(), cloud.sh_degree, cloud_bytes(&cloud));
    drop(cloud);
    let mut times = Vec::with_capacity(args.repeat.max(1));
    for _ in 0..args.repeat.max(1) {
        let t = Instant::now();
        let loaded = read_ply(&args.file, &opts)?;
        times.push(t.elapsed().as_secs_f64());
        drop(loaded);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let mb_s = file_bytes as f64 / 1e6 / median;
    let peak = proc_status_bytes("VmHWM:");
    let above = match (peak, rss_before) {
        (Some(p), Some(b)) => Some(p.saturating_sub(b)),
        _ => None,
    };
    let ratio = above.map(|a| a as f64 / data.max(1) as f64);
    if args.json {
        let v = serde_json::json!({
            "file": args.file.display().to_string(),
            "gaussians": n,
            "sh_degree": degree,
            "file_bytes": file_bytes,
            "cloud_bytes": data,
            "repeat": times.len(),
            "median_s": median,
            "min_s": times[0],
            "max_s": times[times.len() - 1],
            "mb_per_s": mb_s,
            "rss_before_bytes": rss_before,
            "peak_rss_bytes": peak,
            "peak_above_start_bytes": above,
            "peak_over_cloud": ratio,
        });
        println!("{v}");
        return Ok(());
    }
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    println!(
        "file          {} ({:.1} MiB)",
        args.file.display(),
        mib(file_bytes)
    );
    println!(
        "gaussians     {n} (SH degree {degree}), cloud arrays {:.1} MiB",
        mib(data)
    );
    println!(
        "load          median {:.2} ms over {} runs (min {:.2}, max {:.2}) = {mb_s:.0} MB/s",
        median * 1e3,
        times.len(),
        times[0] * 1e3,
        times[times.len() - 1] * 1e3
    );
    match (peak, rss_before, ratio) {
        (Some(p), Some(b), Some(r)) => println!(
            "peak memory   VmHWM {:.1} MiB, {:.1} MiB before loading: {:.1} MiB for the load = {r:.2}× the cloud",
            mib(p),
            mib(b),
            mib(p.saturating_sub(b))
        ),
        _ => println!("peak memory   unavailable (no /proc/self/status)"),
    }
    Ok(())
}
