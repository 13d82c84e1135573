//! What `splatbridge info` says about a scene: the format and version read and what its
//! quantisation costs, counts, SH degree, bounds (full and robust), distributions of
//! activated opacities and scales, counts of the unusual values real files hold, and for a
//! manifest its objects, track spans and frames, as one JSON object.
//!
//! Statistics are taken over the composite at the scene's start time (every Gaussian, objects
//! placed by their first pose). Percentiles are nearest-rank on the sorted values.

use std::path::Path;

use serde_json::{json, Value};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::{LoadInfo, SplatFormat};
use splatbridge_scene::gaussians::sigmoid;
use splatbridge_scene::GaussianCloud;

/// Fraction cut from each end for the robust bounds (orbit rigs use the same idea).
pub const ROBUST_P: f32 = 0.02;
/// Quaternions whose norm differs from 1 by more than this count as unnormalised (f32 rounding
/// of a normalised quaternion stays within a few 1e-7).
const QUAT_NORM_TOL: f32 = 1e-3;
/// Log-scales below this (scale < 1.1e-7) count as tiny: far below a pixel at any sane camera,
/// the −23 of `tile_lod1.ply` being the real example.
pub const TINY_LOG_SCALE: f32 = -16.0;
/// The rasterizer skips α < 1/255; a Gaussian whose opacity is below it never contributes.
const ALPHA_MIN: f32 = 1.0 / 255.0;

pub const QUANTILES: [(&str, f64); 9] = [
    ("min", 0.0),
    ("p01", 0.01),
    ("p05", 0.05),
    ("p25", 0.25),
    ("p50", 0.5),
    ("p75", 0.75),
    ("p95", 0.95),
    ("p99", 0.99),
    ("max", 1.0),
];

/// Nearest-rank quantiles of `v` (sorted here), as a JSON object; null when empty.
fn distribution(mut v: Vec<f32>) -> Value {
    if v.is_empty() {
        return Value::Null;
    }
    v.sort_by(f32::total_cmp);
    let mut m = serde_json::Map::new();
    for (name, q) in QUANTILES {
        let i = (q * (v.len() - 1) as f64).round() as usize;
        m.insert(name.into(), json!(v[i]));
    }
    m.insert(
        "mean".into(),
        json!(v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64),
    );
    Value::Object(m)
}

fn vec3(v: glam::Vec3) -> Value {
    json!([v.x, v.y, v.z])
}

/// Everything `info` says about one cloud.
pub fn cloud_stats(c: &GaussianCloud) -> Value {
    let bounds = c
        .bounds()
        .map(|(lo, hi)| json!({"min": vec3(lo), "max": vec3(hi), "size": vec3(hi - lo)}));
    let robust = c.robust_bounds(ROBUST_P).map(
        |(lo, hi)| json!({"p": ROBUST_P, "min": vec3(lo), "max": vec3(hi), "size": vec3(hi - lo)}),
    );
    let opacity: Vec<f32> = c.opacity_logits.iter().map(|&l| sigmoid(l)).collect();
    let below_alpha = opacity.iter().filter(|&&o| o < ALPHA_MIN).count();
    let max_axis: Vec<f32> = c.log_scales.iter().map(|s| s.max_element().exp()).collect();
    let min_axis: Vec<f32> = c.log_scales.iter().map(|s| s.min_element().exp()).collect();
    let count = |f: &dyn Fn(usize) -> bool| (0..c.len()).filter(|&i| f(i)).count();
    json!({
        "gaussians": c.len(),
        "sh_degree": c.sh_degree,
        "bounds": bounds,
        "robust_bounds": robust,
        "opacity": distribution(opacity),
        "scale_max_axis": distribution(max_axis),
        "scale_min_axis": distribution(min_axis),
        "unusual": {
            "opacity_logit_pos_inf": count(&|i| c.opacity_logits[i] == f32::INFINITY),
            "opacity_logit_neg_inf": count(&|i| c.opacity_logits[i] == f32::NEG_INFINITY),
            "opacity_below_1_255": below_alpha,
            "unnormalised_quaternions": count(&|i| (c.rotations[i].length() - 1.0).abs() > QUAT_NORM_TOL),
            "tiny_log_scales": count(&|i| c.log_scales[i].min_element() < TINY_LOG_SCALE),
            "invalid": count(&|i| c.invalid_reason(i).is_some()),
        },
    })
}

