//! `--splats` with SPZ compression (`KHR_gaussian_splatting_compression_spz_2`): a dynamic
//! scene written and read back keeps its objects, tracks and cameras, and its Gaussians stay
//! within SPZ v3's quantisation.

mod common;

use splatbridge_convert::splats_gltf::{read_file, write_file, write_file_with, KhrCompression};
use splatbridge_convert::ConvertOptions;
use splatbridge_scene::GaussianCloud;

/// SPZ v3 as the scene crate writes it: positions in 24-bit fixed point with 12 fraction bits
/// (step 1/4096, rounded: half a step; the street fixture spans far less than the ±2048 that
/// leaves); log-scales in 1/16 steps (rounded: relative e^(1/32) − 1 < 3.2%); opacity in
/// 1/255 steps (rounded: half a step, plus the sigmoid's f32 rounding); rotations as 10-bit
/// smallest-three (each small component within half of (1/√2)/511, so 1 − |q·q'| < 2e-6;
/// 1e-5 leaves room for the renormalisation).
fn assert_within_spz(a: &GaussianCloud, b: &GaussianCloud) {
    assert_eq!(a.len(), b.len());
    assert_eq!(a.sh_degree, b.sh_degree);
    for i in 0..a.len() {
        let e = (a.means[i] - b.means[i]).abs().max_element();
        assert!(
            e <= 0.5 / 4096.0 + 1e-6 * a.means[i].abs().max_element(),
            "mean {i}: {e}"
        );
        let e = ((b.scale(i) - a.scale(i)) / a.scale(i)).abs().max_element();
        assert!(e < 0.032, "scale {i}: {e}");
        let e = (a.opacity(i) - b.opacity(i)).abs();
        assert!(e <= 0.5 / 255.0 + 1e-6, "opacity {i}: {e}");
        let d = a.unit_rotation(i).dot(b.unit_rotation(i)).abs();
        assert!(1.0 - d < 1e-5, "rotation {i}: |dot| {d}");
    }
}

#[test]
fn dynamic_scene_round_trips_through_khr_spz() {
    let scene = common::street(400);
    let dir = tempfile::tempdir().unwrap();
    for ext in ["glb", "gltf"] {
        let p = dir.path().join(format!("s.{ext}"));
        write_file_with(&p, &scene, &ConvertOptions::default(), KhrCompression::Spz).unwrap();
        let back = read_file(&p).unwrap();
        assert_within_spz(&scene.static_gaussians, &back.static_gaussians);
        assert_eq!(scene.objects.len(), back.objects.len());
        for (a, b) in scene.objects.iter().zip(&back.objects) {
            assert_eq!(a.name, b.name);
            assert_within_spz(&a.gaussians, &b.gaussians);
            // The writer may re-key a track; its samples must agree (f32 keys: 1e-5).
            for k in 0..=8 {
                let t = scene.time.start + (scene.time.end - scene.time.start) * k as f64 / 8.0;
                let (pa, pb) = (a.track.sample(t), b.track.sample(t));
                assert!(
                    (pa.translation - pb.translation).length() < 1e-5,
                    "{} at {t}",
                    a.name
                );
                assert!(
                    pa.rotation.dot(pb.rotation).abs() > 1.0 - 1e-6,
                    "{} at {t}",
                    a.name
                );
            }
        }
        assert_eq!(scene.cameras.len(), back.cameras.len());
    }
}

#[test]
fn khr_spz_declares_the_extension_and_is_smaller() {
    let scene = common::street(2000);
    let dir = tempfile::tempdir().unwrap();
    let (plain, spz) = (dir.path().join("p.glb"), dir.path().join("z.glb"));
    write_file(&plain, &scene, &ConvertOptions::default()).unwrap();
    write_file_with(
        &spz,
        &scene,
        &ConvertOptions::default(),
        KhrCompression::Spz,
    )
    .unwrap();
    let bytes = std::fs::read(&spz).unwrap();
    let jlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + jlen]).unwrap();
    let name = "KHR_gaussian_splatting_compression_spz_2";
    assert!(json["extensionsRequired"]
        .as_array()
        .unwrap()
        .iter()
        .any(|e| e == name));
    let prim = &json["meshes"][0]["primitives"][0];
    assert!(
        prim["extensions"]["KHR_gaussian_splatting"]["extensions"][name]["bufferView"].is_u64()
    );
    // Accessors describe the decoded attributes and have no buffer views of their own.
    let pos = prim["attributes"]["POSITION"].as_u64().unwrap() as usize;
    assert!(json["accessors"][pos]["bufferView"].is_null());
    // SPZ stores ~ 64 bytes per degree-3 Gaussian before gzip against 248 as floats.
    let (a, b) = (
        std::fs::metadata(&plain).unwrap().len(),
        std::fs::metadata(&spz).unwrap().len(),
    );
    assert!(b * 3 < a, "SPZ {b} bytes vs plain {a}");
}
