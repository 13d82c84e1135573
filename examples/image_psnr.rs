//! PSNR and SSIM of PNG images against a reference PNG, with the metrics `compare` uses
//! (`scene::metrics` on display values in [0, 1]). Used by `scripts/viewer-levers.sh`.
//!
//! `cargo run --release --example image_psnr -- REFERENCE IMAGE [REFERENCE IMAGE …]` prints
//! one line per pair (`psnr ssim`) and the mean PSNR of all pairs. `--border PX` (first
//! argument) measures only the interior, `PX` pixels in from every edge: it tells errors at the
//! image's edges (a viewer's frustum culling) from errors everywhere. Exit status 2 on a load
//! error, a size mismatch or a border that leaves no pixel.
//!
//! An example rather than a CLI subcommand: it is an instrument of the measurement script.

use std::path::Path;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut border = 0u32;
    if args.first().map(String::as_str) == Some("--border") {
        match args.get(1).and_then(|v| v.parse().ok()) {
            Some(b) => border = b,
            None => {
                eprintln!("error: --border: expected a pixel count");
                return ExitCode::from(2);
            }
        }
        args.drain(..2);
    }
    if args.is_empty() || !args.len().is_multiple_of(2) {
        eprintln!("usage: image_psnr [--border PX] REFERENCE IMAGE [REFERENCE IMAGE …]");
        return ExitCode::from(2);
    }
    let mut sum = 0.0;
    for pair in args.chunks_exact(2) {
        let load = |p: &str| {
            splatbridge_scene::image_io::load_png(Path::new(p)).and_then(|f| interior(f, border))
        };
        let res = load(&pair[0]).and_then(|a| {
            let b = load(&pair[1])?;
            Ok((
                splatbridge_scene::metrics::psnr(&a, &b)?,
                splatbridge_scene::metrics::ssim(&a, &b)?,
            ))
        });
        match res {
            Ok((p, s)) => {
                println!("{} {p:.3} {s:.4}", pair[1]);
                sum += p;
            }
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        }
    }
    println!("mean {:.3}", sum / (args.len() / 2) as f64);
    ExitCode::SUCCESS
}

/// The frame without `b` pixels at every edge (colour only: the metrics read nothing else).
fn interior(
    f: splatbridge_scene::Frame,
    b: u32,
) -> Result<splatbridge_scene::Frame, splatbridge_scene::SceneError> {
    if b == 0 {
        return Ok(f);
    }
    let (w, h) = (
        f.width.saturating_sub(2 * b),
        f.height.saturating_sub(2 * b),
    );
    if w == 0 || h == 0 {
        return Err(splatbridge_scene::SceneError::Invalid(format!(
            "a border of {b} pixels leaves nothing of a {}×{} image",
            f.width, f.height
        )));
    }
    let mut out = splatbridge_scene::Frame::new(w, h);
    for y in 0..h {
        let src = 3 * ((y + b) * f.width + b) as usize;
        let dst = 3 * (y * w) as usize;
        out.rgb[dst..dst + 3 * w as usize].copy_from_slice(&f.rgb[src..src + 3 * w as usize]);
    }
    Ok(out)
}
