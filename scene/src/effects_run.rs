//! The frame producer every renderer and exporter calls: the world-space content of one frame
//! with the declared effects applied, and counters saying what that cost. An effect that is not
//! declared costs nothing: with no `weather` and no `motion_blur`, [`build_frame`] returns
//! exactly [`DynamicScene::composite`] (bit-identical) and all-zero counters.
//!
//! - `weather` ([`crate::weather::particles`]): particles at the frame time in the declared
//!   volume, appended after the scene's Gaussians with object id `objects.len() + 1`. The
//!   `scene` volume is the static Gaussians' robust bounds (2nd–98th percentile per axis; every
//!   Gaussian's when there is no static cloud), widened to at least a tenth of the largest
//!   extent on each axis (upwards, −y, for the vertical axis) so a flat capture still gets a
//!   layer of air. The `camera` volume is a box around the scene's camera `index`, or around
//!   the render camera when the scene has no camera of that index (a PLY rendered from an
//!   orbit camera).
//! - `motion_blur` ([`time_samples`], [`build_blur_frames`]): the shutter `[t, t + shutter]`
//!   sampled at stratified centres `t + shutter·(i + ½)/n` with equal weights, only when some
//!   object moves. Static Gaussians and objects whose track is constant are composited once per
//!   frame and copied into every sample; only moving objects are posed per sample. Weather
//!   particles are generated once per frame (rain streaks already encode their exposure) and
//!   shared by all samples. A renderer renders each sample and averages with [`blend_frames`].
//! - `shadows` and `lidar` are simulated by the ray tracer (`splatbridge_raytrace::shadows`,
//!   `splatbridge_raytrace::lidar`); renderers that cannot simulate them list them in
//!   [`EffectCounters::not_simulated`] via [`not_simulated`].
//!
//! Per-frame exports of weather (one glTF node per frame, OBJ per frame) take
//! [`weather_frames`].

use std::time::Instant;

use glam::Vec3;

use crate::dynamic::DynamicScene;
use crate::effects::{EffectCounters, Effects, Weather, WeatherVolume};
use crate::error::{Result, SceneError};
use crate::{Camera, Frame, GaussianCloud};

/// One frame's content and what the effects cost.
#[derive(Clone, Debug)]
pub struct FrameBuild {
    pub cloud: GaussianCloud,
    pub counters: EffectCounters,
}

/// A motion-blurred frame: one cloud per time sample with its weight (weights sum to 1).
#[derive(Clone, Debug)]
pub struct BlurBuild {
    pub samples: Vec<BlurSample>,
    pub counters: EffectCounters,
}

#[derive(Clone, Debug)]
pub struct BlurSample {
    pub time: f64,
    pub weight: f32,
    pub cloud: GaussianCloud,
}

/// The scene's declared effects, parsed and validated.
pub fn effects_of(scene: &DynamicScene) -> Result<Effects> {
    Effects::from_json(&scene.effects).map_err(SceneError::Invalid)
}

/// Object id given to weather particles: one past the last object's (`k + 1` for object k).
pub fn weather_object_id(scene: &DynamicScene) -> u32 {
    scene.objects.len() as u32 + 1
}

/// The content of the frame at `t`: the composite plus weather particles when declared.
/// `camera` is the render camera (see the module docs for the `camera` weather volume).
/// Motion blur is not applied here (see [`build_blur_frames`]); shadows and LiDAR are not
/// content.
pub fn build_frame(scene: &DynamicScene, t: f64, camera: Option<&Camera>) -> Result<FrameBuild> {
    let effects = effects_of(scene)?;
    let mut cloud = scene.composite(t);
    let mut counters = EffectCounters::default();
    if let Some(w) = &effects.weather {
        let start = Instant::now();
        let p = weather_particles(scene, w, t, camera)?;
        counters.particles = p.len() as u64;
        cloud.extend_from(&p, Some(weather_object_id(scene)));
        counters.milliseconds += start.elapsed().as_secs_f64() * 1e3;
        counters.simulated.push("weather".into());
    }
    Ok(FrameBuild { cloud, counters })
}

/// The particles of `w` at time `t` in its resolved volume.
pub fn weather_particles(
    scene: &DynamicScene,
    w: &Weather,
    t: f64,
    camera: Option<&Camera>,
) -> Result<GaussianCloud> {
    let (lo, hi) = weather_volume(scene, w, t, camera)?;
    Ok(crate::weather::particles(w, t, lo, hi))
}

