//! A spinning LiDAR ray-cast through the scene (the manifest's `effects.lidar`): the seeds'
//! LiDAR prior made a sensor, for mesh scenes and for the Gaussians themselves.
//!
//! Sensor frame: like a camera (x right, y down, z forward); the head spins about its local −y
//! (up). A beam at elevation `e` (positive up) and azimuth `a` (0 = local +z, increasing towards
//! +x) has local direction `(cos e·sin a, −sin e, cos e·cos a)`. `channels` beams are spread
//! evenly over `vertical_fov_deg` (inclusive ends; one channel sits at the middle). A `pose`
//! mount maps local to world with its rotation (w, x, y, z) and position; a `camera` mount
//! uses that camera's pose (so the identity pose in a y-down world spins about world up).
//!
//! One frame is one revolution: azimuth step `j` of `azimuth_steps` fires at
//! `t_j = t + j/(rotation_hz·azimuth_steps)` with azimuth `2π·(rotation_hz·t + j/steps)`, so the
//! head keeps turning continuously from frame to frame and every point carries its own
//! timestamp. The geometry is the scene at the frame time `t` (frozen for the sweep).
//!
//! Return: hits are taken front to back in the tracer's order; the first hit at which the
//! accumulated opacity `1 − Π(1 − αᵢ)` reaches `hit_threshold` gives the range (its distance).
//! Nothing within `range` reaches it: no point. Intensity = that hit's α × |cos θ|, θ between
//! the beam and the hit surface's normal (triangle normal in mode `mesh`; a Gaussian's
//! shortest axis in mode `gaussian`): a simple Lambertian-like return strength in [0, 1].
//!
//! Output: [`write_ply`] writes x, y, z, intensity (float), time (double), ring (ushort) as
//! binary little-endian PLY, atomically.

use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DMat3, DQuat, DVec3, Vec3};
use rayon::prelude::*;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::{Lidar, LidarMount};
use splatbridge_scene::output::OutputSet;
use splatbridge_scene::Camera;

use crate::backend::{BackendKind, BuildPreset};
use crate::error::{Result, TraceError};
use crate::gaussian::GaussianTracer;
use crate::kbuffer::{walk, KBuffer};
use crate::mesh_tracer::{MeshHit, MeshTracer};
use crate::secondary::MeshAt;

/// A LiDAR head at a fixed pose.
#[derive(Clone, Debug, PartialEq)]
pub struct LidarSensor {
    pub origin: DVec3,
    /// Sensor-local to world.
    pub to_world: DMat3,
    /// Elevation of each channel, radians (positive up).
    pub elevations: Vec<f64>,
    pub azimuth_steps: u32,
    pub rotation_hz: f64,
    pub range: f64,
    pub hit_threshold: f32,
}

/// One return.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LidarPoint {
    pub position: DVec3,
    pub range: f64,
    pub intensity: f32,
    /// Scene time the beam fired, seconds.
    pub time: f64,
    /// Channel index (0 = lowest elevation).
    pub ring: u16,
}

/// One revolution's returns, ordered by azimuth step then channel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LidarScan {
    pub points: Vec<LidarPoint>,
    pub rays: u64,
    pub seconds: f64,
}

/// Where an opacity march stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Return {
    /// Distance along the unit beam.
    pub t: f64,
    /// α of the hit that crossed the threshold.
    pub alpha: f32,
    /// Unit surface normal at that hit (either orientation).
    pub normal: DVec3,
}

/// Tracers a LiDAR can be cast through.
pub trait OpacityMarch: Sync {
    /// The first hit along `o + t·d` (`d` unit, `0 ≤ t ≤ tmax`) at which accumulated opacity
    /// reaches `threshold`.
    fn first_return(&self, o: DVec3, d: DVec3, tmax: f64, threshold: f32) -> Option<Return>;
}

