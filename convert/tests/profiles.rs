//! Meshing profiles against f64 references: the rings error bound, fan geometry, topology
//! counts, classification, the budget, colours and degenerate inputs.

mod common;

use glam::{DMat3, DVec3, Quat, Vec3};
use splatbridge_convert::classify::{corrected_alpha, THREE_FAN_DEPTH_SCALE};
use splatbridge_convert::profile::{
    cutoff_radius, layout_alpha_at, minimax_knots, polygon_radius_error, texture_radius, FanLayout,
    ProfileShape,
};
use splatbridge_convert::{mesh_cloud, ConvertOptions, Profile, VolumetricMode};
use splatbridge_scene::GaussianCloud;

fn one(scale: Vec3, rot: Quat, o: f32) -> GaussianCloud {
    let mut c = GaussianCloud::new(0);
    c.push_activated(
        Vec3::new(0.3, -0.2, 1.5),
        scale,
        rot,
        o,
        Vec3::new(0.8, 0.4, 0.1),
    );
    c
}

#[test]
fn rings_minimax_error_table() {
    // The table in profile.rs's docs, o = 1 (r_max = sqrt(2 ln 255)); printed values are
    // rounded to 2–3 significant digits there, so compare to 3 % of each entry.
    let r = texture_radius() as f64;
    let doc = [
        (1, 0.267),
        (2, 0.108),
        (3, 0.050),
        (4, 0.020),
        (6, 0.011),
        (8, 0.0068),
    ];
    for (m, _) in doc {
        let (knots, err) = minimax_knots(r, m);
        println!("m = {m}: ε = {err:.5}, knots {knots:?}");
    }
    for (m, want) in doc {
        let (knots, err) = minimax_knots(r, m);
        assert_eq!(knots.len(), m);
        assert!((knots[m - 1] - r).abs() < 1e-12);
        assert!(
            (err - want).abs() <= 0.03 * want,
            "m = {m}: ε = {err}, docs say {want}"
        );
    }
}

/// Max |mesh alpha − o·exp(−r²/2)| over a dense grid covering the fan, in f64.
fn max_footprint_error(layout: &FanLayout, o: f64, extent: f64) -> f64 {
    let steps = 400;
    let mut e: f64 = 0.0;
    for i in 0..=steps {
        for j in 0..=steps {
            let x = -extent + 2.0 * extent * i as f64 / steps as f64;
            let y = -extent + 2.0 * extent * j as f64 / steps as f64;
            let truth = o * (-0.5 * (x * x + y * y)).exp();
            e = e.max((layout_alpha_at(layout, x, y, None) - truth).abs());
        }
    }
    e
}

#[test]
fn rings_profile_error_is_within_the_documented_bound() {
    for n in [8usize, 16] {
        for m in [2usize, 3, 4] {
            let shape = ProfileShape::new(Profile::Rings, n, m);
            for o in [1.0f32, 0.6, 0.1, 0.02, 4.0 / 255.0] {
                let mut lay = FanLayout::default();
                assert!(shape.layout(o, &mut lay));
                let r_max = cutoff_radius(o).unwrap() as f64;
                // The knots actually used (tabulated fractions × r_max) and their radial error.
                let knots: Vec<f64> = (0..m)
                    .map(|j| {
                        (lay.verts[1 + j * n].x as f64).hypot(lay.verts[1 + j * n].y as f64)
                            / splatbridge_convert::profile::area_factor(n)
                    })
                    .collect();
                let (_, eps_opt) = minimax_knots(r_max, m);
                let mut eps_used: f64 = 0.0;
                let mut a = 0.0;
                for &k in &knots {
                    for s in 1..200 {
                        let x = a + (k - a) * s as f64 / 200.0;
                        let ga = (-0.5 * a * a).exp();
                        let gk = (-0.5 * k * k).exp();
                        let lin = ga + (gk - ga) * (x - a) / (k - a);
                        eps_used = eps_used.max((lin - (-0.5 * x * x).exp()).abs());
                    }
                    a = k;
                }
                // Tabulating knot fractions at 96 levels of r_max costs at most 15 % over the
                // per-Gaussian optimum (measured maximum over this grid: see the print).
                assert!(
                    eps_used <= eps_opt * 1.15 + 1e-4,
                    "n {n} m {m} o {o}: used knots ε {eps_used} vs optimum {eps_opt}"
                );
                let bound = o as f64
                    * (eps_used + 2.0 / std::f64::consts::E * polygon_radius_error(n))
                    + 1.0 / 255.0;
                let err = max_footprint_error(&lay, o as f64, 1.2 * r_max);
                println!("n {n} m {m} o {o:.3}: max error {err:.4}, bound {bound:.4} (ε used {eps_used:.4}, optimum {eps_opt:.4})");
                assert!(
                    err <= bound,
                    "n {n} m {m} o {o}: error {err} above bound {bound}"
                );
            }
        }
    }
}

