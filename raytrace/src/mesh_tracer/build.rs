//! Building a mode-mesh scene's BVHs: one per mesh over runs of a Gaussian's consecutive
//! triangles (obvhs) or over single triangles (the backend's own triangle test), each
//! relative to an anchor, with the mesh's planar groups and their planes. An obvhs BVH over
//! runs is left for the first frame that traces ray by ray ([`MeshTracer::accel`]); frames
//! through the screen tiles never read it (`docs/trace-speed-groups.md`, "What a mesh costs
//! before its first ray").

use std::sync::OnceLock;
use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{run_length, Blas, GroupIds, MeshTracer, PreparedInstance};
use crate::backend::{build_boxes, build_triangles, check_boxes, Accel, BackendKind, BuildPreset};
use crate::error::Result;
use crate::model::{Mesh, TriScene};

/// Where each run of triangles starts (and, last, the triangle count): at most `per_box`
/// consecutive triangles of one Gaussian (`tri_gaussian`). Runs never cross Gaussians:
/// exports list Gaussians in no spatial order, and a box spanning two far-apart Gaussians
/// would be entered by most rays.
fn run_starts(tri_gaussian: &[u32], count: usize, per_box: usize) -> Vec<u32> {
    let mut starts = Vec::with_capacity(count / per_box + 1);
    let mut start = 0;
    for t in 0..count {
        let other = t > 0 && tri_gaussian.get(t) != tri_gaussian.get(t - 1);
        if t == 0 || t - start == per_box || other {
            starts.push(t as u32);
            start = t;
        }
    }
    starts.push(count as u32);
    starts
}

