//! The triangle scene a viewer would see: meshes (positions, RGBA vertex colours, optional UVs,
//! per-triangle material and Gaussian id), materials (glTF metallic-roughness base colour
//! factor × texture, alpha mode), a node hierarchy with TRS and animation channels sampled at
//! time t (glTF 2.0 §3.11: STEP, LINEAR with shortest-path slerp for rotations, CUBICSPLINE),
//! and camera nodes.
//!
//! Loading (see `scene_load`) fills this model from the exported file only, so a writer bug
//! shows up in renders. Geometry stays in each mesh's local frame: animated objects are
//! rendered as instances under their node's world transform at t, never rebuilt; only meshes
//! with morph targets change shape, posed per time by `morph`.

use glam::{DAffine3, DMat3, DQuat, DVec3, Vec2, Vec3, Vec4};
use splatbridge_scene::Camera;

pub use crate::texture::{Texture, Wrap};

mod planar;

/// glTF `alphaMode`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    /// Alpha ≥ cutoff renders opaque, anything below is discarded.
    Mask(f32),
    Blend,
}

impl AlphaMode {
    /// The α a fragment of shaded alpha `a` (material, texture and vertex alphas multiplied)
    /// is drawn with: `a` clamped to [0, 1], then this mode's rule.
    #[inline]
    pub fn alpha(self, a: f32) -> f32 {
        let a = a.clamp(0.0, 1.0);
        match self {
            AlphaMode::Opaque => 1.0,
            AlphaMode::Mask(cut) => {
                if a >= cut {
                    1.0
                } else {
                    0.0
                }
            }
            AlphaMode::Blend => a,
        }
    }
}

/// A material reduced to what an unlit BLEND viewer uses.
#[derive(Clone, Debug)]
pub struct Material {
    pub base_color: Vec4,
    pub texture: Option<usize>,
    pub alpha_mode: AlphaMode,
}

impl Default for Material {
    /// glTF's default material: white, opaque.
    fn default() -> Self {
        Material {
            base_color: Vec4::ONE,
            texture: None,
            alpha_mode: AlphaMode::Opaque,
        }
    }
}

/// Each triangle's material, stored as runs (a primitive's triangles share one): an export's
/// tens of millions of triangles have a handful of materials, so a `u32` per triangle (148 MB
/// for a 37 M-triangle export) would hold the same number over and over.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MaterialRuns {
    /// First triangle of each run, ascending; `materials[i]` is run `i`'s material.
    starts: Vec<u32>,
    materials: Vec<u32>,
    len: usize,
}

impl MaterialRuns {
    /// Triangles covered.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Append one triangle of material `m`.
    pub fn push(&mut self, m: u32) {
        self.extend_with(1, m);
    }

    /// Append `n` triangles of material `m`.
    pub fn extend_with(&mut self, n: usize, m: u32) {
        if n == 0 {
            return;
        }
        if self.materials.last() != Some(&m) {
            self.starts.push(self.len as u32);
            self.materials.push(m);
        }
        self.len += n;
    }

    /// Triangle `t`'s material (`t < len`).
    #[inline]
    pub fn get(&self, t: usize) -> u32 {
        match self.materials.len() {
            1 => self.materials[0],
            _ => {
                let run = self.starts.partition_point(|&s| s as usize <= t);
                self.materials[run.saturating_sub(1)]
            }
        }
    }

    /// The materials the runs name, once a run (each distinct material at least once).
    pub fn named(&self) -> impl Iterator<Item = u32> + '_ {
        self.materials.iter().copied()
    }

    /// Every triangle's material, in order.
    pub fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.starts.len()).flat_map(move |i| {
            let end = self.starts.get(i + 1).map_or(self.len, |&e| e as usize);
            std::iter::repeat_n(self.materials[i], end - self.starts[i] as usize)
        })
    }
}

impl From<Vec<u32>> for MaterialRuns {
    fn from(v: Vec<u32>) -> Self {
        let mut r = MaterialRuns::default();
        for m in v {
            r.push(m);
        }
        r
    }
}

/// One mesh (all its primitives merged), in its local frame.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub name: String,
    /// Local positions as stored in the file.
    pub positions: Vec<Vec3>,
    /// RGBA vertex colours (white where the file has none).
    pub colors: Vec<Vec4>,
    pub uvs: Option<Vec<Vec2>>,
    pub tris: Vec<[u32; 3]>,
    pub tri_material: MaterialRuns,
    /// The Gaussian each triangle came from (`_GAUSSIAN_ID` of its first vertex), or, without
    /// that attribute, the index of the connected component the triangle belongs to.
    pub tri_gaussian: Vec<u32>,
    /// True when `tri_gaussian` came from the file's `_GAUSSIAN_ID`.
    pub has_gaussian_ids: bool,
}

