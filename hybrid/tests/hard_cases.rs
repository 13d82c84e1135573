//! Degenerate and extreme inputs: finite output, no panic, and agreement with the reference
//! where the reference itself is meaningful.

mod common;

use common::*;
use glam::{DVec3, Quat, Vec3};
use splatbridge_hybrid::{render, Extent, RenderOptions};
use splatbridge_scene::{Camera, GaussianCloud};

fn render_ok(cloud: &GaussianCloud, cam: &Camera, what: &str) -> splatbridge_hybrid::RenderStats {
    for opts in [
        RenderOptions::default(),
        RenderOptions {
            extent: Extent::Alpha,
            alpha_clamp: 0.999,
            ..Default::default()
        },
        RenderOptions {
            exhaustive: true,
            ..Default::default()
        },
    ] {
        let (f, _) = render(cloud, cam, &opts).unwrap();
        assert!(f.is_finite(), "{what}: non-finite output with {opts:?}");
        assert!(
            f.alpha.iter().all(|a| (0.0..=1.0).contains(a)),
            "{what}: alpha out of [0, 1]"
        );
    }
    // The footprint box only skips work: the image equals visiting every pixel of every tile.
    let (a, stats) = render(cloud, cam, &RenderOptions::default()).unwrap();
    let (b, _) = render(
        cloud,
        cam,
        &RenderOptions {
            exhaustive: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(a == b, "{what}: the footprint box changed the image");
    stats
}

#[test]
fn near_plane_straddlers() {
    let cam = front_camera(64, 48);
    let mut c = GaussianCloud::new(0);
    // Means just beyond and just before z = 0.2, with extents reaching far across it.
    for z in [0.2001f32, 0.21, 0.25, 0.1999, 0.19, 0.0, -0.1] {
        c.push_activated(
            Vec3::new(0.01, -0.02, z),
            Vec3::new(0.5, 0.3, 2.0),
            Quat::IDENTITY,
            0.9,
            Vec3::ONE,
        );
        // Off-axis ones exercise the Jacobian clamp (x/z far beyond 1.3·tan(fov/2)).
        c.push_activated(
            Vec3::new(1.0, 0.5, z),
            Vec3::splat(0.3),
            Quat::from_rotation_y(0.7),
            0.9,
            Vec3::X,
        );
    }
    let stats = render_ok(&c, &cam, "near-plane straddlers");
    assert_eq!(stats.culled_near, 4, "{stats:?}");
    assert_eq!(stats.culled_behind, 4, "{stats:?}");
    assert!(stats.culled_near_in_view >= 2, "{stats:?}");
    assert!(stats.blends > 0);
}

#[test]
fn image_border() {
    let (w, h) = (50u32, 35u32);
    let cam = front_camera(w, h);
    let mut c = GaussianCloud::new(0);
    // Means projected exactly onto the corners and edges of the image and just outside.
    let f = cam.fx;
    for (u, v) in [
        (-0.5, -0.5),
        (w as f64 - 0.5, h as f64 - 0.5),
        (-3.0, 17.0),
        (w as f64 + 2.0, 10.0),
        (25.0, -1.0),
    ] {
        let z = 3.0;
        let x = (u + 0.5 - cam.cx) * z / f;
        let y = (v + 0.5 - cam.cy) * z / f;
        c.push_activated(
            Vec3::new(x as f32, y as f32, z as f32),
            Vec3::splat(0.05),
            Quat::IDENTITY,
            0.8,
            Vec3::ONE,
        );
    }
    render_ok(&c, &cam, "image border");
    let (frame, _) = render(&c, &cam, &RenderOptions::default()).unwrap();
    let r = reference_render(&c, &cam, &RenderOptions::default());
    let d = diffs(&frame, &r);
    // Same bar as tests/reference.rs (f32 rounding far below 1e-4).
    assert!(d.rgb <= 1e-4 && d.alpha <= 1e-4, "{d:?}");
    assert!(frame.alpha[0] > 0.1, "corner Gaussian missing");
}

#[test]
fn far_from_origin_with_camera_near() {
    let base = DVec3::new(1.0e5, 2.0e5, -1.0e5);
    let mut c = GaussianCloud::new(1);
    for k in 0..50 {
        let p = base + DVec3::new(0.01 * k as f64, 0.005 * k as f64, 1.0 + 0.02 * k as f64);
        c.push_activated(
            p.as_vec3(),
            Vec3::splat(0.02),
            Quat::from_rotation_z(k as f32),
            0.7,
            Vec3::new(0.2, 0.8, 0.4),
        );
    }
    let cam = Camera::look_at(base, base + DVec3::Z, DVec3::NEG_Y, 60.0, 64, 48).unwrap();
    let stats = render_ok(&c, &cam, "1e5 from origin");
    assert!(stats.blends > 0, "{stats:?}");
}

#[test]
fn needles_subpixel_and_opaque() {
    let cam = front_camera(64, 48);
    let mut c = GaussianCloud::new(0);
    let mut rng = splatbridge_scene::rng::Rng::new(9);
    for k in 0..40 {
        let q = Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal());
        let mean = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-0.7, 0.7),
            rng.range(2.0, 4.0),
        );
        let scale = match k % 4 {
            0 => Vec3::new(1.0, 1e-6, 1e-6), // needle, ratio 1e6
            1 => Vec3::new(1e-6, 1.0, 1.0),  // disc, ratio 1e6
            2 => Vec3::splat(1e-10),         // far below a pixel
            _ => Vec3::new(3.0, 3e-6, 1e-3), // long needle
        };
        c.push_activated(mean, scale, q, 0.6, Vec3::new(0.3, 0.6, 0.9));
        if k % 5 == 0 {
            *c.opacity_logits.last_mut().unwrap() = f32::INFINITY;
        }
    }
    // Stored log-scales down to −23 as real files hold, and a huge one.
    c.push(
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::splat(-23.0),
        Quat::IDENTITY,
        2.0,
        &[Vec3::ONE],
    );
    c.push(
        Vec3::new(0.0, 0.0, 30.0),
        Vec3::new(30.0, -23.0, 0.0),
        Quat::from_xyzw(0.3, 0.1, 0.0, 2.0),
        2.0,
        &[Vec3::ONE],
    );
    // Huge, far off-screen means (1e6 px away in f32) whose footprint reaches the image.
    c.push_activated(
        Vec3::new(3.0e4, 0.0, 0.5),
        Vec3::new(3.0e4, 0.3, 0.3),
        Quat::IDENTITY,
        0.9,
        Vec3::ONE,
    );
    c.push_activated(
        Vec3::new(0.0, -2.0e4, 0.3),
        Vec3::new(0.2, 2.5e4, 0.2),
        Quat::from_rotation_z(0.01),
        0.9,
        Vec3::Y,
    );
    // Unnormalised quaternions.
    c.push(
        Vec3::new(0.2, 0.0, 3.0),
        Vec3::splat(-3.0),
        Quat::from_xyzw(0.5, 1.0, 2.0, 3.2),
        1.0,
        &[Vec3::ONE],
    );
    let stats = render_ok(&c, &cam, "needles");
    assert!(stats.projected > 20, "{stats:?}");
}

#[test]
fn tiny_and_odd_images() {
    let cloud = random_cloud(300, 4);
    for (w, h) in [(1u32, 1u32), (1, 200), (17, 3), (16, 16)] {
        let cam = front_camera(w, h);
        render_ok(&cloud, &cam, &format!("{w}x{h}"));
    }
}

#[test]
fn bad_options_are_errors() {
    let cloud = random_cloud(10, 4);
    let cam = front_camera(8, 8);
    for opts in [
        RenderOptions {
            near: f32::NAN,
            ..Default::default()
        },
        RenderOptions {
            near: -1.0,
            ..Default::default()
        },
        RenderOptions {
            alpha_clamp: 1.0,
            ..Default::default()
        },
        RenderOptions {
            background: [f32::INFINITY, 0.0, 0.0],
            ..Default::default()
        },
    ] {
        assert!(render(&cloud, &cam, &opts).is_err(), "{opts:?} accepted");
    }
    let mut bad = cloud.clone();
    bad.opacity_logits.pop();
    assert!(render(&bad, &cam, &RenderOptions::default()).is_err());
}
