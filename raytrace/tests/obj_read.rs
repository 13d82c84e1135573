//! The streaming OBJ reader against `tobj` (single-index, triangulated) as the reference:
//! the same triangles by world position, the same colours and materials, on hand-written OBJs
//! (polygons, negative indices, missing `vt`, several objects and materials) and on an OBJ
//! written by `splatbridge convert`'s writer; malformed lines give `line N` errors.

use std::path::Path;

use splatbridge_raytrace::obj_read::{read_mtl, read_obj, ObjMaterial};

/// Triangles as corner (position, colour) triples, in file order, per material name.
type Corners = Vec<(Option<String>, [[f32; 6]; 3])>;

fn ours(obj: &str, mtl: &str) -> Corners {
    let p = Path::new("t.obj");
    let (objs, mats) = read_obj(&mut obj.as_bytes(), p, |_| {
        Some(read_mtl(&mut mtl.as_bytes(), Path::new("t.mtl")).unwrap())
    })
    .unwrap();
    let mut out = Vec::new();
    for o in objs {
        for t in &o.tris {
            let c = t.map(|i| {
                let v = o.positions[i as usize];
                let c = o
                    .colors
                    .as_ref()
                    .map_or([1.0; 3], |c| c[i as usize].to_array());
                [v.x, v.y, v.z, c[0], c[1], c[2]]
            });
            out.push((o.material.map(|m: usize| mats[m].name.clone()), c));
        }
    }
    out
}

fn reference(obj: &str, mtl: &str) -> Corners {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let (models, mats) = tobj::load_obj_buf(&mut obj.as_bytes(), &opts, |_| {
        tobj::load_mtl_buf(&mut mtl.as_bytes())
    })
    .unwrap();
    let mats = mats.unwrap_or_default();
    let mut out = Vec::new();
    for m in models {
        let mesh = &m.mesh;
        for t in mesh.indices.chunks_exact(3) {
            let c = [t[0], t[1], t[2]].map(|i| {
                let i = i as usize;
                let p = &mesh.positions[3 * i..3 * i + 3];
                let c = if mesh.vertex_color.is_empty() {
                    [1.0; 3]
                } else {
                    [
                        mesh.vertex_color[3 * i],
                        mesh.vertex_color[3 * i + 1],
                        mesh.vertex_color[3 * i + 2],
                    ]
                };
                [p[0], p[1], p[2], c[0], c[1], c[2]]
            });
            out.push((mesh.material_id.map(|m| mats[m].name.clone()), c));
        }
    }
    out
}

fn agree(obj: &str, mtl: &str) {
    let (a, b) = (ours(obj, mtl), reference(obj, mtl));
    assert!(!a.is_empty());
    assert_eq!(a, b);
}

const MTL: &str = "newmtl red\nKd 1 0 0\nd 0.5\nnewmtl blue\nKd 0 0 1\n";

#[test]
fn plain_triangles_and_quads() {
    agree(
        "# c\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\nf 1 2 3 4\n",
        "",
    );
}

#[test]
fn polygon_negative_indices_and_corner_forms() {
    agree(
        "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvn 0 0 1\n\
         f -5/1/1 -4/2/1 -3/1/1 -2/2/1 -1/1/1\nf 1//1 2//1 3//1\nf 1/1 2/2 4/1\nf -1 -2 -3\n",
        "",
    );
}

#[test]
fn vertex_colours_objects_groups_materials() {
    agree(
        "mtllib t.mtl\no a\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0 1 0 0.5 0.5 0.5\n\
         usemtl red\ns 1\nf 1 2 3\nusemtl blue\nf 1 3 4\ng b\nf 4 3 2\nusemtl nosuch\nf 1 2 4\n\
         o c\nusemtl red\nf 2 3 4 1\n",
        MTL,
    );
}

/// The layout `convert`'s OBJ writer produces (`convert/src/obj.rs`; this crate may not depend
/// on `convert`): header comments, `mtllib`, then per object `o`, `usemtl`, `v` with colour,
/// `vn`, and `f a//a b//b c//c` with indices continuing across objects.
#[test]
fn splatbridge_export_layout_agrees() {
    let mut obj =
        String::from("# splatbridge mesh export at t = 0 s.\n# {\"up\":\"-y\"}\nmtllib s.mtl\n");
    let mut base = 1;
    for (k, name) in ["background", "car_0"].iter().enumerate() {
        obj += &format!("o {name}\nusemtl gaussian_splats\n");
        for v in 0..6 {
            let f = (v + 7 * k) as f32;
            obj += &format!(
                "v {} {} {} {} {} {}\nvn 0 0 1\n",
                f * 0.5,
                -f,
                f * f * 0.1,
                f / 13.0,
                0.25,
                1.0 - f / 13.0
            );
        }
        for t in [[0, 1, 2], [2, 1, 3], [3, 4, 5], [5, 0, 3]] {
            let [a, b, c] = t.map(|i| i + base);
            obj += &format!("f {a}//{a} {b}//{b} {c}//{c}\n");
        }
        base += 6;
    }
    agree(&obj, "newmtl gaussian_splats\nKd 1 1 1\nd 1\n");
}

#[test]
fn malformed_lines_name_the_line() {
    let bad = [
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", "line 3"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n", "line 4"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 -4\n", "line 4"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n", "line 4"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/2 2 3\n", "line 4"),
        ("v 0 0\n", "line 1"),
        ("v 0 x 0\n", "line 1"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/1/1/1 2 3\n", "line 4"),
    ];
    for (obj, want) in bad {
        let e = read_obj(&mut obj.as_bytes(), Path::new("t.obj"), |_| {
            None::<Vec<ObjMaterial>>
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains(want) && e.starts_with("t.obj: "), "{obj:?}: {e}");
    }
    let long = format!(
        "# {}\n",
        "x".repeat(splatbridge_raytrace::obj_read::MAX_LINE + 10)
    );
    let e = read_obj(&mut long.as_bytes(), Path::new("t.obj"), |_| None).unwrap_err();
    assert!(e.to_string().contains("line 1"), "{e}");
}