/// Resolve the declared weather volume to a box (see the module docs).
pub fn weather_volume(
    scene: &DynamicScene,
    w: &Weather,
    t: f64,
    camera: Option<&Camera>,
) -> Result<(Vec3, Vec3)> {
    match &w.volume {
        WeatherVolume::Box { min, max } => Ok((Vec3::from(*min), Vec3::from(*max))),
        WeatherVolume::Camera { index, half_extent } => {
            let centre = match (scene.cameras.get(*index), camera) {
                (Some(c), _) => c.centre,
                (None, Some(c)) => c.centre,
                (None, None) => {
                    return Err(SceneError::Invalid(format!(
                        "effects.weather.volume.camera.index = {index}: the scene has {} cameras and no render camera was given",
                        scene.cameras.len()
                    )))
                }
            };
            let h = Vec3::from(*half_extent);
            let c = centre.as_vec3();
            Ok((c - h, c + h))
        }
        WeatherVolume::Scene => {
            let bounds = if scene.static_gaussians.is_empty() {
                scene.composite(t).robust_bounds(0.02)
            } else {
                scene.static_gaussians.robust_bounds(0.02)
            };
            let (mut lo, mut hi) = bounds.ok_or_else(|| {
                SceneError::Invalid(
                    "effects.weather.volume = scene: the scene has no (finite) Gaussians to bound the weather; give a box".into(),
                )
            })?;
            let min_extent = 0.1 * (hi - lo).max_element().max(1e-3);
            for axis in 0..3 {
                let deficit = min_extent - (hi[axis] - lo[axis]);
                if deficit > 0.0 {
                    if axis == 1 {
                        // World up is −y: add the missing air above the capture.
                        lo[axis] -= deficit;
                    } else {
                        lo[axis] -= 0.5 * deficit;
                        hi[axis] += 0.5 * deficit;
                    }
                }
            }
            Ok((lo, hi))
        }
    }
}

/// Shutter samples for the frame at `t`: `(time, weight)` pairs, weights summing to 1. One
/// sample `(t, 1)` unless `motion_blur` is declared and some object moves.
pub fn time_samples(scene: &DynamicScene, t: f64) -> Result<Vec<(f64, f32)>> {
    let effects = effects_of(scene)?;
    Ok(samples_for(&effects, scene, t))
}

fn samples_for(effects: &Effects, scene: &DynamicScene, t: f64) -> Vec<(f64, f32)> {
    match &effects.motion_blur {
        Some(m) if scene.is_dynamic() => {
            let n = m.samples.max(1);
            (0..n)
                .map(|i| (t + m.shutter * (i as f64 + 0.5) / n as f64, 1.0 / n as f32))
                .collect()
        }
        _ => vec![(t, 1.0)],
    }
}

/// The frame at `t` as motion-blur samples (one sample, equal to [`build_frame`], when motion
/// blur is not declared or nothing moves). Static content and constant objects are composited
/// once and copied into each sample; each sample's cloud equals `composite(time)` (plus the
/// frame's particles) bit for bit.
pub fn build_blur_frames(
    scene: &DynamicScene,
    t: f64,
    camera: Option<&Camera>,
) -> Result<BlurBuild> {
    let effects = effects_of(scene)?;
    let times = samples_for(&effects, scene, t);
    if times.len() == 1 {
        let f = build_frame(scene, t, camera)?;
        let mut counters = f.counters;
        if effects.motion_blur.is_some() {
            counters.simulated.push("motion_blur".into());
        }
        return Ok(BlurBuild {
            samples: vec![BlurSample {
                time: times[0].0,
                weight: times[0].1,
                cloud: f.cloud,
            }],
            counters,
        });
    }
    let mut counters = EffectCounters::default();
    let degree = scene.sh_degree();
    let k = crate::gaussians::sh_coeffs(degree);
    // The frame at `t` laid out as composite() lays it out: static, then objects in order.
    let base = scene.composite(t);
    let mut ranges = Vec::with_capacity(scene.objects.len() + 1);
    let mut off = scene.static_gaussians.len();
    ranges.push((0, off, None));
    for (i, o) in scene.objects.iter().enumerate() {
        let n = o.gaussians.len();
        let moving = !o.track.is_constant();
        ranges.push((off, off + n, moving.then_some(i)));
        off += n;
    }
    // Moving objects, each alone in a scene of the same SH degree, so posing them runs the
    // same code as composite() (bit-identical results).
    let singles: Vec<Option<DynamicScene>> = scene
        .objects
        .iter()
        .map(|o| {
            (!o.track.is_constant()).then(|| DynamicScene {
                time: scene.time,
                static_gaussians: GaussianCloud::new(degree),
                objects: vec![o.clone()],
                frames: Vec::new(),
                cameras: Vec::new(),
                effects: serde_json::Map::new(),
                four_d: None,
            })
        })
        .collect();
    let particles = match &effects.weather {
        Some(w) => {
            let p0 = Instant::now();
            let p = weather_particles(scene, w, t, camera)?;
            counters.particles = p.len() as u64;
            counters.milliseconds += p0.elapsed().as_secs_f64() * 1e3;
            counters.simulated.push("weather".into());
            Some(p)
        }
        None => None,
    };
    let blur_start = Instant::now();
    let mut samples = Vec::with_capacity(times.len());
    for &(ts, weight) in &times {
        let mut c = GaussianCloud::with_capacity(degree, base.len());
        let ids = c.object_ids.get_or_insert_with(Vec::new);
        ids.reserve(base.len());
        for &(a, b, moving) in &ranges {
            match moving {
                None => copy_range(&base, a, b, k, &mut c),
                Some(i) => {
                    let posed = singles[i]
                        .as_ref()
                        .ok_or_else(|| {
                            SceneError::Invalid(format!("moving object {i} has no posed copy"))
                        })?
                        .composite(ts);
                    c.extend_from(&posed, Some(i as u32 + 1));
                }
            }
        }
        if let Some(p) = &particles {
            c.extend_from(p, Some(weather_object_id(scene)));
        }
        samples.push(BlurSample {
            time: ts,
            weight,
            cloud: c,
        });
    }
    counters.extra_time_samples = times.len() as u64 - 1;
    counters.simulated.push("motion_blur".into());
    // Only the blur's own work counts as its time (the base composite is every frame's cost).
    counters.milliseconds += blur_start.elapsed().as_secs_f64() * 1e3;
    Ok(BlurBuild { samples, counters })
}

