//! What `convert` prints: the summary of a mesh or glTF splat export and of a single-cloud
//! splat file (on stderr; `--json` reports go to stdout).

use splatbridge::pipeline::export::CloudExport;
use splatbridge_convert::ConvertReport;

use super::Args;

/// A single-cloud splat file: what was written (`objects`: the scene's dynamic objects,
/// composited into the one cloud).
pub fn print_cloud(
    args: &Args,
    c: &CloudExport,
    objects: usize,
    seconds: f64,
) -> anyhow::Result<()> {
    if args.json {
        let v = serde_json::json!({
            "input": args.scene.display().to_string(),
            "output": args.output.display().to_string(),
            "format": c.format,
            "gaussians": c.gaussians,
            "sh_degree": c.sh_degree,
            "time": c.time,
            "bytes": c.bytes,
            "seconds": seconds,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        eprintln!(
            "{} → {} ({}, {} Gaussians, SH degree {}{})",
            args.scene.display(),
            args.output.display(),
            c.format,
            c.gaussians,
            c.sh_degree,
            if objects == 0 {
                String::new()
            } else {
                format!(", composited at t = {}", c.time)
            }
        );
        print_bytes_and_time(c.bytes, seconds);
    }
    Ok(())
}

/// The closing lines of both summaries.
fn print_bytes_and_time(bytes: u64, seconds: f64) {
    eprintln!(
        "  bytes          {:>12}  ({:.1} MB)",
        bytes,
        bytes as f64 / 1e6
    );
    eprintln!("  time           {seconds:>12.3} s");
}

pub fn print_summary(args: &Args, r: &ConvertReport) {
    eprintln!(
        "{} → {} ({}, profile {}, {} segments, {} rings)",
        args.scene.display(),
        args.output.display(),
        r.format,
        r.profile,
        r.segments,
        r.rings
    );
    let kept: u64 = r.meshes.iter().map(|m| m.flat + m.volumetric).sum();
    let flat: u64 = r.meshes.iter().map(|m| m.flat).sum();
    eprintln!("  Gaussians in   {:>12}", r.gaussians_in);
    eprintln!(
        "  kept           {:>12}  ({} flat, {} volumetric)",
        kept,
        flat,
        kept - flat
    );
    for (what, n) in [
        ("invalid", r.dropped_invalid),
        ("below 1/255 opacity", r.dropped_transparent),
        ("scale overflow", r.dropped_overflow),
        ("triangle budget", r.dropped_budget),
    ] {
        if n > 0 {
            eprintln!("  dropped        {n:>12}  ({what})");
        }
    }
    if let Some(s) = &r.surfels {
        eprintln!(
            "  surfels        {:>12}  (opacity ≥ {}, flatness ≤ {}, {}, {}-segment opaque fans{})",
            s.surfels,
            s.min_opacity,
            s.max_flatness,
            if s.guarded {
                format!("guarded: {} kept as Gaussians", s.guarded_out)
            } else {
                "unguarded".to_string()
            },
            s.segments,
            if s.dropped_overflow > 0 {
                format!(", {} dropped: scale overflow", s.dropped_overflow)
            } else {
                String::new()
            }
        );
        eprintln!(
            "  residual       {:>12}  (Gaussians left to profile {})",
            s.residual, r.profile
        );
    }
    if r.triangles > 0 {
        eprintln!("  vertices       {:>12}", r.vertices);
        eprintln!("  triangles      {:>12}", r.triangles);
    }
    print_bytes_and_time(r.bytes, r.seconds);
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
}
