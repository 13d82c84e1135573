//! The fast tiled renderer against the slow per-pixel f64 reference.

mod common;

use common::*;
use glam::DVec3;
use splatbridge_hybrid::{render, Extent, RenderOptions};
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::Camera;

// Tolerance 1e-4 per channel is the bar. The fast renderer differs from the f64
// reference by f32 rounding of the conic/colour/transmittance (relative ~1e-6 after a few
// hundred blends) and by the polynomial exp (< 3.6e-7 relative).
const TOL: f64 = 1e-4;
// At a pixel where the reference took a decision within AMBIGUITY of its threshold, f32 may
// decide the other way: a flipped 1/255 skip changes the pixel by at most α·T·|colour| plus the
// (1 − α) rescaling of what lies behind, ≤ 2/255 for colours ≤ 1; a flipped stop by ≤ 1e-4
// plus the stopped Gaussian's share. 0.01 per event covers both with colours up to ~1.2.
const PER_EVENT: f64 = 0.01;
// Ambiguous pixels must stay rare: the band is 1e-3 wide, so far below 1% of pixels.
const MAX_AMBIGUOUS_FRACTION: f64 = 0.01;

fn check(cloud: &splatbridge_scene::GaussianCloud, cam: &Camera, opts: &RenderOptions, what: &str) {
    let (frame, stats) = render(cloud, cam, opts).unwrap();
    let exhaustive = render(
        cloud,
        cam,
        &RenderOptions {
            exhaustive: true,
            ..*opts
        },
    )
    .unwrap()
    .0;
    assert!(
        frame == exhaustive,
        "{what}: the footprint box changed the image"
    );
    let r = reference_render(cloud, cam, opts);
    let d = diffs(&frame, &r);
    println!(
        "{what}: {} projected, {} pairs, {} blends; {d:?}",
        stats.projected, stats.tile_pairs, stats.blends
    );
    assert!(
        stats.blends > 0,
        "{what}: nothing was blended, the comparison would be empty"
    );
    assert!(d.rgb <= TOL, "{what}: rgb differs by {}", d.rgb);
    assert!(d.alpha <= TOL, "{what}: alpha differs by {}", d.alpha);
    assert!(d.depth <= TOL, "{what}: depth differs by {}", d.depth);
    assert!(d.ambiguous_per_event <= PER_EVENT, "{what}: {d:?}");
    let frac = d.ambiguous_pixels as f64 / r.alpha.len() as f64;
    assert!(
        frac <= MAX_AMBIGUOUS_FRACTION,
        "{what}: {frac} of pixels ambiguous"
    );
}

#[test]
fn synthetic_scenes_match_reference() {
    for (seed, w, h) in [(1u64, 100u32, 70u32), (2, 64, 64), (3, 37, 90)] {
        let cloud = random_cloud(1500, seed);
        let cam = front_camera(w, h);
        check(
            &cloud,
            &cam,
            &RenderOptions::default(),
            &format!("seed {seed} {w}x{h} reference settings"),
        );
    }
}

#[test]
fn knobs_match_reference() {
    let cloud = random_cloud(1200, 7);
    let cam = Camera::look_at(
        DVec3::new(1.0, -0.5, -1.0),
        DVec3::new(0.0, 0.0, 5.0),
        DVec3::NEG_Y,
        55.0,
        80,
        60,
    )
    .unwrap();
    let variants = [
        (
            "alpha extent",
            RenderOptions {
                extent: Extent::Alpha,
                ..Default::default()
            },
        ),
        (
            "clamp 0.999",
            RenderOptions {
                alpha_clamp: 0.999,
                ..Default::default()
            },
        ),
        (
            "sh cap 1",
            RenderOptions {
                sh_degree_cap: 1,
                ..Default::default()
            },
        ),
        (
            "sh cap 0",
            RenderOptions {
                sh_degree_cap: 0,
                ..Default::default()
            },
        ),
        (
            "background, near 3",
            RenderOptions {
                background: [0.2, 0.5, 1.0],
                near: 3.0,
                ..Default::default()
            },
        ),
    ];
    for (what, opts) in variants {
        check(&cloud, &cam, &opts, what);
    }
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn fourth_st_matches_reference() {
    let path = real_data("fourth_st.ply");
    let (cloud, _) = splatbridge_scene::ply::read_ply(&path, &Default::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let rig = OrbitRig {
        width: 64,
        height: 48,
        ..Default::default()
    };
    let cams = rig.cameras(&cloud, 3).unwrap();
    for (k, cam) in cams.iter().enumerate() {
        check(
            &cloud,
            cam,
            &RenderOptions::default(),
            &format!("fourth_st orbit {k}/3"),
        );
    }
    let opts = RenderOptions {
        extent: Extent::Alpha,
        alpha_clamp: 0.999,
        ..Default::default()
    };
    check(
        &cloud,
        &cams[1],
        &opts,
        "fourth_st orbit 1/3, alpha extent, clamp 0.999",
    );
}
