//! Loading what a viewer would see from a GLB written independently here (JSON + binary
//! chunks by hand, as the glTF 2.0 spec lays them out): normalized u16 COLOR_0, f32
//! `_GAUSSIAN_ID`, TEXCOORD_0 with an embedded PNG base-colour texture, a root node with the
//! converter's axis rotation, an animated node (LINEAR translation, STEP scale visibility) and a
//! camera node; then rendering it against the f64 reference. Also OBJ with vertex colours.

mod common;

use common::*;
use glam::{DVec3, Vec2, Vec3, Vec4};
use serde_json::json;
use splatbridge_raytrace::scene_load::{load_glb_bytes, load_obj_bytes, load_path};
use splatbridge_raytrace::{RenderOptions, TriScene};
use splatbridge_scene::Camera;

struct Bin {
    data: Vec<u8>,
    views: Vec<serde_json::Value>,
    accessors: Vec<serde_json::Value>,
}

impl Bin {
    fn push(
        &mut self,
        bytes: &[u8],
        comp: u32,
        count: usize,
        ty: &str,
        normalized: bool,
        minmax: Option<(Vec<f32>, Vec<f32>)>,
    ) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len()}));
        self.data.extend_from_slice(bytes);
        let mut a = json!({"bufferView": self.views.len() - 1, "componentType": comp, "count": count, "type": ty});
        if normalized {
            a["normalized"] = json!(true);
        }
        if let Some((lo, hi)) = minmax {
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }
    fn f32s(&mut self, v: &[f32], count: usize, ty: &str) -> usize {
        let b: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.push(&b, 5126, count, ty, false, None)
    }
}