fn copy_range(src: &GaussianCloud, a: usize, b: usize, k: usize, out: &mut GaussianCloud) {
    out.means.extend_from_slice(&src.means[a..b]);
    out.log_scales.extend_from_slice(&src.log_scales[a..b]);
    out.rotations.extend_from_slice(&src.rotations[a..b]);
    out.opacity_logits
        .extend_from_slice(&src.opacity_logits[a..b]);
    out.sh.extend_from_slice(&src.sh[a * k..b * k]);
    let ids = out.object_ids.get_or_insert_with(Vec::new);
    match &src.object_ids {
        Some(s) => ids.extend_from_slice(&s[a..b]),
        None => ids.extend(std::iter::repeat_n(0, b - a)),
    }
}

/// Weighted average of same-sized frames (the motion-blur resolve): RGB and alpha averaged
/// with `weights` (normalised here), depth averaged with weight × alpha (0 where nothing
/// covers the pixel in any sample).
pub fn blend_frames(frames: &[Frame], weights: &[f32]) -> Result<Frame> {
    let first = frames
        .first()
        .ok_or_else(|| SceneError::Invalid("blend_frames: no frames".into()))?;
    if frames.len() != weights.len() {
        return Err(SceneError::Invalid(format!(
            "blend_frames: {} frames but {} weights",
            frames.len(),
            weights.len()
        )));
    }
    if frames
        .iter()
        .any(|f| f.width != first.width || f.height != first.height)
    {
        return Err(SceneError::Invalid(
            "blend_frames: frames differ in size".into(),
        ));
    }
    let total: f32 = weights.iter().sum();
    if !(total > 0.0 && total.is_finite()) || weights.iter().any(|w| !(*w >= 0.0)) {
        return Err(SceneError::Invalid(
            "blend_frames: weights must be finite, non-negative and not all zero".into(),
        ));
    }
    if frames.len() == 1 {
        return Ok(first.clone());
    }
    let mut out = Frame::new(first.width, first.height);
    let n = first.pixels();
    let mut dw = vec![0.0f32; n];
    for (f, &w) in frames.iter().zip(weights) {
        let w = w / total;
        for (o, v) in out.rgb.iter_mut().zip(&f.rgb) {
            *o += w * v;
        }
        for i in 0..n {
            out.alpha[i] += w * f.alpha[i];
            let wd = w * f.alpha[i];
            out.depth[i] += wd * f.depth[i];
            dw[i] += wd;
        }
    }
    for i in 0..n {
        out.depth[i] = if dw[i] > 0.0 {
            out.depth[i] / dw[i]
        } else {
            0.0
        };
    }
    Ok(out)
}

/// Per-frame weather content for exporters: the frame times and, per time, the particles
/// alone (no scene Gaussians), in the scene's world frame. `None` when weather is not
/// declared. The `camera` volume uses the scene's camera (there is no render camera here).
pub fn weather_frames(scene: &DynamicScene) -> Result<Option<(Vec<f64>, Vec<GaussianCloud>)>> {
    let effects = effects_of(scene)?;
    let Some(w) = &effects.weather else {
        return Ok(None);
    };
    let times = scene.frame_times();
    let mut clouds = Vec::with_capacity(times.len());
    for &t in &times {
        clouds.push(weather_particles(scene, w, t, None)?);
    }
    Ok(Some((times, clouds)))
}

/// Declared effects that a renderer does not simulate (for its report), given the ones it does.
pub fn not_simulated(effects: &Effects, simulates: &[&str]) -> Vec<String> {
    effects
        .names()
        .into_iter()
        .filter(|n| !simulates.contains(n))
        .map(str::to_string)
        .collect()
}
