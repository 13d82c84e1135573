//! Fans made from 2DGS surfels, traced, against 2D Gaussian Splatting's own rasterizer
//! (`hybrid::surfel2d`) on a real capture flattened to surfels (`fourth_st.ply` through
//! `flatten_to_surfels`, the scene `examples/flatten_2dgs.rs` writes): the path of
//! `splatbridge compare SURFELS.ply --profiles rings` (reference `native-2dgs`), with the
//! exported GLB read back and traced, and the same surfels through 3DGS splatting beside them.
//! Against 2DGS itself fans score 28.3 / 25.9 dB; the gap is measured term by term against 2DGS
//! with its named departures (DC colours, no screen-space low-pass, per-pixel hit order): the
//! low-pass is 12 dB of it, the colours' view dependence 1–2.6 dB, the blending order 0.3 dB,
//! and with colours and low-pass matched fans reach the 40 dB goal (docs/formats.md#2dgs-surfels).

use std::path::PathBuf;

use splatbridge::measure::parity;
use splatbridge_convert::options::VolumetricMode;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_hybrid::native::RenderOptions as NativeOptions;
use splatbridge_hybrid::surfel2d::{LowPassCentre, SurfelOrder, SurfelRenderer};
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

/// A shared capture flattened to 2DGS surfels, and the 320×240 orbit rig of these tests.
fn flattened(name: &str) -> (splatbridge_scene::GaussianCloud, OrbitRig) {
    let (cloud, _) = read_ply(&real(name), &ReadOptions::default()).unwrap();
    let rig = OrbitRig {
        width: 320,
        height: 240,
        ..OrbitRig::default()
    };
    (flatten_to_surfels(&cloud), rig)
}

/// What `compare SURFELS.ply --profiles rings` exports (the rings profile at its defaults, one
/// fan per surfel), written into `dir` and loaded for tracing.
fn export_fans(scene: &DynamicScene, dir: &std::path::Path) -> parity::TracedMesh {
    let opts = ConvertOptions {
        profile: Profile::Rings,
        volumetric: VolumetricMode::Flat,
        ..ConvertOptions::default()
    };
    parity::export_and_load(
        scene,
        &opts,
        &dir.join("fans.glb"),
        BackendKind::Obvhs,
        BuildPreset::default(),
    )
    .unwrap()
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
    let (surfels, rig) = flattened("fourth_st.ply");
    let cams: Vec<_> = [0usize, 3]
        .iter()
        .map(|&k| rig.camera(&surfels, 8, k).unwrap())
        .collect();
    let scene = DynamicScene::from_static(surfels);
    let dir = tempfile::tempdir().unwrap();
    let m = export_fans(&scene, dir.path());
    let (mut fans, mut splat3) = (Vec::new(), Vec::new());
    // Fans against 2DGS with its named departures, one at a time (docs/formats.md#2dgs-surfels):
    // DC colours (fans carry no view dependence), then no low-pass, then per-pixel hit order.
    let (mut dc, mut dc_off, mut dc_off_hit) = (Vec::new(), Vec::new(), Vec::new());
    for cam in &cams {
        let native = NativeOptions::default();
        let r2 = parity::render_reference(&scene.static_gaussians, cam, &native, true).unwrap();
        let r3 = parity::render_reference(&scene.static_gaussians, cam, &native, false).unwrap();
        splat3.push(metrics::psnr(&r2.frame, &r3.frame).unwrap());
        let (t, _) = m.tracer.render_traced(cam, 0.0).unwrap();
        fans.push(metrics::psnr(&r2.frame, &t).unwrap());
        let dc_opts = NativeOptions {
            sh_degree_cap: 0,
            ..native
        };
        for (low_pass, order, out) in [
            (LowPassCentre::Code, SurfelOrder::CentreDepth, &mut dc),
            (LowPassCentre::Off, SurfelOrder::CentreDepth, &mut dc_off),
            (LowPassCentre::Off, SurfelOrder::HitDepth, &mut dc_off_hit),
        ] {
            let mut r = SurfelRenderer::new();
            r.low_pass = low_pass;
            r.blend_order = order;
            let (f, _) = r.render(&scene.static_gaussians, cam, &dc_opts).unwrap();
            out.push(metrics::psnr(&f, &t).unwrap());
        }
    }
    eprintln!("against 2DGS: fans {fans:?}, 3DGS splatting {splat3:?}");
    eprintln!(
        "fans against 2DGS with DC colours {dc:?}, and no low-pass {dc_off:?}, and hit order {dc_off_hit:?}"
    );
    // Floors: the means measured when they were set minus 0.5 dB (docs/formats.md#2dgs-surfels):
    // fans 28.26 / 25.85 dB (mean 27.05), the same surfels through 3DGS splatting 41.53 /
    // 39.04 dB (mean 40.29); fans against 2DGS with DC colours 29.27 / 28.49 (mean 28.88), and
    // without the low-pass 41.26 / 41.18 (mean 41.22), and in hit order 41.55 / 41.58 (mean
    // 41.57). The goal, 40 dB, is asserted on every view where it is reached: with the colours
    // and the low-pass matched.
    assert!(
        mean(&fans) >= FANS_FLOOR,
        "fans {fans:?} below {FANS_FLOOR} dB"
    );
    assert!(
        mean(&splat3) >= SPLAT3_FLOOR,
        "3DGS splatting {splat3:?} below {SPLAT3_FLOOR} dB"
    );
    assert!(
        mean(&dc) >= DC_FLOOR,
        "DC colours {dc:?} below {DC_FLOOR} dB"
    );
    assert!(
        mean(&dc_off) >= NO_LOW_PASS_FLOOR && dc_off.iter().all(|&p| p >= GOAL),
        "no low-pass {dc_off:?}: below {NO_LOW_PASS_FLOOR} dB, or a view below {GOAL} dB"
    );
    assert!(
        mean(&dc_off_hit) >= HIT_ORDER_FLOOR && dc_off_hit.iter().all(|&p| p >= GOAL),
        "hit order {dc_off_hit:?}: below {HIT_ORDER_FLOOR} dB, or a view below {GOAL} dB"
    );
}