/// The runs' boxes (`starts` from [`run_starts`]).
fn run_boxes(
    vertices: usize,
    rel: &dyn Fn(u32) -> Vec3,
    tris: &[[u32; 3]],
    starts: &[u32],
) -> Result<Vec<(Vec3, Vec3)>> {
    if let Some(t) = tris
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= vertices))
    {
        return Err(crate::error::TraceError::Invalid(format!(
            "triangle {t} indexes past {vertices} vertices"
        )));
    }
    Ok(starts
        .windows(2)
        .map(|w| {
            let run = &tris[w[0] as usize..w[1] as usize];
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for t in run {
                for &i in t {
                    let v = rel(i);
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            (lo, hi)
        })
        .collect())
}

impl MeshTracer {
    /// Build per-mesh BVHs with `backend`: obvhs over runs of [`run_length`] triangles, other
    /// backends over single triangles.
    pub fn new(scene: TriScene, backend: BackendKind, preset: BuildPreset) -> Result<Self> {
        if backend != BackendKind::Obvhs {
            return Self::with_boxes(scene, backend, preset, None);
        }
        Self::with_runs(scene, backend, preset, &run_length)
    }

    /// Build per-mesh BVHs with `backend` over boxes of `per_box` consecutive triangles, or,
    /// with `None`, over the triangles themselves (the backend's own triangle test reports
    /// hits). The hit set and the images do not depend on the choice; only memory and speed do.
    pub fn with_boxes(
        scene: TriScene,
        backend: BackendKind,
        preset: BuildPreset,
        per_box: Option<usize>,
    ) -> Result<Self> {
        match per_box {
            Some(n) => Self::with_runs(scene, backend, preset, &|_| n),
            None => Self::build(scene, backend, preset, None),
        }
    }

    /// Build over runs whose length `per_box(triangles of the mesh)` chooses for each mesh.
    pub fn with_runs(
        scene: TriScene,
        backend: BackendKind,
        preset: BuildPreset,
        per_box: &dyn Fn(usize) -> usize,
    ) -> Result<Self> {
        Self::build(scene, backend, preset, Some(per_box))
    }

    fn build(
        scene: TriScene,
        backend: BackendKind,
        preset: BuildPreset,
        runs: Option<&dyn Fn(usize) -> usize>,
    ) -> Result<Self> {
        let start = Instant::now();
        let per_boxes: Vec<Option<usize>> = scene
            .meshes
            .iter()
            .map(|m| runs.map(|f| f(m.tris.len()).max(1)))
            .collect();
        // obvhs builds the meshes side by side (a viewer layout has hundreds of small meshes,
        // each built on one thread); Embree's builds are threaded within each scene, so its
        // meshes go one after the other. Errors are reported in mesh order either way.
        let one =
            |(m, &per_box): (&Mesh, &Option<usize>)| Self::build_blas(m, backend, preset, per_box);
        let built: Vec<Result<Blas>> = match backend {
            BackendKind::Obvhs => scene
                .meshes
                .par_iter()
                .zip(per_boxes.par_iter())
                .map(one)
                .collect(),
            BackendKind::Embree => scene.meshes.iter().zip(&per_boxes).map(one).collect(),
        };
        let blas = built.into_iter().collect::<Result<Vec<Blas>>>()?;
        Ok(MeshTracer {
            scene,
            blas,
            backend,
            preset,
            per_box: per_boxes,
            build_seconds: start.elapsed().as_secs_f64(),
            deferred_build_nanos: Default::default(),
        })
    }

    /// Pose the scene at `t` for the next renders: the meshes morph weights move are posed
    /// (`TriScene::pose_morphs`) and their BVHs rebuilt (the rebuild time is added to
    /// `build_seconds`). A scene without morph targets is unchanged: its animation is
    /// instancing, taken per render.
    pub fn set_time(&mut self, t: f64) -> Result<()> {
        if self.scene.morphs.is_empty() {
            return Ok(());
        }
        let start = Instant::now();
        for m in self.scene.pose_morphs(t)? {
            self.blas[m] = Self::build_blas(
                &self.scene.meshes[m],
                self.backend,
                self.preset,
                self.per_box[m],
            )?;
        }
        self.build_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// One mesh's BVH over runs of `per_box` triangles (`None`: single triangles).
    fn build_blas(
        m: &Mesh,
        backend: BackendKind,
        preset: BuildPreset,
        per_box: Option<usize>,
    ) -> Result<Blas> {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let finite = m.positions.iter().all(|p| p.is_finite());
        for p in &m.positions {
            lo = lo.min(p.as_dvec3());
            hi = hi.max(p.as_dvec3());
        }
        if m.positions.is_empty() {
            (lo, hi) = (DVec3::ZERO, DVec3::ZERO);
        }
        // An f32-representable anchor keeps `p − anchor` as exact as f32 allows.
        let anchor = (0.5 * (lo + hi)).as_vec3().as_dvec3();
        // Vertices relative to the anchor are computed where they are used (as the hit
        // test does, `Blas::relative`); only the single-triangle structure keeps a copy.
        let rel_of = |i: u32| (m.positions[i as usize].as_dvec3() - anchor).as_vec3();
        let (group, ngroups) = m.planar_groups();
        // Each group's plane from its largest triangle (best conditioned normal).
        let mut best = vec![(0.0f64, (DVec3::ZERO, 0.0)); ngroups as usize];
        for (t, tri) in m.tris.iter().enumerate() {
            let [a, b, c] = tri.map(|i| rel_of(i).as_dvec3());
            let n = (b - a).cross(c - a);
            let area = n.length();
            let g = group[t] as usize;
            if area > best[g].0 {
                let n = n / area;
                best[g] = (area, (n, n.dot(a)));
            }
        }
        let planes = best.into_iter().map(|(_, p)| p).collect();
        let run_start = match per_box {
            Some(n) => run_starts(&m.tri_gaussian, m.tris.len(), n),
            None => Vec::new(),
        };
        let accel = OnceLock::new();
        let group = match per_box {
            Some(_) => {
                let boxes = run_boxes(m.positions.len(), &rel_of, &m.tris, &run_start)?;
                // Compacted before the build, whose scratch is the stage's peak.
                let group = GroupIds::over_runs(group, &run_start);
                if backend == BackendKind::Obvhs {
                    // Checked now, built on first use (`MeshTracer::accel`) from the same
                    // boxes, made again then (a pass over the triangles, not kept meanwhile).
                    check_boxes(&boxes)?;
                } else {
                    let _ = accel.set(build_boxes(backend, preset, &boxes)?);
                }
                group
            }
            None => {
                let rel: Vec<Vec3> = (0..m.positions.len() as u32).map(rel_of).collect();
                let _ = accel.set(build_triangles(backend, preset, &rel, &m.tris)?);
                GroupIds::Full(group)
            }
        };
        let prims = m.tris.len();
        let (mut slot_verts, mut slot_tri, mut slot_group) = (Vec::new(), Vec::new(), Vec::new());
        if per_box.is_none() {
            let accel = accel.get().map(|a| a.as_ref());
            slot_tri = match accel.and_then(|a| a.slots()) {
                Some(s) => s.to_vec(),
                None => (0..prims as u32).collect(),
            };
            slot_verts = slot_tri
                .iter()
                .map(|&t| m.tris[t as usize].map(rel_of))
                .collect();
            slot_group = slot_tri.iter().map(|&t| group.get(0, t as usize)).collect();
        }
        // Over single triangles the slots carry their groups.
        let group = if per_box.is_some() {
            group
        } else {
            GroupIds::Full(Vec::new())
        };
        Ok(Blas {
            anchor,
            planes,
            lo,
            hi,
            finite,
            accel,
            slot_verts,
            slot_tri,
            slot_group,
            run_start,
            group,
            mirror: std::sync::OnceLock::new(),
            group_extent: std::sync::OnceLock::new(),
            groups: std::sync::OnceLock::new(),
            records: std::sync::OnceLock::new(),
        })
    }

    /// Mesh `mesh`'s BVH, built here if it was left for its first use (an obvhs BVH over
    /// runs). Nothing inside the build runs on other threads, so a thread waiting for it
    /// never holds work it needs.
    pub fn accel(&self, mesh: usize) -> &dyn Accel {
        let (blas, m) = (&self.blas[mesh], &self.scene.meshes[mesh]);
        blas.accel
            .get_or_init(|| {
                let start = Instant::now();
                let rel = |i: u32| blas.relative(m.positions[i as usize]);
                // `build_blas` made these boxes and refused any an f32 BVH cannot hold (the
                // only way an obvhs build fails) before leaving the build for later.
                let accel = run_boxes(m.positions.len(), &rel, &m.tris, &blas.run_start)
                    .and_then(|boxes| build_boxes(BackendKind::Obvhs, self.preset, &boxes))
                    .unwrap_or_else(|e| unreachable!("the run boxes were checked: {e}"));
                let nanos = start.elapsed().as_nanos().min(u64::MAX as u128) as u64;
                self.deferred_build_nanos
                    .fetch_add(nanos, std::sync::atomic::Ordering::Relaxed);
                accel
            })
            .as_ref()
    }

    /// Seconds spent building BVHs: at load ([`MeshTracer::build_seconds`]) and on first use
    /// since (summed over the threads that built them).
    pub fn total_build_seconds(&self) -> f64 {
        let deferred = self
            .deferred_build_nanos
            .load(std::sync::atomic::Ordering::Relaxed);
        self.build_seconds + deferred as f64 * 1e-9
    }

    /// The BVHs of `insts`' meshes left for their first use, built side by side (each build
    /// is serial within), before any ray reads them.
    pub(super) fn build_deferred(&self, insts: &[PreparedInstance]) {
        insts.par_iter().for_each(|i| {
            self.accel(i.mesh);
        });
    }
}
