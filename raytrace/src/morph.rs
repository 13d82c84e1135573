//! Morph targets (glTF 2.0 §3.7.2.2 "Morph Targets", §3.6.2.3 "Sparse Accessors", §3.11
//! "Animations", `weights` path): a primitive's positions at time t are
//! `base + Σ_i w_i(t)·Δ_i`, the weights coming from the `weights` channel of the node's
//! animation (STEP, LINEAR, CUBICSPLINE with in-tangent, value, out-tangent per key), else the
//! node's `weights`, else the mesh's, else 0.
//!
//! Only POSITION targets matter here: the tracer shades unlit vertex colours and keeps no
//! normals. The loader keeps each morphed mesh's base positions and the open document, and
//! reads a target's deltas only when its weight is non-zero at the time being posed (a capture
//! of 300 frames written as 300 targets costs the base and the few targets that are on, not
//! 300 deltas). The sum is taken in f64 and rounded to f32 once, so a target of weight 1
//! gives `base + Δ` as exactly as f32 holds it.
//!
//! A morphed mesh is posed per node: a mesh shown by several nodes gets a copy per further
//! node (each node has its own weights). Posing changes the mesh's positions, so a tracer
//! rebuilds the BVH of every mesh whose weights changed (`MeshTracer::set_time`).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use glam::{DVec3, Vec3};

use crate::backend::{fits_bvh, MAX_BVH_COORD};
use crate::error::{Result, TraceError};
use crate::gltf_stream::Buffers;
use crate::model::{hermite, key_at, Interpolation, KeyAt, Mesh, Node};

/// The document and buffers targets are read from when posing (a streamed GLB keeps only its
/// open file; any other glTF its buffers as loaded).
pub struct MorphSource {
    path: PathBuf,
    doc: gltf::Document,
    buffers: Mutex<Buffers>,
}

/// A `weights` channel: key times and, per key, one weight per target (three blocks of them
/// for CUBICSPLINE: in-tangents, values, out-tangents).
#[derive(Clone, Debug, PartialEq)]
pub struct WeightsChannel {
    pub interpolation: Interpolation,
    pub times: Vec<f64>,
    pub values: Vec<f64>,
}

/// One triangle primitive of a morphed mesh: its vertices in the merged mesh and the
/// accessor of each target's POSITION deltas (`None`: the target moves no position).
#[derive(Clone, Debug, PartialEq)]
pub struct MorphPrim {
    pub start: usize,
    pub count: usize,
    pub targets: Vec<Option<usize>>,
}

/// A mesh posed by morph weights, as one node shows it.
#[derive(Clone, Debug)]
pub struct MorphMesh {
    pub mesh: usize,
    pub node: usize,
    /// Positions with every weight 0.
    pub base: Vec<Vec3>,
    pub prims: Vec<MorphPrim>,
    /// Weights when no channel drives them (node's, else mesh's, else zeros).
    pub default_weights: Vec<f64>,
    pub channel: Option<WeightsChannel>,
    /// The weights the mesh's positions currently hold.
    pub posed: Vec<f64>,
}

/// Every morphed mesh of a scene and where their targets are read from.
#[derive(Clone, Default)]
pub struct Morphs {
    pub meshes: Vec<MorphMesh>,
    source: Option<Arc<MorphSource>>,
}

impl std::fmt::Debug for Morphs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Morphs")
            .field("meshes", &self.meshes)
            .field("source", &self.source.as_ref().map(|s| &s.path))
            .finish()
    }
}

impl MorphMesh {
    /// Number of targets.
    pub fn targets(&self) -> usize {
        self.default_weights.len()
    }

    /// The weights at time `t`.
    pub fn weights_at(&self, t: f64) -> Vec<f64> {
        match &self.channel {
            Some(c) => sample_weights(c, self.targets(), t),
            None => self.default_weights.clone(),
        }
    }
}