/// glTF perspective camera parameters, plus the exact OpenCV intrinsics when the file keeps
/// them (`extras.opencv` on the camera, as `splatbridge convert` writes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Perspective {
    pub yfov: f64,
    pub aspect: Option<f64>,
    pub opencv: Option<Intrinsics>,
}

/// Pixel size and intrinsics of a camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// Which property an animation channel drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelPath {
    Translation,
    Rotation,
    Scale,
}

/// Animation sampler interpolation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// One animation channel with its sampler's keys (times in seconds, strictly increasing).
/// Values are xyz(w); CUBICSPLINE stores (in-tangent, value, out-tangent) per key.
#[derive(Clone, Debug)]
pub struct Channel {
    pub node: usize,
    pub path: ChannelPath,
    pub interpolation: Interpolation,
    pub times: Vec<f64>,
    pub values: Vec<[f64; 4]>,
}

/// A node: TRS (or a fixed matrix), optional mesh and camera.
#[derive(Clone, Debug)]
pub struct Node {
    pub name: String,
    pub parent: Option<usize>,
    pub translation: DVec3,
    pub rotation: DQuat,
    pub scale: DVec3,
    /// A node given as `matrix` (never animated, glTF forbids it).
    pub matrix: Option<DAffine3>,
    pub mesh: Option<usize>,
    pub camera: Option<Perspective>,
}

impl Default for Node {
    fn default() -> Self {
        Node {
            name: String::new(),
            parent: None,
            translation: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
            scale: DVec3::ONE,
            matrix: None,
            mesh: None,
            camera: None,
        }
    }
}

/// A mesh placed in the world at some time.
#[derive(Clone, Copy, Debug)]
pub struct Instance {
    pub node: usize,
    pub mesh: usize,
    pub to_world: DAffine3,
}

/// The whole triangle scene.
#[derive(Clone, Debug, Default)]
pub struct TriScene {
    pub meshes: Vec<Mesh>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub nodes: Vec<Node>,
    pub channels: Vec<Channel>,
    /// Meshes posed by morph target weights ([`TriScene::pose_morphs`]).
    pub morphs: crate::morph::Morphs,
    /// Vertex colours are linear (glTF's rule; splatbridge writes sRGB-decoded 3DGS colours)
    /// rather than display values (OBJ, or a glTF whose splatbridge metadata says `display`).
    pub colors_linear: bool,
}

/// Default image height for glTF cameras, which carry no pixel size (the width follows the
/// aspect ratio); `CameraArgs` resizes when `--width/--height` are given.
pub const GLTF_CAMERA_HEIGHT: u32 = 480;

impl TriScene {
    /// A scene of one mesh under an identity node.
    pub fn single(mesh: Mesh, materials: Vec<Material>, textures: Vec<Texture>) -> Self {
        TriScene {
            meshes: vec![mesh],
            materials,
            textures,
            nodes: vec![Node {
                mesh: Some(0),
                ..Node::default()
            }],
            channels: Vec::new(),
            morphs: Default::default(),
            colors_linear: false,
        }
    }

    /// Pose the morphed meshes at time `t` (see `morph`); returns the meshes whose positions
    /// changed, whose BVHs are then stale.
    pub fn pose_morphs(&mut self, t: f64) -> crate::error::Result<Vec<usize>> {
        self.morphs.pose(&mut self.meshes, t)
    }

    /// Undo the axis-convention root of a splatbridge export: files written by the converter
    /// put everything under a root node `splatbridge_root` whose rotation maps the capture's
    /// up axis onto glTF's +Y. Making that node the identity puts geometry and camera nodes
    /// back in the capture's frame, where `cameras.json`, orbit rigs and native renders live.
    /// Returns whether such a root was found.
    pub fn to_capture_frame(&mut self) -> bool {
        let Some(i) = self
            .nodes
            .iter()
            .position(|n| n.parent.is_none() && n.name == "splatbridge_root")
        else {
            return false;
        };
        let n = &mut self.nodes[i];
        n.translation = DVec3::ZERO;
        n.rotation = DQuat::IDENTITY;
        n.scale = DVec3::ONE;
        n.matrix = None;
        self.channels.retain(|c| c.node != i);
        true
    }

