//! The k-buffer and the ordered-hit loop, generic over what a hit carries: the k nearest hits
//! of a ray beyond the last visited one, ordered by (distance, Gaussian id, instance, group),
//! and [`walk`], the one loop that refills the buffer round after round and visits the hits in
//! that order. The mesh tracer (`mesh_tracer`: triangle and barycentrics), the Gaussian
//! tracer (`gaussian`: Gaussian index and α), secondary rays and LiDAR all run on it.
//!
//! Equal keys are one hit: a Gaussian's fan is counted once per ray and ties order by Gaussian
//! id whatever the traversal order. Among equal keys the payload with the lower
//! [`Payload::rank`] is kept, except for the k-th key of a full buffer, which keeps the one
//! found first (a key not below the k-th is rejected before the buffer is searched; the
//! tracers' images depend on that rule, so it stays). Ordering by the full key means hits at
//! one distance are never lost or repeated across rounds, however many there are.

use std::ops::ControlFlow;

/// What a hit carries besides its key.
pub trait Payload: Copy {
    /// Among hits with equal keys, the one with the lower rank is kept (see the module
    /// documentation for the k-th key of a full buffer).
    fn rank(&self) -> u32;

    /// The opacity compositing will give the hit, when known at insertion (for
    /// [`KBuffer::stop`]); 0 never stops a ray.
    #[inline]
    fn opacity(&self) -> f32 {
        0.0
    }
}

/// A hit in the k-buffer.
///
/// `repr(C)` in this field order so that the key's two halves as [`packed`] forms them,
/// `t·2³² + gaussian` and `instance·2³² + group`, are each one little-endian 64-bit word
/// (`gaussian` then `t`, `group` then `instance`): the compiler then reads them with two
/// loads instead of assembling four fields with shifts at every probe of the buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Hit<P> {
    pub gaussian: u32,
    /// World ray parameter (distance along the unit world direction).
    pub t: f32,
    pub group: u32,
    pub instance: u32,
    pub payload: P,
}

/// Sort key: distance, then Gaussian id, instance, group (t ≥ 0, so its bits order like it).
pub type Key = (u32, u32, u32, u32);

impl<P> Hit<P> {
    #[inline]
    pub fn key(&self) -> Key {
        (self.t.to_bits(), self.gaussian, self.instance, self.group)
    }
}

/// A key as one integer that orders as the key does (lexicographically, field by field): two
/// 64-bit comparisons instead of a branch per field.
#[inline(always)]
fn packed(k: Key) -> u128 {
    (k.0 as u128) << 96 | (k.1 as u128) << 64 | (k.2 as u128) << 32 | k.3 as u128
}

/// A small sorted buffer of the k smallest keys; equal keys are one hit.
pub struct KBuffer<P> {
    pub k: usize,
    pub hits: Vec<Hit<P>>,
    /// Candidates tested since the counter was last reset (statistics only).
    pub candidates: u32,
    /// Shade hits as they are found and keep only those with α > 0 (mode mesh compositing;
    /// see `MeshTracer::trace`). Off for hit enumeration, which reports every crossing.
    pub shade_on_insert: bool,
    /// With `shade_on_insert`, shade a mesh hit's α and the factor its material and texture
    /// multiply the vertex α by, not its colour: the payload's RGBA is (factor, 0, 0, α)
    /// (`Mesh::shade_alpha`). Hit recording (`hit_record`) keeps the factor and composites
    /// no colour.
    pub record_alpha: bool,
    /// Compositing's stop, when the buffer feeds a compositing walk: the transmittance `T`
    /// before this round's hits and the threshold below which the ray stops. The first
    /// buffered hit (in key order) with `T·Π(1 − α) < threshold` is where both tracers stop
    /// (the Gaussian one without adding it, the mesh one after), so nothing keyed beyond it
    /// can change the pixel: the cull distance stops there too, with the same float
    /// operations the compositing does, so it stops at exactly the same hit. Without it, a
    /// ray through an opaque surface traversed the whole scene behind it until k hits were
    /// found. None for hit enumeration.
    pub stop: Option<(f32, f32)>,
    /// The key of that stopping hit among the buffered hits.
    stop_key: Option<Key>,
    /// The transmittance before each buffered hit up to the stopping one, for the `stop` it
    /// was computed with (`trs_for`): an insertion recomputes from its own position on, with
    /// the same products in the same order as a pass from the first hit.
    trs: Vec<f32>,
    trs_for: Option<(f32, f32)>,
}