fn png_bytes() -> Vec<u8> {
    // 4×1 texture: white RGB, alpha falling 1, 0.75, 0.5, 0.25 left to right.
    let img = image::RgbaImage::from_raw(
        4,
        1,
        vec![
            255, 255, 255, 255, 255, 255, 255, 191, 255, 255, 255, 128, 255, 255, 255, 64,
        ],
    )
    .unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// The test scene: mesh 0 (two fans, ids 10 and 11, textured), mesh 1 (one fan, id 12) under
/// an animated node; root rotated 180° about X; a camera at (0, 0, 5) under the root.
fn build_glb() -> (Vec<u8>, Vec<Vec3>, Vec<Vec4>) {
    let mut mesh = splatbridge_raytrace::model::Mesh::default();
    push_fan(
        &mut mesh,
        10,
        Vec3::new(-0.6, 0.0, 0.0),
        Vec3::X * 0.5,
        Vec3::Y * 0.5,
        8,
        Vec3::new(1.0, 0.2, 0.1),
        0.9,
    );
    push_fan(
        &mut mesh,
        11,
        Vec3::new(0.6, 0.1, 0.3),
        Vec3::X * 0.4,
        Vec3::new(0.0, 0.6, 0.6),
        8,
        Vec3::new(0.1, 0.8, 0.3),
        0.6,
    );
    let n = mesh.positions.len();
    let uvs: Vec<Vec2> = (0..n)
        .map(|i| Vec2::new((i % 9) as f32 / 9.0, 0.5))
        .collect();
    let mut bin = Bin {
        data: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let pos: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
    let lo = mesh
        .positions
        .iter()
        .fold(Vec3::splat(f32::MAX), |a, p| a.min(*p));
    let hi = mesh
        .positions
        .iter()
        .fold(Vec3::splat(f32::MIN), |a, p| a.max(*p));
    let pb: Vec<u8> = pos.iter().flat_map(|x| x.to_le_bytes()).collect();
    let a_pos = bin.push(
        &pb,
        5126,
        n,
        "VEC3",
        false,
        Some((lo.to_array().to_vec(), hi.to_array().to_vec())),
    );
    let cb: Vec<u8> = mesh
        .colors
        .iter()
        .flat_map(|c| {
            c.to_array()
                .map(|v| ((v * 65535.0).round() as u16).to_le_bytes())
        })
        .flatten()
        .collect();
    let a_col = bin.push(&cb, 5123, n, "VEC4", true, None);
    let ids: Vec<f32> = (0..n).map(|i| if i < 9 { 10.0 } else { 11.0 }).collect();
    let a_id = bin.f32s(&ids, n, "SCALAR");
    let uvf: Vec<f32> = uvs.iter().flat_map(|u| u.to_array()).collect();
    let a_uv = bin.f32s(&uvf, n, "VEC2");
    let ib: Vec<u8> = mesh
        .tris
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let a_idx = bin.push(&ib, 5125, mesh.tris.len() * 3, "SCALAR", false, None);
    // Mesh 1: one fan, id 12, no texture coordinates.
    let mut m1 = splatbridge_raytrace::model::Mesh::default();
    push_fan(
        &mut m1,
        12,
        Vec3::ZERO,
        Vec3::X * 0.3,
        Vec3::Y * 0.3,
        6,
        Vec3::new(0.2, 0.3, 1.0),
        0.8,
    );
    let p1: Vec<f32> = m1.positions.iter().flat_map(|p| p.to_array()).collect();
    let lo1 = m1
        .positions
        .iter()
        .fold(Vec3::splat(f32::MAX), |a, p| a.min(*p));
    let hi1 = m1
        .positions
        .iter()
        .fold(Vec3::splat(f32::MIN), |a, p| a.max(*p));
    let p1b: Vec<u8> = p1.iter().flat_map(|x| x.to_le_bytes()).collect();
    let b_pos = bin.push(
        &p1b,
        5126,
        m1.positions.len(),
        "VEC3",
        false,
        Some((lo1.to_array().to_vec(), hi1.to_array().to_vec())),
    );
    let c1: Vec<f32> = m1.colors.iter().flat_map(|c| c.to_array()).collect();
    let b_col = bin.f32s(&c1, m1.positions.len(), "VEC4");
    let b_id = bin.f32s(
        &vec![12.0; m1.positions.len()],
        m1.positions.len(),
        "SCALAR",
    );
    let i1: Vec<u8> = m1
        .tris
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let b_idx = bin.push(&i1, 5125, m1.tris.len() * 3, "SCALAR", false, None);
    // Animation: node 2 moves from x = −1 to x = 1 over 2 s; hidden (scale 0) from 0.5 s to 1 s.
    let times = bin.f32s(&[0.0, 2.0], 2, "SCALAR");
    bin.accessors[times]["min"] = json!([0.0]);
    bin.accessors[times]["max"] = json!([2.0]);
    let tr = bin.f32s(&[-1.0, 0.0, -0.5, 1.0, 0.0, -0.5], 2, "VEC3");
    let stimes = bin.f32s(&[0.0, 0.5, 1.0], 3, "SCALAR");
    bin.accessors[stimes]["min"] = json!([0.0]);
    bin.accessors[stimes]["max"] = json!([1.0]);
    let sc = bin.f32s(&[1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0], 3, "VEC3");
    let png = png_bytes();
    while !bin.data.len().is_multiple_of(4) {
        bin.data.push(0);
    }
    bin.views
        .push(json!({"buffer": 0, "byteOffset": bin.data.len(), "byteLength": png.len()}));
    bin.data.extend_from_slice(&png);
    let img_view = bin.views.len() - 1;
    while !bin.data.len().is_multiple_of(4) {
        bin.data.push(0);
    }
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "splatbridge_root", "rotation": [1.0, 0.0, 0.0, 0.0], "children": [1, 2, 3]},
            {"mesh": 0},
            {"mesh": 1, "translation": [-1.0, 0.0, -0.5]},
            {"camera": 0, "translation": [0.0, 0.0, 5.0]}
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": a_pos, "COLOR_0": a_col, "_GAUSSIAN_ID": a_id, "TEXCOORD_0": a_uv}, "indices": a_idx, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": b_pos, "COLOR_0": b_col, "_GAUSSIAN_ID": b_id}, "indices": b_idx, "material": 1}]}
        ],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "alphaMode": "BLEND", "doubleSided": true},
            {"alphaMode": "BLEND", "doubleSided": true}
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"bufferView": img_view, "mimeType": "image/png"}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.01}}],
        "animations": [{
            "samplers": [
                {"input": times, "output": tr, "interpolation": "LINEAR"},
                {"input": stimes, "output": sc, "interpolation": "STEP"}
            ],
            "channels": [
                {"sampler": 0, "target": {"node": 2, "path": "translation"}},
                {"sampler": 1, "target": {"node": 2, "path": "scale"}}
            ]
        }],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.data.len()}]
    });
    let mut js = serde_json::to_vec(&doc).unwrap();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let total = 12 + 8 + js.len() + 8 + bin.data.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(js.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&js);
    glb.extend_from_slice(&(bin.data.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin.data);
    (glb, mesh.positions, mesh.colors)
}