    /// World-space vertex positions of the instances at `t` (every `stride`-th vertex), e.g.
    /// to frame an orbit camera around the scene.
    pub fn sample_points(&self, t: f64, stride: usize) -> Vec<DVec3> {
        let mut out = Vec::new();
        for inst in self.instances(t) {
            for p in self.meshes[inst.mesh]
                .positions
                .iter()
                .step_by(stride.max(1))
            {
                out.push(inst.to_world.transform_point3(p.as_dvec3()));
            }
        }
        out
    }

    /// Total triangle count over meshes (not instances).
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.tris.len()).sum()
    }

    /// The time range the animation channels span (`(0, 0)` without animation).
    pub fn time_range(&self) -> (f64, f64) {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for c in &self.channels {
            if let (Some(a), Some(b)) = (c.times.first(), c.times.last()) {
                lo = lo.min(*a);
                hi = hi.max(*b);
            }
        }
        if let Some((a, b)) = self.morphs.time_range() {
            lo = lo.min(a);
            hi = hi.max(b);
        }
        if lo <= hi {
            (lo, hi)
        } else {
            (0.0, 0.0)
        }
    }

    /// Node `i`'s local transform at time `t` (its TRS with animated channels applied).
    pub fn local_transform(&self, i: usize, t: f64) -> DAffine3 {
        let n = &self.nodes[i];
        if let Some(m) = n.matrix {
            return m;
        }
        let (mut tr, mut rot, mut sc) = (n.translation, n.rotation, n.scale);
        for c in self.channels.iter().filter(|c| c.node == i) {
            let v = sample_channel(c, t);
            match c.path {
                ChannelPath::Translation => tr = DVec3::new(v[0], v[1], v[2]),
                ChannelPath::Scale => sc = DVec3::new(v[0], v[1], v[2]),
                ChannelPath::Rotation => {
                    let q = DQuat::from_xyzw(v[0], v[1], v[2], v[3]);
                    let l = q.length();
                    rot = if l > 0.0 && l.is_finite() {
                        q / l
                    } else {
                        DQuat::IDENTITY
                    };
                }
            }
        }
        DAffine3::from_scale_rotation_translation(sc, rot, tr)
    }

    /// World transforms of all nodes at time `t` (parents before children is not assumed).
    pub fn world_transforms(&self, t: f64) -> Vec<DAffine3> {
        let local: Vec<DAffine3> = (0..self.nodes.len())
            .map(|i| self.local_transform(i, t))
            .collect();
        let mut world: Vec<Option<DAffine3>> = vec![None; self.nodes.len()];
        fn resolve(
            i: usize,
            nodes: &[Node],
            local: &[DAffine3],
            world: &mut [Option<DAffine3>],
            depth: usize,
        ) -> DAffine3 {
            if let Some(w) = world[i] {
                return w;
            }
            // Loaders reject cycles; the depth cap keeps a malformed model finite regardless.
            let w = match nodes[i].parent {
                Some(p) if depth < nodes.len() => {
                    resolve(p, nodes, local, world, depth + 1) * local[i]
                }
                _ => local[i],
            };
            world[i] = Some(w);
            w
        }
        (0..self.nodes.len())
            .map(|i| resolve(i, &self.nodes, &local, &mut world, 0))
            .collect()
    }

    /// Mesh instances visible at `t`: nodes with a mesh whose world transform is invertible
    /// (a STEP scale of 0 hides a node, the glTF idiom for per-frame visibility).
    pub fn instances(&self, t: f64) -> Vec<Instance> {
        let world = self.world_transforms(t);
        self.nodes
            .iter()
            .enumerate()
            .filter_map(|(i, n)| {
                let mesh = n.mesh?;
                let w = world[i];
                let det = w.matrix3.determinant();
                (det.is_finite() && det.abs() > 1e-18 && w.translation.is_finite()).then_some(
                    Instance {
                        node: i,
                        mesh,
                        to_world: w,
                    },
                )
            })
            .collect()
    }

    /// The scene's camera nodes at time `t` as OpenCV cameras. The glTF camera looks down −Z
    /// with +Y up; OpenCV looks down +Z with +Y down, so the camera-to-world rotation is the
    /// node's (scale removed) times diag(1, −1, −1). Pixel size: `GLTF_CAMERA_HEIGHT` rows,
    /// columns from the aspect ratio (4:3 when absent), square pixels.
    pub fn cameras(&self, t: f64) -> Vec<Camera> {
        let world = self.world_transforms(t);
        let mut out = Vec::new();
        for (i, n) in self.nodes.iter().enumerate() {
            let Some(p) = n.camera else { continue };
            let w = world[i];
            let m = w.matrix3;
            let (x, y) = (m.x_axis, m.y_axis);
            // Gram–Schmidt removes scale and shear; a degenerate node yields no camera.
            let xa = x.normalize_or_zero();
            let ya = (y - xa * xa.dot(y)).normalize_or_zero();
            if xa == DVec3::ZERO || ya == DVec3::ZERO {
                continue;
            }
            let za = xa.cross(ya);
            let c2w = DMat3::from_cols(xa, -ya, -za);
            let k = p.opencv.unwrap_or_else(|| {
                let h = GLTF_CAMERA_HEIGHT;
                let aspect = p
                    .aspect
                    .filter(|a| *a > 0.0 && a.is_finite())
                    .unwrap_or(4.0 / 3.0);
                let wpx = ((h as f64 * aspect).round() as u32).max(1);
                let f = 0.5 * h as f64 / (0.5 * p.yfov).tan();
                Intrinsics {
                    width: wpx,
                    height: h,
                    fx: f,
                    fy: f,
                    cx: 0.5 * wpx as f64,
                    cy: 0.5 * h as f64,
                }
            });
            out.push(Camera {
                width: k.width,
                height: k.height,
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
                centre: w.translation,
                world_to_cam: c2w.transpose(),
                name: if n.name.is_empty() {
                    format!("node {i}")
                } else {
                    n.name.clone()
                },
            });
        }
        out
    }
}

