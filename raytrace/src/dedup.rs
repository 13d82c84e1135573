//! Building over many bit-identical primitive boxes (thousands of copies of one triangle, or of
//! one Gaussian). obvhs's PLOC builder pairs each cluster with its cheapest neighbour and merges
//! only mutual pairs; when all costs tie, each cluster picks the same side and one pair merges
//! per pass, so the build is quadratic (20 000 copies of one triangle took minutes). Copies are
//! therefore folded: the structure is built over the distinct boxes, and each visit of a
//! distinct box visits every primitive that has it, in index order. The hit set is unchanged
//! (every primitive whose box the ray enters is still visited; the caller's exact test decides).

use glam::Vec3;

use crate::backend::Accel;
use crate::error::Result;

/// Fold copies only when one box is shared by more primitives than this: below it PLOC's
/// passes stay short, and real meshes (a few duplicated faces) keep their one-level structure.
pub const FOLD_THRESHOLD: usize = 64;

fn key(b: &(Vec3, Vec3)) -> [u32; 6] {
    let (lo, hi) = b;
    [
        lo.x.to_bits(),
        lo.y.to_bits(),
        lo.z.to_bits(),
        hi.x.to_bits(),
        hi.y.to_bits(),
        hi.z.to_bits(),
    ]
}

/// An axis-aligned box (min, max).
pub type Bounds = (Vec3, Vec3);

/// Distinct boxes and, per distinct box, the primitives that have it (ascending), when some box
/// is shared by more than [`FOLD_THRESHOLD`] primitives; `None` otherwise.
pub fn fold(boxes: &[Bounds]) -> Option<(Vec<Bounds>, Vec<Vec<u32>>)> {
    if boxes.len() <= FOLD_THRESHOLD {
        return None;
    }
    let mut order: Vec<u32> = (0..boxes.len() as u32).collect();
    order.sort_by_key(|&i| (key(&boxes[i as usize]), i));
    let mut largest = 0;
    let mut run = 0;
    for w in 0..order.len() {
        run = if w > 0 && key(&boxes[order[w] as usize]) == key(&boxes[order[w - 1] as usize]) {
            run + 1
        } else {
            1
        };
        largest = largest.max(run);
    }
    if largest <= FOLD_THRESHOLD {
        return None;
    }
    let mut distinct: Vec<(Vec3, Vec3)> = Vec::new();
    let mut members: Vec<Vec<u32>> = Vec::new();
    for (w, &i) in order.iter().enumerate() {
        if w == 0 || key(&boxes[i as usize]) != key(&boxes[order[w - 1] as usize]) {
            distinct.push(boxes[i as usize]);
            members.push(Vec::new());
        }
        if let Some(m) = members.last_mut() {
            m.push(i);
        }
    }
    Some((distinct, members))
}

/// A structure over distinct boxes that visits every primitive of a visited box.
pub struct FoldedAccel {
    inner: Box<dyn Accel>,
    members: Vec<Vec<u32>>,
}

impl FoldedAccel {
    /// Wrap a structure built over `fold`'s distinct boxes.
    pub fn new(inner: Box<dyn Accel>, members: Vec<Vec<u32>>) -> Self {
        FoldedAccel { inner, members }
    }

    /// Build with `build` over the distinct boxes when [`fold`] folds, else `None`.
    pub fn build(
        boxes: &[(Vec3, Vec3)],
        build: impl FnOnce(&[(Vec3, Vec3)]) -> Result<Box<dyn Accel>>,
    ) -> Result<Option<Box<dyn Accel>>> {
        match fold(boxes) {
            Some((distinct, members)) => {
                Ok(Some(Box::new(FoldedAccel::new(build(&distinct)?, members))))
            }
            None => Ok(None),
        }
    }
}

impl Accel for FoldedAccel {
    fn traverse(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        self.inner.traverse(origin, dir, tmax, &mut |u, _, cull| {
            for &p in &self.members[u as usize] {
                visit(p, false, cull);
            }
        });
    }
}

/// The bounds of each triangle.
pub fn triangle_boxes(verts: &[Vec3], tris: &[[u32; 3]]) -> Vec<(Vec3, Vec3)> {
    tris.iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| verts[i as usize]);
            (a.min(b).min(c), a.max(b).max(c))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fold_groups_copies_and_keeps_index_order() {
        let a = (Vec3::ZERO, Vec3::ONE);
        let b = (Vec3::ONE, Vec3::splat(2.0));
        let mut boxes = vec![a; FOLD_THRESHOLD + 5];
        boxes.insert(3, b);
        let (distinct, members) = fold(&boxes).expect("folds");
        assert_eq!(distinct.len(), 2);
        let total: usize = members.iter().map(Vec::len).sum();
        assert_eq!(total, boxes.len());
        for (d, m) in distinct.iter().zip(&members) {
            assert!(m.windows(2).all(|w| w[0] < w[1]));
            assert!(m.iter().all(|&i| key(&boxes[i as usize]) == key(d)));
        }
    }

    /// The folded structure against the obvious reference (the primitives whose boxes the ray
    /// enters, by brute force): a ray aimed through the middle of a box visits every primitive
    /// with that box, each once. The unfolded obvhs build is no reference here: on 500 equal
    /// boxes its tree is deeper than obvhs's 32-entry traversal stack (its own debug validation
    /// fails), which is what folding is for.
    #[test]
    fn folded_build_visits_every_copy_like_the_plain_build() {
        use crate::backend::{build_boxes, BackendKind, BuildPreset};
        let mut boxes = Vec::new();
        for i in 0..5u32 {
            let lo = Vec3::new(i as f32 * 3.0, 0.0, 0.0);
            let copies = if i == 2 { 500 } else { 3 };
            boxes.extend(std::iter::repeat_n((lo, lo + Vec3::ONE), copies));
        }
        assert!(fold(&boxes).is_some());
        let folded = build_boxes(BackendKind::Obvhs, BuildPreset::Medium, &boxes).unwrap();
        for i in 0..5 {
            let origin = Vec3::new(i as f32 * 3.0 + 0.5, 0.5, -10.0);
            let mut a = Vec::new();
            folded.traverse(origin, Vec3::Z, 100.0, &mut |p, _, _| a.push(p));
            a.sort_unstable();
            let want: Vec<u32> = (0..boxes.len() as u32)
                .filter(|&p| boxes[p as usize].0.x == i as f32 * 3.0)
                .collect();
            // A backend visits at least the primitives whose boxes the ray enters (leaves may
            // add neighbours), each once.
            assert!(a.windows(2).all(|w| w[0] < w[1]), "ray {i}: repeats");
            assert!(want.iter().all(|p| a.binary_search(p).is_ok()), "ray {i}");
        }
    }

    #[test]
    fn few_copies_are_not_folded() {
        let boxes = vec![(Vec3::ZERO, Vec3::ONE); FOLD_THRESHOLD];
        assert!(fold(&boxes).is_none());
        let mut more = boxes.clone();
        more.push((Vec3::ZERO, Vec3::ONE));
        assert!(fold(&more).is_some());
    }
}
