//! Writers read back: GLB/glTF through the `gltf` crate (what a viewer sees), OBJ through
//! `tobj`, the PLY mesh through its reader, KHR_gaussian_splatting through ours; atomic
//! writes leave nothing behind on failure.

mod common;

use glam::{DVec3, Quat, Vec3};
use splatbridge_convert::{
    convert_to_file, glb_bytes, mesh_cloud, ColorEncoding, ConvertOptions, Profile, UpAxis,
};

#[test]
fn glb_reads_back_with_the_same_mesh_nodes_animation_and_cameras() {
    let scene = common::street(300);
    for profile in [Profile::MeshSplats, Profile::Rings, Profile::Texture] {
        let opts = ConvertOptions {
            profile,
            ..Default::default()
        };
        let (bytes, report) = glb_bytes(&scene, None, &opts).unwrap();
        assert_eq!(bytes.len() as u64, report.bytes);
        let (doc, buffers, images) = gltf::import_slice(&bytes).unwrap();
        assert_eq!(images.len(), usize::from(profile == Profile::Texture));
        // Root rotates −y up to +y (180° about x).
        let root = doc.default_scene().unwrap().nodes().next().unwrap();
        assert_eq!(root.name(), Some("splatbridge_root"));
        let (_, r, _) = root.transform().decomposed();
        assert!(
            (Quat::from_array(r)
                .dot(Quat::from_xyzw(1.0, 0.0, 0.0, 0.0))
                .abs()
                - 1.0)
                .abs()
                < 1e-6
        );
        let children: Vec<_> = root.children().collect();
        // static, two objects, two cameras
        assert_eq!(children.len(), 5);
        // Static mesh: same vertices as the in-memory mesher.
        let (soup, _) = mesh_cloud(&scene.static_gaussians, &opts).unwrap();
        let prim = children[0].mesh().unwrap().primitives().next().unwrap();
        let rd = prim.reader(|b| Some(&buffers[b.index()]));
        let pos: Vec<[f32; 3]> = rd.read_positions().unwrap().collect();
        assert_eq!(pos, soup.positions);
        let cols: Vec<[f32; 4]> = rd.read_colors(0).unwrap().into_rgba_f32().collect();
        for (a, b) in cols.iter().zip(&soup.colors) {
            for c in 0..4 {
                // normalized u16: half a step is 7.6e-6.
                assert!((a[c] - b[c]).abs() <= 0.5 / 65535.0 + 1e-7);
            }
        }
        let idx: Vec<u32> = rd.read_indices().unwrap().into_u32().collect();
        assert_eq!(idx, soup.indices);
        assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
        let mat = prim.material();
        assert_eq!(mat.alpha_mode(), gltf::material::AlphaMode::Blend);
        assert!(mat.double_sided() && mat.unlit());
        assert_eq!(
            mat.pbr_metallic_roughness().base_color_texture().is_some(),
            profile == Profile::Texture
        );
        assert_eq!(rd.read_tex_coords(0).is_some(), profile == Profile::Texture);
        // _GAUSSIAN_ID is present; the object's ids start after the static cloud.
        let obj = children[1].mesh().unwrap();
        let extras: serde_json::Value =
            serde_json::from_str(obj.extras().as_ref().unwrap().get()).unwrap();
        assert_eq!(extras["idOffset"], scene.static_gaussians.len());
        assert!(prim
            .attributes()
            .any(|(s, _)| s == gltf::Semantic::Extras("GAUSSIAN_ID".into())));
        // One scene animation with a translation and a rotation channel per moving object,
        // spanning the scene's time range.
        assert_eq!(doc.animations().count(), 1);
        assert_eq!(doc.animations().next().unwrap().channels().count(), 4);
        for a in doc.animations() {
            for ch in a.channels() {
                let r = ch.reader(|b| Some(&buffers[b.index()]));
                let t: Vec<f32> = r.read_inputs().unwrap().collect();
                assert_eq!((t[0], *t.last().unwrap()), (0.0, 2.0));
                assert_eq!(
                    ch.sampler().interpolation(),
                    gltf::animation::Interpolation::Linear
                );
            }
        }
        // Cameras: the glTF camera looks down its −Z; in the input frame that is the OpenCV +z.
        for (k, cam) in scene.cameras.iter().enumerate() {
            let node = &children[3 + k];
            let c = node.camera().unwrap();
            let gltf::camera::Projection::Perspective(p) = c.projection() else {
                panic!()
            };
            let yfov = 2.0 * (cam.height as f64 / (2.0 * cam.fy)).atan();
            assert!((p.yfov() as f64 - yfov).abs() < 1e-6);
            assert!((p.aspect_ratio().unwrap() as f64 - 320.0 / 240.0).abs() < 1e-6);
            let (t, r, _) = node.transform().decomposed();
            let fwd = Quat::from_array(r) * Vec3::NEG_Z;
            let up = Quat::from_array(r) * Vec3::Y;
            let c2w = cam.cam_to_world();
            assert!((fwd.as_dvec3() - c2w.col(2)).length() < 1e-6);
            assert!(
                (up.as_dvec3() + c2w.col(1)).length() < 1e-6,
                "glTF +Y is OpenCV −y"
            );
            assert!((DVec3::from_array(t.map(|x| x as f64)) - cam.centre).length() < 1e-5);
        }
        let meta: serde_json::Value =
            serde_json::from_str(doc.as_json().asset.extras.as_ref().unwrap().get()).unwrap();
        assert_eq!(meta["splatbridge"]["options"]["profile"], profile.name());
        assert_eq!(meta["splatbridge"]["counts"]["triangles"], report.triangles);
    }
}

