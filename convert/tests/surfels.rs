//! `--surfels` export: the split against a brute-force reference, opaque fans (alpha
//! exactly 1) on the 1/255 footprint, one OPAQUE and one BLEND material assigned to the
//! right primitives, surfels of objects under their animated nodes, metadata.

mod common;

use std::collections::BTreeSet;

use glam::{DVec3, Vec3};
use splatbridge_convert::surfels::{split_scene, SurfelMesher, SurfelOptions};
use splatbridge_convert::{
    convert_to_file, glb_bytes, ChunkedMesh, ConvertOptions, FrameClouds, Profile,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::GaussianCloud;

/// Reference predicate, written out from the definition (not the library's): opacity ≥ A,
/// sorted scales s_min/s_mid ≤ R, everything finite.
fn ref_is_surfel(c: &GaussianCloud, i: usize, a: f32, r: f32) -> bool {
    let o = 1.0 / (1.0 + (-(c.opacity_logits[i] as f64)).exp());
    let mut s: Vec<f64> = c.log_scales[i]
        .to_array()
        .iter()
        .map(|l| (*l as f64).exp())
        .collect();
    s.sort_by(|x, y| y.total_cmp(x));
    let flat = if s[1] > 0.0 { s[2] / s[1] } else { 0.0 };
    c.means[i].is_finite()
        && s.iter().all(|x| x.is_finite())
        && c.rotations[i].length() > 0.0
        && o >= a as f64
        && flat <= r as f64
}

/// Composite ids (static, objects, frames) of the reference surfels.
fn ref_surfel_ids(clouds: &[&GaussianCloud], a: f32, r: f32) -> BTreeSet<u32> {
    let mut ids = BTreeSet::new();
    let mut off = 0u32;
    for c in clouds {
        for i in 0..c.len() {
            if ref_is_surfel(c, i, a, r) {
                ids.insert(off + i as u32);
            }
        }
        off += c.len() as u32;
    }
    ids
}

fn frames() -> FrameClouds {
    FrameClouds {
        times: vec![0.0, 1.0],
        clouds: vec![common::cloud(40, 3, 11), common::cloud(40, 3, 12)],
    }
}

fn clouds<'a>(scene: &'a DynamicScene, fr: &'a FrameClouds) -> Vec<&'a GaussianCloud> {
    let mut v = vec![&scene.static_gaussians];
    v.extend(scene.objects.iter().map(|o| &o.gaussians));
    v.extend(fr.clouds.iter());
    v
}

fn read_ids(prim: &gltf::Primitive, buffers: &[gltf::buffer::Data]) -> Vec<u32> {
    let acc = prim
        .attributes()
        .find(|(s, _)| *s == gltf::Semantic::Extras("GAUSSIAN_ID".into()))
        .expect("_GAUSSIAN_ID")
        .1;
    gltf::accessor::Iter::<f32>::new(acc, |b| Some(&buffers[b.index()][..]))
        .unwrap()
        .map(|x| x as u32)
        .collect()
}

#[test]
fn surfel_glb_splits_assigns_materials_and_keeps_ids() {
    let scene = common::street(500);
    let fr = frames();
    // The local test alone, checked against the reference predicate (the guards have
    // `export_applies_the_guards`).
    let so = SurfelOptions {
        guarded: false,
        ..Default::default()
    };
    // As `splatbridge convert --surfels` writes it (coplanar separation on).
    let opts = ConvertOptions {
        surfels: Some(so),
        coplanar_offset: true,
        ..Default::default()
    };
    let (bytes, report) = glb_bytes(&scene, Some(&fr), &opts).unwrap();
    let all = clouds(&scene, &fr);
    let total: usize = all.iter().map(|c| c.len()).sum();
    let want = ref_surfel_ids(&all, so.min_opacity, so.max_flatness);
    assert!(
        want.len() > 50 && want.len() < total / 2,
        "fixture has {} surfels",
        want.len()
    );
    // Counts: residual = input − surfels, in the report and per part.
    let sr = report.surfels.as_ref().expect("surfel report");
    assert_eq!(sr.surfels as usize, want.len());
    assert_eq!(sr.gaussians_in as usize, total);
    assert_eq!(sr.residual as usize, total - want.len());
    assert_eq!(report.gaussians_in as usize, total);
    let residual_in: u64 = report.meshes.iter().map(|m| m.gaussians_in).sum();
    assert_eq!(residual_in as usize, total - want.len());
    assert_eq!(sr.parts.len(), all.len());
    for (p, c) in sr.parts.iter().zip(&all) {
        assert_eq!(p.surfels + p.residual, c.len() as u64, "{}", p.name);
    }

    let (doc, buffers, _) = gltf::import_slice(&bytes).unwrap();
    let meta: serde_json::Value =
        serde_json::from_str(doc.as_json().asset.extras.as_ref().unwrap().get()).unwrap();
    let m = &meta["splatbridge"];
    assert_eq!(m["surfels"]["surfels"], want.len());
    assert_eq!(m["surfels"]["residual"], total - want.len());
    assert_eq!(m["surfels"]["min_opacity"], so.min_opacity as f64);
    assert_eq!(
        m["options"]["surfels"]["max_flatness"],
        so.max_flatness as f64
    );
    assert_eq!(m["counts"]["triangles"], report.triangles);

    // Two materials: the splat material (BLEND, textured) and the surfel material.
    let mats: Vec<_> = doc.materials().collect();
    assert_eq!(mats.len(), 2);
    let n = so.segments;
    let mut got_surfels = BTreeSet::new();
    let mut got_residual = BTreeSet::new();
    let mut surfel_verts = 0usize;
    let mut animated_with_surfels = 0;
    let animated: BTreeSet<usize> = doc
        .animations()
        .flat_map(|a| {
            a.channels()
                .filter(|c| c.target().property() == gltf::animation::Property::Translation)
                .map(|c| c.target().node().index())
                .collect::<Vec<_>>()
        })
        .collect();
    for node in doc.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        for prim in mesh.primitives() {
            let mat = prim.material();
            let rd = prim.reader(|b| Some(&buffers[b.index()]));
            let ids = read_ids(&prim, &buffers);
            assert!(mat.double_sided() && mat.unlit());
            match mat.name() {
                Some("surfels") => {
                    assert_eq!(mat.alpha_mode(), gltf::material::AlphaMode::Opaque);
                    assert!(mat.pbr_metallic_roughness().base_color_texture().is_none());
                    assert!(rd.read_tex_coords(0).is_none());
                    // Alpha is exactly 1 at every vertex (normalized u16 65535).
                    let cols: Vec<[u16; 4]> = rd.read_colors(0).unwrap().into_rgba_u16().collect();
                    assert!(cols.iter().all(|c| c[3] == u16::MAX));
                    assert_eq!(cols.len() % (n + 1), 0);
                    let tris = rd.read_indices().unwrap().into_u32().count() / 3;
                    assert_eq!(tris * (n + 1), cols.len() * n);
                    surfel_verts += cols.len();
                    // Every vertex of one fan carries the same id; one fan per surfel.
                    for f in ids.chunks(n + 1) {
                        assert!(f.iter().all(|&x| x == f[0]));
                        assert!(got_surfels.insert(f[0]), "surfel {} twice", f[0]);
                    }
                    if animated.contains(&node.index()) {
                        animated_with_surfels += 1;
                    }
                }
                Some("gaussian_splats") => {
                    assert_eq!(mat.alpha_mode(), gltf::material::AlphaMode::Blend);
                    assert!(mat.pbr_metallic_roughness().base_color_texture().is_some());
                    got_residual.extend(ids);
                }
                other => panic!("unexpected material {other:?}"),
            }
        }
    }
    assert_eq!(
        got_surfels, want,
        "surfel ids are the unsplit composite ids"
    );
    assert!(got_residual.is_disjoint(&want));
    assert_eq!(surfel_verts, want.len() * (n + 1));
    // Both objects have surfels, and they sit on the objects' moving nodes.
    assert_eq!(animated_with_surfels, 2);

    // The residual mesh is exactly the plain export of the non-surfel Gaussians.
    let mut rest = GaussianCloud::new(scene.static_gaussians.sh_degree);
    let c = &scene.static_gaussians;
    for i in 0..c.len() {
        if !want.contains(&(i as u32)) {
            rest.push(
                c.means[i],
                c.log_scales[i],
                c.rotations[i],
                c.opacity_logits[i],
                c.sh_of(i),
            );
        }
    }
    // (Exact positions: both without the coplanar separation, which hashes the ids and the
    // residual keeps its unsplit ids.)
    let exact = ConvertOptions {
        coplanar_offset: false,
        ..opts.clone()
    };
    let (bytes, _) = glb_bytes(&scene, Some(&fr), &exact).unwrap();
    let (doc, buffers, _) = gltf::import_slice(&bytes).unwrap();
    let (plain, _) = splatbridge_convert::mesh_cloud(
        &rest,
        &ConvertOptions {
            coplanar_offset: false,
            ..Default::default()
        },
    )
    .unwrap();
    let stat = doc
        .nodes()
        .find(|n| n.name() == Some("static"))
        .unwrap()
        .mesh()
        .unwrap();
    let prim = stat
        .primitives()
        .find(|p| p.material().name() == Some("gaussian_splats"))
        .unwrap();
    let pos: Vec<[f32; 3]> = prim
        .reader(|b| Some(&buffers[b.index()]))
        .read_positions()
        .unwrap()
        .collect();
    assert_eq!(pos, plain.positions);
}