impl LidarSensor {
    /// From the declared effect; `cameras` are the scene's (for a camera mount).
    pub fn from_effect(l: &Lidar, cameras: &[Camera]) -> Result<Self> {
        splatbridge_scene::effects::Effects {
            lidar: Some(l.clone()),
            ..Default::default()
        }
        .validate()
        .map_err(TraceError::Invalid)?;
        let (origin, to_world) = match &l.mount {
            LidarMount::Pose { position, rotation } => {
                let q = DQuat::from_xyzw(
                    rotation[1] as f64,
                    rotation[2] as f64,
                    rotation[3] as f64,
                    rotation[0] as f64,
                );
                let n = q.length();
                if !(n > 0.0 && n.is_finite()) {
                    return Err(TraceError::Invalid(
                        "lidar.mount.pose.rotation must be a finite non-zero quaternion".into(),
                    ));
                }
                (Vec3::from(*position).as_dvec3(), DMat3::from_quat(q / n))
            }
            LidarMount::Camera { index } => {
                let c = cameras.get(*index).ok_or_else(|| {
                    TraceError::Invalid(format!(
                        "lidar.mount.camera.index = {index}, but the scene has {} cameras",
                        cameras.len()
                    ))
                })?;
                (c.centre, c.cam_to_world())
            }
        };
        let n = l.channels as usize;
        let (lo, hi) = (
            (l.vertical_fov_deg[0] as f64).to_radians(),
            (l.vertical_fov_deg[1] as f64).to_radians(),
        );
        let elevations = (0..n)
            .map(|c| {
                if n == 1 {
                    0.5 * (lo + hi)
                } else {
                    lo + (hi - lo) * c as f64 / (n - 1) as f64
                }
            })
            .collect();
        Ok(LidarSensor {
            origin,
            to_world,
            elevations,
            azimuth_steps: l.azimuth_steps,
            rotation_hz: l.rotation_hz as f64,
            range: l.range as f64,
            hit_threshold: l.hit_threshold,
        })
    }

    /// World direction of channel `ring` at azimuth `a` (radians).
    pub fn direction(&self, ring: usize, a: f64) -> DVec3 {
        let e = self.elevations[ring];
        let local = DVec3::new(e.cos() * a.sin(), -e.sin(), e.cos() * a.cos());
        (self.to_world * local).normalize()
    }

    /// Firing time and azimuth of step `j` in the revolution starting at frame time `t`.
    pub fn step(&self, t: f64, j: u32) -> (f64, f64) {
        let steps = self.azimuth_steps as f64;
        let time = t + j as f64 / (self.rotation_hz * steps);
        let turns = (self.rotation_hz * t).rem_euclid(1.0) + j as f64 / steps;
        (time, std::f64::consts::TAU * turns)
    }

    /// Rays per revolution.
    pub fn rays_per_frame(&self) -> u64 {
        self.elevations.len() as u64 * self.azimuth_steps as u64
    }
}

/// Cast one revolution starting at frame time `t` through `scene` (frozen at `t`).
pub fn scan<M: OpacityMarch + ?Sized>(scene: &M, sensor: &LidarSensor, t: f64) -> LidarScan {
    let start = Instant::now();
    let channels = sensor.elevations.len();
    let per_step: Vec<Vec<LidarPoint>> = (0..sensor.azimuth_steps)
        .into_par_iter()
        .map(|j| {
            let (time, a) = sensor.step(t, j);
            let mut out = Vec::new();
            for ring in 0..channels {
                let d = sensor.direction(ring, a);
                if let Some(r) =
                    scene.first_return(sensor.origin, d, sensor.range, sensor.hit_threshold)
                {
                    if r.t <= sensor.range && r.t.is_finite() {
                        let cos = r.normal.dot(d).abs();
                        out.push(LidarPoint {
                            position: sensor.origin + d * r.t,
                            range: r.t,
                            intensity: (r.alpha * cos as f32).clamp(0.0, 1.0),
                            time,
                            ring: ring as u16,
                        });
                    }
                }
            }
            out
        })
        .collect();
    LidarScan {
        points: per_step.into_iter().flatten().collect(),
        rays: sensor.rays_per_frame(),
        seconds: start.elapsed().as_secs_f64(),
    }
}

impl OpacityMarch for MeshAt<'_> {
    fn first_return(&self, o: DVec3, d: DVec3, tmax: f64, threshold: f32) -> Option<Return> {
        let mut buf = KBuffer::new(self.k.max(1));
        let mut tr = 1.0f32;
        let collect = |after, buf: &mut _| {
            self.tracer
                .collect(&self.insts, o, d, 0.0, tmax as f32, after, buf)
        };
        walk(&mut buf, collect, |h| {
            let a = self.tracer.shade(&self.insts, h).w;
            tr *= 1.0 - a;
            if 1.0 - tr >= threshold {
                return ControlFlow::Break(Return {
                    t: h.t as f64,
                    alpha: a,
                    normal: self.normal(h),
                });
            }
            ControlFlow::Continue(())
        })
        .1
    }
}

