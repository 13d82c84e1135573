//! Every frame of a 4D capture as mesh glTF, one frame in memory at a time (`convert SEQUENCE
//! --frames`).
//!
//! [`write_frames_file`] writes the animated glTF the in-memory writer writes for a scene whose
//! frames are all per-frame content (`gltf_writer`: one node per frame, shown on its frame by
//! STEP scale keys), byte for byte, without holding the frames: each frame is read, classified,
//! its bounds taken and its mesh bytes streamed to a spool file next to the output; the
//! document is planned from the frames' counts and bounds once every frame is done, and the
//! output is assembled from the JSON, the small data and the spool and committed atomically
//! ([`splatbridge_scene::output::OutputSet`]; the spool is removed with the set). A GLB's
//! length is a u32, so a capture whose frames will not fit is refused before the spool grows
//! past one frame: the first frame's bytes per Gaussian give the estimate, and the writer stops
//! at the frame that crosses [`GLB_LIMIT`] whatever the estimate said.
//!
//! [`write_frames_dir`] is the form that scales: one GLB per frame (what `convert` writes for
//! that frame alone) and an index, `frames.json`, naming each file and its time.

use std::borrow::Cow;
use std::io::{self, BufWriter, Read, Seek, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::output::OutputSet;
use splatbridge_scene::GaussianCloud;

use crate::gltf_writer::{
    entry_regions, frame_key_times, layout_for, plan_at, region_of, stream_entry, EntryInfo,
};
use crate::motion::stream::FrameSource;
use crate::options::{ConvertOptions, ConvertReport};
use crate::order::{arrange_part, Part};
use crate::{check_entry, piece_entry, shape_for, ConvertError, Piece, ProfileShape, Result, Role};

/// Largest GLB: its header's length field is a u32.
pub const GLB_LIMIT: u64 = u32::MAX as u64;

/// Largest id `_GAUSSIAN_ID` holds exactly (a float attribute).
const ID_LIMIT: u64 = 1 << 24;

/// Name of the index [`write_frames_dir`] writes beside the frames.
pub const FRAMES_INDEX: &str = "frames.json";

/// What the streamed single-file writer may know before it starts, and its limit.
#[derive(Clone, Copy, Debug)]
pub struct FramesLimits {
    /// Largest file (GLB) or binary buffer (`.gltf`) written; [`GLB_LIMIT`] unless a test asks
    /// for less.
    pub max_bytes: u64,
    /// Gaussians over every frame, when the reader knows it without reading the frames (a
    /// numbered sequence's headers, a `params.npz`'s shape): the size estimate scales the first
    /// frame's bytes by it, and the `_GAUSSIAN_ID` limit is checked before anything is read.
    pub total_gaussians: Option<u64>,
}

impl Default for FramesLimits {
    fn default() -> Self {
        FramesLimits {
            max_bytes: GLB_LIMIT,
            total_gaussians: None,
        }
    }
}

/// Sizes as people read them: `811.0 MB`, `48.7 GB` (powers of ten).
fn human(bytes: u64) -> String {
    if bytes >= 1_000_000_000 {
        format!("{:.1} GB", bytes as f64 / 1e9)
    } else {
        format!("{:.1} MB", bytes as f64 / 1e6)
    }
}

/// Check the frame times: one per frame, finite, strictly increasing, distinct in f32.
pub(crate) fn check_times(path: &Path, frames: usize, times: &[f64]) -> Result<()> {
    let err = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    if frames == 0 || times.len() != frames {
        return Err(err(format!("{frames} frames, {} times", times.len())));
    }
    if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| !(w[1] > w[0])) {
        return Err(err(
            "frame times must be finite and strictly increasing".into()
        ));
    }
    frame_key_times(times).map_err(|e| err(e.to_string()))?;
    Ok(())
}

/// What the streamed writer carries from frame to frame.
struct Stream<'o> {
    path: &'o Path,
    opts: &'o ConvertOptions,
    shape: ProfileShape,
    /// A scene with nothing in it: the in-memory writer's frames scene has no static
    /// Gaussians, objects or cameras, and the plan reads nothing else of it.
    scene: DynamicScene,
    report: ConvertReport,
    infos: Vec<EntryInfo>,
    spool: BufWriter<std::fs::File>,
    /// Mesh bytes in the spool.
    written: u64,
    /// Gaussians so far (the next whole part's first `_GAUSSIAN_ID`).
    offset: u64,
}

