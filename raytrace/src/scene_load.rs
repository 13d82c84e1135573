//! Loading triangle scenes from what was exported: glTF 2.0 (GLB or .gltf, through the `gltf`
//! crate) and OBJ/MTL (through `obj_read`, streamed). The loader reads only the file, so a writer bug shows
//! in renders.
//!
//! glTF: every mesh primitive of mode TRIANGLES (strips and fans are expanded), POSITION,
//! COLOR_0 (any component type, RGB gets alpha 1), TEXCOORD_0, the custom `_GAUSSIAN_ID`
//! vertex attribute (any scalar component type; a triangle takes its first vertex's id), the
//! material's base colour factor and texture (decoded by the `gltf` importer, RGB sRGB-decoded)
//! and alpha mode; nodes of the default scene with TRS or matrix, animation channels
//! (translation/rotation/scale; morph target weights, see `morph`) and perspective cameras.
//! POINTS primitives (e.g. `KHR_gaussian_splatting`) carry no surface and are skipped.
//!
//! OBJ: positions, `v x y z r g b` vertex colours (OBJ has no per-vertex alpha: alpha is 1,
//! times the MTL dissolve `d` when one is given), MTL diffuse colour when there are no vertex
//! colours; one mesh per object. A splatbridge OBJ (its header names the up axis whose
//! rotation was baked into the vertices, `obj_frame`) gets the glTF export's shape: vertices
//! in the capture frame under a `splatbridge_root` node carrying that rotation; any other OBJ
//! is taken as written, every mesh under the identity.

use std::path::Path;

use glam::{DAffine3, DMat4, DQuat, DVec3, Vec2, Vec3, Vec4};

use crate::backend::{fits_bvh, MAX_BVH_COORD};
use crate::error::{Result, TraceError};
use crate::gltf_stream::Buffers;
use crate::model::{
    srgb_to_linear, AlphaMode, Channel, ChannelPath, Interpolation, Intrinsics, Material, Mesh,
    Node, Perspective, Texture, TriScene, Wrap,
};

/// Load a triangle scene by extension: `.glb`, `.gltf`, `.obj`.
pub fn load_path(path: &Path) -> Result<TriScene> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "glb" | "gltf" => {
            // A GLB file is streamed: one accessor's bytes at a time beside the scene.
            let (doc, buffers, images) = crate::gltf_stream::import_path(path)?;
            from_gltf(path, &doc, buffers, &images)
        }
        "obj" => load_obj(path),
        _ => Err(TraceError::format(
            path,
            "unknown triangle-scene extension (expected .glb, .gltf or .obj)",
        )),
    }
}

/// [`load_glb_bytes`] taking the bytes over, so the GLB's blob is not copied.
pub fn load_glb_vec(bytes: Vec<u8>, name: &Path) -> Result<TriScene> {
    let (doc, buffers, images) = crate::gltf_check::import_vec(bytes, None, name)?;
    from_gltf(name, &doc, Buffers::whole(buffers), &images)
}

/// Load a GLB (or self-contained glTF JSON) from memory; `name` is used in error messages.
pub fn load_glb_bytes(bytes: &[u8], name: &Path) -> Result<TriScene> {
    let (doc, buffers, images) = crate::gltf_check::import(bytes, None, name)?;
    from_gltf(name, &doc, Buffers::whole(buffers), &images)
}