/// Sample a weights channel of `n` targets at `t`, clamped to the first/last key outside the
/// keyed range (as `model::sample_channel` does for the other paths).
pub fn sample_weights(c: &WeightsChannel, n: usize, t: f64) -> Vec<f64> {
    let cubic = c.interpolation == Interpolation::CubicSpline;
    let block = |k: usize, part: usize| -> &[f64] {
        let at = if cubic { (3 * k + part) * n } else { k * n };
        &c.values[at..at + n]
    };
    let (k, s, dt) = match key_at(&c.times, t) {
        None => return vec![0.0; n],
        Some(KeyAt::Key(k)) => return block(k, 1).to_vec(),
        Some(KeyAt::Segment { k, s, dt }) => (k, s, dt),
    };
    let (a, b) = (block(k, 1), block(k + 1, 1));
    match c.interpolation {
        Interpolation::Step => a.to_vec(),
        Interpolation::Linear => (0..n).map(|i| a[i] + (b[i] - a[i]) * s).collect(),
        Interpolation::CubicSpline => {
            let (out_a, in_b) = (block(k, 2), block(k + 1, 0));
            let [h00, h10, h01, h11] = hermite(s);
            (0..n)
                .map(|i| h00 * a[i] + h10 * dt * out_a[i] + h01 * b[i] + h11 * dt * in_b[i])
                .collect()
        }
    }
}

impl Morphs {
    /// Whether the scene has no morphed mesh.
    pub fn is_empty(&self) -> bool {
        self.meshes.is_empty()
    }

    /// The time range the weights channels span, if any.
    pub fn time_range(&self) -> Option<(f64, f64)> {
        let mut r: Option<(f64, f64)> = None;
        for c in self.meshes.iter().filter_map(|m| m.channel.as_ref()) {
            if let (Some(&a), Some(&b)) = (c.times.first(), c.times.last()) {
                r = Some(r.map_or((a, b), |(lo, hi)| (lo.min(a), hi.max(b))));
            }
        }
        r
    }

    /// Pose every morphed mesh at `t`; returns the meshes whose positions changed.
    pub fn pose(&mut self, meshes: &mut [Mesh], t: f64) -> Result<Vec<usize>> {
        let mut changed = Vec::new();
        for mm in &mut self.meshes {
            let w = mm.weights_at(t);
            if w == mm.posed {
                continue;
            }
            let source = self.source.as_ref().ok_or_else(|| {
                TraceError::Invalid("morphed mesh without a source to read targets".into())
            })?;
            pose_mesh(source, mm, &w, &mut meshes[mm.mesh], t)?;
            mm.posed = w;
            changed.push(mm.mesh);
        }
        Ok(changed)
    }
}

/// `mesh.positions = base + Σ w_i Δ_i` (f64 sum, one rounding), reading only the targets of
/// non-zero weight.
fn pose_mesh(
    source: &MorphSource,
    mm: &MorphMesh,
    w: &[f64],
    mesh: &mut Mesh,
    t: f64,
) -> Result<()> {
    let path = &source.path;
    if let Some(i) = w.iter().position(|x| !x.is_finite()) {
        return Err(TraceError::format(
            path,
            format!(
                "node {}: morph weight {i} at t = {t} is not finite",
                mm.node
            ),
        ));
    }
    let mut acc: Option<Vec<DVec3>> = None;
    let mut buffers = source
        .buffers
        .lock()
        .map_err(|_| TraceError::Invalid("morph target buffers poisoned".into()))?;
    for prim in &mm.prims {
        for (ti, target) in prim.targets.iter().enumerate() {
            let (Some(ai), wi) = (*target, w[ti]) else {
                continue;
            };
            if wi == 0.0 {
                continue;
            }
            let sum = acc.get_or_insert_with(|| mm.base.iter().map(|p| p.as_dvec3()).collect());
            let a = source.doc.accessors().nth(ai).ok_or_else(|| {
                TraceError::format(path, format!("morph target accessor {ai} is missing"))
            })?;
            let what = format!("mesh {} morph target {ti} accessor {ai}", mm.mesh);
            let out = &mut sum[prim.start..prim.start + prim.count];
            buffers.with_accessors(&[&a], |bufs| {
                read_deltas(path, &a, bufs, &what, &mut |v, d| {
                    out[v] += wi * d.as_dvec3();
                })
            })?;
        }
    }
    match acc {
        Some(sum) => {
            for (i, (p, s)) in mesh.positions.iter_mut().zip(&sum).enumerate() {
                *p = s.as_vec3();
                if !fits_bvh(*p) {
                    return Err(TraceError::format(
                        path,
                        format!(
                            "node {}: morphed POSITION of vertex {i} at t = {t} is not finite or beyond ±{MAX_BVH_COORD}",
                            mm.node
                        ),
                    ));
                }
            }
        }
        None => mesh.positions.copy_from_slice(&mm.base),
    }
    Ok(())
}