impl Stream<'_> {
    /// Classify one part of the scene (arranged as the options ask, as `order::arrange_for`
    /// does), add its counts to the report and stream its meshes to the spool.
    fn part(&mut self, role: Role, name: &str, cloud: &GaussianCloud, max: usize) -> Result<()> {
        let parts: Vec<Part>;
        let pieces: Vec<Piece<'_>> = if self.opts.arranged() {
            let mut p = Vec::new();
            arrange_part(role, name, cloud, max, self.offset, self.opts, &mut p)?;
            parts = p;
            parts.iter().map(Piece::of_part).collect()
        } else {
            vec![Piece::whole(role, name, cloud)]
        };
        let base = self.offset;
        let layout = layout_for(self.opts);
        for piece in pieces {
            let e = piece_entry(piece, &self.scene, self.opts, &self.shape, &mut self.offset)?;
            check_entry(&e, &mut self.report)?;
            let info = EntryInfo::of(&e);
            let [a, b] = entry_regions(&info, layout).map(|r| r.map(|(v, i)| region_of(v, i)));
            self.written += stream_entry(&mut self.spool, &e, layout, [a.as_ref(), b.as_ref()])
                .map_err(crate::io_err(self.path))?;
            self.infos.push(info);
        }
        self.offset = base + cloud.len() as u64;
        Ok(())
    }
}

/// Write every frame of `src` (frame `f` at `times[f]`) as the animated mesh glTF (`.glb`, or
/// `.gltf` + `.bin`) that `convert_to_file` writes for a scene holding them as per-frame
/// content, with one frame in memory at a time. Refuses `--surfels` and `--max-triangles`
/// (they split or budget every frame together: the in-memory writer does those).
pub fn write_frames_file(
    path: &Path,
    src: &(impl FrameSource + ?Sized),
    times: &[f64],
    opts: &ConvertOptions,
    limits: &FramesLimits,
) -> Result<ConvertReport> {
    let t0 = std::time::Instant::now();
    let glb = match crate::Format::from_path(path)? {
        crate::Format::Glb => true,
        crate::Format::Gltf => false,
        _ => {
            return Err(ConvertError::Format {
                path: path.into(),
                what: "--frames writes a .glb or .gltf file, or one GLB per frame into a folder"
                    .into(),
            })
        }
    };
    if opts.surfels.is_some() || opts.max_triangles.is_some() {
        return Err(ConvertError::Invalid(
            "the streamed per-frame writer takes neither surfels nor a triangle budget".into(),
        ));
    }
    opts.validate()?;
    check_times(path, src.len(), times)?;
    let too_big = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    let ids_err = |n: u64| {
        too_big(format!(
            "{n} Gaussians over the frames: _GAUSSIAN_ID is a float attribute, exact only below 2^24 = 16777216; convert with --no-ids, or write one GLB per frame (-o DIR/)"
        ))
    };
    if let Some(n) = limits.total_gaussians {
        if opts.gaussian_ids && n > ID_LIMIT {
            return Err(ids_err(n));
        }
    }
    let frames = src.len() as u64;
    // The animation's keys: a time and a scale output of 3 floats per frame for each frame.
    let small = 4 * frames + 12 * frames * frames;
    let mut set = OutputSet::new();
    let (spool_path, spool) = set.scratch(path).map_err(crate::scene_err)?;
    let mut s = Stream {
        path,
        opts,
        shape: shape_for(opts),
        scene: DynamicScene::from_static(GaussianCloud::new(0)),
        report: ConvertReport::new(if glb { "glb" } else { "gltf" }, opts),
        infos: Vec::new(),
        spool: BufWriter::with_capacity(1 << 20, spool),
        written: 0,
        offset: 0,
    };
    let what = if glb { "a GLB" } else { "a .gltf's buffer" };
    let empty = GaussianCloud::new(0);
    s.part(Role::Static, "static", &empty, opts.chunk_size)?;
    for f in 0..src.len() {
        let cloud = src.frame(f)?;
        s.part(Role::Frame(f), &format!("frame {f}"), &cloud, 0)?;
        if opts.gaussian_ids && s.offset > ID_LIMIT {
            return Err(ids_err(limits.total_gaussians.unwrap_or(s.offset)));
        }
        if f == 0 {
            let total = limits
                .total_gaussians
                .unwrap_or(frames * cloud.len() as u64);
            let per = s.written as f64 / cloud.len().max(1) as f64;
            let estimate = small + (per * total as f64) as u64;
            if estimate > limits.max_bytes {
                return Err(too_big(format!(
                    "--frames would write about {} ({} frames; frame 0 alone is {}), more than the {} {what} holds: write one GLB per frame with -o DIR/, or decompose with --objects auto",
                    human(estimate),
                    frames,
                    human(s.written),
                    human(limits.max_bytes)
                )));
            }
        }
        if small + s.written > limits.max_bytes {
            return Err(too_big(format!(
                "--frames passed {} at frame {f} of {frames}, more than the {} {what} holds: write one GLB per frame with -o DIR/, or decompose with --objects auto",
                human(small + s.written),
                human(limits.max_bytes)
            )));
        }
        drop(cloud);
    }
    let Stream {
        report: mut r,
        infos,
        spool,
        written,
        scene,
        ..
    } = s;
    let mut spool = spool
        .into_inner()
        .map_err(|e| crate::io_err(&spool_path)(e.into_error()))?;
    let bin_path = path.with_extension("bin");
    let uri = (!glb).then(|| {
        bin_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    });
    let plan = plan_at(&infos, &scene, Some(times), opts, &r, uri).map_err(crate::io_err(path))?;
    if plan.bin_len != plan.small.len() as u64 + written {
        return Err(ConvertError::Invalid(format!(
            "internal: planned {} bytes of buffer, streamed {} + {written}",
            plan.bin_len,
            plan.small.len()
        )));
    }
    if !glb && plan.bin_len > limits.max_bytes {
        return Err(too_big(format!(
            "--frames would write a {} buffer, more than the {} {what} holds: write one GLB per frame with -o DIR/",
            human(plan.bin_len),
            human(limits.max_bytes)
        )));
    }
    spool.rewind().map_err(crate::io_err(&spool_path))?;
    let mut body = |w: &mut BufWriter<std::fs::File>| -> io::Result<u64> {
        w.write_all(&plan.small)?;
        let n = io::copy(&mut (&mut spool).take(written), w)?;
        if n != written {
            return Err(io::Error::other(format!(
                "spool holds {n} bytes, {written} were written"
            )));
        }
        Ok(plan.small.len() as u64 + n)
    };
    if glb && 12 + 8 + plan.json.len() as u64 + 3 + 8 + plan.bin_len + 3 > limits.max_bytes {
        return Err(too_big(format!(
            "--frames would write {}, more than the {} a GLB holds: write one GLB per frame with -o DIR/, or decompose with --objects auto",
            human(20 + plan.json.len() as u64 + 8 + plan.bin_len),
            human(limits.max_bytes)
        )));
    }
    let bytes = write_staged(
        &mut set,
        path,
        &bin_path,
        glb,
        &plan.json,
        plan.bin_len,
        &mut body,
    )?;
    set.commit().map_err(crate::scene_err)?;
    r.bytes = bytes;
    r.seconds = t0.elapsed().as_secs_f64();
    Ok(r)
}

