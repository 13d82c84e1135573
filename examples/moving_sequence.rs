//! A numbered PLY frame sequence with known motion, for measuring `convert --objects` and
//! `convert --frames` at scale: the synthetic capture `scene::fixtures::large(COUNT, SEED)` as
//! the background, rigid balls cut out and moved along SE(3) paths and one deforming ball
//! (`scene::fixtures::moving::moving_cutouts`), written as `OUT/frame_0000.ply`, … (binary,
//! SH degree 0).
//!
//! `cargo run --release --example moving_sequence -- OUT [--count N] [--frames T] [--distinct K]
//! [--objects B] [--radius R] [--seed S] [--input PLY [--every E]] [--noise F]`
//!
//! `--input PLY` takes a real capture as the background instead of the synthetic one (every
//! E-th Gaussian of it; `--count` is then ignored); `--noise F` sets the per-frame jitter of
//! every mean (σ per axis as a fraction of the robust diagonal; default 1e-4, so every Gaussian
//! moves a little in every frame; 0 leaves the background still).
//!
//! `--distinct K` writes K distinct frames (default: all T) and hard-links frame i to distinct
//! frame i mod K, so a long sequence costs K frames of disk (the motion then repeats every K
//! frames: still rigid per group, a harder trajectory for the search). Exit status 2 on bad
//! arguments or an output that cannot be written.
//!
//! An example rather than a CLI subcommand: it is an instrument of the measurements in
//! docs/motion.md.

use std::path::PathBuf;
use std::process::ExitCode;

use splatbridge_scene::fixtures::moving::{moving_cutouts, MovingParams};
use splatbridge_scene::ply::{write_ply, PlyFormat};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut out: Option<PathBuf> = None;
    let (mut count, mut frames, mut distinct, mut objects, mut radius, mut seed) =
        (500_000usize, 300usize, None, 3usize, 0.05f64, 1u64);
    let (mut input, mut every, mut noise): (Option<PathBuf>, usize, f64) =
        (None, 1, MovingParams::default().noise);
    while let Some(a) = args.next() {
        let mut value = |name: &str| {
            args.next()
                .ok_or_else(|| format!("{name}: expected a value"))
        };
        match a.as_str() {
            "--count" => count = num(&value("--count")?, "--count")?,
            "--frames" => frames = num(&value("--frames")?, "--frames")?,
            "--distinct" => distinct = Some(num(&value("--distinct")?, "--distinct")?),
            "--objects" => objects = num(&value("--objects")?, "--objects")?,
            "--seed" => seed = num(&value("--seed")?, "--seed")? as u64,
            "--input" => input = Some(PathBuf::from(value("--input")?)),
            "--every" => every = num(&value("--every")?, "--every")?.max(1),
            "--noise" => {
                let v = value("--noise")?;
                noise = v
                    .parse()
                    .ok()
                    .filter(|r: &f64| (0.0..0.1).contains(r))
                    .ok_or(format!("--noise: '{v}' is not in [0, 0.1)"))?;
            }
            "--radius" => {
                let v = value("--radius")?;
                radius = v
                    .parse()
                    .ok()
                    .filter(|r: &f64| *r > 0.0 && *r < 0.5)
                    .ok_or(format!("--radius: '{v}' is not in (0, 0.5)"))?;
            }
            _ if out.is_none() && !a.starts_with("--") => out = Some(PathBuf::from(a)),
            _ => return Err(format!("unexpected argument '{a}' (usage: moving_sequence OUT [--count N] [--frames T] [--distinct K] [--objects B] [--radius R] [--seed S] [--input PLY [--every E]] [--noise F])")),
        }
    }
    let out = out.ok_or("usage: moving_sequence OUT [--count N] [--frames T] [--distinct K]")?;
    if count == 0 || frames == 0 {
        return Err("--count and --frames must be at least 1".into());
    }
    let distinct = distinct.unwrap_or(frames).clamp(1, frames);
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let base = match &input {
        Some(p) => {
            let opts = splatbridge_scene::ply::ReadOptions { drop_invalid: true };
            let (c, _) = splatbridge_scene::formats::load_cloud(p, &opts)
                .map_err(|e| format!("{}: {e}", p.display()))?;
            let mut c = c;
            c.retain_indices(|i| i % every == 0);
            count = c.len();
            c
        }
        None => splatbridge_scene::fixtures::large(count, seed),
    };
    let params = MovingParams {
        objects,
        frames: distinct,
        fps: 30.0,
        radius,
        seed,
        noise,
        ..MovingParams::default()
    };
    let (clouds, _, truth) = moving_cutouts(&base, &params);
    drop(base);
    let name = |i: usize| out.join(format!("frame_{i:04}.ply"));
    for (i, c) in clouds.iter().enumerate() {
        write_ply(&name(i), c, PlyFormat::BinaryLittleEndian).map_err(|e| e.to_string())?;
    }
    for i in distinct..frames {
        let p = name(i);
        let _ = std::fs::remove_file(&p);
        std::fs::hard_link(name(i % distinct), &p).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    let moving = truth.labels.iter().filter(|&&l| l != 0).count();
    println!(
        "{}: {frames} frames ({distinct} distinct) of {count} Gaussians; {objects} rigid balls and a deforming one hold {moving} ({:.1} %)",
        out.display(),
        100.0 * moving as f64 / count as f64
    );
    Ok(())
}

fn num(v: &str, name: &str) -> Result<usize, String> {
    v.parse()
        .map_err(|_| format!("{name}: '{v}' is not a count"))
}
