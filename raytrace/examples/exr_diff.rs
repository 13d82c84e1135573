//! Compare two EXR renders: pixels whose RGBA bits differ, largest difference and PSNR of the
//! RGB clamped to [0, 1] (as `splatbridge_scene::metrics::psnr`). Used to check that a faster
//! trace keeps its images (`docs/trace-speed.md`).
//!
//! `cargo run --release -p splatbridge-raytrace --example exr_diff -- A.exr B.exr`

use exr::prelude::*;

type Pixels = (usize, Vec<[f32; 4]>);

fn load(path: &str) -> Pixels {
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0f32; 4]; res.width() * res.height()]),
        |(w, v): &mut Pixels, pos, (r, g, b, a): (f32, f32, f32, f32)| {
            v[pos.y() * *w + pos.x()] = [r, g, b, a];
        },
    )
    .unwrap_or_else(|e| panic!("{path}: {e}"));
    img.layer_data.channel_data.pixels
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [a, b] = &args[..] else {
        eprintln!("usage: exr_diff A.exr B.exr");
        std::process::exit(2);
    };
    let ((wa, pa), (wb, pb)) = (load(a), load(b));
    assert!(wa == wb && pa.len() == pb.len(), "sizes differ");
    let (mut differ, mut max, mut se) = (0usize, 0f32, 0f64);
    for (x, y) in pa.iter().zip(&pb) {
        if x.iter().zip(y).any(|(p, q)| p.to_bits() != q.to_bits()) {
            differ += 1;
        }
        for c in 0..3 {
            let d = x[c].clamp(0.0, 1.0) - y[c].clamp(0.0, 1.0);
            max = max.max(d.abs());
            se += (d as f64) * (d as f64);
        }
    }
    let mse = se / (3 * pa.len()) as f64;
    let psnr = if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    };
    println!(
        "{} of {} pixels differ in bits; max |Δ| {max:.3e}; PSNR {psnr:.2} dB",
        differ,
        pa.len()
    );
}
