//! Wavefront OBJ + MTL writer: `v x y z r g b` vertex colours, `vn` normals, one `o` per
//! scene part, streamed.
//!
//! OBJ has no node hierarchy and no per-vertex alpha: the up-axis rotation and the objects'
//! poses at the written time are baked into the vertices, and opacity is lost (every
//! triangle is drawn opaque; the compare issue measures what that costs). Colours are
//! display values (what 3DGS computes), the convention OBJ importers assume for vertex
//! colours. Numbers are printed in Rust's shortest round-trip form (`Display`, written by
//! [`crate::decimal`]), so a reader parsing f32 gets back the exact written values.

use std::io::{self, Write};
use std::path::Path;

use glam::{Affine3A, Vec3};
use splatbridge_scene::dynamic::DynamicScene;

use crate::chunked::ChunkedMesh;
use crate::decimal::{push_f32, push_u64};
use crate::options::{ColorEncoding, ConvertOptions, ConvertReport};
use crate::{prepare, shape_for, FrameClouds, MeshEntry, Role};

/// The transform that places a mesh entry in the written (up-corrected) world at time `t`,
/// or `None` when the entry is not shown at `t` (per-frame content of another frame).
pub(crate) fn placement(
    e: &MeshEntry<'_>,
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    t: f64,
) -> Option<Affine3A> {
    let root = Affine3A::from_quat(opts.up.root_rotation());
    match e.role {
        Role::Static => Some(root),
        Role::Object(k) => {
            let p = scene.objects[k].track.sample(t);
            Some(root * Affine3A::from_rotation_translation(p.rotation.normalize(), p.translation))
        }
        Role::Frame(k) => {
            let times = &frames?.times;
            // The frame shown at t is the last one starting at or before t (STEP).
            let shown = times.partition_point(|&x| x <= t).saturating_sub(1);
            (shown == k).then_some(root)
        }
    }
}

/// Options for the display-colour formats (OBJ, PLY).
pub(crate) fn display_opts(opts: &ConvertOptions) -> ConvertOptions {
    ConvertOptions {
        color_encoding: ColorEncoding::Display,
        ..opts.clone()
    }
}

/// Frame times written with `--frames`: the scene's time range at its frame rate.
pub fn frame_times(scene: &DynamicScene) -> Vec<f64> {
    let tr = scene.time;
    if !(tr.end > tr.start) || !(tr.fps > 0.0) {
        return vec![tr.start];
    }
    let n = ((tr.end - tr.start) * tr.fps + 1e-9).floor() as usize + 1;
    (0..n).map(|i| tr.start + i as f64 / tr.fps).collect()
}

fn write_obj<W: Write>(
    w: &mut W,
    entries: &[MeshEntry<'_>],
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    report: &ConvertReport,
    mtl_name: &str,
    t: f64,
) -> io::Result<u64> {
    let mut n = 0u64;
    let mut out = |w: &mut W, s: &[u8]| -> io::Result<()> {
        n += s.len() as u64;
        w.write_all(s)
    };
    let meta = serde_json::to_string(&report.metadata(opts)).map_err(io::Error::other)?;
    let head = format!(
        "# splatbridge mesh export at t = {t} s. OBJ carries no per-vertex alpha: opacity is dropped.\n# {meta}\nmtllib {mtl_name}\n"
    );
    out(w, head.as_bytes())?;
    let mut base = 1u64;
    for e in entries {
        if e.mesher.is_empty() {
            continue;
        }
        let Some(xf) = placement(e, scene, frames, opts, t) else {
            continue;
        };
        out(
            w,
            format!(
                "o {}\nusemtl gaussian_splats\n",
                e.mesher.counts.name.replace(char::is_whitespace, "_")
            )
            .as_bytes(),
        )?;
        e.mesher.map_chunks(
            |c| {
                let mut s = Vec::with_capacity(c.vertex_count() * 96);
                for v in 0..c.vertex_count() {
                    let p = xf.transform_point3(Vec3::from_array(c.positions[v]));
                    let nn = xf
                        .transform_vector3(Vec3::from_array(c.normals[v]))
                        .normalize_or_zero();
                    let col = c.colors[v];
                    s.extend_from_slice(b"v");
                    for x in [p.x, p.y, p.z, col[0], col[1], col[2]] {
                        s.push(b' ');
                        push_f32(&mut s, x);
                    }
                    s.extend_from_slice(b"\nvn");
                    for x in [nn.x, nn.y, nn.z] {
                        s.push(b' ');
                        push_f32(&mut s, x);
                    }
                    s.push(b'\n');
                }
                s
            },
            |s| out(w, &s),
        )?;
        e.mesher.map_index_chunks(
            0,
            |idx| {
                let mut s = Vec::with_capacity(idx.len() * 16);
                for t in idx.chunks_exact(3) {
                    s.push(b'f');
                    for i in t {
                        let i = *i as u64 + base;
                        s.push(b' ');
                        push_u64(&mut s, i);
                        s.extend_from_slice(b"//");
                        push_u64(&mut s, i);
                    }
                    s.push(b'\n');
                }
                s
            },
            |s| out(w, &s),
        )?;
        base += e.mesher.counts.vertices;
    }
    Ok(n)
}

const MTL: &str = "# splatbridge: unlit vertex-coloured material (OBJ has no per-vertex alpha)\nnewmtl gaussian_splats\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 0\n";

/// Write OBJ (+ MTL next to it). With `per_frame`, one OBJ per frame time
/// (`OUT_0000.obj`, …) sharing one MTL; otherwise one OBJ at the scene's start time.
pub fn write_file(
    path: &Path,
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    per_frame: bool,
) -> crate::Result<ConvertReport> {
    // The MTL and every OBJ (one per frame with `per_frame`) appear together or not at all.
    let mut set = splatbridge_scene::output::OutputSet::new();
    let (report, _) = write_into(&mut set, path, scene, frames, opts, per_frame, &|_, _| true)?;
    set.commit().map_err(crate::scene_err)?;
    Ok(report)
}

/// [`write_file`] staged into the caller's output set (committed by the caller), writing only
/// the frames `keep(index, time)` selects (a shard's, see the root crate's `shard`); the MTL
/// is always written. Returns the report (bytes of what was written) and the files staged.
pub fn write_into(
    set: &mut splatbridge_scene::output::OutputSet,
    path: &Path,
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    per_frame: bool,
    keep: &dyn Fn(usize, f64) -> bool,
) -> crate::Result<(ConvertReport, Vec<std::path::PathBuf>)> {
    let dopts = display_opts(opts);
    let mut report = ConvertReport::new("obj", &dopts);
    let shape = shape_for(&dopts);
    let entries = prepare(scene, frames, &dopts, &shape, &mut report)?;
    let mtl_path = path.with_extension("mtl");
    let mtl_name = mtl_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    set.write(&mtl_path, MTL.as_bytes())
        .map_err(crate::scene_err)?;
    let mut written = vec![mtl_path.clone()];
    let mut bytes = MTL.len() as u64;
    let times = if per_frame {
        frame_times(scene)
    } else {
        vec![scene.time.start]
    };
    for (i, &t) in times.iter().enumerate() {
        if !keep(i, t) {
            continue;
        }
        let target = if per_frame {
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            path.with_file_name(format!("{stem}_{i:04}.obj"))
        } else {
            path.to_path_buf()
        };
        set.write_with(&target, |w| {
            bytes += write_obj(w, &entries, scene, frames, &dopts, &report, &mtl_name, t)?;
            Ok(())
        })
        .map_err(crate::scene_err)?;
        written.push(target);
    }
    report.bytes = bytes;
    Ok((report, written))
}
