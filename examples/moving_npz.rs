//! A Dynamic3DGaussians `params.npz` with known motion, for measuring the per-frame `.npz`
//! reader at scale: the capture `examples/moving_sequence.rs` writes as numbered PLYs (the
//! synthetic `scene::fixtures::large(COUNT, SEED)` with rigid balls moved along SE(3) paths
//! and one deforming ball), written as `helpers.py::save_params` writes it: `means3D` T×N×3,
//! `unnorm_rotations` T×N×4 (w,x,y,z), `rgb_colors` T×N×3, `log_scales` N×3,
//! `logit_opacities` N×1, `seg_colors` N×3, float32, C order, stored (`np.savez`) or deflated
//! (`--compressed`, `np.savez_compressed`); ZIP64 when a member passes 4 GiB, as NumPy does.
//!
//! `cargo run --release --example moving_npz -- OUT.npz [--count N] [--frames T] [--distinct K]
//! [--compressed] [--seed S]`
//!
//! `--distinct K` makes K distinct frames (default: all T) and writes frame i as distinct frame
//! i mod K, so generating a long capture holds K frames (the file still holds all T). Exit
//! status 2 on bad arguments or an output that cannot be written.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use splatbridge_scene::fixtures::moving::{moving_cutouts, MovingParams};
use splatbridge_scene::GaussianCloud;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// A `.npy` header (version 1) for a float32 C-order array, padded as NumPy pads it (the
/// values start at a multiple of 64).
fn npy_header(shape: &[usize]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let tuple = if shape.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut h = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {tuple}, }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((h.len() as u16).to_le_bytes());
    out.extend(h.as_bytes());
    out
}

fn floats(v: impl Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(f32::to_le_bytes).collect()
}

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut out: Option<PathBuf> = None;
    let (mut count, mut frames, mut distinct, mut seed, mut compressed) =
        (500_000usize, 300usize, None, 1u64, false);
    while let Some(a) = args.next() {
        let mut value = |name: &str| {
            args.next()
                .ok_or_else(|| format!("{name}: expected a value"))
        };
        match a.as_str() {
            "--count" => count = num(&value("--count")?, "--count")?,
            "--frames" => frames = num(&value("--frames")?, "--frames")?,
            "--distinct" => distinct = Some(num(&value("--distinct")?, "--distinct")?),
            "--seed" => seed = num(&value("--seed")?, "--seed")? as u64,
            "--compressed" => compressed = true,
            _ if out.is_none() && !a.starts_with("--") => out = Some(PathBuf::from(a)),
            _ => return Err(format!("unexpected argument '{a}' (usage: moving_npz OUT.npz [--count N] [--frames T] [--distinct K] [--compressed] [--seed S])")),
        }
    }
    let out = out.ok_or("usage: moving_npz OUT.npz [--count N] [--frames T] [--distinct K]")?;
    if count == 0 || frames == 0 {
        return Err("--count and --frames must be at least 1".into());
    }
    let distinct = distinct.unwrap_or(frames).clamp(1, frames);
    let base = splatbridge_scene::fixtures::large(count, seed);
    // The parameters `moving_sequence` uses: three rigid balls and a deforming one of radius
    // 0.05 diagonal.
    let params = MovingParams {
        objects: 3,
        frames: distinct,
        fps: 30.0,
        radius: 0.05,
        seed,
        ..MovingParams::default()
    };
    let (clouds, _, truth) = moving_cutouts(&base, &params);
    drop(base);
    let n = clouds[0].len();
    if clouds.iter().any(|c| c.len() != n) {
        return Err("the capture's frames differ in count".into());
    }
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", out.display());
    let file = std::fs::File::create(&out).map_err(|e| err(&e))?;
    let mut z = zip::ZipWriter::new(std::io::BufWriter::with_capacity(1 << 20, file));
    let method = if compressed {
        zip::CompressionMethod::Deflated
    } else {
        zip::CompressionMethod::Stored
    };
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(method)
        .large_file(true);
    let c0 = splatbridge_scene::sh::SH_C0;
    type PerFrame = fn(&GaussianCloud, f32) -> Vec<u8>;
    let per_frame: [(&str, usize, PerFrame); 3] = [
        ("means3D", 3, |c, _| {
            floats(c.means.iter().flat_map(|m| m.to_array()))
        }),
        ("unnorm_rotations", 4, |c, _| {
            floats(c.rotations.iter().flat_map(|q| [q.w, q.x, q.y, q.z]))
        }),
        ("rgb_colors", 3, |c, c0| {
            floats(
                (0..c.len()).flat_map(|i| (glam::Vec3::splat(0.5) + c0 * c.sh_of(i)[0]).to_array()),
            )
        }),
    ];
    for (name, k, values) in per_frame {
        z.start_file(format!("{name}.npy"), opts)
            .map_err(|e| err(&e))?;
        z.write_all(&npy_header(&[frames, n, k]))
            .map_err(|e| err(&e))?;
        for f in 0..frames {
            z.write_all(&values(&clouds[f % distinct], c0))
                .map_err(|e| err(&e))?;
        }
    }
    let first = &clouds[0];
    let constants: [(&str, Vec<usize>, Vec<u8>); 3] = [
        (
            "log_scales",
            vec![n, 3],
            floats(first.log_scales.iter().flat_map(|s| s.to_array())),
        ),
        (
            "logit_opacities",
            vec![n, 1],
            floats(first.opacity_logits.iter().copied()),
        ),
        (
            "seg_colors",
            vec![n, 3],
            floats(truth.labels.iter().flat_map(|&l| {
                let on = if l == 0 { 0.0 } else { 1.0 };
                [on, 0.0, 1.0 - on]
            })),
        ),
    ];
    for (name, shape, bytes) in constants {
        z.start_file(format!("{name}.npy"), opts)
            .map_err(|e| err(&e))?;
        z.write_all(&npy_header(&shape)).map_err(|e| err(&e))?;
        z.write_all(&bytes).map_err(|e| err(&e))?;
    }
    z.finish().map_err(|e| err(&e))?;
    let moving = truth.labels.iter().filter(|&&l| l != 0).count();
    println!(
        "{}: {frames} timesteps ({distinct} distinct) of {n} Gaussians, {}; {moving} move ({:.1} %)",
        out.display(),
        if compressed { "deflated" } else { "stored" },
        100.0 * moving as f64 / n as f64
    );
    Ok(())
}

fn num(v: &str, name: &str) -> Result<usize, String> {
    v.parse()
        .map_err(|_| format!("{name}: '{v}' is not a count"))
}