fn texture_from(path: &Path, tex: &gltf::Texture, images: &[gltf::image::Data]) -> Result<Texture> {
    use gltf::image::Format as F;
    let img = images.get(tex.source().index()).ok_or_else(|| {
        TraceError::format(
            path,
            format!("texture {} names a missing image", tex.index()),
        )
    })?;
    let n = img.width as usize * img.height as usize;
    let (ch, bytes): (usize, usize) = match img.format {
        F::R8 => (1, 1),
        F::R8G8 => (2, 1),
        F::R8G8B8 => (3, 1),
        F::R8G8B8A8 => (4, 1),
        F::R16 => (1, 2),
        F::R16G16 => (2, 2),
        F::R16G16B16 => (3, 2),
        F::R16G16B16A16 => (4, 2),
        F::R32G32B32FLOAT => (3, 4),
        F::R32G32B32A32FLOAT => (4, 4),
    };
    if img.pixels.len() < n * ch * bytes {
        return Err(TraceError::format(
            path,
            format!("image {} is shorter than its size", tex.source().index()),
        ));
    }
    let get = |i: usize| -> f32 {
        match bytes {
            1 => img.pixels[i] as f32 / 255.0,
            2 => u16::from_ne_bytes([img.pixels[2 * i], img.pixels[2 * i + 1]]) as f32 / 65535.0,
            _ => f32::from_ne_bytes([
                img.pixels[4 * i],
                img.pixels[4 * i + 1],
                img.pixels[4 * i + 2],
                img.pixels[4 * i + 3],
            ]),
        }
    };
    // One texel's channels as (R, G, B, A) positions in the image, and a constant alpha.
    let layout = |p: usize| -> ([usize; 3], Option<usize>) {
        let b = p * ch;
        match ch {
            1 => ([b, b, b], None),
            2 => ([b, b, b], Some(b + 1)),
            3 => ([b, b + 1, b + 2], None),
            _ => ([b, b + 1, b + 2], Some(b + 3)),
        }
    };
    let s = tex.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    };
    let wrap = [wrap(s.wrap_s()), wrap(s.wrap_t())];
    let nearest = s.mag_filter() == Some(gltf::texture::MagFilter::Nearest);
    if bytes == 1 {
        // Kept as bytes, decoded on read by the same conversion (`Texture::from_bytes`).
        let texels = (0..n)
            .map(|p| {
                let ([r, g, b], a) = layout(p);
                let px = &img.pixels;
                [px[r], px[g], px[b], a.map_or(255, |a| px[a])]
            })
            .collect();
        return Ok(Texture::from_bytes(
            img.width, img.height, texels, wrap, nearest,
        ));
    }
    let texels = (0..n)
        .map(|p| {
            let ([r, g, b], a) = layout(p);
            Vec4::new(
                srgb_to_linear(get(r)),
                srgb_to_linear(get(g)),
                srgb_to_linear(get(b)),
                a.map_or(1.0, get),
            )
        })
        .collect();
    Ok(Texture::from_texels(
        img.width, img.height, texels, wrap, nearest,
    ))
}

fn read_scalar_u32(
    path: &Path,
    acc: &gltf::Accessor,
    buffers: &Buffers,
    what: &str,
) -> Result<Vec<u32>> {
    use gltf::accessor::{DataType, Dimensions, Iter};
    if acc.dimensions() != Dimensions::Scalar {
        return Err(TraceError::format(
            path,
            format!("{what}: accessor {} is not SCALAR", acc.index()),
        ));
    }
    let get = |b: gltf::Buffer| buffers.get(b.index());
    let bad = || {
        TraceError::format(
            path,
            format!("{what}: accessor {} cannot be read", acc.index()),
        )
    };
    let v: Vec<u32> = match acc.data_type() {
        DataType::F32 => {
            let it = Iter::<f32>::new(acc.clone(), get).ok_or_else(bad)?;
            let mut out = Vec::with_capacity(acc.count());
            for (i, x) in it.enumerate() {
                if !(x >= 0.0 && x <= u32::MAX as f32 && x.fract() == 0.0) {
                    return Err(TraceError::format(
                        path,
                        format!("{what}: vertex {i} has id {x}, not a non-negative integer"),
                    ));
                }
                out.push(x as u32);
            }
            out
        }
        DataType::U32 => Iter::<u32>::new(acc.clone(), get)
            .ok_or_else(bad)?
            .collect(),
        DataType::U16 => Iter::<u16>::new(acc.clone(), get)
            .ok_or_else(bad)?
            .map(u32::from)
            .collect(),
        DataType::U8 => Iter::<u8>::new(acc.clone(), get)
            .ok_or_else(bad)?
            .map(u32::from)
            .collect(),
        DataType::I16 => Iter::<i16>::new(acc.clone(), get)
            .ok_or_else(bad)?
            .map(|x| x.max(0) as u32)
            .collect(),
        DataType::I8 => Iter::<i8>::new(acc.clone(), get)
            .ok_or_else(bad)?
            .map(|x| x.max(0) as u32)
            .collect(),
    };
    Ok(v)
}

