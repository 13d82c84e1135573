//! Sun shadows against analytic cases: an occluding square of known opacity over a ground
//! plane (mode mesh, exact), a flat occluding Gaussian (mode gaussian, against an f64
//! closed-form transmittance), and a moving object whose shadow follows it.

use glam::{DVec3, Quat, Vec3, Vec4};
use splatbridge_raytrace::model::{Material, Mesh, TriScene};
use splatbridge_raytrace::render::camera_ray;
use splatbridge_raytrace::shadows::{
    gaussian_bounds, mesh_bounds, render_gaussian_shadowed, render_mesh_shadowed, SunShadows,
};
use splatbridge_raytrace::{
    AlphaMode, BackendKind, BuildPreset, GaussianTracer, MeshTracer, RenderOptions,
};
use splatbridge_scene::dynamic::{DynamicScene, PoseKey, SceneObject, TimeRange, Track};
use splatbridge_scene::effects::Shadows;
use splatbridge_scene::{Camera, GaussianCloud};

fn quad(m: &mut Mesh, corners: [Vec3; 4], rgba: Vec4, material: u32, gid: u32) {
    let base = m.positions.len() as u32;
    for c in corners {
        m.positions.push(c);
        m.colors.push(rgba);
    }
    for t in [[0, 1, 2], [0, 2, 3]] {
        m.tris.push(t.map(|i| base + i));
        m.tri_material.push(material);
        m.tri_gaussian.push(gid);
    }
}

/// Looking straight down (+y, the world is y-down) from height 10 at the origin: the ground
/// footprint is x, z ∈ ±3 (tan(16.7°)·10 ≈ 3) and at height 2 only ±2.4, so an occluder at
/// x ≥ 3 and height ≥ 2 is out of view while its shadow is in view.
fn top_camera(n: u32) -> Camera {
    Camera::look_at(
        DVec3::new(0.0, -10.0, 0.0),
        DVec3::ZERO,
        DVec3::Z,
        2.0 * 0.3f64.atan().to_degrees(),
        n,
        n,
    )
    .unwrap()
}

fn ground_point(cam: &Camera, i: u32, j: u32) -> DVec3 {
    let (o, d) = camera_ray(cam, i as f64 + 0.5, j as f64 + 0.5);
    o + d * (-o.y / d.y)
}

#[test]
fn mesh_square_of_known_opacity_darkens_exactly_its_shadow() {
    let mut m = Mesh {
        has_gaussian_ids: true,
        ..Mesh::default()
    };
    let g = 20.0;
    quad(
        &mut m,
        [
            Vec3::new(-g, 0.0, -g),
            Vec3::new(g, 0.0, -g),
            Vec3::new(g, 0.0, g),
            Vec3::new(-g, 0.0, g),
        ],
        Vec4::new(0.5, 0.5, 0.5, 1.0),
        0,
        0,
    );
    let opacity = 0.6;
    quad(
        &mut m,
        [
            Vec3::new(3.0, -2.0, -1.0),
            Vec3::new(5.0, -2.0, -1.0),
            Vec3::new(5.0, -2.0, 1.0),
            Vec3::new(3.0, -2.0, 1.0),
        ],
        Vec4::new(0.9, 0.1, 0.1, opacity),
        1,
        1,
    );
    let mats = vec![
        Material::default(),
        Material {
            base_color: Vec4::ONE,
            texture: None,
            alpha_mode: AlphaMode::Blend,
        },
    ];
    let tracer = MeshTracer::new(
        TriScene::single(m, mats, Vec::new()),
        BackendKind::Obvhs,
        BuildPreset::Medium,
    )
    .unwrap();
    let strength = 0.8;
    // Towards the sun: up (−y) and +x at 45°, so a ground point x sees the occluder plane
    // (height 2) at x + 2: shadowed iff x ∈ (1, 3) and z ∈ (−1, 1).
    let (lo, hi) = mesh_bounds(&tracer, 0.0);
    let sun = SunShadows::from_effect(
        &Shadows {
            sun_direction: [1.0, -1.0, 0.0],
            strength,
        },
        lo,
        hi,
    )
    .unwrap();
    let cam = top_camera(64);
    let opts = RenderOptions::default();
    let (plain, _) = tracer.render(&cam, 0.0, &opts).unwrap();
    let (shadowed, _, st) = render_mesh_shadowed(&tracer, &cam, 0.0, &opts, &sun).unwrap();
    assert_eq!(st.shadow_rays, 64 * 64, "one shadow ray per (opaque) pixel");
    let expected = 1.0 - strength * opacity;
    let (mut inside, mut outside) = (0, 0);
    for j in 0..64 {
        for i in 0..64 {
            let p = ground_point(&cam, i, j);
            // 1e-3 from the shadow's edges: f32 hit distances are exact to ~1e-6 here, so only
            // pixels whose ground point is practically on an edge are skipped.
            let margin = 1e-3;
            let near_edge = (p.x - 1.0).abs() < margin
                || (p.x - 3.0).abs() < margin
                || (p.z.abs() - 1.0).abs() < margin;
            if near_edge {
                continue;
            }
            let in_shadow = p.x > 1.0 && p.x < 3.0 && p.z.abs() < 1.0;
            let a = plain.rgb_at(i, j);
            let b = shadowed.rgb_at(i, j);
            for c in 0..3 {
                // Barycentric interpolation of equal vertex colours rounds by an ulp or two.
                assert!(
                    (a[c] - 0.5).abs() < 1e-6,
                    "the ground is grey and the square out of view: {}",
                    a[c]
                );
                // f32 products of the plain value: 1e-6 covers their rounding.
                let want = if in_shadow { a[c] * expected } else { a[c] };
                assert!(
                    (b[c] - want).abs() < 1e-6,
                    "pixel ({i},{j}) at {p}: {} vs {want}",
                    b[c]
                );
            }
            if in_shadow {
                inside += 1;
            } else {
                outside += 1;
            }
        }
    }
    // The shadow covers x ∈ (1, 3), z ∈ (−1, 1) of the 6×6 footprint: about 2/36 of it.
    assert!(inside > 100 && outside > 2000, "{inside} {outside}");
}