impl MeshAt<'_> {
    /// World unit normal of a hit's triangle (normals transform with the inverse transpose of
    /// local-to-world, i.e. the transpose of `to_local`'s linear part).
    fn normal(&self, h: &MeshHit) -> DVec3 {
        let inst = &self.insts[h.instance as usize];
        let blas = &self.tracer.blas[inst.mesh];
        let mesh = &self.tracer.scene.meshes[inst.mesh];
        let [a, b, c] = mesh.tris[h.payload.tri as usize]
            .map(|i| blas.relative(mesh.positions[i as usize]).as_dvec3());
        let n = (b - a).cross(c - a);
        let w = inst.to_local.matrix3.transpose() * n;
        w.try_normalize().unwrap_or(DVec3::ZERO)
    }
}

impl OpacityMarch for GaussianTracer {
    fn first_return(&self, o: DVec3, d: DVec3, tmax: f64, threshold: f32) -> Option<Return> {
        let tmax = tmax as f32;
        let mut buf = KBuffer::new(16);
        let mut tr = 1.0f32;
        // The tracer's own collection: the same hits in the same (t*, index) order.
        let collect = |after, buf: &mut _| self.collect(o, d, None, tmax, after, buf);
        walk(&mut buf, collect, |h| {
            let a = h.payload.alpha;
            tr *= 1.0 - a;
            if 1.0 - tr >= threshold {
                return ControlFlow::Break(Return {
                    t: h.t as f64,
                    alpha: a,
                    normal: self.hit_normal(h),
                });
            }
            ControlFlow::Continue(())
        })
        .1
    }
}

/// What a per-frame LiDAR run produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LidarRun {
    /// One PLY per frame, `DIR/lidar_NNNN.ply` (frame index).
    pub files: Vec<PathBuf>,
    pub rays: u64,
    pub points: u64,
    /// Time spent casting (not building tracers or writing), seconds.
    pub seconds: f64,
}

/// File name of frame `i`'s scan.
pub fn frame_file(dir: &Path, i: usize) -> PathBuf {
    dir.join(format!("lidar_{i:04}.ply"))
}

/// Scan every frame of `scene` through its Gaussians (mode gaussian) with the declared
/// `lidar` effect and write one PLY per frame into `dir` (created). Each frame's content is
/// [`splatbridge_scene::effects_run::build_frame`]'s (declared weather particles included, so
/// rain and snow return points as they would on a real sensor). `Ok(None)` when the scene
/// declares no LiDAR.
pub fn scan_scene_gaussian(
    scene: &DynamicScene,
    dir: &Path,
    backend: BackendKind,
    preset: BuildPreset,
) -> Result<Option<LidarRun>> {
    scan_scene_gaussian_selected(scene, dir, backend, preset, &|_, _| true)
}

/// [`scan_scene_gaussian`] of only the frames `keep(index, time)` selects (a shard's); each
/// frame's scan is the same as in a scan of every frame.
pub fn scan_scene_gaussian_selected(
    scene: &DynamicScene,
    dir: &Path,
    backend: BackendKind,
    preset: BuildPreset,
    keep: &dyn Fn(usize, f64) -> bool,
) -> Result<Option<LidarRun>> {
    let effects = splatbridge_scene::effects_run::effects_of(scene)?;
    let Some(l) = &effects.lidar else {
        return Ok(None);
    };
    let sensor = LidarSensor::from_effect(l, &scene.cameras)?;
    std::fs::create_dir_all(dir).map_err(|e| TraceError::Io {
        path: dir.to_path_buf(),
        err: e,
    })?;
    let mut run = LidarRun::default();
    // The frames' scans appear together or not at all.
    let mut set = OutputSet::new();
    // One BVH per part for the whole range: frames only re-pose the objects and replace the
    // frame's weather particles.
    let mut tracer: Option<GaussianTracer> = None;
    for (i, t) in scene.frame_times().into_iter().enumerate() {
        if !keep(i, t) {
            continue;
        }
        let particles = match &effects.weather {
            Some(w) => Some(splatbridge_scene::effects_run::weather_particles(
                scene, w, t, None,
            )?),
            None => None,
        };
        let tracer = match &mut tracer {
            Some(tr) => {
                tr.set_time(t);
                tr
            }
            None => tracer.insert(GaussianTracer::for_scene(scene, t, backend, preset)?),
        };
        tracer.set_particles(particles)?;
        let s = scan(&*tracer, &sensor, t);
        let path = frame_file(dir, i);
        stage_ply(&mut set, &path, &s)?;
        run.rays += s.rays;
        run.points += s.points.len() as u64;
        run.seconds += s.seconds;
        run.files.push(path);
    }
    set.commit()?;
    Ok(Some(run))
}

