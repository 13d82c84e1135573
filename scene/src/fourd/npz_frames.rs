//! A Dynamic3DGaussians `params.npz` read one timestep at a time ([`NpzFrames`]): what
//! [`super::load`] gives, so a long capture is never held whole. The per-Gaussian constants
//! (`log_scales`, `logit_opacities`, and `rgb_colors` when it is N×3) are read at open; the
//! per-timestep arrays (`means3D`, `unnorm_rotations`, and `rgb_colors` when it is T×N×3) are
//! read per frame:
//!
//! * a stored member (`np.savez`, ZIP method 0) is read at its offset: frame t's slice is the
//!   `N·k` values at `header + t·N·k·size` of the member's data, one read per array, any
//!   order, any frame at the same cost;
//! * a deflated member (`np.savez_compressed`) cannot be entered in the middle, so it is
//!   decompressed sequentially: each array keeps its decoder where the last read left it and
//!   the last frame it decoded. Frames read in order (every pass of `convert --frames`,
//!   `--objects`, `info`) cost one decompression of the file per pass; the same frame again
//!   is free; an earlier frame restarts the member from its start, so reading frame t at
//!   random costs decompressing frames 0..=t (O(t·N) work, O(N) memory).
//!
//! Every check of the whole-file reader ([`super::npz::read_params_npz`], kept as the
//! reference the tests compare against) is made: shapes and sizes at open, before any frame
//! is read; a frame's values (finite, quaternions not zero) when that frame is read, with the
//! same messages and value indices.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom, Take};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use glam::{Quat, Vec3};

use super::npz::{check_npy_len, decode_values, parse_npy_header, NpyHeader};
use super::npz::{DEFLATE_MAX_RATIO, MAX_NPY_HEADER};
use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// A per-timestep array of the file: where its values are and how to read a frame of them.
#[derive(Debug)]
struct Member {
    name: &'static str,
    /// Offset of the member's (stored or deflated) data in the file.
    data_start: u64,
    stored_size: u64,
    deflated: bool,
    header: NpyHeader,
    /// Values per frame (`N·k`).
    per_frame: usize,
    state: Mutex<Inflate>,
}

/// Where a deflated member's decoder is, and the last frame it decoded.
#[derive(Default)]
struct Inflate {
    decoder: Option<Box<flate2::read::DeflateDecoder<Take<BufReader<File>>>>>,
    /// The frame the decoder's next bytes belong to.
    next: usize,
    last: Option<(usize, std::sync::Arc<Vec<f32>>)>,
}

impl std::fmt::Debug for Inflate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Inflate")
            .field("next", &self.next)
            .field("last", &self.last.as_ref().map(|l| l.0))
            .finish()
    }
}

/// A `params.npz` opened for per-frame reads.
#[derive(Debug)]
pub struct NpzFrames {
    path: PathBuf,
    pub frames: usize,
    pub count: usize,
    means: Member,
    rotations: Member,
    /// `rgb_colors` per timestep, or `None` when it is N×3 (then in `colors`).
    colors_t: Option<Member>,
    colors: Vec<Vec3>,
    log_scales: Vec<Vec3>,
    opacity_logits: Vec<f32>,
}