fn bytes<'a>(
    path: &Path,
    bufs: &'a Buffers,
    view: &gltf::buffer::View,
    offset: usize,
    len: usize,
    what: &str,
) -> Result<&'a [u8]> {
    let start = view.offset() + offset;
    bufs.get(view.buffer().index())
        .and_then(|b| b.get(start..start.checked_add(len)?))
        .filter(|_| offset + len <= view.length())
        .ok_or_else(|| {
            TraceError::format(
                path,
                format!("{what}: {len} bytes at {offset} run past its bufferView"),
            )
        })
}

fn f3(b: &[u8]) -> Vec3 {
    let f = |k: usize| f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]]);
    Vec3::new(f(0), f(1), f(2))
}

/// Call `add(vertex, delta)` for each stored delta of a VEC3 float accessor: the dense part
/// (zeros without a buffer view), then the sparse substitutions, which replace dense values.
/// A sparse accessor's indices must be strictly increasing and in range (§3.6.2.3).
pub(crate) fn read_deltas(
    path: &Path,
    a: &gltf::Accessor,
    bufs: &Buffers,
    what: &str,
    add: &mut dyn FnMut(usize, Vec3),
) -> Result<()> {
    use gltf::accessor::sparse::IndexType;
    let n = a.count();
    let sparse = a.sparse();
    let dense = match a.view() {
        Some(view) => {
            let stride = view.stride().unwrap_or(12);
            let len = if n == 0 { 0 } else { (n - 1) * stride + 12 };
            Some((bytes(path, bufs, &view, a.offset(), len, what)?, stride))
        }
        None => None,
    };
    let Some(sp) = sparse else {
        if let Some((b, stride)) = dense {
            for v in 0..n {
                add(v, f3(&b[v * stride..]));
            }
        }
        return Ok(());
    };
    let m = sp.count();
    let iw = match sp.indices().index_type() {
        IndexType::U8 => 1,
        IndexType::U16 => 2,
        IndexType::U32 => 4,
    };
    let ib = bytes(
        path,
        bufs,
        &sp.indices().view(),
        sp.indices().offset(),
        m * iw,
        what,
    )?;
    let vb = bytes(
        path,
        bufs,
        &sp.values().view(),
        sp.values().offset(),
        m * 12,
        what,
    )?;
    let index = |k: usize| -> usize {
        let b = &ib[k * iw..];
        match iw {
            1 => b[0] as usize,
            2 => u16::from_le_bytes([b[0], b[1]]) as usize,
            _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
        }
    };
    let mut prev: Option<usize> = None;
    for k in 0..m {
        let i = index(k);
        if i >= n || prev.is_some_and(|p| i <= p) {
            return Err(TraceError::format(
                path,
                format!("{what}: sparse index {i} is out of range ({n}) or not increasing"),
            ));
        }
        prev = Some(i);
    }
    // Dense values where no substitution falls, then the substitutions.
    let mut next = 0;
    if let Some((b, stride)) = dense {
        for v in 0..n {
            if next < m && index(next) == v {
                next += 1;
                continue;
            }
            add(v, f3(&b[v * stride..]));
        }
    }
    for k in 0..m {
        add(index(k), f3(&vb[12 * k..]));
    }
    Ok(())
}

