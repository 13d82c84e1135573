//! PSNR and SSIM of PNG images against a reference PNG, with the metrics `compare` uses
//! (`scene::metrics` on display values in [0, 1]). Used by `scripts/viewer-levers.sh`.
//!
//! `cargo run --release --example image_psnr -- REFERENCE IMAGE [REFERENCE IMAGE …]` prints
//! one line per pair (`psnr ssim`) and the mean PSNR of all pairs. Exit status 2 on a load
//! error or a size mismatch.
//!
//! An example rather than a CLI subcommand: it is an instrument of the measurement script.

use std::path::Path;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.is_empty() || !args.len().is_multiple_of(2) {
        eprintln!("usage: image_psnr REFERENCE IMAGE [REFERENCE IMAGE …]");
        return ExitCode::from(2);
    }
    let mut sum = 0.0;
    for pair in args.chunks_exact(2) {
        let load = |p: &str| splatbridge_scene::image_io::load_png(Path::new(p));
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
