//! `splatbridge bench trace`: for every compiled-in backend (obvhs, and Embree with
//! `--features embree`), BVH build time, primary-ray throughput with full compositing
//! (median over repeats) and mean hits per ray, on one input and camera; and the largest
//! pixel difference between the backends' images. Native splatting renders the same camera in
//! the same run (median over the same repeats, after one warm-up render) and every traced time
//! is printed as a multiple of it: the input itself when it is a scene, `--native SCENE` for an
//! exported file (the scene it was exported from). The load average is printed beside it.

use anyhow::Context;
use splatbridge_raytrace::backend::EMBREE_AVAILABLE;
use splatbridge_raytrace::BackendKind;

use splatbridge::pipeline::Renderer;

use crate::cmd::trace::TraceInput;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub input: TraceInput,
    /// Timed renders per backend (the median is reported).
    #[arg(long = "repeat", alias = "repeats", default_value_t = 3)]
    pub repeats: usize,
    /// The scene native splatting renders for the ratio (default: the input, when it is a
    /// scene rather than an exported file).
    #[arg(long, value_name = "SCENE")]
    pub native: Option<std::path::PathBuf>,
}

/// Median wall time of native splatting of `scene` through `cam` over `repeats` renders, after
/// one warm-up render (as `bench render` times it).
fn native_seconds(
    scene: &std::path::Path,
    cam: &splatbridge_scene::Camera,
    repeats: usize,
) -> anyhow::Result<f64> {
    let s = crate::cmd::common::load(scene, false)?;
    let cloud = s.composite(s.time.start);
    let opts = splatbridge_hybrid::RenderOptions::default();
    let mut r = splatbridge_hybrid::Renderer::new();
    r.render(&cloud, cam, &opts)?;
    let mut times = Vec::new();
    for _ in 0..repeats.max(1) {
        let t = std::time::Instant::now();
        r.render(&cloud, cam, &opts)?;
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let p = args.input.prepare()?;
    println!("{}", p.what);
    println!(
        "camera '{}' {}×{}, k = {}, preset {:?}, {} rayon threads",
        p.camera.name,
        p.camera.width,
        p.camera.height,
        p.options.k,
        args.input.preset,
        rayon::current_num_threads()
    );
    let native_scene = args.native.clone().or_else(|| {
        let i = &args.input.input;
        (!splatbridge::pipeline::source::is_mesh_file(i)).then(|| i.clone())
    });
    let native = match &native_scene {
        Some(n) => Some(
            native_seconds(n, &p.camera, args.repeats)
                .with_context(|| format!("native render of {}", n.display()))?,
        ),
        None => None,
    };
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    match native {
        Some(t) => println!(
            "native splatting: {:.1} ms (median of {}); load average {}",
            t * 1e3,
            args.repeats.max(1),
            load.split_whitespace()
                .take(3)
                .collect::<Vec<_>>()
                .join(" ")
        ),
        None => {
            println!("native splatting: not measured (give --native SCENE for an exported file)")
        }
    }
    let mut backends = vec![BackendKind::Obvhs];
    if EMBREE_AVAILABLE {
        backends.push(BackendKind::Embree);
    } else {
        println!(
            "embree: not compiled in (build with --features embree after scripts/get-embree.sh)"
        );
    }
    let mut frames = Vec::new();
    println!(
        "{:<8} {:>10} {:>12} {:>10} {:>10} {:>14} {:>14} {:>10}",
        "backend",
        "build s",
        "trace s",
        "Mrays/s",
        "hits/ray",
        "traversals/ray",
        "candidates/ray",
        "× native"
    );
    for b in backends {
        let tracer = Renderer::tracer(&p, b, args.input.preset.into())
            .with_context(|| format!("backend {b}"))?;
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..args.repeats.max(1) {
            let (f, s) = tracer.render_traced(&p.camera, p.time)?;
            times.push(s.seconds);
            last = Some((f, s));
        }
        times.sort_by(f64::total_cmp);
        let med = times[times.len() / 2];
        let (f, s) = last.expect("at least one repeat");
        let ratio = native.map_or("—".to_string(), |n| format!("{:.1}", med / n));
        println!(
            "{:<8} {:>10.3} {:>12.3} {:>10.3} {:>10.2} {:>14.2} {:>14.1} {:>10}",
            b.to_string(),
            tracer.build_seconds(),
            med,
            s.rays as f64 / med / 1e6,
            s.hits_per_ray(),
            s.traversals as f64 / s.rays.max(1) as f64,
            s.candidates as f64 / s.rays.max(1) as f64,
            ratio
        );
        frames.push((b, f));
    }
    if frames.len() == 2 {
        let (a, b) = (&frames[0].1, &frames[1].1);
        // Pixels beyond the brute-force tests' 1e-5 bound: rays within f32 rounding of an
        // outer fan edge, where Embree's triangle test and the watertight one can disagree.
        let differ = a
            .rgb
            .chunks(3)
            .zip(b.rgb.chunks(3))
            .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| (x - y).abs() > 1e-5))
            .count();
        println!(
            "max |obvhs − embree| per channel: {:.3e}; pixels differing by more than 1e-5: {differ} of {}",
            a.max_rgb_diff(b),
            a.rgb.len() / 3
        );
    }
    Ok(())
}