/// One frame of a per-frame folder, as [`FRAMES_INDEX`] lists it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FrameFile {
    /// The frame's time in seconds: it is shown from `t` until the next frame's.
    pub t: f64,
    /// The GLB, relative to the index.
    pub uri: String,
    pub gaussians: u64,
    pub triangles: u64,
    pub bytes: u64,
}

/// The index of a per-frame folder (`frames.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FramesIndex {
    /// `splatbridge-frames/1`.
    pub format: String,
    pub fps: f64,
    pub frames: Vec<FrameFile>,
}

/// The index's format name.
pub const FRAMES_FORMAT: &str = "splatbridge-frames/1";

/// Write every frame of `src` as its own GLB into `dir` (`frame_0000.glb`, …: each what
/// `convert` writes for that frame alone, its `_GAUSSIAN_ID`s from 0) and the index
/// [`FRAMES_INDEX`]; one frame in memory at a time. The files appear together or not at all
/// (staged, then committed as one [`OutputSet`]); other files in `dir` are kept.
pub fn write_frames_dir(
    dir: &Path,
    src: &(impl FrameSource + ?Sized),
    times: &[f64],
    fps: f64,
    opts: &ConvertOptions,
) -> Result<(FramesIndex, ConvertReport)> {
    let t0 = std::time::Instant::now();
    opts.validate()?;
    check_times(dir, src.len(), times)?;
    let mut set = OutputSet::new();
    let stage = set.stage_dir(dir).map_err(crate::scene_err)?;
    let width = 4.max(src.len().saturating_sub(1).to_string().len());
    let mut index = FramesIndex {
        format: FRAMES_FORMAT.into(),
        fps,
        frames: Vec::with_capacity(src.len()),
    };
    let mut total = ConvertReport::new("glb", opts);
    for (f, &t) in times.iter().enumerate() {
        let cloud = match src.frame(f)? {
            Cow::Owned(c) => c,
            Cow::Borrowed(c) => c.clone(),
        };
        let scene = DynamicScene::from_static(cloud);
        let uri = format!("frame_{f:0width$}.glb");
        let staged: PathBuf = stage.join(&uri);
        let r =
            crate::gltf_writer::write_file(&staged, true, &scene, None, opts).map_err(
                |e| match e {
                    // Name the file where it will be, not the staging folder.
                    ConvertError::Invalid(what) => ConvertError::Format {
                        path: dir.join(&uri),
                        what,
                    },
                    other => other,
                },
            )?;
        index.frames.push(FrameFile {
            t,
            uri,
            gaussians: r.gaussians_in,
            triangles: r.triangles,
            bytes: r.bytes,
        });
        total.gaussians_in += r.gaussians_in;
        total.dropped_invalid += r.dropped_invalid;
        total.dropped_transparent += r.dropped_transparent;
        total.dropped_overflow += r.dropped_overflow;
        total.dropped_budget += r.dropped_budget;
        total.vertices += r.vertices;
        total.triangles += r.triangles;
        total.bytes += r.bytes;
    }
    let json = serde_json::to_vec_pretty(&index)
        .map_err(|e| ConvertError::Invalid(format!("frames index: {e}")))?;
    std::fs::write(stage.join(FRAMES_INDEX), &json).map_err(crate::io_err(dir))?;
    total.bytes += json.len() as u64;
    set.commit().map_err(crate::scene_err)?;
    total.seconds = t0.elapsed().as_secs_f64();
    Ok((index, total))
}