fn load() -> TriScene {
    let (glb, _, _) = build_glb();
    load_glb_bytes(&glb, std::path::Path::new("test.glb")).unwrap()
}

#[test]
fn attributes_read_back() {
    let (glb, pos, cols) = build_glb();
    let s = load_glb_bytes(&glb, std::path::Path::new("test.glb")).unwrap();
    assert_eq!(s.meshes.len(), 2);
    let m = &s.meshes[0];
    assert_eq!(m.positions, pos);
    for (a, b) in m.colors.iter().zip(&cols) {
        // u16 normalized: 1/65535 quantisation, half of it after rounding.
        assert!((*a - *b).abs().max_element() <= 0.5 / 65535.0 + 1e-7);
    }
    assert!(m.has_gaussian_ids);
    assert_eq!(m.tri_gaussian[..8], [10; 8]);
    assert_eq!(m.tri_gaussian[8..], [11; 8]);
    assert_eq!(s.meshes[1].tri_gaussian, vec![12; 6]);
    assert!(m.uvs.is_some() && s.meshes[1].uvs.is_none());
    assert_eq!(s.textures.len(), 1);
    assert_eq!(s.textures[0].width, 4);
    // Alpha is linear in glTF textures; RGB white decodes to 1.
    assert!((s.textures[0].texel_at(2).w - 128.0 / 255.0).abs() < 1e-6);
    assert!((s.textures[0].texel_at(2).x - 1.0).abs() < 1e-6);
    // The same file from a path.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.glb");
    std::fs::write(&p, &glb).unwrap();
    let s2 = load_path(&p).unwrap();
    assert_eq!(s2.meshes[0].positions, s.meshes[0].positions);
}

