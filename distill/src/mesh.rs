//! The fitted mesh as the tracer holds it: the export built in memory and loaded, each
//! vertex's Gaussian, the Gaussians' centres, the file's colour quantisation, the alpha
//! factor of a hit's material and texture, and the check that materials leave the vertex
//! colour alone.

use glam::Vec3;
use splatbridge_convert::ConvertOptions;
use splatbridge_raytrace::model::TriScene;
use splatbridge_scene::dynamic::DynamicScene;

use super::{DistillError, Result};

/// The export `convert` writes of `mesh_scene`, without fitted colours, built in memory and
/// loaded by the tracer in the capture frame (the native targets' frame).
pub(crate) fn export_mesh(mesh_scene: &DynamicScene, convert: &ConvertOptions) -> Result<TriScene> {
    let mut fit_opts = convert.clone();
    fit_opts.vertex_colours = None;
    let (bytes, _) = splatbridge_convert::glb_bytes(mesh_scene, None, &fit_opts)?;
    let mut tri = splatbridge_raytrace::scene_load::load_glb_bytes(
        &bytes,
        std::path::Path::new("<distillation mesh>"),
    )?;
    drop(bytes);
    // The cameras are in the capture frame, like the native targets.
    tri.to_capture_frame();
    check_white(&tri)?;
    Ok(tri)
}

/// The Gaussians of one mesh: each id's index in `centres`, and the centres themselves (the
/// mean of the vertices carrying the id; `ids` gives each vertex's, from
/// [`vertex_gaussians`]). Every profile's template is point-symmetric about the Gaussian's
/// mean, so that mean is the Gaussian's centre.
pub(crate) fn gaussian_centres(
    m: &splatbridge_raytrace::model::Mesh,
    ids: &[u32],
) -> (std::collections::HashMap<u32, usize>, Vec<glam::DVec3>) {
    let mut index = std::collections::HashMap::new();
    let mut sums: Vec<(glam::DVec3, u32)> = Vec::new();
    for (p, &g) in m.positions.iter().zip(ids) {
        let k = *index.entry(g).or_insert_with(|| {
            sums.push((glam::DVec3::ZERO, 0));
            sums.len() - 1
        });
        sums[k].0 += p.as_dvec3();
        sums[k].1 += 1;
    }
    let centres = sums.iter().map(|(s, n)| *s / (*n).max(1) as f64).collect();
    (index, centres)
}

/// Per mesh, the Gaussian id of every vertex (`u32::MAX` for a vertex before any triangle).
pub(crate) fn vertex_gaussians(scene: &TriScene) -> Vec<Vec<u32>> {
    let mut per_vertex = Vec::with_capacity(scene.meshes.len());
    for m in &scene.meshes {
        let mut g = vec![u32::MAX; m.positions.len()];
        for (t, tri) in m.tris.iter().enumerate() {
            for &v in tri {
                g[v as usize] = m.tri_gaussian[t];
            }
        }
        // A vertex no triangle uses belongs to the Gaussian emitted around it.
        let mut last = u32::MAX;
        for x in g.iter_mut() {
            if *x == u32::MAX {
                *x = last;
            } else {
                last = *x;
            }
        }
        per_vertex.push(g);
    }
    per_vertex
}

/// One vertex RGBA as the file stores it: normalized u16.
pub(crate) fn quantise(p: [f32; 4]) -> [f32; 4] {
    p.map(|x| (x.clamp(0.0, 1.0) * 65535.0).round() / 65535.0)
}

/// The fit assumes the materials and textures leave colour alone (white, as splatbridge
/// writes them) and blend: the vertex colour is the hit's colour.
pub(crate) fn check_white(scene: &TriScene) -> Result<()> {
    let white = |v: Vec3| (v - Vec3::ONE).abs().max_element() < 1e-6;
    let mut used = vec![false; scene.materials.len()];
    for m in &scene.meshes {
        for t in m.tri_material.iter() {
            if let Some(u) = used.get_mut(t as usize) {
                *u = true;
            }
        }
    }
    for (m, _) in scene.materials.iter().zip(&used).filter(|(_, &u)| u) {
        if !white(m.base_color.truncate()) {
            return Err(DistillError::Invalid(
                "distillation needs white materials (the vertex colour is the hit's colour)".into(),
            ));
        }
        if !matches!(m.alpha_mode, splatbridge_raytrace::AlphaMode::Blend) {
            return Err(DistillError::Invalid(
                "distillation needs blended materials".into(),
            ));
        }
        if let Some(t) = m.texture.and_then(|t| scene.textures.get(t)) {
            if t.texels().any(|c| !white(c.truncate())) {
                return Err(DistillError::Invalid(
                    "distillation needs white textures (the falloff texture carries alpha only)"
                        .into(),
                ));
            }
        }
    }
    Ok(())
}
