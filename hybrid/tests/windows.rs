//! `Renderer::render_window` against the whole frame cut: the same bits in every plane, for
//! windows at the frame's corners and edges, across tile boundaries, one pixel and the whole
//! frame, under every knob that changes which Gaussians a tile holds.

mod common;

use common::*;
use glam::DVec3;
use splatbridge_hybrid::native::Renderer;
use splatbridge_hybrid::{Extent, RenderOptions};
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{Camera, GaussianCloud};

/// Every plane of the window equals the whole frame's pixels there, bit for bit.
fn check(cloud: &GaussianCloud, cam: &Camera, opts: &RenderOptions, win: [u32; 4], what: &str) {
    let mut r = Renderer::new();
    let (whole, all) = r.render(cloud, cam, opts).unwrap();
    let expect = whole.crop(win[0], win[1], win[2], win[3]).unwrap();
    let (got, stats) = r.render_window(cloud, cam, opts, win).unwrap();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!((got.width, got.height), (win[2], win[3]), "{what} {win:?}");
    assert!(
        bits(&got.rgb) == bits(&expect.rgb)
            && bits(&got.alpha) == bits(&expect.alpha)
            && bits(&got.depth) == bits(&expect.depth),
        "{what}: window {win:?} differs from the frame's pixels"
    );
    // The window renders no more than the frame does (fewer where it is a part of it).
    assert!(stats.projected <= all.projected && stats.blends <= all.blends);
}

/// Windows that touch each corner and edge, straddle tiles, are one pixel, or the frame.
fn windows(w: u32, h: u32, rng: &mut Rng) -> Vec<[u32; 4]> {
    let mut out = vec![
        [0, 0, w, h],
        [0, 0, 1, 1],
        [w - 1, h - 1, 1, 1],
        [w - 37, 0, 37, 21],
        [0, h - 19, 45, 19],
        [15, 15, 2, 2],
        [16, 16, 16, 16],
        [w - 40, h - 30, 40, 30],
    ];
    for _ in 0..6 {
        let ww = 1 + (rng.range(0.0, 1.0) * (w - 1) as f32) as u32;
        let wh = 1 + (rng.range(0.0, 1.0) * (h - 1) as f32) as u32;
        let x0 = (rng.range(0.0, 1.0) * (w - ww) as f32) as u32;
        let y0 = (rng.range(0.0, 1.0) * (h - wh) as f32) as u32;
        out.push([x0, y0, ww, wh]);
    }
    out
}

#[test]
fn windows_are_the_frames_pixels() {
    let mut rng = Rng::new(17);
    // Sides that are not multiples of the 16-pixel tile, and a principal point off the
    // centre (distillation's windows are cut from such frames).
    let mut off = front_camera(203, 131);
    off.cx += 23.5;
    off.cy -= 11.0;
    let cams = [front_camera(203, 131), front_camera(64, 48), off];
    for (seed, cam) in cams.iter().enumerate() {
        let cloud = random_cloud(600, 40 + seed as u64);
        for win in windows(cam.width, cam.height, &mut rng) {
            check(&cloud, cam, &RenderOptions::default(), win, "default");
        }
    }
    // The knobs that change extents and what a tile's list holds.
    let cloud = random_cloud(400, 7);
    let cam = front_camera(150, 100);
    let knobs = [
        RenderOptions {
            extent: Extent::Alpha,
            alpha_clamp: 0.999,
            ..Default::default()
        },
        RenderOptions {
            exhaustive: true,
            background: [0.2, 0.5, 1.0],
            sh_degree_cap: 1,
            near: 3.0,
            ..Default::default()
        },
    ];
    for opts in &knobs {
        for win in windows(cam.width, cam.height, &mut rng) {
            check(&cloud, &cam, opts, win, "knobs");
        }
    }
}

#[test]
fn windows_outside_the_frame_are_refused() {
    let cloud = random_cloud(10, 1);
    let cam = front_camera(64, 48);
    let mut r = Renderer::new();
    for win in [
        [0, 0, 65, 48],
        [60, 0, 5, 1],
        [0, 48, 1, 1],
        [0, 0, 0, 10],
        [u32::MAX, 0, 2, 2],
    ] {
        let e = r.render_window(&cloud, &cam, &RenderOptions::default(), win);
        assert!(e.is_err(), "{win:?} was rendered");
    }
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn fourth_st_windows_are_the_frames_pixels() {
    let path = real_data("fourth_st.ply");
    let (cloud, _) = splatbridge_scene::ply::read_ply(&path, &Default::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let rig = OrbitRig {
        width: 320,
        height: 240,
        ..Default::default()
    };
    let mut rng = Rng::new(3);
    for cam in rig.cameras(&cloud, 2).unwrap() {
        for win in windows(cam.width, cam.height, &mut rng)
            .into_iter()
            .take(10)
        {
            check(&cloud, &cam, &RenderOptions::default(), win, "fourth_st");
        }
    }
    // A close-up, where the near plane and the Jacobian clamp matter.
    let c = cloud
        .means
        .iter()
        .fold(DVec3::ZERO, |a, m| a + m.as_dvec3())
        / cloud.len() as f64;
    let cam = Camera::look_at(
        c + DVec3::new(0.0, -0.5, -1.0),
        c,
        DVec3::NEG_Y,
        60.0,
        320,
        240,
    )
    .unwrap();
    for win in windows(cam.width, cam.height, &mut rng) {
        check(
            &cloud,
            &cam,
            &RenderOptions::default(),
            win,
            "fourth_st close-up",
        );
    }
}
