//! `splatbridge bench effects [SCENE]`: the cost of each declared effect per frame, switched on
//! alone, against the same frame with no effects: frame building (composite + particles, or
//! the motion-blur samples), native splatting of the frame (all samples, blended), the
//! Gaussian ray tracer (with shadow rays when shadows are on), and the LiDAR sweep; medians
//! over repeats, with the effect counters that explain them.
//!
//! Without SCENE the street fixture is built in memory. An effect the scene declares is
//! benchmarked with its own parameters; otherwise with the street's defaults
//! (`splatbridge fixture street --effects …`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use splatbridge::pipeline::{render_frame, FrameRequest, Renderer};
use splatbridge_raytrace::lidar::{scan, LidarSensor};
use splatbridge_raytrace::{BackendKind, BuildPreset, GaussianTracer, RenderOptions};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::effects_run::{blend_frames, build_blur_frames, effects_of};
use splatbridge_scene::fixtures::{self, street_effect, StreetParams, DEFAULT_STREET_GAUSSIANS};
use splatbridge_scene::{Camera, Frame};

use crate::cmd::common::{load, CameraArgs};

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), "; default: the street fixture in memory."))]
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Frame time in seconds.
    #[arg(long, default_value_t = 1.0, value_parser = crate::cmd::ranges::time, allow_hyphen_values = true)]
    pub time: f64,
    /// Timed runs per effect (the median is reported).
    #[arg(long = "repeat", alias = "repeats", default_value_t = 3)]
    pub repeats: usize,
}

/// Timings of one frame, milliseconds.
#[derive(Clone, Copy, Default)]
struct Times {
    build: f64,
    native: f64,
    bvh: f64,
    trace: f64,
    lidar: f64,
}

