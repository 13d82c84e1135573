//! Fans made from 2DGS surfels, traced, against 2D Gaussian Splatting's own rasterizer
//! (`hybrid::surfel2d`) on a real capture flattened to surfels (`fourth_st.ply` through
//! `flatten_to_surfels`, the scene `examples/flatten_2dgs.rs` writes): the path of
//! `splatbridge compare SURFELS.ply --profiles rings` (reference `native-2dgs`), with the
//! exported GLB read back and traced, and the same surfels through 3DGS splatting beside them.
//! The goal for fans, 40 dB, is not met (28.3 / 25.9 dB): docs/formats.md#2dgs-surfels says
//! why (2DGS's screen-space low-pass, which no fixed geometry carries).

use std::path::PathBuf;

use splatbridge::measure::parity;
use splatbridge_convert::options::VolumetricMode;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_hybrid::native::RenderOptions as NativeOptions;
use splatbridge_raytrace::{BackendKind, BuildPreset};
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::metrics;
use splatbridge_scene::ply::{flatten_to_surfels, read_ply, ReadOptions};

/// `../shared/data/real/NAME`; tests that call this are ignored unless `build.rs` found the
/// folder (`cfg(real_data)`).
fn real(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/real")).join(name)
}

/// Mean of a list of PSNRs.
fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn fans_from_flattened_fourth_st_against_the_2dgs_rasterizer() {
    let (cloud, _) = read_ply(&real("fourth_st.ply"), &ReadOptions::default()).unwrap();
    let surfels = flatten_to_surfels(&cloud);
    let rig = OrbitRig {
        width: 320,
        height: 240,
        ..OrbitRig::default()
    };
    let cams: Vec<_> = [0usize, 3]
        .iter()
        .map(|&k| rig.camera(&surfels, 8, k).unwrap())
        .collect();
    let scene = DynamicScene::from_static(surfels);
    let dir = tempfile::tempdir().unwrap();
    // What `compare SURFELS.ply --profiles rings` exports: the rings profile at its defaults,
    // one fan per surfel.
    let opts = ConvertOptions {
        profile: Profile::Rings,
        volumetric: VolumetricMode::Flat,
        ..ConvertOptions::default()
    };
    let m = parity::export_and_load(
        &scene,
        &opts,
        &dir.path().join("fans.glb"),
        BackendKind::Obvhs,
        BuildPreset::default(),
    )
    .unwrap();
    let (mut fans, mut splat3) = (Vec::new(), Vec::new());
    for cam in &cams {
        let native = NativeOptions::default();
        let r2 = parity::render_reference(&scene.static_gaussians, cam, &native, true).unwrap();
        let r3 = parity::render_reference(&scene.static_gaussians, cam, &native, false).unwrap();
        splat3.push(metrics::psnr(&r2.frame, &r3.frame).unwrap());
        let (t, _) = m.tracer.render_traced(cam, 0.0).unwrap();
        fans.push(metrics::psnr(&r2.frame, &t).unwrap());
    }
    eprintln!("against 2DGS: fans {fans:?}, 3DGS splatting {splat3:?}");
    // Floors: the means measured when they were set minus 0.5 dB (docs/formats.md#2dgs-surfels):
    // fans 28.26 / 25.85 dB (mean 27.05), the same surfels through 3DGS splatting 41.53 /
    // 39.04 dB (mean 40.29). The goal for fans, 40 dB, is not met: see the docs for why.
    assert!(
        mean(&fans) >= FANS_FLOOR,
        "fans {fans:?} below {FANS_FLOOR} dB"
    );
    assert!(
        mean(&splat3) >= SPLAT3_FLOOR,
        "3DGS splatting {splat3:?} below {SPLAT3_FLOOR} dB"
    );
}

/// Fans of the rings profile against 2DGS (module test), dB.
const FANS_FLOOR: f64 = 26.5;
/// The surfels through 3DGS splatting against 2DGS, dB.
const SPLAT3_FLOOR: f64 = 39.7;