/// A checked glTF document (see `gltf_check`, which runs first) to a triangle scene, step by
/// step: textures, materials, meshes, the node forest, animation channels, morph targets
/// (which keep the buffers to read targets from when posed), colour encoding.
fn from_gltf(
    path: &Path,
    doc: &gltf::Document,
    mut buffers: Buffers,
    images: &[gltf::image::Data],
) -> Result<TriScene> {
    let textures = doc
        .textures()
        .map(|t| texture_from(path, &t, images))
        .collect::<Result<Vec<_>>>()?;
    let materials = gltf_materials(doc);
    // Primitives without a material use glTF's default material, appended last.
    let default_material = materials.len() as u32 - 1;
    let mut meshes = doc
        .meshes()
        .map(|m| gltf_mesh(path, &m, &mut buffers, default_material))
        .collect::<Result<Vec<_>>>()?;
    let mut nodes = gltf_nodes(path, doc)?;
    let channels = gltf_channels(path, doc, &mut buffers)?;
    let morphed = crate::morph::load_morphs(path, doc, &mut buffers, &mut meshes, &mut nodes)?;
    let morphs = crate::morph::Morphs::new(path, doc, buffers, morphed);
    let mut scene = TriScene {
        meshes,
        materials,
        textures,
        nodes,
        channels,
        morphs,
        colors_linear: colors_linear(doc),
    };
    // Loaded posed at t = 0, as a viewer shows the file before playing it.
    scene.pose_morphs(0.0)?;
    Ok(scene)
}

/// The document's materials, then glTF's default material (for primitives without one).
fn gltf_materials(doc: &gltf::Document) -> Vec<Material> {
    let mut materials: Vec<Material> = doc
        .materials()
        .map(|m| {
            let pbr = m.pbr_metallic_roughness();
            Material {
                base_color: Vec4::from_array(pbr.base_color_factor()),
                texture: pbr.base_color_texture().map(|t| t.texture().index()),
                alpha_mode: match m.alpha_mode() {
                    gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                    gltf::material::AlphaMode::Mask => {
                        AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5))
                    }
                    gltf::material::AlphaMode::Blend => AlphaMode::Blend,
                },
            }
        })
        .collect();
    materials.push(Material::default());
    materials
}

/// One triangle primitive's vertices, validated (counts agree, positions within BVH range,
/// indices in range), with strips and fans expanded to triangles.
struct Primitive {
    pos: Vec<Vec3>,
    cols: Vec<Vec4>,
    uv: Option<Vec<Vec2>>,
    gid: Option<Vec<u32>>,
    tris: Vec<[u32; 3]>,
    material: u32,
}

fn check_index(path: &Path, what: &str, i: u32, n: usize) -> Result<()> {
    if i as usize >= n {
        return Err(TraceError::format(
            path,
            format!("{what}: index {i} is out of range ({n} vertices)"),
        ));
    }
    Ok(())
}

