//! Parity of every renderer and converter profile against native splatting, asserted with
//! documented thresholds on the street fixture (always) and on the real `fourth_st.ply` (when
//! `../shared/data/real` is present). Meshes are traced from the exported files, so a writer
//! bug shows up here.
//!
//! Each threshold is the PSNR measured when it was set minus a margin; the comment on each
//! says what was measured. A threshold may only be raised by new measurements, never lowered
//! to make a test pass.

use std::path::PathBuf;

use splatbridge::measure::parity::{self, CompareConfig};
use splatbridge::measure::report::Record;
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::ply::{read_ply, ReadOptions};
use splatbridge_scene::{fixtures, Camera};

fn mean_psnr(records: &[Record], renderer: &str, profile: &str, format: &str) -> f64 {
    let v: Vec<f64> = records
        .iter()
        .filter(|r| r.renderer == renderer && r.profile == profile && r.format == format)
        .map(|r| r.psnr)
        .collect();
    assert!(
        !v.is_empty(),
        "no records for {renderer} {profile} {format}"
    );
    assert!(
        v.iter().all(|p| p.is_finite()),
        "{renderer} {profile} {format}: {v:?}"
    );
    v.iter().sum::<f64>() / v.len() as f64
}

fn run(scene: &mut DynamicScene, cams: &[Camera], times: &[f64]) -> Vec<Record> {
    let dir = tempfile::tempdir().unwrap();
    let cfg = CompareConfig::default();
    let records = parity::compare(scene, cams, times, dir.path(), &cfg, &|_| {}).unwrap();
    for r in &records {
        eprintln!(
            "{:15} {:10} {:4} {:>22} t={:.2} PSNR {:6.2} SSIM {:.4}",
            r.renderer, r.profile, r.format, r.camera, r.time, r.psnr, r.ssim
        );
    }
    // Every image the comparison wrote exists and is finite (the records carry its metrics).
    assert!(records
        .iter()
        .all(|r| r.ssim.is_finite() && r.max_error.is_finite()));
    records
}

/// Asserted floors, in dB, for (renderer, profile, format).
struct Floors {
    gaussian: f64,
    meshsplats: f64,
    rings: f64,
    texture: f64,
    obj: f64,
    hybrid: f64,
}

fn check(records: &[Record], f: &Floors, rings_beats_meshsplats: bool) {
    let got = |r: &str, p: &str, fm: &str| mean_psnr(records, r, p, fm);
    let g = got("trace-gaussian", "", "");
    let ms = got("trace-mesh", "meshsplats", "glb");
    let ri = got("trace-mesh", "rings", "glb");
    let tx = got("trace-mesh", "texture", "glb");
    let obj = got("trace-mesh", "rings", "obj");
    let hy = got("hybrid", "", "");
    eprintln!("gaussian {g:.2}  meshsplats {ms:.2}  rings {ri:.2}  texture {tx:.2}  rings.obj {obj:.2}  hybrid {hy:.2}");
    assert!(
        g >= f.gaussian,
        "traced Gaussians {g:.2} dB < {}",
        f.gaussian
    );
    assert!(
        ms >= f.meshsplats,
        "meshsplats {ms:.2} dB < {}",
        f.meshsplats
    );
    assert!(ri >= f.rings, "rings {ri:.2} dB < {}", f.rings);
    assert!(tx >= f.texture, "texture {tx:.2} dB < {}", f.texture);
    assert!(obj >= f.obj, "rings OBJ {obj:.2} dB < {}", f.obj);
    assert!(hy >= f.hybrid, "hybrid {hy:.2} dB < {}", f.hybrid);
    // Losing alpha (OBJ) must cost something, and where the margin was measured to be large
    // the opacity-aware profile must beat the MeshSplats cone it replaces: claims docs/parity.md
    // makes.
    if rings_beats_meshsplats {
        assert!(
            ri > ms,
            "rings ({ri:.2}) does not beat meshsplats ({ms:.2})"
        );
    }
    assert!(obj < ri, "OBJ ({obj:.2}) is not worse than GLB ({ri:.2})");
}

#[test]
fn street_fixture_parity() {
    let mut scene = fixtures::street(1);
    let cams: Vec<Camera> = scene.cameras.iter().map(|c| c.resized(320, 240)).collect();
    let times = [scene.time.start, 0.5 * (scene.time.start + scene.time.end)];
    let records = run(&mut scene, &cams, &times);
    // Measured (4 cameras × 2 times, 320×240): see the comment of each floor.
    check(
        &records,
        &Floors {
            gaussian: THRESH_STREET[0],
            meshsplats: THRESH_STREET[1],
            rings: THRESH_STREET[2],
            texture: THRESH_STREET[3],
            obj: THRESH_STREET[4],
            hybrid: THRESH_STREET[5],
        },
        // Measured margin 2.8 dB.
        true,
    );
}

/// Street fixture floors (dB): gaussian, meshsplats, rings, texture, rings OBJ, hybrid.
/// Measured at 320×240 over 4 cameras × 2 times: 28.65, 23.15, 25.97, 25.92, 14.97, 16.89;
/// each floor is the measurement minus 0.5 dB, rounded down to 0.1 dB. The OBJ figure is
/// `splatbridge compare` of the fixture (`--cameras scene --times 0,2`, the same code path)
/// once OBJs are traced in their written frame (10.75 dB before, mirrored geometry).
const THRESH_STREET: [f64; 6] = [28.1, 22.6, 25.4, 25.4, 14.4, 16.3];

/// `../shared/data/real/NAME`; tests that call this are ignored unless `build.rs` found the
/// folder (`cfg(real_data)`).
fn real(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/real")).join(name)
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn fourth_st_parity() {
    let path = real("fourth_st.ply");
    let (cloud, _) = read_ply(&path, &ReadOptions::default()).unwrap();
    let rig = OrbitRig {
        width: 320,
        height: 240,
        ..OrbitRig::default()
    };
    let cams = rig.cameras(&cloud, 4).unwrap();
    let cams = vec![cams[0].clone(), cams[2].clone()];
    let mut scene = DynamicScene::from_static(cloud);
    let records = run(&mut scene, &cams, &[0.0]);
    check(
        &records,
        &Floors {
            gaussian: THRESH_FOURTH[0],
            meshsplats: THRESH_FOURTH[1],
            rings: THRESH_FOURTH[2],
            texture: THRESH_FOURTH[3],
            obj: THRESH_FOURTH[4],
            hybrid: THRESH_FOURTH[5],
        },
        // Measured margin only 0.17 dB at 320×240 (1.4 dB at 480×360, where native's 0.3 px
        // dilation matters less): the ordering is asserted on the street scene only.
        false,
    );
}

/// fourth_st floors (dB): gaussian, meshsplats, rings, texture, rings OBJ, hybrid.
/// Measured at 320×240 over orbit cameras 0 and 2 of 4: 29.89, 29.29, 29.46, 28.81, 21.12,
/// 30.18; each floor is the measurement minus 0.5 dB, rounded down to 0.1 dB. The OBJ figure is
/// `splatbridge compare fourth_st.ply --cameras orbit:4:0,orbit:4:2` (the same code path) once
/// OBJs are traced in their written frame (12.11 dB before, mirrored geometry).
const THRESH_FOURTH: [f64; 6] = [29.3, 28.7, 28.9, 28.3, 20.6, 29.6];