impl<P: Payload> KBuffer<P> {
    pub fn new(k: usize) -> Self {
        KBuffer {
            k,
            hits: Vec::with_capacity(k + 1),
            candidates: 0,
            shade_on_insert: false,
            record_alpha: false,
            stop: None,
            stop_key: None,
            trs: Vec::new(),
            trs_for: None,
        }
    }

    /// A buffer that is never full: it keeps every hit up to [`KBuffer::stop`]'s (for a
    /// query that finds all of a ray's hits in one pass, `mesh_tiles`).
    pub fn unbounded() -> Self {
        KBuffer {
            k: usize::MAX,
            hits: Vec::new(),
            candidates: 0,
            shade_on_insert: false,
            record_alpha: false,
            stop: None,
            stop_key: None,
            trs: Vec::new(),
            trs_for: None,
        }
    }

    pub fn clear(&mut self) {
        self.hits.clear();
        self.stop_key = None;
        self.trs.clear();
        self.trs_for = None;
    }

    /// Recompute [`KBuffer::stop`]'s hit after the hit at `from` changed (inserted or
    /// replaced): the transmittances before it are unchanged, so the pass resumes there. The
    /// changed hit is never beyond the stopping one (such keys are rejected), so the
    /// transmittances it resumes from were computed.
    #[inline]
    fn update_stop(&mut self, from: usize) {
        let Some((t0, threshold)) = self.stop else {
            self.trs_for = None;
            return;
        };
        let mut from = from.min(self.hits.len());
        if self.trs_for != self.stop {
            self.trs_for = self.stop;
            from = 0;
        }
        self.trs.resize(self.hits.len(), 0.0);
        let mut tr = match from {
            0 => t0,
            i => self.trs[i - 1] * (1.0 - self.hits[i - 1].payload.opacity()),
        };
        self.stop_key = None;
        for (h, slot) in self.hits[from..].iter().zip(&mut self.trs[from..]) {
            *slot = tr;
            let a = h.payload.opacity();
            // `Accum::after`, then `Accum::add`: the same operations in the same order.
            if tr * (1.0 - a) < threshold {
                self.stop_key = Some(h.key());
                return;
            }
            tr *= 1.0 - a;
        }
    }

    pub fn is_full(&self) -> bool {
        self.hits.len() >= self.k
    }

    /// Whether a hit with this key would be dropped by [`KBuffer::insert`] (the buffer is full
    /// and the key is not below its last one).
    /// Also dropped: a key beyond the stopping hit of [`KBuffer::stop`].
    #[inline]
    pub fn rejects(&self, key: Key) -> bool {
        (self.is_full() && packed(key) >= packed(self.hits[self.k - 1].key()))
            || self.stop_key.is_some_and(|s| packed(key) > packed(s))
    }

    /// Whether inserting a hit with this key and rank would change nothing: the buffer holds
    /// the key already, with a rank no higher (the other winding of a double-sided export's
    /// triangle, or another triangle of its fan, found first). The caller can skip the work of
    /// building the hit.
    #[inline]
    pub fn holds(&self, key: Key, rank: u32) -> bool {
        self.holds_at(self.search(key), rank)
    }