/// Read primitive `p` (`what` names it in errors); `None` for a mode without surface.
fn gltf_primitive(
    path: &Path,
    p: &gltf::Primitive,
    what: &str,
    buffers: &mut Buffers,
    default_material: u32,
) -> Result<Option<Primitive>> {
    use gltf::mesh::Mode;
    if !matches!(
        p.mode(),
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return Ok(None);
    }
    // Each accessor is made readable just before it is read and dropped after (streamed
    // GLB files, `gltf_stream`; a no-op for buffers held whole).
    let pos_acc = p
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| TraceError::format(path, format!("{what}: no POSITION")))?;
    let pos: Vec<Vec3> = buffers.with_accessors(&[&pos_acc], |bufs| {
        Ok(p.reader(|b: gltf::Buffer| bufs.get(b.index()))
            .read_positions()
            .ok_or_else(|| TraceError::format(path, format!("{what}: no POSITION")))?
            .map(Vec3::from_array)
            .collect())
    })?;
    if let Some(i) = pos.iter().position(|v| !fits_bvh(*v)) {
        return Err(TraceError::format(
            path,
            format!("{what}: POSITION of vertex {i} is not finite or beyond ±{MAX_BVH_COORD}"),
        ));
    }
    let n = pos.len();
    let cols: Vec<Vec4> = match p.get(&gltf::Semantic::Colors(0)) {
        Some(acc) => buffers.with_accessors(&[&acc], |bufs| {
            Ok(p.reader(|b: gltf::Buffer| bufs.get(b.index()))
                .read_colors(0)
                .ok_or_else(|| TraceError::format(path, format!("{what}: COLOR_0 cannot be read")))?
                .into_rgba_f32()
                .map(Vec4::from_array)
                .collect())
        })?,
        None => vec![Vec4::ONE; n],
    };
    if cols.len() != n {
        return Err(TraceError::format(
            path,
            format!(
                "{what}: COLOR_0 has {} entries for {n} vertices",
                cols.len()
            ),
        ));
    }
    let uv: Option<Vec<Vec2>> = match p.get(&gltf::Semantic::TexCoords(0)) {
        Some(acc) => buffers.with_accessors(&[&acc], |bufs| {
            Ok(p.reader(|b: gltf::Buffer| bufs.get(b.index()))
                .read_tex_coords(0)
                .map(|t| t.into_f32().map(Vec2::from_array).collect()))
        })?,
        None => None,
    };
    let gid = match p
        .attributes()
        .find(|(s, _)| matches!(s, gltf::Semantic::Extras(name) if name == "GAUSSIAN_ID"))
    {
        Some((_, acc)) => Some(buffers.with_accessors(&[&acc], |bufs| {
            read_scalar_u32(path, &acc, bufs, &format!("{what}: _GAUSSIAN_ID"))
        })?),
        None => None,
    };
    let index_acc = p.indices();
    let accs: Vec<&gltf::Accessor> = index_acc.iter().collect();
    let tris: Vec<[u32; 3]> = buffers.with_accessors(&accs, |bufs| {
        let reader = p.reader(|b: gltf::Buffer| bufs.get(b.index()));
        let mut indices: Box<dyn Iterator<Item = u32>> = match reader.read_indices() {
            Some(i) => Box::new(i.into_u32()),
            None => Box::new(0..n as u32),
        };
        Ok(if p.mode() == Mode::Triangles {
            // Straight into triangles: no separate index list (a third of a mesh's bytes).
            let mut tris = Vec::with_capacity(indices.size_hint().0 / 3);
            let mut t = [0u32; 3];
            let mut k = 0;
            for i in indices {
                check_index(path, what, i, n)?;
                t[k] = i;
                k += 1;
                if k == 3 {
                    tris.push(t);
                    k = 0;
                }
            }
            tris
        } else {
            let idx: Vec<u32> = indices.by_ref().collect();
            for &i in &idx {
                check_index(path, what, i, n)?;
            }
            if p.mode() == Mode::TriangleStrip {
                (2..idx.len())
                    .map(|i| {
                        if i % 2 == 0 {
                            [idx[i - 2], idx[i - 1], idx[i]]
                        } else {
                            [idx[i - 1], idx[i - 2], idx[i]]
                        }
                    })
                    .collect()
            } else {
                (2..idx.len())
                    .map(|i| [idx[0], idx[i - 1], idx[i]])
                    .collect()
            }
        })
    })?;
    let material = p
        .material()
        .index()
        .map(|i| i as u32)
        .unwrap_or(default_material);
    if let Some(u) = &uv {
        if u.len() != n {
            return Err(TraceError::format(
                path,
                format!(
                    "{what}: TEXCOORD_0 has {} entries for {n} vertices",
                    u.len()
                ),
            ));
        }
    }
    if let Some(g) = &gid {
        if g.len() != n {
            return Err(TraceError::format(
                path,
                format!(
                    "{what}: _GAUSSIAN_ID has {} entries for {n} vertices",
                    g.len()
                ),
            ));
        }
    }
    Ok(Some(Primitive {
        pos,
        cols,
        uv,
        gid,
        tris,
        material,
    }))
}