#[test]
fn surfel_fans_reach_the_footprint_in_the_object_frame() {
    let scene = common::street(200);
    // The local test alone: the fan geometry is the point here, and the guards judge the
    // 200-Gaussian fixture's small car cloud too sparse for any surfel.
    let so = SurfelOptions {
        segments: 12,
        guarded: false,
        ..Default::default()
    };
    let opts = ConvertOptions {
        coplanar_offset: true,
        ..Default::default()
    };
    let split = split_scene(&scene, None, &so);
    // Object 0 ("car"): surfels in its local frame, centres at the local means.
    let part = &split.parts[1];
    let car = &scene.objects[0].gaussians;
    assert!(!part.surfels.is_empty());
    let m = SurfelMesher::new(part, &so, &opts, car.len() as u64);
    let soup = m.build();
    let n = so.segments;
    // f64 reference: footprint sqrt(2 ln 255) σ times the area-preserving n-gon factor.
    let r_fp = (2.0 * 255f64.ln()).sqrt();
    let k_n = (2.0 * std::f64::consts::PI
        / (n as f64 * (2.0 * std::f64::consts::PI / n as f64).sin()))
    .sqrt();
    for (j, f) in soup.positions.chunks(n + 1).enumerate() {
        let id = part.surfel_ids[j] as usize - scene.static_gaussians.len();
        let mean = car.means[id].as_dvec3();
        // Reference axes from the stored quaternion, scales sorted largest first.
        let q = car.rotations[id].as_dquat().normalize();
        let s = car.log_scales[id].as_dvec3().to_array().map(f64::exp);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| s[b].total_cmp(&s[a]));
        let axes = [0, 1, 2].map(|k| q * [DVec3::X, DVec3::Y, DVec3::Z][order[k]]);
        // The centre is the mean moved along the normal by the coplanar separation: at most
        // 128 steps of 2^-20 of the world-coordinate bound rounded up to a power of two
        // (≤ 2× the bound; classify.rs).
        let centre = Vec3::from(f[0]).as_dvec3();
        let off = centre - mean;
        let frame = scene.objects[0]
            .track
            .keys
            .iter()
            .map(|k| k.pose.translation.abs().max_element() as f64)
            .fold(0.0, f64::max);
        let reach = mean.abs().max_element() + frame + 4.0 * s[order[0]];
        assert!(
            off.length() <= 2.0 * 128.0 * reach / 1048576.0 * 1.0001,
            "{off}"
        );
        // f32 rounding of a centre ≈ 2 m from the origin: 1e-6 is a few ulps.
        assert!((off - axes[2] * off.dot(axes[2])).length() < 1e-6);
        for (k, v) in f[1..].iter().enumerate() {
            let d = Vec3::from(*v).as_dvec3() - centre;
            let (u, w) = (d.dot(axes[0]) / s[order[0]], d.dot(axes[1]) / s[order[1]]);
            let theta = std::f64::consts::TAU * k as f64 / n as f64;
            // f32 positions of a few-centimetre fan 2 m from the origin: 1e-4 σ is ~50 ulp.
            assert!((u - r_fp * k_n * theta.cos()).abs() < 1e-4, "{u}");
            assert!((w - r_fp * k_n * theta.sin()).abs() < 1e-4, "{w}");
            assert!(d.dot(axes[2]).abs() < 1e-5 * d.length().max(1e-3));
        }
    }
    assert!(soup.colors.iter().all(|c| c[3] == 1.0));
    // Winding: counter-clockwise around the written normal.
    for t in soup.indices.chunks(3) {
        let p = [0, 1, 2].map(|k| Vec3::from(soup.positions[t[k] as usize]));
        let nrm = Vec3::from(soup.normals[t[0] as usize]);
        assert!((p[1] - p[0]).cross(p[2] - p[0]).dot(nrm) > 0.0);
    }
}