impl NpzFrames {
    /// Open `path`: every member's shape and size checked, the constants read.
    pub fn open(path: &Path) -> Result<Self> {
        let err = |what: String| SceneError::format(path, what);
        crate::formats::regular_file_len(path)?;
        let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
        let mut zip = zip::ZipArchive::new(BufReader::new(file))
            .map_err(|e| err(format!("not a readable .npz (zip): {e}")))?;
        let means = member(&mut zip, path, "means3D")?;
        let (t, n) = match means.header.shape[..] {
            [t, n, 3] => (t as usize, n as usize),
            _ => {
                return Err(super::npz::shape_err(
                    path,
                    "means3D",
                    &means.header.shape,
                    "T×N×3",
                ))
            }
        };
        if t == 0 {
            return Err(err("means3D has no timesteps".into()));
        }
        let rotations = member(&mut zip, path, "unnorm_rotations")?;
        if rotations.header.shape[..] != [t as u64, n as u64, 4] {
            return Err(super::npz::shape_err(
                path,
                "unnorm_rotations",
                &rotations.header.shape,
                &format!("{t}×{n}×4"),
            ));
        }
        let colors_m = member(&mut zip, path, "rgb_colors")?;
        let per_frame = match colors_m.header.shape[..] {
            [a, b, 3] if a == t as u64 && b == n as u64 => true,
            [b, 3] if b == n as u64 => false,
            _ => {
                return Err(super::npz::shape_err(
                    path,
                    "rgb_colors",
                    &colors_m.header.shape,
                    &format!("{t}×{n}×3 or {n}×3"),
                ))
            }
        };
        // The constants are O(N): read whole, checked as the whole-file reader checks them.
        let scales = super::npz::read_array(&mut zip, path, "log_scales")?;
        let iso = match scales.shape[..] {
            [b, 3] if b == n as u64 => false,
            [b, 1] if b == n as u64 => true,
            _ => {
                return Err(super::npz::shape_err(
                    path,
                    "log_scales",
                    &scales.shape,
                    &format!("{n}×3 or {n}×1"),
                ))
            }
        };
        let opac = super::npz::read_array(&mut zip, path, "logit_opacities")?;
        if !(opac.shape[..] == [n as u64, 1] || opac.shape[..] == [n as u64]) {
            return Err(super::npz::shape_err(
                path,
                "logit_opacities",
                &opac.shape,
                &format!("{n}×1"),
            ));
        }
        let colors = if per_frame {
            Vec::new()
        } else {
            let c = super::npz::read_array(&mut zip, path, "rgb_colors")?;
            finite(path, "rgb_colors", &c.data, 0)?;
            c.data.chunks_exact(3).map(Vec3::from_slice).collect()
        };
        finite(path, "log_scales", &scales.data, 0)?;
        if let Some(k) = opac.data.iter().position(|v| v.is_nan()) {
            return Err(err(format!("logit_opacities: value {k} is NaN")));
        }
        let mut m = NpzFrames {
            path: path.to_path_buf(),
            frames: t,
            count: n,
            means,
            rotations,
            colors_t: per_frame.then_some(colors_m),
            colors,
            log_scales: if iso {
                scales.data.iter().map(|&s| Vec3::splat(s)).collect()
            } else {
                scales.data.chunks_exact(3).map(Vec3::from_slice).collect()
            },
            opacity_logits: opac.data,
        };
        m.means.per_frame = 3 * n;
        m.rotations.per_frame = 4 * n;
        if let Some(c) = &mut m.colors_t {
            c.per_frame = 3 * n;
        }
        Ok(m)
    }

    /// Whether the per-timestep arrays are deflated (`np.savez_compressed`): frames are then
    /// decompressed in order, and an earlier frame than the last read restarts the array.
    pub fn deflated(&self) -> bool {
        self.means.deflated || self.rotations.deflated
    }

    /// Frame `i` (clamped) as a cloud, read from the file.
    pub fn frame(&self, i: usize) -> Result<GaussianCloud> {
        let i = i.min(self.frames - 1);
        let n = self.count;
        let means = self.read(&self.means, i)?;
        let rots = self.read(&self.rotations, i)?;
        // The whole-file reader checks the arrays in this order, over every timestep; the
        // indices in its messages are into the whole array, so these are too.
        finite(&self.path, "means3D", &means, i * 3 * n)?;
        finite(&self.path, "unnorm_rotations", &rots, i * 4 * n)?;
        let colors_t = match &self.colors_t {
            Some(m) => {
                let c = self.read(m, i)?;
                finite(&self.path, "rgb_colors", &c, i * 3 * n)?;
                Some(c)
            }
            None => None,
        };
        let mut c = GaussianCloud::with_capacity(0, n);
        c.means.extend(means.chunks_exact(3).map(Vec3::from_slice));
        c.rotations.extend(
            rots.chunks_exact(4)
                .map(|q| Quat::from_xyzw(q[1], q[2], q[3], q[0])),
        );
        if let Some(k) = c.rotations.iter().position(|q| q.length_squared() == 0.0) {
            return Err(SceneError::format(
                &self.path,
                format!("unnorm_rotations: quaternion {k} of timestep {i} is zero"),
            ));
        }
        match &colors_t {
            Some(col) => c.sh.extend(
                col.chunks_exact(3)
                    .map(|v| super::rgb_to_dc(Vec3::from_slice(v))),
            ),
            None => {
                c.sh.extend(self.colors.iter().map(|&rgb| super::rgb_to_dc(rgb)))
            }
        }
        c.log_scales.extend_from_slice(&self.log_scales);
        c.opacity_logits.extend_from_slice(&self.opacity_logits);
        Ok(c)
    }