/// A glTF mesh: its triangle primitives concatenated; a triangle's Gaussian id is its first
/// vertex's `_GAUSSIAN_ID` when every primitive has one, else connected components.
fn gltf_mesh(
    path: &Path,
    m: &gltf::Mesh,
    buffers: &mut Buffers,
    default_material: u32,
) -> Result<Mesh> {
    let mut mesh = Mesh {
        name: m.name().unwrap_or("").to_string(),
        ..Mesh::default()
    };
    // Built in place, one primitive at a time: the first primitive's arrays are moved in,
    // texture coordinates are only materialised once a primitive has them, and a triangle's
    // Gaussian id is kept only while every primitive has ids (an exported mesh runs to tens
    // of millions of triangles, so transient copies of it matter).
    let mut uvs: Option<Vec<Vec2>> = None;
    let mut all_ids = true;
    let mut tri_ids: Vec<u32> = Vec::new();
    for (pi, p) in m.primitives().enumerate() {
        let what = format!("mesh {} primitive {pi}", m.index());
        let Some(prim) = gltf_primitive(path, &p, &what, buffers, default_material)? else {
            continue;
        };
        let n = prim.pos.len();
        let base = mesh.positions.len();
        match (prim.uv, &mut uvs) {
            (Some(uv), Some(all)) => all.extend(uv),
            (Some(uv), None) => {
                let mut all = vec![Vec2::ZERO; base];
                all.extend(uv);
                uvs = Some(all);
            }
            (None, Some(all)) => all.resize(base + n, Vec2::ZERO),
            (None, None) => {}
        }
        match &prim.gid {
            Some(g) if all_ids => tri_ids.extend(prim.tris.iter().map(|t| g[t[0] as usize])),
            _ => {
                all_ids = false;
                tri_ids = Vec::new();
            }
        }
        mesh.tri_material
            .extend_with(prim.tris.len(), prim.material);
        if mesh.tris.is_empty() {
            mesh.tris = prim.tris;
        } else {
            let b = base as u32;
            mesh.tris.extend(prim.tris.iter().map(|t| t.map(|i| i + b)));
        }
        if mesh.positions.is_empty() {
            mesh.positions = prim.pos;
            mesh.colors = prim.cols;
        } else {
            mesh.positions.extend(prim.pos);
            mesh.colors.extend(prim.cols);
        }
    }
    mesh.uvs = uvs;
    if all_ids && !mesh.tris.is_empty() {
        mesh.tri_gaussian = tri_ids;
        mesh.has_gaussian_ids = true;
    } else {
        mesh.assign_components();
    }
    Ok(mesh)
}

/// A node's local transform as stored (TRS, or a matrix).
fn gltf_node(n: &gltf::Node) -> Node {
    let mut node = Node {
        name: n.name().unwrap_or("").to_string(),
        ..Node::default()
    };
    match n.transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            let m = DMat4::from_cols_array_2d(&matrix.map(|c| c.map(|v| v as f64)));
            node.matrix = Some(DAffine3::from_mat4(m));
        }
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            node.translation = DVec3::from_array(translation.map(|v| v as f64));
            let q = DQuat::from_array(rotation.map(|v| v as f64));
            node.rotation = if q.length() > 0.0 {
                q.normalize()
            } else {
                DQuat::IDENTITY
            };
            node.scale = DVec3::from_array(scale.map(|v| v as f64));
        }
    }
    node
}

/// The node forest: transforms, one parent per node, and meshes and cameras on the nodes
/// the default scene (or scene 0) reaches, which are the only ones viewers show.
fn gltf_nodes(path: &Path, doc: &gltf::Document) -> Result<Vec<Node>> {
    let mut nodes: Vec<Node> = doc.nodes().map(|n| gltf_node(&n)).collect();
    for n in doc.nodes() {
        for c in n.children() {
            if nodes[c.index()].parent.is_some() {
                return Err(TraceError::format(
                    path,
                    format!("node {} has more than one parent", c.index()),
                ));
            }
            nodes[c.index()].parent = Some(n.index());
        }
    }
    let reachable = reachable_nodes(doc, nodes.len());
    for n in doc.nodes() {
        if !reachable[n.index()] {
            continue;
        }
        let node = &mut nodes[n.index()];
        node.mesh = n.mesh().map(|m| m.index());
        if let Some(c) = n.camera() {
            node.camera = gltf_camera(path, &c)?;
        }
    }
    Ok(nodes)
}