#[test]
fn per_frame_content_is_visible_only_on_its_frame() {
    let scene = splatbridge_scene::dynamic::DynamicScene::from_static(common::cloud(50, 0, 1));
    let frames = splatbridge_convert::FrameClouds {
        times: vec![0.0, 0.1, 0.2],
        clouds: (0..3).map(|k| common::cloud(20, 0, 10 + k)).collect(),
    };
    let (bytes, _) = glb_bytes(&scene, Some(&frames), &ConvertOptions::default()).unwrap();
    let (doc, buffers, _) = gltf::import_slice(&bytes).unwrap();
    let anim = doc
        .animations()
        .find(|a| a.name() == Some("scene"))
        .unwrap();
    assert_eq!(anim.channels().count(), 3);
    for (k, ch) in anim.channels().enumerate() {
        assert_eq!(
            ch.sampler().interpolation(),
            gltf::animation::Interpolation::Step
        );
        let r = ch.reader(|b| Some(&buffers[b.index()]));
        let Some(gltf::animation::util::ReadOutputs::Scales(s)) = r.read_outputs() else {
            panic!()
        };
        let s: Vec<[f32; 3]> = s.collect();
        for (j, v) in s.iter().enumerate() {
            assert_eq!(v[0], if j == k { 1.0 } else { 0.0 });
        }
    }
}

