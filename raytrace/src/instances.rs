//! The instances of a mesh scene at one time, under a top-level BVH over their world bounds.
//!
//! A scene exported for stock viewers holds hundreds of nodes (spatial chunks); testing each
//! node's bounds per ray and traversing the nodes in file order made the layout of a file cost
//! most of the trace (639 nodes of `fourth_st`: 80.8 s against 28.8 s for the same triangles in
//! one node). The top-level structure hands a ray only the instances whose bounds it enters, in
//! near-to-far order, and stops at the k-buffer's cull distance, so the chunks beyond the k-th
//! hit are never entered. It is two-level instancing (each mesh keeps its own BVH in its own
//! frame), which keeps every hit's arithmetic, and so every image, exactly as before: the
//! structure only decides which instances are visited and in which order, and the hit set is
//! ordered by its full key, not by discovery.

use glam::{DVec3, Vec3};

use crate::backend::{build_boxes, fits_bvh, Accel, BackendKind, BuildPreset};
use crate::mesh_tracer::PreparedInstance;

/// Fewest instances for which the top-level structure is built; below it a ray tests each
/// instance's bounds in turn (one or two boxes cost less than a traversal).
pub const MIN_INSTANCES: usize = 3;

/// A scene's instances at one time, with the structure over their bounds.
pub struct Instances {
    list: Vec<PreparedInstance>,
    top: Option<Top>,
}

/// The top-level structure: instance boxes relative to `anchor`, in f32.
struct Top {
    anchor: DVec3,
    accel: Box<dyn Accel>,
}

impl Instances {
    /// The instances `list` with a top-level structure over their bounds when there are at
    /// least [`MIN_INSTANCES`] and the bounds fit an f32 BVH (otherwise rays visit each one).
    pub fn new(list: Vec<PreparedInstance>, backend: BackendKind) -> Self {
        let top = (list.len() >= MIN_INSTANCES)
            .then(|| Top::build(&list, backend))
            .flatten();
        Instances { list, top }
    }

    /// The same instances, visited one by one in order (the reference the tests compare the
    /// top-level traversal with).
    pub fn linear(list: Vec<PreparedInstance>) -> Self {
        Instances { list, top: None }
    }

    /// The instances, in order.
    pub(crate) fn list(&self) -> &[PreparedInstance] {
        &self.list
    }

    /// Whether rays go through the top-level structure.
    pub fn has_top_level(&self) -> bool {
        self.top.is_some()
    }

    /// Call `visit(index, instance, &mut cull)` for (at least) every instance whose world
    /// bounds the ray `o + t·d` (unit `d`) enters before `cull`; `visit` may lower `cull`,
    /// which prunes the instances entered beyond it.
    pub fn visit(
        &self,
        o: DVec3,
        d: DVec3,
        cull: f32,
        visit: &mut dyn FnMut(usize, &PreparedInstance, &mut f32),
    ) {
        match &self.top {
            None => {
                let mut cull = cull;
                for (i, inst) in self.list.iter().enumerate() {
                    visit(i, inst, &mut cull);
                }
            }
            Some(top) => {
                let ro = (o - top.anchor).as_vec3();
                let rd = d.as_vec3();
                if !ro.is_finite() || !rd.is_finite() || rd == Vec3::ZERO {
                    // The top-level ray cannot be formed in f32: fall back to every instance.
                    let mut cull = cull;
                    for (i, inst) in self.list.iter().enumerate() {
                        visit(i, inst, &mut cull);
                    }
                    return;
                }
                top.accel.traverse(ro, rd, cull, &mut |i, _, cull| {
                    let i = i as usize;
                    visit(i, &self.list[i], cull);
                });
            }
        }
    }
}

impl Top {
    /// None when a box does not fit an f32 BVH (rays then visit every instance).
    fn build(list: &[PreparedInstance], backend: BackendKind) -> Option<Top> {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for i in list {
            lo = lo.min(i.lo);
            hi = hi.max(i.hi);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let anchor = (0.5 * (lo + hi)).as_vec3().as_dvec3();
        // The f32 ray (origin relative to the anchor, direction rounded) strays from the f64 one
        // by about 2⁻²⁴ of the distances involved, all within the scene's extent plus the
        // ray's origin offset: boxes are padded by 1e-5 of the scene's size and of their own
        // coordinates (a hundredfold margin over f32's 6e-8), so the top level never misses an
        // instance whose f64 bounds the ray enters. The f64 test then decides as before.
        let scene = (hi - lo).max_element().max(1e-30);
        let boxes: Vec<(Vec3, Vec3)> = list
            .iter()
            .map(|i| {
                let (a, b) = (i.lo - anchor, i.hi - anchor);
                let pad = 1e-5 * (scene + a.abs().max(b.abs()).max_element());
                ((a - pad).as_vec3(), (b + pad).as_vec3())
            })
            .collect();
        if !boxes.iter().all(|(a, b)| fits_bvh(*a) && fits_bvh(*b)) {
            return None;
        }
        let accel = build_boxes(backend, BuildPreset::Medium, &boxes).ok()?;
        Some(Top { anchor, accel })
    }
}

impl std::ops::Deref for Instances {
    type Target = [PreparedInstance];
    fn deref(&self) -> &[PreparedInstance] {
        &self.list
    }
}

impl IntoIterator for Instances {
    type Item = PreparedInstance;
    type IntoIter = std::vec::IntoIter<PreparedInstance>;
    fn into_iter(self) -> Self::IntoIter {
        self.list.into_iter()
    }
}

impl<'a> IntoIterator for &'a Instances {
    type Item = &'a PreparedInstance;
    type IntoIter = std::slice::Iter<'a, PreparedInstance>;
    fn into_iter(self) -> Self::IntoIter {
        self.list.iter()
    }
}