/// Flat Gaussian discs tiling the ground plane y = 0 (thin along y).
fn ground_cloud(half: f32, spacing: f32) -> GaussianCloud {
    let n = (2.0 * half / spacing).round() as i32;
    let mut c = GaussianCloud::with_capacity(0, (n * n) as usize);
    for a in 0..n {
        for b in 0..n {
            let x = -half + (a as f32 + 0.5) * spacing;
            let z = -half + (b as f32 + 0.5) * spacing;
            c.push_activated(
                Vec3::new(x, 0.0, z),
                Vec3::new(spacing, 1e-3, spacing),
                Quat::IDENTITY,
                0.99,
                Vec3::splat(0.6),
            );
        }
    }
    c
}

/// α the tracer gives a Gaussian (mean `mu`, axis-aligned scales `s`, opacity `o`) on the ray
/// `p + t·d`, in f64 from the closed form (3DGRT's maximum response), or 0 below 1/255 or
/// before `tmin`.
fn ref_alpha(mu: DVec3, s: DVec3, o: f64, p: DVec3, d: DVec3, tmin: f64) -> f64 {
    let og = (p - mu) / s;
    let dg = d / s;
    let n = dg.normalize();
    let d2 = n.cross(og).length_squared();
    let a = (o * (-0.5 * d2).exp()).min(0.99);
    let t = (-og.dot(dg) / dg.length_squared()).max(0.0);
    if a < 1.0 / 255.0 || t < tmin {
        0.0
    } else {
        a
    }
}