    /// Where `key` is among the buffered hits (`Ok`: held; `Err`: where it would go), for
    /// [`KBuffer::holds_at`] and [`KBuffer::insert_at`] to share one search.
    #[inline]
    pub fn search(&self, key: Key) -> Result<usize, usize> {
        // Hits mostly arrive in key order (the tile lists are sorted by a bound of it): a key
        // beyond the last goes at the end, which is the binary search's answer too (keys are
        // unique in the buffer).
        let p = packed(key);
        match self.hits.last() {
            None => Err(0),
            Some(l) if packed(l.key()) < p => Err(self.hits.len()),
            Some(_) => self.hits.binary_search_by(|x| packed(x.key()).cmp(&p)),
        }
    }

    /// [`KBuffer::holds`] at the position [`KBuffer::search`] found.
    #[inline]
    pub fn holds_at(&self, pos: Result<usize, usize>, rank: u32) -> bool {
        pos.is_ok_and(|i| self.hits[i].payload.rank() <= rank)
    }

    /// Insert; returns the cull distance to use afterwards (with a relative margin of 2⁻²⁰ so
    /// rounding in node tests never culls a hit at exactly the k-th distance).
    #[inline]
    pub fn insert(&mut self, h: Hit<P>, tmax: f32) -> f32 {
        let key = h.key();
        if self.rejects(key) {
            return self.cull(tmax);
        }
        self.insert_at(h, self.search(key), tmax)
    }

    /// [`KBuffer::insert`] of a hit the buffer does not reject, at the position
    /// [`KBuffer::search`] found for its key in the buffer as it is.
    #[inline]
    pub fn insert_at(&mut self, h: Hit<P>, pos: Result<usize, usize>, tmax: f32) -> f32 {
        debug_assert!(!self.rejects(h.key()) && pos == self.search(h.key()));
        match pos {
            Ok(i) => {
                if h.payload.rank() < self.hits[i].payload.rank() {
                    self.hits[i] = h;
                    self.update_stop(i);
                } else if self.trs_for != self.stop {
                    // The stop was set since the last pass: one from the first hit.
                    self.update_stop(0);
                }
            }
            Err(i) => {
                self.hits.insert(i, h);
                if self.stop.is_some() {
                    self.trs.insert(i.min(self.trs.len()), 0.0);
                }
                self.hits.truncate(self.k);
                self.trs.truncate(self.k);
                self.update_stop(i);
            }
        }
        self.cull(tmax)
    }

    /// The distance beyond which no hit can enter: the k-th hit's of a full buffer, or the
    /// stopping hit's ([`KBuffer::stop`]), whichever is nearer.
    #[inline]
    pub fn cull(&self, tmax: f32) -> f32 {
        let margin = |t: f32| t + t * (1.0 / 1_048_576.0) + f32::MIN_POSITIVE;
        let mut c = tmax;
        if self.is_full() {
            c = c.min(margin(self.hits[self.k - 1].t));
        }
        if let Some(k) = self.stop_key {
            c = c.min(margin(f32::from_bits(k.0)));
        }
        c
    }
}

/// The ordered-hit loop: `collect(after, buf)` fills `buf` with the k smallest-key hits with
/// key > `after` (None: from the start); `visit` sees them in key order and breaks to stop.
/// A round that leaves the buffer short of full was the last. Returns the number of rounds
/// (traversals) and the break value, if any.
pub fn walk<P: Payload, R>(
    buf: &mut KBuffer<P>,
    mut collect: impl FnMut(Option<Key>, &mut KBuffer<P>),
    mut visit: impl FnMut(&Hit<P>) -> ControlFlow<R>,
) -> (u32, Option<R>) {
    let mut after = None;
    let mut rounds = 0u32;
    loop {
        collect(after, buf);
        rounds += 1;
        for h in &buf.hits {
            if let ControlFlow::Break(r) = visit(h) {
                return (rounds, Some(r));
            }
        }
        if !buf.is_full() {
            return (rounds, None);
        }
        after = buf.hits.last().map(Hit::key);
    }
}

