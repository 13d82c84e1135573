//! `splatbridge bench ply`: load throughput and peak memory of any splat file (every format
//! [`splatbridge_scene::formats`] reads, detected by content; the name is historical), and
//! with `--encode` the time to encode the loaded cloud as SPZ, `.splat` or compressed PLY.
//!
//! One untimed load warms the page cache, then `--repeat` timed loads; reported: the median
//! wall time, file MB/s at the median (MB = 10⁶ bytes), and the process's peak resident memory
//! (`VmHWM` from `/proc/self/status`) above its resident size before the first load, relative
//! to the size of the loaded cloud's arrays; and the most the load held on the heap at once
//! (`splatbridge::measure::heap`, the counting allocator), which leaves out the fixed runtime costs the
//! resident figure includes (code pages, thread stacks, malloc arenas). Each cloud is dropped before the next load, so
//! the peak is one load's.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use splatbridge::measure::heap;
use splatbridge::measure::memory::proc_status_bytes;
use splatbridge_scene::formats::{compressed_ply, load_cloud, splat, spz};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::GaussianCloud;

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), "."))]
    pub file: PathBuf,
    /// Also time encoding the loaded cloud (in memory) in this format.
    #[arg(long, value_enum)]
    pub encode: Option<EncodeArg>,
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

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum EncodeArg {
    /// SPZ v3, gzip level 6.
    Spz,
    /// antimatter15 .splat.
    Splat,
    /// Compressed PLY.
    CompressedPly,
}

fn encode(c: &GaussianCloud, e: EncodeArg) -> anyhow::Result<usize> {
    Ok(match e {
        EncodeArg::Spz => spz::encode_spz(c, &spz::SpzOptions::default())?.len(),
        EncodeArg::Splat => splat::encode_splat(c)?.len(),
        EncodeArg::CompressedPly => compressed_ply::encode_compressed_ply(c)?.len(),
    })
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
    let (cloud, info) = load_cloud(&args.file, &opts)?;
    let (n, degree, data) = (cloud.len(), cloud.sh_degree, cloud_bytes(&cloud));
    drop(cloud);
    let mut times = Vec::with_capacity(args.repeat.max(1));
    // The most any one load held on the heap above what was allocated before it.
    heap::enable();
    let mut heap_peak = 0usize;
    for _ in 0..args.repeat.max(1) {
        let base = heap::current();
        heap::reset_peak();
        let t = Instant::now();
        let loaded = load_cloud(&args.file, &opts)?;
        times.push(t.elapsed().as_secs_f64());
        heap_peak = heap_peak.max((heap::peak() - base).max(0) as usize);
        drop(loaded);
    }
    let heap_ratio = heap_peak as f64 / data.max(1) as f64;
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let mb_s = file_bytes as f64 / 1e6 / median;
    let peak = proc_status_bytes("VmHWM:");
    let above = match (peak, rss_before) {
        (Some(p), Some(b)) => Some(p.saturating_sub(b)),
        _ => None,
    };
    let ratio = above.map(|a| a as f64 / data.max(1) as f64);
    // Encoding after the load measurements, so its buffers do not count in the load's peak.
    let encoded = match args.encode {
        Some(e) => {
            let (cloud, _) = load_cloud(&args.file, &opts)?;
            let mut t_enc = Vec::with_capacity(args.repeat.max(1));
            let mut bytes = 0;
            for _ in 0..args.repeat.max(1) {
                let t = Instant::now();
                bytes = encode(&cloud, e)?;
                t_enc.push(t.elapsed().as_secs_f64());
            }
            t_enc.sort_by(f64::total_cmp);
            Some((
                format!("{e:?}").to_lowercase(),
                t_enc[t_enc.len() / 2],
                bytes,
            ))
        }
        None => None,
    };
    if args.json {
        let v = serde_json::json!({
            "file": args.file.display().to_string(),
            "format": info.format.to_string(),
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
            "heap_peak_bytes": heap_peak,
            "heap_peak_over_cloud": heap_ratio,
            "encode": encoded.as_ref().map(|(f, s, b)| serde_json::json!({"format": f, "median_s": s, "bytes": b})),
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
    println!("format        {}", info.format);
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
    println!(
        "peak heap     {:.1} MiB allocated by one load = {heap_ratio:.2}× the cloud",
        mib(heap_peak as u64)
    );
    if let Some((f, s, b)) = encoded {
        println!("encode {f:<6} median {:.2} ms, {b} bytes", s * 1e3);
    }
    Ok(())
}
