//! The k-buffer: the k nearest hits of a ray beyond the last composited one, ordered by
//! (distance, Gaussian id, instance, group), shared by the mesh tracer (`composite`), the
//! Gaussian tracer (`gaussian`), secondary rays and LiDAR. Equal keys are one hit, so a
//! Gaussian's fan is counted once per ray and ties order by Gaussian id whatever the traversal
//! order.

use glam::Vec4;

/// A hit in the k-buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// World ray parameter (distance along the unit world direction).
    pub t: f32,
    pub gaussian: u32,
    pub instance: u32,
    pub group: u32,
    pub tri: u32,
    pub bary: [f32; 3],
    /// Mode mesh, when shaded during collection (see [`KBuffer::shade_on_insert`]): the hit's
    /// RGBA; unused otherwise.
    pub rgba: Vec4,
}

/// Sort key: distance, then Gaussian id, instance, group (t ≥ 0, so its bits order like it).
pub type Key = (u32, u32, u32, u32);

impl Hit {
    #[inline]
    pub fn key(&self) -> Key {
        (self.t.to_bits(), self.gaussian, self.instance, self.group)
    }
}

/// A small sorted buffer of the k smallest keys; equal keys are one hit (the lower triangle
/// index is kept, so the choice does not depend on traversal order).
pub struct KBuffer {
    pub k: usize,
    pub hits: Vec<Hit>,
    /// Candidates tested since the counter was last reset (statistics only).
    pub candidates: u32,
    /// Shade hits as they are found and keep only those with α > 0 (compositing; see
    /// `MeshTracer::trace`). Off for hit enumeration, which reports every crossing.
    pub shade_on_insert: bool,
}

impl KBuffer {
    pub fn new(k: usize) -> Self {
        KBuffer {
            k,
            hits: Vec::with_capacity(k + 1),
            candidates: 0,
            shade_on_insert: false,
        }
    }

    pub fn clear(&mut self) {
        self.hits.clear();
    }

    pub fn is_full(&self) -> bool {
        self.hits.len() >= self.k
    }

    /// Whether a hit with this key would be dropped by [`KBuffer::insert`] (the buffer is full
    /// and the key is not below its last one).
    #[inline]
    pub fn rejects(&self, key: Key) -> bool {
        self.is_full() && key >= self.hits[self.k - 1].key()
    }

    /// Insert; returns the cull distance to use afterwards (with a relative margin of 2⁻²⁰ so
    /// rounding in node tests never culls a hit at exactly the k-th distance).
    #[inline]
    pub fn insert(&mut self, h: Hit, tmax: f32) -> f32 {
        let key = h.key();
        if self.rejects(key) {
            return self.cull(tmax);
        }
        match self.hits.binary_search_by(|x| x.key().cmp(&key)) {
            Ok(i) => {
                if h.tri < self.hits[i].tri {
                    self.hits[i] = h;
                }
            }
            Err(i) => {
                self.hits.insert(i, h);
                self.hits.truncate(self.k);
            }
        }
        self.cull(tmax)
    }

    #[inline]
    pub fn cull(&self, tmax: f32) -> f32 {
        if self.is_full() {
            let t = self.hits[self.k - 1].t;
            (t + t * (1.0 / 1_048_576.0) + f32::MIN_POSITIVE).min(tmax)
        } else {
            tmax
        }
    }
}