/// Every hit in key order: [`walk`] without a stop.
pub fn all_hits<P: Payload>(
    k: usize,
    collect: impl FnMut(Option<Key>, &mut KBuffer<P>),
) -> Vec<Hit<P>> {
    let mut out = Vec::new();
    let mut buf = KBuffer::new(k.max(1));
    walk::<P, ()>(&mut buf, collect, |h| {
        out.push(*h);
        ControlFlow::Continue(())
    });
    out
}

/// Define `fn NAME<T>(k, f: impl FnOnce(&mut KBuffer<P>) -> T) -> T`, which lends `f` a
/// thread-local k-buffer of capacity `k` for payload `P` (a buffer per payload type, reused
/// by every ray a render thread traces).
macro_rules! thread_buffer {
    ($vis:vis fn $name:ident, $p:ty) => {
        $vis fn $name<T>(k: usize, f: impl FnOnce(&mut $crate::kbuffer::KBuffer<$p>) -> T) -> T {
            thread_local! {
                static BUF: std::cell::RefCell<$crate::kbuffer::KBuffer<$p>> =
                    std::cell::RefCell::new($crate::kbuffer::KBuffer::new(16));
            }
            BUF.with(|b| {
                let mut b = b.borrow_mut();
                if b.k != k {
                    *b = $crate::kbuffer::KBuffer::new(k);
                }
                f(&mut b)
            })
        }
    };
}
pub(crate) use thread_buffer;

/// Front-to-back compositing state of one ray: colour, transmittance and the weighted depth
/// sum. Both tracers add a hit with the same operations in the same order, so they share it.
#[derive(Clone, Copy, Debug)]
pub struct Accum {
    pub rgb: glam::Vec3,
    pub tr: f32,
    pub dsum: f32,
    pub wsum: f32,
}

impl Default for Accum {
    fn default() -> Self {
        Accum {
            rgb: glam::Vec3::ZERO,
            tr: 1.0,
            dsum: 0.0,
            wsum: 0.0,
        }
    }
}

impl Accum {
    /// Blend `rgb` with opacity `a` at distance `t` behind what is there.
    #[inline]
    pub fn add(&mut self, rgb: glam::Vec3, a: f32, t: f32) {
        let w = a * self.tr;
        self.rgb += rgb * w;
        self.dsum += w * t;
        self.wsum += w;
        self.tr *= 1.0 - a;
    }

    /// The transmittance after blending a hit of opacity `a`.
    #[inline]
    pub fn after(&self, a: f32) -> f32 {
        self.tr * (1.0 - a)
    }

    /// The weighted mean distance (0 when nothing was blended).
    pub fn depth(&self) -> f32 {
        if self.wsum > 0.0 {
            self.dsum / self.wsum
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Copy, Debug, PartialEq)]
    struct Tag(u32);

    impl Payload for Tag {
        fn rank(&self) -> u32 {
            self.0
        }
    }