/// Read every morphed mesh of a checked document: targets of each triangle primitive
/// (validated against the base), `weights` channels, and one [`MorphMesh`] per node that
/// shows a morphed mesh (copying the mesh for each further node). `meshes` and `nodes` are
/// the loader's, in document order; the mesh copies are appended.
pub(crate) fn load_morphs(
    path: &Path,
    doc: &gltf::Document,
    buffers: &mut Buffers,
    meshes: &mut Vec<Mesh>,
    nodes: &mut [Node],
) -> Result<Vec<MorphMesh>> {
    let prims: Vec<Option<Vec<MorphPrim>>> = doc
        .meshes()
        .map(|m| mesh_targets(path, &m))
        .collect::<Result<_>>()?;
    let channels = weights_channels(path, doc, &prims, buffers)?;
    let mut out = Vec::new();
    let mut shown = vec![false; meshes.len()];
    for (ni, node) in doc.nodes().enumerate() {
        let Some(mi) = nodes[ni].mesh else { continue };
        let Some(Some(mp)) = prims.get(mi) else {
            continue;
        };
        let targets = mp.first().map_or(0, |p| p.targets.len());
        let Some(gm) = node.mesh() else { continue };
        let what = |w: &str| format!("node {ni}: {w} weights");
        let default_weights = match (node.weights(), gm.weights()) {
            (Some(w), _) => weights_vec(path, w, targets, &what("node"))?,
            (None, Some(w)) => weights_vec(path, w, targets, &what("mesh"))?,
            (None, None) => vec![0.0; targets],
        };
        let mesh = if shown[mi] {
            meshes.push(meshes[mi].clone());
            nodes[ni].mesh = Some(meshes.len() - 1);
            meshes.len() - 1
        } else {
            shown[mi] = true;
            mi
        };
        out.push(MorphMesh {
            mesh,
            node: ni,
            base: meshes[mesh].positions.clone(),
            prims: mp.clone(),
            posed: vec![0.0; targets],
            default_weights,
            channel: channels
                .iter()
                .rev()
                .find(|c| c.0 == ni)
                .map(|c| c.1.clone()),
        });
    }
    Ok(out)
}

impl Morphs {
    /// Morphed meshes reading their targets from `doc` and `buffers`, posed at time 0.
    pub(crate) fn new(
        path: &Path,
        doc: &gltf::Document,
        buffers: Buffers,
        meshes: Vec<MorphMesh>,
    ) -> Self {
        if meshes.is_empty() {
            return Morphs::default();
        }
        Morphs {
            meshes,
            source: Some(Arc::new(MorphSource {
                path: path.to_path_buf(),
                doc: doc.clone(),
                buffers: Mutex::new(buffers),
            })),
        }
    }
}

fn weights_vec(path: &Path, w: &[f32], targets: usize, what: &str) -> Result<Vec<f64>> {
    if w.len() != targets || w.iter().any(|x| !x.is_finite()) {
        return Err(TraceError::format(
            path,
            format!(
                "{what}: {} values for {targets} morph targets, or not finite",
                w.len()
            ),
        ));
    }
    Ok(w.iter().map(|&x| x as f64).collect())
}

/// A mesh's triangle primitives with their targets, `None` when it has none. Every primitive
/// has the same number of targets (§3.7.2.2), and each POSITION target is VEC3 float with the
/// base's count.
fn mesh_targets(path: &Path, m: &gltf::Mesh) -> Result<Option<Vec<MorphPrim>>> {
    use gltf::mesh::Mode;
    let mut prims = Vec::new();
    let mut start = 0;
    let mut any = false;
    let counts: Vec<usize> = m.primitives().map(|p| p.morph_targets().count()).collect();
    if counts.windows(2).any(|w| w[0] != w[1]) {
        return Err(TraceError::format(
            path,
            format!(
                "mesh {}: primitives have different numbers of morph targets {counts:?}",
                m.index()
            ),
        ));
    }
    for (pi, p) in m.primitives().enumerate() {
        if !matches!(
            p.mode(),
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            continue;
        }
        let what = format!("mesh {} primitive {pi}", m.index());
        let count = p
            .get(&gltf::Semantic::Positions)
            .map(|a| a.count())
            .ok_or_else(|| TraceError::format(path, format!("{what}: no POSITION")))?;
        let mut targets = Vec::new();
        for (ti, t) in p.morph_targets().enumerate() {
            any = true;
            let Some(a) = t.positions() else {
                targets.push(None);
                continue;
            };
            use gltf::accessor::{DataType, Dimensions};
            if a.dimensions() != Dimensions::Vec3 || a.data_type() != DataType::F32 {
                return Err(TraceError::format(
                    path,
                    format!(
                        "{what} morph target {ti}: POSITION accessor {} is not VEC3 of float (only float deltas are read)",
                        a.index()
                    ),
                ));
            }
            if a.count() != count {
                return Err(TraceError::format(
                    path,
                    format!(
                        "{what} morph target {ti}: POSITION has {} entries for {count} vertices",
                        a.count()
                    ),
                ));
            }
            targets.push(Some(a.index()));
        }
        prims.push(MorphPrim {
            start,
            count,
            targets,
        });
        start += count;
    }
    Ok(any.then_some(prims))
}