    /// Frame `i` of a per-timestep member as f32 values.
    fn read(&self, m: &Member, i: usize) -> Result<std::sync::Arc<Vec<f32>>> {
        let err = |what: String| SceneError::format(&self.path, format!("{}: {what}", m.name));
        let size = m.header.dtype.size as usize;
        let len = m.per_frame * size;
        let mut bytes = vec![0u8; len];
        if !m.deflated {
            let at = m.data_start + m.header.data_start as u64 + (i * len) as u64;
            let mut f = File::open(&self.path).map_err(|e| SceneError::io(&self.path, e))?;
            f.seek(SeekFrom::Start(at))
                .and_then(|_| f.read_exact(&mut bytes))
                .map_err(|e| err(format!("timestep {i} unreadable: {e}")))?;
            let mut v = Vec::with_capacity(m.per_frame);
            decode_values(&bytes, m.header.dtype, &mut v);
            return Ok(std::sync::Arc::new(v));
        }
        let mut st = m.state.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((f, v)) = &st.last {
            if *f == i {
                return Ok(v.clone());
            }
        }
        if st.decoder.is_none() || st.next > i {
            st.decoder = Some(Box::new(self.restart(m).map_err(err)?));
            st.next = 0;
            st.last = None;
        }
        let skip = ((i - st.next) * len) as u64;
        let dec = st.decoder.as_mut().expect("decoder set above");
        let skipped = std::io::copy(&mut dec.by_ref().take(skip), &mut std::io::sink())
            .map_err(|e| err(format!("entry unreadable: {e}")))?;
        let got = read_full(dec, &mut bytes).map_err(|e| err(format!("entry unreadable: {e}")))?;
        if skipped != skip || got != len {
            st.decoder = None;
            return Err(err(format!(
                "entry ends in timestep {i}, before the bytes its header declares"
            )));
        }
        st.next = i + 1;
        let mut v = Vec::with_capacity(m.per_frame);
        decode_values(&bytes, m.header.dtype, &mut v);
        let v = std::sync::Arc::new(v);
        st.last = Some((i, v.clone()));
        Ok(v)
    }

    /// A decoder at the start of a deflated member's values (its header skipped).
    fn restart(
        &self,
        m: &Member,
    ) -> std::result::Result<flate2::read::DeflateDecoder<Take<BufReader<File>>>, String> {
        let mut f = File::open(&self.path).map_err(|e| e.to_string())?;
        f.seek(SeekFrom::Start(m.data_start))
            .map_err(|e| e.to_string())?;
        let mut d = flate2::read::DeflateDecoder::new(
            BufReader::with_capacity(1 << 16, f).take(m.stored_size),
        );
        let skip = m.header.data_start as u64;
        let n = std::io::copy(&mut d.by_ref().take(skip), &mut std::io::sink())
            .map_err(|e| format!("entry unreadable: {e}"))?;
        if n != skip {
            return Err("entry ends inside its .npy header".into());
        }
        Ok(d)
    }
}

/// Fill `buf` from `r` until it is full or `r` ends; the bytes read.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Values finite, as the whole-file reader checks them (`first`: the index of `d[0]` in the
/// whole array, so messages name the same value).
fn finite(path: &Path, name: &str, d: &[f32], first: usize) -> Result<()> {
    match d.iter().position(|v| !v.is_finite()) {
        Some(k) => Err(SceneError::format(
            path,
            format!("{name}: value {} is {} (not finite)", first + k, d[k]),
        )),
        None => Ok(()),
    }
}

/// Locate a per-timestep member and parse its `.npy` header, checking its declared sizes as
/// the whole-file reader does (without reading its values).
fn member(
    zip: &mut zip::ZipArchive<BufReader<File>>,
    path: &Path,
    name: &'static str,
) -> Result<Member> {
    let err = |what: String| SceneError::format(path, format!("{name}: {what}"));
    let entry_name = format!("{name}.npy");
    let mut entry = zip
        .by_name(&entry_name)
        .map_err(|e| err(format!("no entry {entry_name} in the .npz ({e})")))?;
    let stored = entry.compressed_size();
    let declared = entry.size();
    let deflated = match entry.compression() {
        zip::CompressionMethod::Stored => false,
        zip::CompressionMethod::Deflated => true,
        other => {
            return Err(err(format!(
                "compression {other} is not read (np.savez stores, np.savez_compressed deflates)"
            )))
        }
    };
    let cap = if deflated {
        stored.saturating_mul(DEFLATE_MAX_RATIO)
    } else {
        stored
    };
    if declared > cap {
        return Err(err(format!(
            "entry declares {declared} bytes from {stored} stored bytes (impossible)"
        )));
    }
    let data_start = entry
        .data_start()
        .ok_or_else(|| err("entry's data offset unknown".into()))?;
    // The header: the first bytes of the entry (decompressed by the zip reader).
    let mut head = Vec::with_capacity(MAX_NPY_HEADER.min(declared as usize));
    (&mut entry)
        .take(MAX_NPY_HEADER.min(declared as usize) as u64)
        .read_to_end(&mut head)
        .map_err(|e| err(format!("entry unreadable: {e}")))?;
    let header = parse_npy_header(&head).map_err(err)?;
    let values = declared
        .checked_sub(header.data_start as u64)
        .ok_or_else(|| err("entry ends inside its .npy header".into()))?;
    check_npy_len(&header, values).map_err(err)?;
    Ok(Member {
        name,
        data_start,
        stored_size: stored,
        deflated,
        header,
        per_frame: 0,
        state: Mutex::new(Inflate::default()),
    })
}