#[test]
fn thresholds_are_knobs_and_degenerate_splits_stay_valid() {
    let scene = common::street(300);
    // Nothing passes A > 1: no surfel material, the same mesh as a plain export.
    let none = ConvertOptions {
        surfels: Some(SurfelOptions {
            min_opacity: 1.01,
            ..Default::default()
        }),
        ..Default::default()
    };
    let (b, r) = glb_bytes(&scene, None, &none).unwrap();
    assert_eq!(r.surfels.as_ref().unwrap().surfels, 0);
    let (plain_b, plain) = glb_bytes(&scene, None, &ConvertOptions::default()).unwrap();
    assert_eq!((r.triangles, r.vertices), (plain.triangles, plain.vertices));
    let (doc, _, _) = gltf::import_slice(&b).unwrap();
    assert_eq!(doc.materials().count(), 1);
    // Same binary chunk as the plain export (only the JSON metadata differs).
    let bin = |x: &[u8]| {
        let jl = u32::from_le_bytes(x[12..16].try_into().unwrap()) as usize;
        x[20 + jl..].to_vec()
    };
    assert_eq!(bin(&b), bin(&plain_b));
    // Everything flat passes A = 0, R = 1: surfels only where every Gaussian qualifies;
    // with a volumetric-free cloud the residual material disappears.
    let mut flat = common::cloud(120, 1, 5);
    for i in 0..flat.len() {
        flat.log_scales[i].z = flat.log_scales[i].x.min(flat.log_scales[i].y) - 3.0;
    }
    let only = DynamicScene::from_static(flat.clone());
    let all = ConvertOptions {
        surfels: Some(SurfelOptions {
            min_opacity: 0.0,
            max_flatness: 1.0,
            segments: 8,
            guarded: false,
        }),
        profile: Profile::Rings,
        ..Default::default()
    };
    let (b, r) = glb_bytes(&only, None, &all).unwrap();
    let s = r.surfels.as_ref().unwrap();
    assert_eq!((s.surfels, s.residual), (120, 0));
    let (doc, _, images) = gltf::import_slice(&b).unwrap();
    assert_eq!(doc.materials().count(), 1);
    assert_eq!(doc.materials().next().unwrap().name(), Some("surfels"));
    assert!(images.is_empty());
    // Bad knobs are errors, not garbage.
    for bad in [
        SurfelOptions {
            segments: 2,
            ..Default::default()
        },
        SurfelOptions {
            max_flatness: f32::NAN,
            ..Default::default()
        },
    ] {
        let o = ConvertOptions {
            surfels: Some(bad),
            ..Default::default()
        };
        assert!(glb_bytes(&only, None, &o).is_err());
    }
    // OBJ/PLY have no alpha modes: a clear error, no file.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.obj");
    let e = convert_to_file(&p, &only, None, &all, false).unwrap_err();
    assert!(e.to_string().contains("glTF"), "{e}");
    assert!(!p.exists());
}