/// Which nodes the default scene (or scene 0; every node when there is no scene) reaches.
/// Cycles and depth were rejected by `gltf_check` (in linear time).
fn reachable_nodes(doc: &gltf::Document, count: usize) -> Vec<bool> {
    let scene = doc.default_scene().or_else(|| doc.scenes().next());
    let mut reachable = vec![scene.is_none(); count];
    if let Some(s) = scene {
        let mut stack: Vec<gltf::Node> = s.nodes().collect();
        while let Some(n) = stack.pop() {
            if !reachable[n.index()] {
                reachable[n.index()] = true;
                stack.extend(n.children());
            }
        }
    }
    reachable
}

/// A perspective camera (with its OpenCV intrinsics when the extras carry them); `None` for
/// an orthographic one.
fn gltf_camera(path: &Path, c: &gltf::Camera) -> Result<Option<Perspective>> {
    let gltf::camera::Projection::Perspective(p) = c.projection() else {
        return Ok(None);
    };
    let yfov = p.yfov() as f64;
    if !(yfov > 0.0 && yfov < std::f64::consts::PI) {
        return Err(TraceError::format(
            path,
            format!("camera {}: yfov {yfov} is outside (0, π)", c.index()),
        ));
    }
    Ok(Some(Perspective {
        yfov,
        aspect: p.aspect_ratio().map(|a| a as f64),
        opencv: opencv_extras(c.extras()),
    }))
}

/// Every animation channel on translation, rotation or scale (morph weights: `morph`),
/// with finite, strictly increasing key times and finite values of the sampler's count.
fn gltf_channels(path: &Path, doc: &gltf::Document, buffers: &mut Buffers) -> Result<Vec<Channel>> {
    let mut channels = Vec::new();
    for a in doc.animations() {
        for (ci, ch) in a.channels().enumerate() {
            let what = format!("animation {} channel {ci}", a.index());
            if let Some(c) = gltf_channel(path, &ch, &what, buffers)? {
                channels.push(c);
            }
        }
    }
    Ok(channels)
}

/// One animation channel (`what` names it in errors); `None` for morph weights (read by
/// `morph`).
fn gltf_channel(
    path: &Path,
    ch: &gltf::animation::Channel,
    what: &str,
    buffers: &mut Buffers,
) -> Result<Option<Channel>> {
    use gltf::animation::Property;
    let path_kind = match ch.target().property() {
        Property::Translation => ChannelPath::Translation,
        Property::Rotation => ChannelPath::Rotation,
        Property::Scale => ChannelPath::Scale,
        Property::MorphTargetWeights => return Ok(None),
    };
    // Keys and values are small: both are read, then dropped.
    let (input, output) = (ch.sampler().input(), ch.sampler().output());
    let values = buffers.with_accessors(&[&input, &output], |bufs| {
        channel_values(path, ch, what, bufs)
    })?;
    let Some((times, values)) = values else {
        return Ok(None);
    };
    channel_from(path, ch, what, path_kind, times, values)
}