#[test]
fn obj_reads_back_with_tobj() {
    let scene = splatbridge_scene::dynamic::DynamicScene::from_static(common::cloud(200, 0, 4));
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.obj");
    let opts = ConvertOptions {
        up: UpAxis::Y,
        profile: Profile::MeshSplats,
        ..Default::default()
    };
    convert_to_file(&p, &scene, None, &opts, false).unwrap();
    let (models, mtl) = tobj::load_obj(
        &p,
        &tobj::LoadOptions {
            single_index: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(mtl.unwrap().len(), 1);
    let (soup, _) = mesh_cloud(
        &scene.static_gaussians,
        &ConvertOptions {
            color_encoding: ColorEncoding::Display,
            ..opts
        },
    )
    .unwrap();
    let m = &models[0].mesh;
    assert_eq!(m.indices.len(), soup.indices.len());
    for (k, &i) in m.indices.iter().enumerate() {
        let s = soup.indices[k] as usize;
        let i = i as usize;
        // Shortest round-trip printing: bit-exact positions and colours.
        assert_eq!(
            [
                m.positions[3 * i],
                m.positions[3 * i + 1],
                m.positions[3 * i + 2]
            ],
            soup.positions[s]
        );
        assert_eq!(
            [
                m.vertex_color[3 * i],
                m.vertex_color[3 * i + 1],
                m.vertex_color[3 * i + 2]
            ],
            [soup.colors[s][0], soup.colors[s][1], soup.colors[s][2]]
        );
    }
}

#[test]
fn obj_frames_bake_object_poses() {
    let scene = common::street(100);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("f.obj");
    convert_to_file(&p, &scene, None, &ConvertOptions::default(), true).unwrap();
    let names: Vec<_> = (0..21)
        .map(|i| dir.path().join(format!("f_{i:04}.obj")))
        .collect();
    assert!(
        names.iter().all(|n| n.exists()),
        "21 frames at 10 fps over 2 s"
    );
    let first = tobj::load_obj(&names[0], &tobj::LoadOptions::default())
        .unwrap()
        .0;
    let last = tobj::load_obj(&names[20], &tobj::LoadOptions::default())
        .unwrap()
        .0;
    let car =
        |ms: &Vec<tobj::Model>| ms.iter().find(|m| m.name == "car").unwrap().mesh.positions[0];
    assert_ne!(car(&first), car(&last));
}

#[test]
fn ply_mesh_reads_back() {
    let scene = splatbridge_scene::dynamic::DynamicScene::from_static(common::cloud(150, 1, 6));
    let dir = tempfile::tempdir().unwrap();
    for profile in [Profile::Rings, Profile::Texture] {
        let p = dir.path().join("m.ply");
        let opts = ConvertOptions {
            up: UpAxis::Y,
            profile,
            ..Default::default()
        };
        let r = convert_to_file(&p, &scene, None, &opts, false).unwrap();
        let back = splatbridge_convert::ply_mesh::read_file(&p).unwrap();
        let (soup, _) = mesh_cloud(
            &scene.static_gaussians,
            &ConvertOptions {
                color_encoding: ColorEncoding::Display,
                ..opts
            },
        )
        .unwrap();
        assert_eq!(back.positions, soup.positions);
        assert_eq!(back.indices, soup.indices);
        assert_eq!(back.gaussian_ids, soup.gaussian_ids);
        assert_eq!(back.uvs, soup.uvs);
        assert_eq!(r.bytes, std::fs::metadata(&p).unwrap().len());
        for (a, b) in back.colors.iter().zip(&soup.colors) {
            for c in 0..4 {
                assert!((a[c] - b[c]).abs() <= 0.5 / 255.0 + 1e-6); // u8 quantisation
            }
        }
    }
}

#[test]
fn splats_round_trip_through_khr_gaussian_splatting() {
    let scene = common::street(400);
    let dir = tempfile::tempdir().unwrap();
    for ext in ["glb", "gltf"] {
        let p = dir.path().join(format!("s.{ext}"));
        splatbridge_convert::splats_gltf::write_file(&p, &scene, &ConvertOptions::default())
            .unwrap();
        let back = splatbridge_convert::splats_gltf::read_file(&p).unwrap();
        let check = |a: &splatbridge_scene::GaussianCloud, b: &splatbridge_scene::GaussianCloud| {
            assert_eq!(a.len(), b.len());
            assert_eq!(a.sh_degree, b.sh_degree);
            assert_eq!(a.means, b.means);
            assert_eq!(a.sh, b.sh);
            for i in 0..a.len() {
                // exp/ln and sigmoid/logit round trips in f32: a few ulps relative.
                assert!(
                    (a.scale(i) - b.scale(i)).abs().max_element()
                        <= 1e-6 * a.scale(i).max_element()
                );
                assert!((a.opacity(i) - b.opacity(i)).abs() < 1e-6);
                assert!(a.unit_rotation(i).dot(b.unit_rotation(i)).abs() > 1.0 - 1e-6);
            }
        };
        check(&scene.static_gaussians, &back.static_gaussians);
        assert_eq!(back.objects.len(), 2);
        for (o, b) in scene.objects.iter().zip(&back.objects) {
            assert_eq!(o.name, b.name);
            check(&o.gaussians, &b.gaussians);
            for t in [0.0, 0.3, 0.77, 1.2, 2.0] {
                let (pa, pb) = (o.track.sample(t), b.track.sample(t));
                assert!((pa.translation - pb.translation).length() < 1e-5);
                assert!(pa.rotation.dot(pb.rotation).abs() > 1.0 - 1e-6);
            }
        }
        assert_eq!(back.cameras.len(), 2);
        for (a, b) in scene.cameras.iter().zip(&back.cameras) {
            assert!((a.centre - b.centre).length() < 1e-5);
            assert!((a.world_to_cam - b.world_to_cam)
                .to_cols_array()
                .iter()
                .all(|x| x.abs() < 1e-5));
            assert_eq!((a.width, a.height, a.fx), (b.width, b.height, b.fx));
        }
    }
}

#[test]
fn failed_writes_leave_no_file() {
    let scene = common::street(50);
    let dir = tempfile::tempdir().unwrap();
    let bad_opts = ConvertOptions {
        segments: Some(2),
        ..Default::default()
    };
    let p = dir.path().join("x.glb");
    assert!(convert_to_file(&p, &scene, None, &bad_opts, false).is_err());
    let missing = dir.path().join("no/such/dir/x.glb");
    let err =
        convert_to_file(&missing, &scene, None, &ConvertOptions::default(), false).unwrap_err();
    assert!(err.to_string().contains("x.glb"), "{err}");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "no file, no temporary left"
    );
    let unknown = convert_to_file(
        &dir.path().join("x.fbx"),
        &scene,
        None,
        &ConvertOptions::default(),
        false,
    )
    .unwrap_err();
    assert!(unknown.to_string().contains("x.fbx"));
}

#[test]
fn up_axis_is_a_root_rotation_not_baked_into_vertices() {
    let scene = splatbridge_scene::dynamic::DynamicScene::from_static(common::cloud(20, 0, 2));
    for (up, input_up) in [
        (UpAxis::Y, Vec3::Y),
        (UpAxis::Z, Vec3::Z),
        (UpAxis::NegY, Vec3::NEG_Y),
    ] {
        let opts = ConvertOptions {
            up,
            ..Default::default()
        };
        let (bytes, _) = glb_bytes(&scene, None, &opts).unwrap();
        let (doc, buffers, _) = gltf::import_slice(&bytes).unwrap();
        let root = doc.default_scene().unwrap().nodes().next().unwrap();
        let (_, r, _) = root.transform().decomposed();
        // The input's up direction appears as glTF +Y.
        assert!(
            (Quat::from_array(r) * input_up - Vec3::Y).length() < 1e-6,
            "{up:?}"
        );
        let child = root.children().next().unwrap();
        let prim = child.mesh().unwrap().primitives().next().unwrap();
        let pos: Vec<[f32; 3]> = prim
            .reader(|b| Some(&buffers[b.index()]))
            .read_positions()
            .unwrap()
            .collect();
        assert_eq!(
            pos,
            mesh_cloud(&scene.static_gaussians, &opts)
                .unwrap()
                .0
                .positions
        );
    }
}