/// A wall of small flat opaque Gaussians and one metre-wide flat opaque floater in front of it:
/// every Gaussian passes the local test; the scene-scale guard keeps the floater a Gaussian in
/// the export, as in the hybrid, and only with the guards on.
#[test]
fn export_applies_the_guards() {
    use glam::Quat;
    let mut c = GaussianCloud::new(0);
    let (n, spacing) = (40usize, 2.0f32 / 39.0);
    let half = 0.5 * spacing * (n as f32 - 1.0);
    for i in 0..n {
        for j in 0..n {
            c.push_activated(
                Vec3::new(i as f32 * spacing - half, j as f32 * spacing - half, 1.5),
                Vec3::new(0.7 * spacing, 0.7 * spacing, 0.07 * spacing),
                Quat::IDENTITY,
                0.95,
                Vec3::new(0.2, 0.6, 0.3),
            );
        }
    }
    let floater = c.len() as u32;
    c.push_activated(
        Vec3::new(0.3, 0.0, 1.0),
        Vec3::new(1.2, 1.2, 0.06),
        Quat::IDENTITY,
        0.9,
        Vec3::new(0.9, 0.1, 0.1),
    );
    let scene = DynamicScene::from_static(c.clone());
    let guarded = split_scene(&scene, None, &SurfelOptions::default());
    let unguarded = split_scene(
        &scene,
        None,
        &SurfelOptions {
            guarded: false,
            ..Default::default()
        },
    );
    let (g, u) = (&guarded.parts[0], &unguarded.parts[0]);
    assert_eq!(
        u.surfel_ids.len(),
        c.len(),
        "every Gaussian passes the local test"
    );
    assert_eq!(u.guarded_out, 0);
    assert!(u.surfel_ids.contains(&floater));
    assert!(
        g.residual_ids.contains(&floater),
        "the floater stays a Gaussian"
    );
    assert!(!g.surfel_ids.contains(&floater));
    assert_eq!(g.guarded_out as usize, c.len() - g.surfel_ids.len());
    // The wall itself is a fair surfel split: the guards keep nearly all of it.
    assert!(
        g.surfel_ids.len() * 10 >= c.len() * 9,
        "{}",
        g.surfel_ids.len()
    );
}