/// Every `weights` channel as (node, channel), checked: the node shows a mesh with targets,
/// key times finite and strictly increasing, keys × targets (× 3 for CUBICSPLINE) finite
/// values.
fn weights_channels(
    path: &Path,
    doc: &gltf::Document,
    prims: &[Option<Vec<MorphPrim>>],
    buffers: &mut Buffers,
) -> Result<Vec<(usize, WeightsChannel)>> {
    use gltf::animation::util::ReadOutputs;
    use gltf::animation::Property;
    let mut out = Vec::new();
    for a in doc.animations() {
        for (ci, ch) in a.channels().enumerate() {
            if ch.target().property() != Property::MorphTargetWeights {
                continue;
            }
            let what = format!("animation {} channel {ci}", a.index());
            let node = ch.target().node();
            // Targets as the document declares them (every primitive has as many, checked by
            // `mesh_targets`), whether or not a primitive is a triangle one.
            let targets = node
                .mesh()
                .and_then(|m| m.primitives().next())
                .map_or(0, |p| p.morph_targets().count());
            if targets == 0 {
                return Err(TraceError::format(
                    path,
                    format!(
                        "{what}: weights on node {} whose mesh has no morph targets",
                        node.index()
                    ),
                ));
            }
            let (input, output) = (ch.sampler().input(), ch.sampler().output());
            let (times, values) = buffers.with_accessors(&[&input, &output], |bufs| {
                let r = ch.reader(|b: gltf::Buffer| bufs.get(b.index()));
                let times: Vec<f64> = r
                    .read_inputs()
                    .ok_or_else(|| {
                        TraceError::format(path, format!("{what}: sampler input cannot be read"))
                    })?
                    .map(|t| t as f64)
                    .collect();
                let values: Vec<f64> = match r.read_outputs() {
                    Some(ReadOutputs::MorphTargetWeights(w)) => {
                        w.into_f32().map(|x| x as f64).collect()
                    }
                    _ => {
                        return Err(TraceError::format(
                            path,
                            format!("{what}: sampler output cannot be read"),
                        ))
                    }
                };
                Ok((times, values))
            })?;
            crate::scene_load::check_key_times(path, &what, &times)?;
            let (interpolation, per) = crate::scene_load::interpolation_of(&ch);
            if values.len() != per * targets * times.len() {
                return Err(TraceError::format(
                    path,
                    format!(
                        "{what}: {} weights for {} keys of {targets} morph targets",
                        values.len(),
                        times.len()
                    ),
                ));
            }
            if values.iter().any(|x| !x.is_finite()) {
                return Err(TraceError::format(
                    path,
                    format!("{what}: weights are not finite"),
                ));
            }
            let traced = node
                .mesh()
                .is_some_and(|m| prims.get(m.index()).is_some_and(Option::is_some));
            if !traced {
                // Morphs of primitives without surface (points): nothing to pose.
                continue;
            }
            out.push((
                node.index(),
                WeightsChannel {
                    interpolation,
                    times,
                    values,
                },
            ));
        }
    }
    Ok(out)
}