#[test]
fn gaussian_occluder_darkens_by_its_closed_form_transmittance() {
    let mut cloud = ground_cloud(6.0, 0.15);
    // Occluder: a disc σ = 0.6 at height 4 (y = −4), x = 5. Its proxy reaches 3.2σ ≈ 1.9 from
    // its centre, outside the view's ±1.8 at that height; its shadow (sun at 45° in +x) is
    // centred on x = 1.
    let (mu, s, o) = (DVec3::new(5.0, -4.0, 0.0), DVec3::new(0.6, 1e-3, 0.6), 0.7);
    cloud.push_activated(
        mu.as_vec3(),
        s.as_vec3(),
        Quat::IDENTITY,
        o as f32,
        Vec3::new(1.0, 0.0, 0.0),
    );
    let tracer = GaussianTracer::new(cloud, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let (lo, hi) = gaussian_bounds(&tracer);
    let strength = 0.9f32;
    let sun = SunShadows::from_effect(
        &Shadows {
            sun_direction: [1.0, -1.0, 0.0],
            strength,
        },
        lo,
        hi,
    )
    .unwrap();
    let cam = top_camera(48);
    let opts = RenderOptions::default();
    let (plain, _) = tracer.render(&cam, &opts).unwrap();
    let (shadowed, _, st) = render_gaussian_shadowed(&tracer, &cam, &opts, &sun).unwrap();
    assert!(st.shadow_rays > 0);
    let l = DVec3::new(1.0, -1.0, 0.0).normalize();
    let mut darkened = 0;
    for j in 0..48 {
        for i in 0..48 {
            if plain.alpha[(j * 48 + i) as usize] < 0.5 {
                continue;
            }
            let p = ground_point(&cam, i, j);
            let a = ref_alpha(mu, s, o, p, l, sun.bias);
            let f = 1.0 - strength as f64 * a;
            // The shading point is the tracer's mean hit distance on discs 1e-3 thick: within
            // ~1e-4 of the plane (3DGRT's t* lies within r·σ_n/d_n of the crossing), which moves
            // α by at most 0.7·0.61/0.6·1e-4 ≈ 1e-4; f32 sums add ~1e-6. 1e-3 bounds both.
            let want = plain.rgb_at(i, j)[0] as f64 * f;
            let got = shadowed.rgb_at(i, j)[0] as f64;
            assert!(
                (got - want).abs() < 1e-3,
                "pixel ({i},{j}) at {p}: {got} vs {want} (α_ref {a})"
            );
            if a > 0.1 {
                darkened += 1;
            }
        }
    }
    assert!(darkened > 50, "the shadow is in view ({darkened} pixels)");
}

/// A 3×3×3 block of Gaussians (1 unit wide) at the origin of its own frame.
fn block() -> GaussianCloud {
    let mut c = GaussianCloud::with_capacity(0, 27);
    for a in -1..=1 {
        for b in -1..=1 {
            for e in -1..=1 {
                c.push_activated(
                    Vec3::new(a as f32, b as f32, e as f32) * 0.35,
                    Vec3::splat(0.2),
                    Quat::IDENTITY,
                    0.9,
                    Vec3::new(0.1, 0.3, 0.9),
                );
            }
        }
    }
    c
}

#[test]
fn a_moving_object_darkens_what_lies_behind_it_towards_the_sun() {
    // The block flies at height 2 from x = −1.5 (t = 0) to x = 1.5 (t = 1); with the sun at
    // 45° in +x its shadow is at x − 2: −3.5 then −0.5. From the top camera neither shadow
    // point is hidden by the block (the view ray to (−3.5, 0, 0) crosses height 2 at x = −2.8,
    // to (−0.5, 0, 0) at −0.4; the block spans x ± 0.5).
    let scene = DynamicScene {
        time: TimeRange {
            start: 0.0,
            end: 1.0,
            fps: 1.0,
        },
        static_gaussians: ground_cloud(6.0, 0.15),
        objects: vec![SceneObject {
            name: "block".into(),
            gaussians: block(),
            track: Track::new(vec![
                PoseKey::new(0.0, Vec3::new(-1.5, -2.0, 0.0), Quat::IDENTITY),
                PoseKey::new(1.0, Vec3::new(1.5, -2.0, 0.0), Quat::IDENTITY),
            ]),
        }],
        frames: Vec::new(),
        cameras: Vec::new(),
        effects: serde_json::Map::new(),
        four_d: None,
    };
    let shadows = Shadows {
        sun_direction: [1.0, -1.0, 0.0],
        strength: 0.8,
    };
    let cam = top_camera(64);
    let opts = RenderOptions::default();
    let pixel_of = |p: DVec3| {
        let c = cam.to_camera(p);
        (
            (cam.fx * c.x / c.z + cam.cx) as u32,
            (cam.fy * c.y / c.z + cam.cy) as u32,
        )
    };
    let (p0, p1) = (DVec3::new(-3.5, 0.0, 0.0), DVec3::new(-0.5, 0.0, 0.0));
    let mut ratios = Vec::new();
    for t in [0.0, 1.0] {
        let tracer =
            GaussianTracer::new(scene.composite(t), BackendKind::Obvhs, BuildPreset::Medium)
                .unwrap();
        let (lo, hi) = gaussian_bounds(&tracer);
        let sun = SunShadows::from_effect(&shadows, lo, hi).unwrap();
        let (plain, _) = tracer.render(&cam, &opts).unwrap();
        let (shadowed, _, _) = render_gaussian_shadowed(&tracer, &cam, &opts, &sun).unwrap();
        let ratio = |p: DVec3| {
            let (i, j) = pixel_of(p);
            shadowed.rgb_at(i, j)[0] / plain.rgb_at(i, j)[0]
        };
        ratios.push((ratio(p0), ratio(p1)));
        // The factor at the shadow point itself, straight from the secondary query.
        let (under, free) = if t == 0.0 { (p0, p1) } else { (p1, p0) };
        assert!(sun.factor(&tracer, under) < 0.5, "t = {t}");
        assert_eq!(sun.factor(&tracer, free), 1.0, "t = {t}");
    }
    // The block is ~0.99 opaque through its middle: the shadowed pixel keeps about 1 − 0.8.
    assert!(ratios[0].0 < 0.5 && ratios[0].1 > 0.999, "{ratios:?}");
    assert!(ratios[1].1 < 0.5 && ratios[1].0 > 0.999, "{ratios:?}");
}