/// Scan a triangle scene (an export, mode mesh) at each of `times` with `lidar`, writing one
/// PLY per time into `dir`; `cameras` serve a camera mount. Animated objects are instanced at
/// each time ([`MeshTracer::at`]), not rebuilt; morphed meshes are posed at each time
/// ([`MeshTracer::set_time`]), so the tracer is left posed at the last.
pub fn scan_mesh_frames(
    tracer: &mut MeshTracer,
    lidar: &Lidar,
    cameras: &[Camera],
    times: &[f64],
    dir: &Path,
) -> Result<LidarRun> {
    scan_mesh_frames_selected(tracer, lidar, cameras, times, dir, &|_, _| true)
}

/// [`scan_mesh_frames`] of only the times `keep(index, time)` selects (a shard's).
pub fn scan_mesh_frames_selected(
    tracer: &mut MeshTracer,
    lidar: &Lidar,
    cameras: &[Camera],
    times: &[f64],
    dir: &Path,
    keep: &dyn Fn(usize, f64) -> bool,
) -> Result<LidarRun> {
    let sensor = LidarSensor::from_effect(lidar, cameras)?;
    std::fs::create_dir_all(dir).map_err(|e| TraceError::Io {
        path: dir.to_path_buf(),
        err: e,
    })?;
    let mut run = LidarRun::default();
    // The frames' scans appear together or not at all.
    let mut set = OutputSet::new();
    for (i, &t) in times.iter().enumerate() {
        if !keep(i, t) {
            continue;
        }
        tracer.set_time(t)?;
        let s = scan(&tracer.at(t), &sensor, t);
        let path = frame_file(dir, i);
        stage_ply(&mut set, &path, &s)?;
        run.rays += s.rays;
        run.points += s.points.len() as u64;
        run.seconds += s.seconds;
        run.files.push(path);
    }
    set.commit()?;
    Ok(run)
}

/// Write a scan as a binary little-endian PLY (x, y, z, intensity as float; time as double;
/// ring as ushort), atomically.
pub fn write_ply(path: &Path, scan: &LidarScan) -> splatbridge_scene::Result<()> {
    let mut set = OutputSet::new();
    stage_ply(&mut set, path, scan)?;
    set.commit()
}

/// [`write_ply`] into an output set (a sequence of scans commits as one).
pub fn stage_ply(
    set: &mut OutputSet,
    path: &Path,
    scan: &LidarScan,
) -> splatbridge_scene::Result<()> {
    set.write_with(path, |w| {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\ncomment splatbridge lidar scan\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nproperty double time\nproperty ushort ring\nend_header\n",
            scan.points.len()
        )?;
        for p in &scan.points {
            let v = p.position.as_vec3();
            for x in [v.x, v.y, v.z, p.intensity] {
                w.write_all(&x.to_le_bytes())?;
            }
            w.write_all(&p.time.to_le_bytes())?;
            w.write_all(&p.ring.to_le_bytes())?;
        }
        Ok(())
    })
}

/// Read back a scan written by [`write_ply`] (positions as f32, ranges not stored: 0).
pub fn read_ply(bytes: &[u8]) -> std::result::Result<Vec<LidarPoint>, String> {
    const HEADER_END: &[u8] = b"end_header\n";
    let end = bytes
        .windows(HEADER_END.len())
        .position(|w| w == HEADER_END)
        .ok_or("no end_header")?
        + HEADER_END.len();
    let header = std::str::from_utf8(&bytes[..end]).map_err(|e| e.to_string())?;
    let n: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .ok_or("no vertex element")?
        .trim()
        .parse()
        .map_err(|e| format!("vertex count: {e}"))?;
    const REC: usize = 4 * 4 + 8 + 2;
    let body = &bytes[end..];
    if body.len() != n * REC {
        return Err(format!(
            "{} data bytes for {n} points (expected {})",
            body.len(),
            n * REC
        ));
    }
    let f = |b: &[u8], i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    Ok(body
        .chunks_exact(REC)
        .map(|r| LidarPoint {
            position: Vec3::new(f(r, 0), f(r, 4), f(r, 8)).as_dvec3(),
            range: 0.0,
            intensity: f(r, 12),
            time: f64::from_le_bytes(r[16..24].try_into().expect("8 bytes")),
            ring: u16::from_le_bytes([r[24], r[25]]),
        })
        .collect())
}