fn run_once(scene: &DynamicScene, t: f64, cam: &Camera) -> anyhow::Result<(Times, EffectCounters)> {
    let effects = effects_of(scene)?;
    let mut times = Times::default();
    let start = Instant::now();
    let blur = build_blur_frames(scene, t, Some(cam))?;
    times.build = start.elapsed().as_secs_f64() * 1e3;
    let mut counters = blur.counters.clone();

    let start = Instant::now();
    let mut native = Renderer::native(Default::default())?;
    let mut frames: Vec<Frame> = Vec::with_capacity(blur.samples.len());
    for s in &blur.samples {
        frames.push(native.render_cloud(&s.cloud, cam)?.0);
    }
    let weights: Vec<f32> = blur.samples.iter().map(|s| s.weight).collect();
    blend_frames(&frames, &weights)?;
    times.native = start.elapsed().as_secs_f64() * 1e3;

    // The tracer sees the frame at t: the first sample's content when nothing is blurred.
    let cloud = if blur.samples.len() == 1 {
        match blur.samples.into_iter().next() {
            Some(s) => s.cloud,
            None => splatbridge_scene::effects_run::build_frame(scene, t, Some(cam))?.cloud,
        }
    } else {
        splatbridge_scene::effects_run::build_frame(scene, t, Some(cam))?.cloud
    };
    let start = Instant::now();
    let tracer = GaussianTracer::new(cloud, BackendKind::Obvhs, BuildPreset::Medium)?;
    times.bvh = start.elapsed().as_secs_f64() * 1e3;
    let mut tracer = Renderer::Gaussian {
        tracer,
        options: RenderOptions::default(),
    };
    // One traced frame with the declared shadows: no scene, so one time sample (the frame's
    // content is already in the BVH) and no LiDAR (timed on its own below).
    let start = Instant::now();
    let traced = render_frame(
        &mut tracer,
        &FrameRequest {
            scene: None,
            effects: &effects,
            camera: cam,
            time: t,
            content: Default::default(),
            lidar: None,
        },
    )?;
    times.trace = start.elapsed().as_secs_f64() * 1e3;
    counters.shadow_rays += traced.counters.shadow_rays;
    if effects.shadows.is_some() {
        counters.simulated.push("shadows".into());
    }

    if let Some(l) = &effects.lidar {
        let start = Instant::now();
        let sensor = LidarSensor::from_effect(l, &scene.cameras)?;
        let Renderer::Gaussian { tracer, .. } = &tracer else {
            anyhow::bail!("the effects benchmark traces Gaussians");
        };
        let s = scan(tracer, &sensor, t);
        times.lidar = start.elapsed().as_secs_f64() * 1e3;
        counters.lidar_points += s.points.len() as u64;
        counters.lidar_rays += s.rays;
        counters.simulated.push("lidar".into());
    }
    Ok((times, counters))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (base, what) = match &args.scene {
        Some(p) => (load(p, false)?, p.display().to_string()),
        None => (
            fixtures::street_with(&StreetParams::new(1, DEFAULT_STREET_GAUSSIANS)),
            "street fixture (in memory)".to_string(),
        ),
    };
    let declared = base.effects.clone();
    let composite = base.composite(args.time);
    let mut cam_args = args.camera.clone();
    if cam_args.camera.is_none() && cam_args.eye.is_none() && !base.cameras.is_empty() {
        cam_args.camera = Some("scene:0".into());
    }
    let cam = cam_args
        .resolve(&composite, &base.cameras)
        .context(what.clone())?;
    println!(
        "{what}: {} Gaussians, frame t = {} s, camera '{}' {}×{}, {} rayon threads, median of {}",
        base.gaussian_count(),
        args.time,
        cam.name,
        cam.width,
        cam.height,
        rayon::current_num_threads(),
        args.repeats.max(1)
    );
    let mut cases: Vec<(&str, DynamicScene)> = Vec::new();
    let mut plain = base.clone();
    plain.effects.clear();
    cases.push(("none", plain.clone()));
    for (name, default_name) in [
        ("weather", "rain"),
        ("motion_blur", "motion_blur"),
        ("shadows", "shadows"),
        ("lidar", "lidar"),
    ] {
        let value = match declared.get(name) {
            Some(v) => v.clone(),
            None => {
                street_effect(default_name, 1)
                    .with_context(|| format!("no street default for effect {name}"))?
                    .1
            }
        };
        let mut s = plain.clone();
        s.effects.insert(name.into(), value);
        effects_of(&s).with_context(|| format!("effect {name}"))?;
        cases.push((name, s));
    }
    println!(
        "{:<12} {:>9} {:>10} {:>8} {:>10} {:>10} {:>10}  counters",
        "effect", "build ms", "native ms", "bvh ms", "trace ms", "lidar ms", "total ms"
    );
    // Repeats interleave the cases so that load from other processes falls on all of them alike.
    let mut all: Vec<(Vec<Times>, EffectCounters)> =
        vec![(Vec::new(), EffectCounters::default()); cases.len()];
    for _ in 0..args.repeats.max(1) {
        for ((name, scene), (runs, counters)) in cases.iter().zip(all.iter_mut()) {
            let (t, c) =
                run_once(scene, args.time, &cam).with_context(|| format!("effect {name}"))?;
            runs.push(t);
            *counters = c;
        }
    }
    let mut none_total = None;
    for ((name, _), (runs, counters)) in cases.iter().zip(&all) {
        let m = |f: fn(&Times) -> f64| median(runs.iter().map(f).collect());
        let (b, n, bv, tr, l) = (
            m(|t| t.build),
            m(|t| t.native),
            m(|t| t.bvh),
            m(|t| t.trace),
            m(|t| t.lidar),
        );
        let total = b + n + bv + tr + l;
        let extra = match none_total {
            None => {
                none_total = Some(total);
                String::new()
            }
            Some(z) => format!(" ({:+.1} ms)", total - z),
        };
        println!(
            "{:<12} {:>9.2} {:>10.2} {:>8.2} {:>10.2} {:>10.2} {:>10.2}  particles {}, extra time samples {}, shadow rays {}, lidar rays {} → points {}{extra}",
            name,
            b,
            n,
            bv,
            tr,
            l,
            total,
            counters.particles,
            counters.extra_time_samples,
            counters.shadow_rays,
            counters.lidar_rays,
            counters.lidar_points,
        );
    }
    Ok(())
}
