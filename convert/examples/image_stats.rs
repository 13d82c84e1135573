//! PSNR between two PNG images of the same size (scene::metrics), for the render comparison
//! scripts: `image_stats A.png B.png` prints one JSON line with the PSNR (dB, RGB in [0, 1]),
//! the mean of each image and the mean signed difference A − B.

use splatbridge_scene::image_io::load_png;
use splatbridge_scene::metrics;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: image_stats A.png B.png");
        std::process::exit(2);
    }
    let load = |p: &str| {
        load_png(std::path::Path::new(p)).unwrap_or_else(|e| {
            eprintln!("error: {e}");
            std::process::exit(2);
        })
    };
    let (a, b) = (load(&args[1]), load(&args[2]));
    let psnr = metrics::psnr(&a, &b).unwrap_or_else(|e| {
        eprintln!("error: {}: {e}", args[2]);
        std::process::exit(2);
    });
    let mean = |f: &splatbridge_scene::frame::Frame| {
        f.rgb.iter().map(|&x| x as f64).sum::<f64>() / f.rgb.len().max(1) as f64
    };
    let (ma, mb) = (mean(&a), mean(&b));
    println!(
        "{}",
        serde_json::json!({"a": args[1], "b": args[2], "psnr_db": psnr, "mean_a": ma, "mean_b": mb, "mean_a_minus_b": ma - mb})
    );
}