/// Where time `t` falls among an animation sampler's strictly increasing key times.
pub(crate) enum KeyAt {
    /// At key `k`'s value: a single key, `t` outside the keyed range (clamped, glTF 2.0
    /// §3.11) or NaN.
    Key(usize),
    /// Between key `k` and `k + 1`, at fraction `s` of the segment of duration `dt`.
    Segment { k: usize, s: f64, dt: f64 },
}

/// [`KeyAt`] of `t` among `times`; `None` without keys.
pub(crate) fn key_at(times: &[f64], t: f64) -> Option<KeyAt> {
    let n = times.len();
    if n == 0 {
        return None;
    }
    if n == 1 || t.is_nan() || t <= times[0] {
        return Some(KeyAt::Key(0));
    }
    if t >= times[n - 1] {
        return Some(KeyAt::Key(n - 1));
    }
    // Last key with time ≤ t.
    let k = times.partition_point(|&x| x <= t) - 1;
    let (t0, t1) = (times[k], times[k + 1]);
    let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    Some(KeyAt::Segment { k, s, dt: t1 - t0 })
}

/// The cubic Hermite basis `[h00, h10, h01, h11]` at fraction `s` (glTF 2.0 Appendix C,
/// CUBICSPLINE): `h00·v_k + h10·dt·out_k + h01·v_{k+1} + h11·dt·in_{k+1}`.
pub(crate) fn hermite(s: f64) -> [f64; 4] {
    let (s2, s3) = (s * s, s * s * s);
    [
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        -2.0 * s3 + 3.0 * s2,
        s3 - s2,
    ]
}

/// Sample a channel at time `t`, clamped to its first/last key outside the keyed range.
pub fn sample_channel(c: &Channel, t: f64) -> [f64; 4] {
    let cubic = c.interpolation == Interpolation::CubicSpline;
    let value = |k: usize| {
        if cubic {
            c.values[3 * k + 1]
        } else {
            c.values[k]
        }
    };
    let (k, s, dt) = match key_at(&c.times, t) {
        None => return [0.0, 0.0, 0.0, 1.0],
        Some(KeyAt::Key(k)) => return value(k),
        Some(KeyAt::Segment { k, s, dt }) => (k, s, dt),
    };
    let (a, b) = (value(k), value(k + 1));
    match c.interpolation {
        Interpolation::Step => a,
        Interpolation::Linear => {
            if c.path == ChannelPath::Rotation {
                let qa = DQuat::from_array(a).normalize();
                let mut qb = DQuat::from_array(b).normalize();
                // Shortest path: glTF's slerp takes the short arc.
                if qa.dot(qb) < 0.0 {
                    qb = -qb;
                }
                qa.slerp(qb, s).normalize().to_array()
            } else {
                std::array::from_fn(|j| a[j] + (b[j] - a[j]) * s)
            }
        }
        Interpolation::CubicSpline => {
            let out_a = c.values[3 * k + 2];
            let in_b = c.values[3 * (k + 1)];
            let [h00, h10, h01, h11] = hermite(s);
            let mut v: [f64; 4] = std::array::from_fn(|j| {
                h00 * a[j] + h10 * dt * out_a[j] + h01 * b[j] + h11 * dt * in_b[j]
            });
            if c.path == ChannelPath::Rotation {
                let q = DQuat::from_array(v);
                let l = q.length();
                if l > 0.0 {
                    v = (q / l).to_array();
                }
            }
            v
        }
    }
}