    /// A tiny deterministic generator (xorshift), so the test needs no dependency.
    fn rng(seed: &mut u64) -> u32 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 32) as u32
    }

    /// Hits with many exact ties in distance, Gaussian and group, and duplicates of one key
    /// with different ranks (a fan's triangles), in a random traversal order.
    fn random_hits(seed: &mut u64, n: usize) -> Vec<Hit<Tag>> {
        (0..n)
            .map(|_| Hit {
                t: (rng(seed) % 8) as f32 * 0.25,
                gaussian: rng(seed) % 5,
                instance: rng(seed) % 2,
                group: rng(seed) % 2,
                payload: Tag(rng(seed) % 1000),
            })
            .collect()
    }

    /// The slow reference: sort all hits by key, keep the lowest rank of each key.
    fn reference(hits: &[Hit<Tag>]) -> Vec<Hit<Tag>> {
        let mut v = hits.to_vec();
        v.sort_by_key(|h| (h.key(), h.payload.rank()));
        v.dedup_by_key(|h| h.key());
        v
    }

    /// `got` is the reference's key sequence, and each hit's payload is one that was found
    /// with its key: the lowest rank, or (at the k-th key of a full buffer) another one.
    fn assert_same_hits(got: &[Hit<Tag>], want: &[Hit<Tag>], all: &[Hit<Tag>], what: &str) {
        let keys = |v: &[Hit<Tag>]| v.iter().map(Hit::key).collect::<Vec<_>>();
        assert_eq!(keys(got), keys(want), "{what}");
        for h in got {
            assert!(all.contains(h), "{what}: {h:?} was never found");
        }
    }

    /// What a tracer's `collect` does: every candidate after `after`, inserted in traversal
    /// order.
    fn collect_from(hits: &[Hit<Tag>]) -> impl FnMut(Option<Key>, &mut KBuffer<Tag>) + '_ {
        move |after, buf| {
            buf.clear();
            for h in hits {
                if after.is_some_and(|a| h.key() <= a) || buf.rejects(h.key()) {
                    continue;
                }
                buf.insert(*h, f32::INFINITY);
            }
        }
    }

    #[test]
    fn walk_matches_sorting_all_hits() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for round in 0..200 {
            let n = (rng(&mut seed) % 60) as usize;
            let hits = random_hits(&mut seed, n);
            let want = reference(&hits);
            for k in [1, 2, 3, 7, 16, 64] {
                let got = all_hits(k, collect_from(&hits));
                assert_same_hits(&got, &want, &hits, &format!("round {round}, k {k}"));
                if k >= n {
                    // Everything fits in one round: each key keeps its lowest rank.
                    assert_eq!(got, want, "round {round}, k {k}");
                }
            }
        }
    }

    #[test]
    fn composite_matches_front_to_back_reference() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for round in 0..100 {
            let n = (rng(&mut seed) % 40) as usize;
            let hits = random_hits(&mut seed, n);
            // Opacity and colour follow the key (as a fan's shading does across its triangles).
            let alpha =
                |h: &Hit<Tag>| ((h.gaussian * 7 + h.group * 3 + h.instance) % 10) as f32 / 10.0;
            let colour = |h: &Hit<Tag>| glam::Vec3::new(h.t, h.gaussian as f32 * 0.1, 0.5);
            // Reference: sort everything, blend front to back, stop below T = 1e-4.
            let mut want = Accum::default();
            for h in reference(&hits) {
                want.add(colour(&h), alpha(&h), h.t);
                if want.tr < 1e-4 {
                    break;
                }
            }
            for k in [1, 3, 16] {
                let mut buf = KBuffer::new(k);
                let mut got = Accum::default();
                walk(&mut buf, collect_from(&hits), |h| {
                    got.add(colour(h), alpha(h), h.t);
                    if got.tr < 1e-4 {
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                });
                // Same hits in the same order through the same operations: equal bits.
                assert_eq!(
                    got.rgb.to_array(),
                    want.rgb.to_array(),
                    "round {round}, k {k}"
                );
                assert_eq!(got.tr.to_bits(), want.tr.to_bits(), "round {round}, k {k}");
                assert_eq!(got.depth().to_bits(), want.depth().to_bits());
            }
        }
    }

    /// A payload that knows its opacity, for the compositing stop.
    #[derive(Clone, Copy, Debug, PartialEq)]
    struct Opaque(u32, f32);

    impl Payload for Opaque {
        fn rank(&self) -> u32 {
            self.0
        }
        fn opacity(&self) -> f32 {
            self.1
        }
    }

    /// The compositing stop (`KBuffer::stop`) set per round as the tracers set it: the same
    /// composite, bit for bit, as blending every hit sorted (native's rule: the hit that would
    /// take T below the threshold stops the ray unblended), and fewer hits inserted.
    #[test]
    fn stop_keeps_the_composite() {
        let mut seed = 0x51ed_270b_a1c4_e3f5u64;
        let mut stopped_early = 0;
        for round in 0..300 {
            let n = (rng(&mut seed) % 80) as usize;
            let hits: Vec<Hit<Opaque>> = random_hits(&mut seed, n)
                .into_iter()
                .map(|h| {
                    // Opacity follows the key, as a Gaussian's α does along one ray.
                    let a = [0.0, 0.3, 0.6, 0.9, 0.99][((h.gaussian + h.group) % 5) as usize];
                    Hit {
                        t: h.t,
                        gaussian: h.gaussian,
                        instance: h.instance,
                        group: h.group,
                        payload: Opaque(h.payload.0, a),
                    }
                })
                .collect();
            let mut sorted = hits.clone();
            sorted.sort_by_key(|h| (h.key(), h.payload.rank()));
            sorted.dedup_by_key(|h| h.key());
            let threshold = 1e-4;
            let mut want = Accum::default();
            for h in &sorted {
                if want.after(h.payload.1) < threshold {
                    break;
                }
                want.add(glam::Vec3::splat(h.t), h.payload.1, h.t);
            }
            for k in [1, 3, 16] {
                for stop in [false, true] {
                    let mut buf = KBuffer::new(k);
                    let mut got = Accum::default();
                    let tr = std::cell::Cell::new(1.0f32);
                    let mut inserted = 0;
                    walk(
                        &mut buf,
                        |after, buf| {
                            buf.stop = stop.then_some((tr.get(), threshold));
                            buf.clear();
                            for h in &hits {
                                if after.is_some_and(|a| h.key() <= a) || buf.rejects(h.key()) {
                                    continue;
                                }
                                inserted += 1;
                                buf.insert(*h, f32::INFINITY);
                            }
                        },
                        |h| {
                            if got.after(h.payload.1) < threshold {
                                return ControlFlow::Break(());
                            }
                            got.add(glam::Vec3::splat(h.t), h.payload.1, h.t);
                            tr.set(got.tr);
                            ControlFlow::Continue(())
                        },
                    );
                    let what = format!("round {round}, k {k}, stop {stop}");
                    assert_eq!(got.rgb.to_array(), want.rgb.to_array(), "{what}");
                    assert_eq!(got.tr.to_bits(), want.tr.to_bits(), "{what}");
                    if stop && k == 16 && inserted < hits.len() {
                        stopped_early += 1;
                    }
                }
            }
        }
        assert!(
            stopped_early > 50,
            "the stop never cut a collection ({stopped_early})"
        );
    }

    /// The stopping hit recomputed from the first buffered hit (what [`KBuffer::stop`]'s hit
    /// is defined as), against the buffer's resumed pass, after every insertion: random hits
    /// with equal keys whose lower rank carries another opacity (a replaced hit), bounded and
    /// unbounded buffers, a stop set before or after the first insertion.
    #[test]
    fn resumed_stop_equals_a_pass_from_the_first_hit() {
        let from_scratch = |buf: &KBuffer<Opaque>| {
            let (mut tr, threshold) = buf.stop?;
            for h in &buf.hits {
                if tr * (1.0 - h.payload.1) < threshold {
                    return Some(h.key());
                }
                tr *= 1.0 - h.payload.1;
            }
            None
        };
        let mut seed = 0x0dd1_b1a5_e5c3_7f21_u64;
        let mut stops = 0;
        for round in 0..400 {
            let n = (rng(&mut seed) % 60) as usize;
            let alphas = [0.0, 0.2, 0.5, 0.8, 0.95, 1.0];
            let hits: Vec<Hit<Opaque>> = random_hits(&mut seed, n)
                .into_iter()
                .map(|h| Hit {
                    t: h.t,
                    gaussian: h.gaussian,
                    instance: h.instance,
                    group: h.group,
                    payload: Opaque(h.payload.0, alphas[(h.payload.0 % 6) as usize]),
                })
                .collect();
            let k = [4, 16, usize::MAX][round % 3];
            let mut buf = if k == usize::MAX {
                KBuffer::unbounded()
            } else {
                KBuffer::new(k)
            };
            let t0 = [1.0, 0.5, 0.01][(round / 3) % 3];
            let late = round % 2 == 0;
            if !late {
                buf.stop = Some((t0, 1e-2));
            }
            for (i, h) in hits.iter().enumerate() {
                if late && i == n / 2 {
                    buf.stop = Some((t0, 1e-2));
                }
                // A rejected hit changes nothing (not even a stop set since the last
                // insertion, as before the pass resumed).
                if buf.rejects(h.key()) {
                    continue;
                }
                buf.insert(*h, f32::INFINITY);
                assert_eq!(buf.stop_key, from_scratch(&buf), "round {round}, hit {i}");
                stops += buf.stop_key.is_some() as usize;
            }
        }
        assert!(stops > 1000, "the stop was rarely set ({stops})");
    }

    #[test]
    fn holds_reports_keys_already_kept() {
        let mut buf = KBuffer::<Tag>::new(4);
        let hit = |t: f32, r: u32| Hit {
            t,
            gaussian: 0,
            instance: 0,
            group: 0,
            payload: Tag(r),
        };
        buf.insert(hit(1.0, 5), 10.0);
        assert!(buf.holds(hit(1.0, 0).key(), 5));
        assert!(buf.holds(hit(1.0, 0).key(), 9));
        assert!(!buf.holds(hit(1.0, 0).key(), 4), "a lower rank replaces it");
        assert!(!buf.holds(hit(2.0, 0).key(), 9));
    }

    #[test]
    fn rejects_and_cull_follow_the_kth_hit() {
        let mut buf = KBuffer::<Tag>::new(2);
        let hit = |t: f32, g: u32| Hit {
            t,
            gaussian: g,
            instance: 0,
            group: 0,
            payload: Tag(0),
        };
        assert_eq!(buf.insert(hit(2.0, 0), 10.0), 10.0);
        let cull = buf.insert(hit(1.0, 0), 10.0);
        // Full: the cull is the k-th distance plus its 2⁻²⁰ relative margin.
        assert!(cull > 2.0 && cull < 2.0 + 1e-5, "{cull}");
        assert!(buf.rejects(hit(2.0, 0).key()));
        assert!(buf.rejects(hit(3.0, 0).key()));
        assert!(!buf.rejects(hit(1.5, 0).key()));
    }

    /// [`KBuffer::search`]'s shortcut for a key beyond the last gives the binary search's
    /// answer: on buffers grown from random hits with ties, for keys below, among, equal to
    /// and beyond the buffered ones, and on the empty buffer.
    #[test]
    fn search_equals_the_binary_search() {
        let mut seed = 0x5eed_u64;
        let mut beyond = 0;
        for round in 0..200 {
            let mut buf = KBuffer::<Tag>::unbounded();
            for h in random_hits(&mut seed, round % 40) {
                buf.insert(h, f32::INFINITY);
            }
            for q in random_hits(&mut seed, 30) {
                let key = q.key();
                let want = buf.hits.binary_search_by(|x| x.key().cmp(&key));
                assert_eq!(buf.search(key), want, "{key:?}");
                beyond += (want == Err(buf.hits.len())) as u32;
            }
        }
        assert!(beyond > 100, "{beyond}");
    }

    /// [`packed`] orders keys as the tuples do, field by field, at the fields' extremes.
    #[test]
    fn packed_keys_order_as_the_tuples() {
        let vals = [0u32, 1, 2, 0x7fff_ffff, 0x8000_0000, u32::MAX - 1, u32::MAX];
        let keys: Vec<Key> = (0..7usize.pow(4))
            .map(|i| {
                (
                    vals[i % 7],
                    vals[i / 7 % 7],
                    vals[i / 49 % 7],
                    vals[i / 343],
                )
            })
            .collect();
        for a in &keys {
            for b in keys.iter().step_by(5) {
                assert_eq!(packed(*a).cmp(&packed(*b)), a.cmp(b), "{a:?} {b:?}");
            }
        }
    }
}
