//! OBJ/MTL loading (through `obj_read`, streamed): see the parent module for what is read.

use std::path::Path;

use glam::{DQuat, Vec4};

use crate::backend::{fits_bvh, MAX_BVH_COORD};
use crate::error::{Result, TraceError};
use crate::model::{AlphaMode, Material, MaterialRuns, Mesh, Node, TriScene};

/// Load an OBJ (and its MTL, when present) from a path.
pub fn load_obj(path: &Path) -> Result<TriScene> {
    use splatbridge_scene::input::{check_size, open_regular, read_bounded, Cap};
    use std::io::Read;
    // Streamed, not read whole: an exported OBJ runs to gigabytes of text, which would sit
    // beside everything parsed from it. The header (where a splatbridge OBJ names its frame)
    // is read first; the rest is bounded by the cap, so a growing file cannot read forever.
    let (file, len) = open_regular(path)?;
    check_size(path, len, Cap::Mesh)?;
    let mut file = file.take(Cap::Mesh.bytes());
    let mut head = Vec::new();
    (&mut file)
        .take(crate::obj_frame::HEADER_SCAN as u64)
        .read_to_end(&mut head)
        .map_err(|e| TraceError::format(path, format!("cannot read: {e}")))?;
    let root = crate::obj_frame::written_root(&head);
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut r = std::io::BufReader::with_capacity(1 << 20, std::io::Cursor::new(head).chain(file));
    // `mtllib` files go through the same guards (regular file, bounded size); a refused one
    // counts as a missing MTL.
    // A missing or broken MTL leaves the geometry usable; vertex colours carry the colour.
    let (models, mats) = crate::obj_read::read_obj(&mut r, path, |m| {
        let p = dir.join(m);
        let data = read_bounded(&p, Cap::Mesh).ok()?;
        crate::obj_read::read_mtl(&mut &data[..], &p).ok()
    })?;
    obj_scene(path, models, mats, root)
}

/// Load an OBJ from memory (materials are not resolved).
pub fn load_obj_bytes(bytes: &[u8], name: &Path) -> Result<TriScene> {
    let (models, _) = crate::obj_read::read_obj(&mut &bytes[..], name, |_| None)?;
    obj_scene(
        name,
        models,
        Vec::new(),
        crate::obj_frame::written_root(bytes),
    )
}

fn obj_scene(
    path: &Path,
    models: Vec<crate::obj_read::ObjObject>,
    mats: Vec<crate::obj_read::ObjMaterial>,
    root: Option<DQuat>,
) -> Result<TriScene> {
    let mut materials: Vec<Material> = mats
        .iter()
        .map(|m| {
            let d = m.dissolve.unwrap_or(1.0).clamp(0.0, 1.0);
            let kd = m.diffuse.unwrap_or([1.0; 3]);
            Material {
                base_color: Vec4::new(kd[0], kd[1], kd[2], d),
                texture: None,
                alpha_mode: if d < 1.0 {
                    AlphaMode::Blend
                } else {
                    AlphaMode::Opaque
                },
            }
        })
        .collect();
    let default_material = materials.len() as u32;
    materials.push(Material::default());
    // OBJ has no colour-space rule; splatbridge writes 3DGS display values there.
    let mut scene = TriScene {
        materials,
        colors_linear: false,
        ..TriScene::default()
    };
    // The baked root rotation is undone on the vertices and kept on a root node, as in glTF.
    let unbake = root.map(|q| q.inverse());
    if let Some(q) = root {
        scene.nodes.push(Node {
            name: "splatbridge_root".into(),
            rotation: q,
            ..Node::default()
        });
    }
    for (mi, model) in models.into_iter().enumerate() {
        let m = model;
        let n = m.positions.len();
        let positions = m.positions;
        if let Some(i) = positions.iter().position(|v| !fits_bvh(*v)) {
            return Err(TraceError::format(
                path,
                format!(
                    "object {mi} ('{}'): vertex {i} is not finite or beyond ±{MAX_BVH_COORD}",
                    splatbridge_scene::input::clip(&m.name)
                ),
            ));
        }
        let positions = match unbake {
            Some(q) => positions
                .into_iter()
                .map(|p| (q * p.as_dvec3()).as_vec3())
                .collect(),
            None => positions,
        };
        let mut mat = m.material.map(|i| i as u32).unwrap_or(default_material);
        if mat as usize >= scene.materials.len() {
            mat = default_material;
        }
        let colors: Vec<Vec4> = if let Some(c) = m.colors {
            // Vertex colours replace the MTL diffuse colour (as Blender shows them), alpha stays.
            if let Some(mm) = scene.materials.get_mut(mat as usize) {
                if mat != default_material {
                    mm.base_color = Vec4::new(1.0, 1.0, 1.0, mm.base_color.w);
                }
            }
            c.into_iter().map(|c| c.extend(1.0)).collect()
        } else {
            vec![Vec4::ONE; n]
        };
        // The reader renumbers within the object, so every index is below `n`.
        debug_assert!(m.tris.iter().flatten().all(|&i| (i as usize) < n));
        let tris = m.tris;
        let mut mesh = Mesh {
            name: m.name.clone(),
            positions,
            colors,
            uvs: None,
            tri_material: {
                let mut m = MaterialRuns::default();
                m.extend_with(tris.len(), mat);
                m
            },
            tris,
            tri_gaussian: Vec::new(),
            has_gaussian_ids: false,
        };
        mesh.assign_components();
        scene.nodes.push(Node {
            mesh: Some(scene.meshes.len()),
            name: m.name,
            parent: root.map(|_| 0),
            ..Node::default()
        });
        scene.meshes.push(mesh);
    }
    Ok(scene)
}