/// The sRGB transfer functions (encode for colours clamped to [0, 1]; decode for base-colour
/// texture RGB, as glTF's sRGB textures are decoded).
pub use splatbridge_scene::srgb::decode as srgb_to_linear;

impl Mesh {
    /// RGBA at barycentric position `bary` of triangle `tri`, as an unlit BLEND viewer shades it:
    /// vertex colour × base colour factor × texture, then the material's alpha mode.
    pub fn shade(
        &self,
        tri: usize,
        bary: [f32; 3],
        materials: &[Material],
        textures: &[Texture],
    ) -> Vec4 {
        let [i0, i1, i2] = self.tris[tri].map(|i| i as usize);
        let mut c =
            self.colors[i0] * bary[0] + self.colors[i1] * bary[1] + self.colors[i2] * bary[2];
        let default = Material::default();
        let m = self.material(tri, materials).unwrap_or(&default);
        c *= m.base_color;
        if let Some((tex, uv)) = self.texture_at(tri, bary, m, textures) {
            c *= tex.sample(uv);
        }
        Vec4::new(c.x, c.y, c.z, m.alpha_mode.alpha(c.w))
    }

    /// [`Mesh::shade`]'s α (the same operations on the same lane, so the same bits) and the
    /// factor its material and texture multiply the interpolated vertex α by (the base
    /// colour's α times the texture's; 1 without a material), from one texture sample.
    pub fn shade_alpha(
        &self,
        tri: usize,
        bary: [f32; 3],
        materials: &[Material],
        textures: &[Texture],
    ) -> (f32, f32) {
        let [i0, i1, i2] = self.tris[tri].map(|i| i as usize);
        let mut a =
            self.colors[i0].w * bary[0] + self.colors[i1].w * bary[1] + self.colors[i2].w * bary[2];
        let Some(m) = self.material(tri, materials) else {
            // The default material: white and opaque.
            return (1.0, 1.0);
        };
        let mut factor = m.base_color.w;
        a *= m.base_color.w;
        if let Some((tex, uv)) = self.texture_at(tri, bary, m, textures) {
            let t = tex.sample(uv).w;
            a *= t;
            factor *= t;
        }
        (m.alpha_mode.alpha(a), factor)
    }

    /// Triangle `tri`'s material, if its index names one.
    #[inline]
    pub fn material<'a>(&self, tri: usize, materials: &'a [Material]) -> Option<&'a Material> {
        materials.get(self.tri_material.get(tri) as usize)
    }

    /// The texture material `m` samples on triangle `tri` (whose material it is) and the
    /// texture coordinate at barycentric position `bary`: None when `m` has no texture or the
    /// mesh no coordinates. The one place a hit's coordinate is formed, for shading and for
    /// whatever reads the same texel again (`mesh_hit`'s zero-alpha rule, distillation's
    /// alpha factor).
    #[inline]
    pub fn texture_at<'a>(
        &self,
        tri: usize,
        bary: [f32; 3],
        m: &Material,
        textures: &'a [Texture],
    ) -> Option<(&'a Texture, Vec2)> {
        let tex = m.texture.and_then(|t| textures.get(t))?;
        let uvs = self.uvs.as_ref()?;
        let [i0, i1, i2] = self.tris[tri].map(|i| i as usize);
        Some((
            tex,
            uvs[i0] * bary[0] + uvs[i1] * bary[1] + uvs[i2] * bary[2],
        ))
    }

    /// Fill `tri_gaussian` with connected-component indices (vertices shared through the index
    /// buffer), for files without `_GAUSSIAN_ID`.
    pub fn assign_components(&mut self) {
        let n = self.positions.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(p: &mut [u32], mut x: u32) -> u32 {
            while p[x as usize] != x {
                p[x as usize] = p[p[x as usize] as usize];
                x = p[x as usize];
            }
            x
        }
        for t in &self.tris {
            let a = find(&mut parent, t[0]);
            for &v in &t[1..] {
                let b = find(&mut parent, v);
                if a != b {
                    parent[b as usize] = a;
                }
            }
        }
        let mut label = vec![u32::MAX; n];
        let mut next = 0u32;
        self.tri_gaussian = self
            .tris
            .iter()
            .map(|t| {
                let r = find(&mut parent, t[0]) as usize;
                if label[r] == u32::MAX {
                    label[r] = next;
                    next += 1;
                }
                label[r]
            })
            .collect();
        self.has_gaussian_ids = false;
    }
}