#[test]
fn transparent_gaussians_give_no_rings_but_meshsplats_keeps_them() {
    let c = one(Vec3::new(0.1, 0.05, 0.001), Quat::IDENTITY, 0.003);
    let (m, counts) = mesh_cloud(
        &c,
        &ConvertOptions {
            profile: Profile::Rings,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((m.triangle_count(), counts.dropped_transparent), (0, 1));
    let (m, _) = mesh_cloud(
        &c,
        &ConvertOptions {
            profile: Profile::MeshSplats,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(m.triangle_count(), 8);
}

#[test]
fn topology_counts_per_profile() {
    let flat = one(Vec3::new(0.1, 0.05, 0.001), Quat::from_rotation_y(0.4), 0.9);
    let vol = one(Vec3::new(0.1, 0.08, 0.07), Quat::from_rotation_z(0.7), 0.9);
    let cases = [
        (Profile::MeshSplats, None, 3, (9, 8), (19, 24)),
        (Profile::Rings, None, 3, (25, 40), (0, 120)),
        (Profile::Rings, Some(6), 2, (13, 18), (1 + 3 * 12, 54)),
        (Profile::Texture, None, 3, (4, 2), (12, 6)),
    ];
    for (profile, segments, rings, f, v) in cases {
        let opts = ConvertOptions {
            profile,
            segments,
            rings,
            ..Default::default()
        };
        let (m, _) = mesh_cloud(&flat, &opts).unwrap();
        assert_eq!(
            (m.vertex_count(), m.triangle_count()),
            f,
            "{profile:?} flat"
        );
        let (m, c) = mesh_cloud(&vol, &opts).unwrap();
        assert_eq!(c.volumetric, 1);
        // Rings n=8: each ring's 12 axis-vertex instances (4 per fan) are 6 distinct vertices,
        // and the centre is shared: 3·(1+8m) − 2 − 6m.
        let expect_v = match (profile, segments) {
            (Profile::Rings, None) => 3 * (1 + 8 * 3) - 2 - 6 * 3,
            _ => v.0,
        };
        assert_eq!(
            (m.vertex_count(), m.triangle_count()),
            (expect_v, v.1),
            "{profile:?} volumetric"
        );
        let opts = ConvertOptions {
            volumetric: VolumetricMode::Flat,
            ..opts
        };
        let (m, c) = mesh_cloud(&vol, &opts).unwrap();
        assert_eq!((c.volumetric, m.triangle_count()), (0, f.1));
    }
}

#[test]
fn meshsplats_fan_matches_f64_reference() {
    let rot = Quat::from_xyzw(0.3, -0.5, 0.2, 0.8).normalize();
    let s = Vec3::new(0.2, 0.5, 0.01); // largest axis is y
    let c = one(s, rot, 0.7);
    // The published geometry exactly: without the coplanar separation (tested on its own in
    // tests/coplanar.rs).
    let opts = ConvertOptions {
        profile: Profile::MeshSplats,
        color_encoding: splatbridge_convert::ColorEncoding::Display,
        coplanar_offset: false,
        ..Default::default()
    };
    let (m, _) = mesh_cloud(&c, &opts).unwrap();
    let r = DMat3::from_quat(rot.as_dquat());
    let mu = c.means[0].as_dvec3();
    // Axes sorted by scale: a0 = y column (0.5), a1 = x column (0.2).
    let (a0, a1) = (r.col(1) * 0.5, r.col(0) * 0.2);
    assert_eq!(m.vertex_count(), 9);
    for k in 0..8 {
        let t = -std::f64::consts::PI + 2.0 * std::f64::consts::PI * k as f64 / 8.0;
        let want = mu + 2.7 * (t.cos() * a0 + t.sin() * a1);
        let got = DVec3::from_array(m.positions[1 + k].map(|x| x as f64));
        // f32 storage of values ≈ 1.5 in size: 1e-6 absolute is a few ulps.
        assert!((got - want).length() < 1e-6, "rim {k}: {got} vs {want}");
        assert!((m.colors[1 + k][3] - 0.2 * 0.7).abs() < 1e-6);
    }
    assert!((m.colors[0][3] - 0.7).abs() < 1e-6);
    let n = DVec3::from_array(m.normals[0].map(|x| x as f64));
    assert!((n.length() - 1.0).abs() < 1e-6);
    assert!(
        n.dot(r.col(2)).abs() > 1.0 - 1e-6,
        "normal is the shortest axis"
    );
    let rgb = Vec3::new(0.8, 0.4, 0.1);
    for ch in 0..3 {
        assert!((m.colors[0][ch] - rgb[ch]).abs() < 1e-6);
    }
}

#[test]
fn three_fans_share_centre_and_axis_tips() {
    let c = one(Vec3::new(0.1, 0.08, 0.07), Quat::from_rotation_x(0.3), 0.5);
    let (m, _) = mesh_cloud(
        &c,
        &ConvertOptions {
            profile: Profile::MeshSplats,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((m.vertex_count(), m.triangle_count()), (19, 24));
    // All 19 positions are distinct and every index is in range.
    for i in 0..19 {
        for j in 0..i {
            assert_ne!(m.positions[i], m.positions[j]);
        }
    }
    assert!(m.indices.iter().all(|&i| i < 19));
    // MeshSplats applies no opacity correction; the opacity-aware profiles do.
    assert!((m.colors[0][3] - 0.5).abs() < 1e-6);
    let (r, _) = mesh_cloud(
        &c,
        &ConvertOptions {
            profile: Profile::Rings,
            ..Default::default()
        },
    )
    .unwrap();
    let want = 1.0 - (1.0f64 - 0.5).powf(THREE_FAN_DEPTH_SCALE as f64);
    assert!((r.colors[0][3] as f64 - want).abs() < 1e-6);
    assert_eq!(corrected_alpha(1.0), 1.0);
}

#[test]
fn three_fan_correction_is_minimax_over_view_directions() {
    // Coverage over-count of three fans is ‖v‖₁/‖v‖₂ ∈ [1, √3]; with the depth scale c the
    // relative error c·ratio − 1 must be within ±(√3−1)/(√3+1) for every direction.
    let c = THREE_FAN_DEPTH_SCALE as f64;
    let bound = (3f64.sqrt() - 1.0) / (3f64.sqrt() + 1.0);
    let mut worst: f64 = 0.0;
    for i in 0..=50 {
        for j in 0..=50 {
            let th = std::f64::consts::PI * i as f64 / 50.0;
            let ph = std::f64::consts::TAU * j as f64 / 50.0;
            let v = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            let ratio = (v.x.abs() + v.y.abs() + v.z.abs()) / v.length();
            worst = worst.max((c * ratio - 1.0).abs());
        }
    }
    assert!(
        worst <= bound + 1e-6 && worst > bound - 1e-3,
        "worst {worst}, bound {bound}"
    );
}

#[test]
fn budget_keeps_highest_scores_and_reports_drops() {
    let cloud = common::cloud(500, 0, 11);
    let full = mesh_cloud(&cloud, &ConvertOptions::default()).unwrap().1;
    let max = full.triangles / 3;
    let (m, counts) = mesh_cloud(
        &cloud,
        &ConvertOptions {
            max_triangles: Some(max),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(m.triangle_count() as u64 <= max && m.triangle_count() as u64 > max / 2);
    assert_eq!(
        counts.flat + counts.volumetric + counts.dropped_budget,
        full.flat + full.volumetric
    );
    assert!(counts.dropped_budget > 0);
    // Every kept Gaussian scores at least as high as every dropped one of the same kind.
    let kept: std::collections::HashSet<u32> = m.gaussian_ids.iter().copied().collect();
    let score = |i: usize| splatbridge_convert::classify::score(&cloud, i);
    let min_kept = kept
        .iter()
        .map(|&i| score(i as usize))
        .fold(f32::INFINITY, f32::min);
    let shape = splatbridge_convert::shape_for(&ConvertOptions::default());
    let mesher =
        splatbridge_convert::Mesher::new(&cloud, &shape, &ConvertOptions::default(), "", 0);
    let max_dropped_flat = (0..cloud.len())
        .filter(|&i| {
            mesher.kind(i) == splatbridge_convert::classify::Kind::Flat
                && !kept.contains(&(i as u32))
        })
        .map(score)
        .fold(0.0, f32::max);
    assert!(
        max_dropped_flat <= min_kept,
        "a flat Gaussian scoring {max_dropped_flat} was dropped below kept {min_kept}"
    );
}

#[test]
fn degenerate_gaussians_are_dropped_or_finite() {
    let mut c = GaussianCloud::new(0);
    c.push_activated(
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::ONE,
        Quat::IDENTITY,
        0.5,
        Vec3::ONE,
    );
    c.push(
        Vec3::ZERO,
        Vec3::ZERO,
        Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
        0.0,
        &[Vec3::ZERO],
    );
    c.push(
        Vec3::ZERO,
        Vec3::splat(80.0),
        Quat::IDENTITY,
        0.0,
        &[Vec3::ZERO],
    );
    c.push(
        Vec3::new(1e5, -1e5, 1e5),
        Vec3::splat(-23.0),
        Quat::IDENTITY,
        f32::INFINITY,
        &[Vec3::ZERO],
    );
    c.push(
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, -30.0),
        Quat::from_xyzw(1e-18, 0.0, 0.0, 1e-18),
        f32::NEG_INFINITY,
        &[Vec3::splat(1e3)],
    );
    for profile in [Profile::MeshSplats, Profile::Rings, Profile::Texture] {
        let (m, counts) = mesh_cloud(
            &c,
            &ConvertOptions {
                profile,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(counts.dropped_invalid, 2, "{profile:?}");
        assert_eq!(counts.dropped_overflow, 1, "{profile:?}");
        assert!(m.positions.iter().flatten().all(|x| x.is_finite()));
        assert!(m
            .normals
            .iter()
            .all(|n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-5));
        assert!(m.colors.iter().flatten().all(|x| (0.0..=1.0).contains(x)));
    }
}

#[test]
fn baked_view_colour_follows_the_camera() {
    let mut c = common::cloud(50, 3, 5);
    c.opacity_logits.iter_mut().for_each(|x| *x = 3.0);
    let cam = splatbridge_scene::Camera::look_at(
        DVec3::new(0.0, -1.0, -8.0),
        DVec3::ZERO,
        DVec3::NEG_Y,
        50.0,
        64,
        48,
    )
    .unwrap();
    let opts = ConvertOptions {
        bake_view: Some(cam.clone()),
        color_encoding: splatbridge_convert::ColorEncoding::Display,
        profile: Profile::MeshSplats,
        ..Default::default()
    };
    let (m, _) = mesh_cloud(&c, &opts).unwrap();
    for v in 0..m.vertex_count() {
        let i = m.gaussian_ids[v] as usize;
        let d = (c.means[i].as_dvec3() - cam.centre).normalize();
        let want =
            splatbridge_scene::sh::eval_color_f64(3, c.sh_of(i), d).clamp(DVec3::ZERO, DVec3::ONE);
        for ch in 0..3 {
            // f32 evaluation of a degree-3 SH sum against f64: 1e-5.
            assert!((m.colors[v][ch] as f64 - want[ch]).abs() < 1e-5);
        }
    }
    // Linear encoding decodes the display colour.
    let (lin, _) = mesh_cloud(
        &c,
        &ConvertOptions {
            color_encoding: splatbridge_convert::ColorEncoding::Linear,
            ..opts
        },
    )
    .unwrap();
    let x = m.colors[0][0];
    let want = if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    };
    assert!((lin.colors[0][0] - want).abs() < 1e-6);
}

/// Relative L2 error of a fan's head-on alpha against the rasterizer's footprint
/// `o·exp(−r²/2)` (cut below 1/255), f64 on a dense grid.
fn relative_l2(layout: &FanLayout, o: f64, texture: bool) -> f64 {
    let extent = 6.0;
    let steps = 300;
    let (mut num, mut den) = (0.0, 0.0);
    let tex = |u: f64, v: f64| splatbridge_convert::texture::falloff(u, v);
    for i in 0..=steps {
        for j in 0..=steps {
            let x = -extent + 2.0 * extent * i as f64 / steps as f64;
            let y = -extent + 2.0 * extent * j as f64 / steps as f64;
            let g = o * (-0.5 * (x * x + y * y)).exp();
            let truth = if g >= 1.0 / 255.0 { g } else { 0.0 };
            let a = layout_alpha_at(layout, x, y, if texture { Some(&tex) } else { None });
            num += (a - truth).powi(2);
            den += truth * truth;
        }
    }
    (num / den).sqrt()
}

#[test]
fn profile_footprint_errors_per_triangle() {
    // Head-on footprint error of one flat Gaussian per profile, averaged over opacities; the
    // numbers back the choice of the default profile (see options.rs).
    let cases = [
        ("meshsplats n=8", Profile::MeshSplats, 8, 1),
        ("rings n=8 m=2", Profile::Rings, 8, 2),
        ("rings n=8 m=3", Profile::Rings, 8, 3),
        ("rings n=16 m=3", Profile::Rings, 16, 3),
        ("texture quad", Profile::Texture, 4, 1),
        ("texture n=8", Profile::Texture, 8, 1),
    ];
    let mut errs = Vec::new();
    for (name, profile, n, m) in cases {
        let shape = ProfileShape::new(profile, n, m);
        let mut e = 0.0;
        let mut tris = 0;
        let os = [0.1, 0.3, 0.6, 0.9, 1.0];
        for o in os {
            let mut lay = FanLayout::default();
            shape.layout(o as f32, &mut lay);
            tris = lay.tris.len();
            e += relative_l2(&lay, o, profile == Profile::Texture) / os.len() as f64;
        }
        println!("{name:16} {tris:3} triangles: relative L2 footprint error {e:.4}");
        errs.push(e);
    }
    // The opacity-aware profiles must beat the MeshSplats cone, and more rings must help.
    assert!(
        errs[1] < errs[0] && errs[2] < errs[1] && errs[3] < errs[2],
        "{errs:?}"
    );
    assert!(
        errs[4] < errs[2],
        "the texture quad follows the profile better than 3 rings: {errs:?}"
    );
}