#[test]
fn animation_visibility_and_cameras() {
    let mut s = load();
    // Root rotation 180° about X: y and z flip.
    let at = |s: &TriScene, t: f64| {
        s.instances(t)
            .into_iter()
            .find(|i| i.mesh == 1)
            .map(|i| i.to_world.translation)
    };
    let p = at(&s, 1.5).unwrap();
    assert!((p - DVec3::new(0.5, 0.0, 0.5)).length() < 1e-6, "{p}");
    assert!(
        at(&s, 0.75).is_none(),
        "STEP scale 0 hides the node on [0.5, 1)"
    );
    assert!(at(&s, 1.0).is_some());
    let cams = s.cameras(0.0);
    assert_eq!(cams.len(), 1);
    let c = &cams[0];
    // No extras.opencv in this file: 480 rows, columns from the aspect ratio.
    assert_eq!((c.width, c.height), (720, 480));
    // yfov is an f32 in the file: 0.8 is stored as 0.800000011920929.
    assert!((c.fov().1 - 0.8).abs() < 2e-8);
    // glTF camera at (0,0,5) looking down −Z, under a 180° X turn: at (0,0,−5), OpenCV axes
    // equal the world axes (forward +Z, y down).
    assert!((c.centre - DVec3::new(0.0, 0.0, -5.0)).length() < 1e-6);
    assert!((c.world_to_cam - glam::DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .all(|v| v.abs() < 1e-6));
    // In the capture frame (root undone) the camera is at (0,0,5) looking down −Z.
    assert!(s.to_capture_frame());
    let c = &s.cameras(0.0)[0];
    assert!((c.centre - DVec3::new(0.0, 0.0, 5.0)).length() < 1e-6);
    assert!((c.world_to_cam.row(2) - DVec3::NEG_Z).length() < 1e-6);
}

#[test]
fn texture_alpha_multiplies_vertex_alpha() {
    let s = load();
    let m = &s.meshes[0];
    // At a vertex, alpha = vertex alpha × texture alpha sampled at its UV (bilinear, clamp).
    for (t, tri) in m.tris.iter().enumerate().take(8) {
        let v = tri[1] as usize;
        let uv = m.uvs.as_ref().unwrap()[v];
        let tex = s.textures[0].sample(uv);
        let c = m.shade(t, [0.0, 1.0, 0.0], &s.materials, &s.textures);
        assert!((c.w - (m.colors[v].w * tex.w).clamp(0.0, 1.0)).abs() < 1e-6);
        assert!(tex.w < 1.0 || uv.x <= 0.125 + 1e-6);
    }
}

#[test]
fn glb_renders_like_the_reference() {
    let s = load();
    let cam = s.cameras(0.0)[0].resized(60, 40);
    assert!(s.colors_linear, "glTF COLOR_0 is linear");
    for b in backends() {
        for t in [0.0, 0.75, 1.5] {
            compare(&s, t, &cam, b, &RenderOptions::default());
        }
        let viewer = RenderOptions {
            compositing: splatbridge_raytrace::Compositing::Viewer,
            background: Vec3::new(0.1, 0.2, 0.3),
            ..Default::default()
        };
        compare(&s, 0.0, &cam, b, &viewer);
    }
}

#[test]
fn obj_vertex_colours_are_opaque() {
    let obj = "o a\nv 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nf 1 2 3\no b\nv 0 0 1 0 1 0\nv 1 0 1 0 1 0\nv 0 1 1 0 1 0\nf 1 2 3\n";
    let obj = obj.replace(
        "o b\nv 0 0 1 0 1 0\nv 1 0 1 0 1 0\nv 0 1 1 0 1 0\nf 1 2 3",
        "o b\nv 0 0 1 0 1 0\nv 1 0 1 0 1 0\nv 0 1 1 0 1 0\nf 4 5 6",
    );
    let s = load_obj_bytes(obj.as_bytes(), std::path::Path::new("t.obj")).unwrap();
    assert_eq!(s.meshes.len(), 2);
    let tr =
        splatbridge_raytrace::MeshTracer::new(s, Default::default(), Default::default()).unwrap();
    let insts = tr.prepare(0.0);
    let mut buf = splatbridge_raytrace::kbuffer::KBuffer::new(16);
    // Seen from −z: the red triangle at z = 0 is in front and opaque.
    let px = tr.trace(
        &insts,
        DVec3::new(0.2, 0.2, -1.0),
        DVec3::Z,
        &RenderOptions::default(),
        &mut buf,
    );
    assert_eq!(px.rgb, Vec3::new(1.0, 0.0, 0.0));
    assert_eq!(px.alpha, 1.0);
    assert_eq!(px.hits, 1, "an opaque hit ends the ray");
    let cam = Camera::look_at(
        DVec3::new(0.3, 0.3, 3.0),
        DVec3::new(0.3, 0.3, 0.0),
        DVec3::NEG_Y,
        40.0,
        20,
        20,
    )
    .unwrap();
    let (f, _) = tr.render(&cam, 0.0, &RenderOptions::default()).unwrap();
    assert_eq!(f.rgb_at(10, 10), [0.0, 1.0, 0.0]);
}

#[test]
fn malformed_files_name_the_fault() {
    let e = load_glb_bytes(b"not a glb", std::path::Path::new("bad.glb"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("bad.glb: "), "{e}");
    let (mut glb, _, _) = build_glb();
    // Truncate the binary chunk.
    glb.truncate(glb.len() - 200);
    let e = load_glb_bytes(&glb, std::path::Path::new("cut.glb"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("cut.glb: "), "{e}");
    let e = load_path(std::path::Path::new("/nonexistent/x.obj"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("x.obj"), "{e}");
}