/// Describe `scene`, read from `file` as `info` says.
pub fn describe(file: &Path, scene: &DynamicScene, info: &LoadInfo) -> Value {
    let is_manifest = info.format == SplatFormat::Manifest;
    // A scene without objects is described from its static cloud, not a copy of it (a 10 M
    // Gaussian file is 2.4 GB of cloud); the statistics read no object ids.
    let composite = scene.composite_view(scene.time.start);
    let mut out = cloud_stats(&composite);
    let Some(obj) = out.as_object_mut() else {
        return out;
    };
    obj.insert("file".into(), json!(file.display().to_string()));
    obj.insert("kind".into(), json!(info.format.name()));
    obj.insert(
        "format".into(),
        json!({
            "name": info.format.name(),
            "description": info.format.to_string(),
            "version": info.format.version(),
            "quantisation": info.quantisation(),
            "content": info.kind.name(),
        }),
    );
    if is_manifest || !scene.objects.is_empty() {
        let objects: Vec<Value> = scene
            .objects
            .iter()
            .map(|o| {
                let span = match (o.track.keys.first(), o.track.keys.last()) {
                    (Some(a), Some(b)) => json!([a.t, b.t]),
                    _ => Value::Null,
                };
                json!({
                    "name": o.name,
                    "gaussians": o.gaussians.len(),
                    "sh_degree": o.gaussians.sh_degree,
                    "keys": o.track.keys.len(),
                    "track_span": span,
                })
            })
            .collect();
        obj.insert(
            "static_gaussians".into(),
            json!(scene.static_gaussians.len()),
        );
        obj.insert("objects".into(), json!(objects));
        obj.insert(
            "time".into(),
            json!({"start": scene.time.start, "end": scene.time.end, "fps": scene.time.fps,
                   "frames": scene.time.frame_count()}),
        );
        obj.insert("cameras".into(), json!(scene.cameras.len()));
        obj.insert(
            "effects".into(),
            json!(scene.effects.keys().collect::<Vec<_>>()),
        );
    }
    if let Some(m) = &scene.four_d {
        obj.insert("four_d".into(), four_d(m));
    }
    out
}

/// What `info` reports of a 4D model: its time axis, counts and how far the Gaussians move
/// (read frame by frame; for a continuous model, at its `fps` samples).
fn four_d(m: &splatbridge_scene::fourd::FourD) -> Value {
    let r = m.time_range();
    let moved = match m.displacement() {
        Ok(Some(d)) => json!({
            "median": d.median, "p95": d.p95, "max": d.max,
            "moving_fraction": d.moving_fraction, "extent": d.extent,
        }),
        Ok(None) => Value::Null,
        Err(e) => json!({ "error": e.to_string() }),
    };
    json!({
        "form": m.form.name(),
        "time": {"start": r.start, "end": r.end, "fps": r.fps, "frames": m.frame_count()},
        "max_gaussians": m.max_count(),
        "same_count": m.same_count(),
        "displacement": moved,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};

    #[test]
    fn nearest_rank_quantiles() {
        let d = distribution((1..=101).rev().map(|i| i as f32).collect());
        assert_eq!(d["min"], json!(1.0));
        assert_eq!(d["p01"], json!(2.0));
        assert_eq!(d["p50"], json!(51.0));
        assert_eq!(d["p99"], json!(100.0));
        assert_eq!(d["max"], json!(101.0));
        assert_eq!(d["mean"], json!(51.0));
        assert!(distribution(Vec::new()).is_null());
    }

    #[test]
    fn stats_count_the_unusual_values() {
        let mut c = GaussianCloud::new(0);
        let sh = [Vec3::ZERO];
        c.push(
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::splat(-2.0),
            Quat::IDENTITY,
            f32::INFINITY,
            &sh,
        );
        c.push(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(-23.0, 0.0, 0.0),
            Quat::from_xyzw(0.0, 0.0, 0.0, 3.2),
            f32::NEG_INFINITY,
            &sh,
        );
        c.push(
            Vec3::ZERO,
            Vec3::ZERO,
            Quat::from_xyzw(0.0, 0.0, 0.0, 1.0005),
            0.0,
            &sh,
        );
        let s = cloud_stats(&c);
        assert_eq!(s["gaussians"], json!(3));
        assert_eq!(s["sh_degree"], json!(0));
        assert_eq!(s["bounds"]["min"], json!([-1.0, 0.0, 0.0]));
        assert_eq!(s["bounds"]["max"], json!([1.0, 2.0, 3.0]));
        let u = &s["unusual"];
        assert_eq!(u["opacity_logit_pos_inf"], json!(1));
        assert_eq!(u["opacity_logit_neg_inf"], json!(1));
        // sigmoid(−inf) = 0 is below 1/255; sigmoid(0) = 0.5 is not.
        assert_eq!(u["opacity_below_1_255"], json!(1));
        // 3.2 is unnormalised; 1.0005 is within the 1e-3 tolerance.
        assert_eq!(u["unnormalised_quaternions"], json!(1));
        assert_eq!(u["tiny_log_scales"], json!(1));
        assert_eq!(s["opacity"]["max"], json!(1.0));
        assert_eq!(s["opacity"]["min"], json!(0.0));
    }
}