/// `convert --footprint-for WxH` on a 2DGS file, measured where 2DGS's filter matters most: a
/// capture without view dependence (`plant.ply`, SH degree 0, flattened), at 320×240, where
/// most surfels are narrower than the filter. Fans of the surfels raised to 2DGS's own filter
/// (`LowPass::Surfel2d`) against 2DGS, beside the plain fans and beside the same surfels
/// widened by 3DGS's rule (0.3 px² added): the filter is a maximum, and taking it as one is
/// what gains (docs/formats.md#2dgs-surfels).
#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn fans_made_for_2dgs_filter_at_320x240() {
    use splatbridge_distill::footprint::{widen_scene_for, LowPass};
    let (surfels, rig) = flattened("plant.ply");
    let dir = tempfile::tempdir().unwrap();
    let native = NativeOptions::default();
    let (mut plain, mut as_2dgs, mut as_3dgs) = (Vec::new(), Vec::new(), Vec::new());
    for k in [0usize, 3] {
        let cam = rig.camera(&surfels, 8, k).unwrap();
        let reference = parity::render_reference(&surfels, &cam, &native, true)
            .unwrap()
            .frame;
        for (low_pass, out) in [
            (None, &mut plain),
            (Some(LowPass::Surfel2d), &mut as_2dgs),
            (Some(LowPass::Splat3d), &mut as_3dgs),
        ] {
            let mut scene = DynamicScene::from_static(surfels.clone());
            scene.cameras = vec![cam.clone()];
            if let Some(lp) = low_pass {
                widen_scene_for(&mut scene, 320, 240, lp).unwrap();
            }
            let m = export_fans(&scene, dir.path());
            let (t, _) = m.tracer.render_traced(&cam, 0.0).unwrap();
            out.push(metrics::psnr(&reference, &t).unwrap());
        }
    }
    eprintln!("plant flattened, 320x240, against 2DGS: fans {plain:?}, made for 2DGS's filter {as_2dgs:?}, widened by 3DGS's rule {as_3dgs:?}");
    // Floors: the means measured when they were set minus 0.5 dB: plain fans 24.42 / 23.99
    // (mean 24.21), raised to 2DGS's filter 30.78 / 31.22 (mean 31.00); 3DGS's rule gave
    // 29.56 / 29.93 (mean 29.75) and must stay below 2DGS's. Every view must gain.
    assert!(mean(&plain) >= 23.71, "plain fans {plain:?}");
    assert!(mean(&as_2dgs) >= 30.50, "made for 2DGS {as_2dgs:?}");
    assert!(
        as_2dgs.iter().zip(&plain).all(|(a, p)| a > p),
        "a view lost: {as_2dgs:?} against {plain:?}"
    );
    assert!(
        mean(&as_2dgs) > mean(&as_3dgs),
        "2DGS's rule {as_2dgs:?} not above 3DGS's {as_3dgs:?}"
    );
}

/// The project's goal for meshes against their native renderer, dB.
const GOAL: f64 = 40.0;
/// Fans against 2DGS with DC colours (module test), dB.
const DC_FLOOR: f64 = 28.38;
/// … and without 2DGS's screen-space low-pass, dB.
const NO_LOW_PASS_FLOOR: f64 = 40.72;
/// … and blended in per-pixel hit order, dB.
const HIT_ORDER_FLOOR: f64 = 41.07;
/// Fans of the rings profile against 2DGS (module test), dB.
const FANS_FLOOR: f64 = 26.5;
/// The surfels through 3DGS splatting against 2DGS, dB.
const SPLAT3_FLOOR: f64 = 39.7;