/// Stage a document whose buffer `body` streams: one GLB at `path`, or `path` (.gltf) with
/// its buffer in `bin_path`; nothing is committed here. Returns the bytes written.
pub(crate) fn write_staged(
    set: &mut OutputSet,
    path: &Path,
    bin_path: &Path,
    glb: bool,
    json: &[u8],
    bin_len: u64,
    body: &mut impl FnMut(&mut BufWriter<std::fs::File>) -> io::Result<u64>,
) -> Result<u64> {
    let mut n = 0;
    if glb {
        set.write_with(path, |w| {
            n = crate::gltf_writer::glb_container(w, json, bin_len, body)?;
            Ok(())
        })
        .map_err(crate::scene_err)?;
        return Ok(n);
    }
    set.write_with(bin_path, |w| {
        n = body(w)?;
        Ok(())
    })
    .map_err(crate::scene_err)?;
    set.write(path, json).map_err(crate::scene_err)?;
    Ok(n + json.len() as u64)
}

/// Read a per-frame folder's index (`DIR/frames.json`, or `DIR`), checked: the format name,
/// times finite and increasing, file names inside the folder.
pub fn read_frames_index(path: &Path) -> Result<(PathBuf, FramesIndex)> {
    let file = if path.is_dir() {
        path.join(FRAMES_INDEX)
    } else {
        path.to_path_buf()
    };
    let err = |what: String| ConvertError::Format {
        path: file.clone(),
        what,
    };
    let len = std::fs::metadata(&file)
        .map_err(crate::io_err(&file))?
        .len();
    // An index names a file per frame in a line or two: 64 MiB is millions of frames.
    if len > 64 << 20 {
        return Err(err(format!("{len} bytes is not a frames index")));
    }
    let bytes = std::fs::read(&file).map_err(crate::io_err(&file))?;
    let index: FramesIndex =
        serde_json::from_slice(&bytes).map_err(|e| err(format!("not a frames index: {e}")))?;
    if index.format != FRAMES_FORMAT {
        return Err(err(format!(
            "format '{}', expected {FRAMES_FORMAT}",
            index.format
        )));
    }
    if index.frames.is_empty() {
        return Err(err("lists no frames".into()));
    }
    let times: Vec<f64> = index.frames.iter().map(|f| f.t).collect();
    if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| !(w[1] > w[0])) {
        return Err(err(
            "frame times must be finite and strictly increasing".into()
        ));
    }
    for f in &index.frames {
        let p = Path::new(&f.uri);
        if p.components().count() != 1
            || !matches!(p.components().next(), Some(std::path::Component::Normal(_)))
        {
            return Err(err(format!(
                "frame file '{}' is not a file name in the index's folder",
                f.uri
            )));
        }
    }
    let dir = file
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    Ok((dir, index))
}

impl FramesIndex {
    /// The frame shown at `t`: the last at or before `t` (the first before it starts).
    pub fn frame_at(&self, t: f64) -> usize {
        self.frames.iter().rposition(|f| f.t <= t).unwrap_or(0)
    }
}