/// A channel's key times and values as stored; `None` for morph weights.
#[allow(clippy::type_complexity)]
fn channel_values(
    path: &Path,
    ch: &gltf::animation::Channel,
    what: &str,
    buffers: &Buffers,
) -> Result<Option<(Vec<f64>, Vec<[f64; 4]>)>> {
    use gltf::animation::util::ReadOutputs;
    let r = ch.reader(|b: gltf::Buffer| buffers.get(b.index()));
    let times: Vec<f64> = r
        .read_inputs()
        .ok_or_else(|| TraceError::format(path, format!("{what}: sampler input cannot be read")))?
        .map(|t| t as f64)
        .collect();
    check_key_times(path, what, &times)?;
    let values: Vec<[f64; 4]> = match r
        .read_outputs()
        .ok_or_else(|| TraceError::format(path, format!("{what}: sampler output cannot be read")))?
    {
        ReadOutputs::Translations(it) | ReadOutputs::Scales(it) => it
            .map(|v| [v[0] as f64, v[1] as f64, v[2] as f64, 0.0])
            .collect(),
        ReadOutputs::Rotations(it) => it.into_f32().map(|v| v.map(|x| x as f64)).collect(),
        ReadOutputs::MorphTargetWeights(_) => return Ok(None),
    };
    Ok(Some((times, values)))
}

/// An animation sampler's key times must be finite and strictly increasing (glTF 2.0 §3.11).
pub(crate) fn check_key_times(path: &Path, what: &str, times: &[f64]) -> Result<()> {
    if times.windows(2).any(|w| !(w[1] > w[0])) || times.iter().any(|t| !t.is_finite()) {
        return Err(TraceError::format(
            path,
            format!("{what}: key times are not finite and strictly increasing"),
        ));
    }
    Ok(())
}

/// A channel's interpolation and how many output values it stores a key: three for a cubic
/// spline (in-tangent, value, out-tangent), else one.
pub(crate) fn interpolation_of(ch: &gltf::animation::Channel) -> (Interpolation, usize) {
    match ch.sampler().interpolation() {
        gltf::animation::Interpolation::Step => (Interpolation::Step, 1),
        gltf::animation::Interpolation::Linear => (Interpolation::Linear, 1),
        gltf::animation::Interpolation::CubicSpline => (Interpolation::CubicSpline, 3),
    }
}

/// A channel from its key times and values, checked against its interpolation.
fn channel_from(
    path: &Path,
    ch: &gltf::animation::Channel,
    what: &str,
    path_kind: ChannelPath,
    times: Vec<f64>,
    values: Vec<[f64; 4]>,
) -> Result<Option<Channel>> {
    let (interpolation, per) = interpolation_of(ch);
    if values.len() != per * times.len() {
        return Err(TraceError::format(
            path,
            format!(
                "{what}: {} output values for {} keys",
                values.len(),
                times.len()
            ),
        ));
    }
    if values.iter().any(|v| v.iter().any(|x| !x.is_finite())) {
        return Err(TraceError::format(
            path,
            format!("{what}: output values are not finite"),
        ));
    }
    Ok(Some(Channel {
        node: ch.target().node().index(),
        path: path_kind,
        interpolation,
        times,
        values,
    }))
}

/// glTF's COLOR_0 is linear unless splatbridge metadata says the file keeps display values.
fn colors_linear(doc: &gltf::Document) -> bool {
    let encoding = extras_value(&doc.as_json().asset.extras).and_then(|v| {
        v.pointer("/splatbridge/colorEncoding")
            .and_then(|e| e.as_str().map(str::to_owned))
    });
    encoding.as_deref() != Some("display")
}

fn extras_value(e: &gltf::json::Extras) -> Option<serde_json::Value> {
    e.as_ref()
        .and_then(|raw| serde_json::from_str(raw.get()).ok())
}

/// `extras.opencv` = {width, height, fx, fy, cx, cy} on a camera, when complete and valid.
fn opencv_extras(e: &gltf::json::Extras) -> Option<Intrinsics> {
    let v = extras_value(e)?;
    let o = v.get("opencv")?;
    let f = |k: &str| o.get(k).and_then(|x| x.as_f64()).filter(|x| x.is_finite());
    let k = Intrinsics {
        width: o.get("width")?.as_u64()?.try_into().ok()?,
        height: o.get("height")?.as_u64()?.try_into().ok()?,
        fx: f("fx")?,
        fy: f("fy")?,
        cx: f("cx")?,
        cy: f("cy")?,
    };
    (k.width > 0 && k.height > 0 && k.fx > 0.0 && k.fy > 0.0).then_some(k)
}

mod obj;
pub use obj::{load_obj, load_obj_bytes};
