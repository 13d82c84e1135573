//! A binary 3DGS PLY read front to back in chunks of whole records, each decoded on its own,
//! so memory is bounded by a chunk rather than the file: for consumers that make several
//! passes over clouds larger than memory (3D Tiles' partition pass and bucket pass). Each
//! chunk is decoded by the same code as [`super::read_ply`] and the same invalid-Gaussian
//! policy applies (an error naming the vertex, or dropped with `drop_invalid`), so the
//! Gaussians handed out are exactly those of `read_ply`, in the same order.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use super::header::{self, Encoding, Header, Layout};
use super::{binary, describe_invalid};
use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// A binary PLY opened for chunked reading.
pub struct PlyStream {
    path: PathBuf,
    header: Header,
    layout: Layout,
    r: BufReader<File>,
    /// Records read so far.
    done: usize,
    drop_invalid: bool,
    dropped: usize,
    buf: Vec<u8>,
}

impl PlyStream {
    /// Open `path` at its first record. `Ok(None)` for an ASCII PLY, which has no fixed
    /// record size, or for a layout other than the standard 3DGS one (colours, 2DGS, Mip-Splatting,
    /// points; see `super::variant`): read those whole with [`super::read_ply`].
    pub fn open(path: &Path, drop_invalid: bool) -> Result<Option<PlyStream>> {
        let (file, file_len) = crate::input::open_regular(path)?;
        let mut r = BufReader::with_capacity(1 << 20, file);
        let header = header::parse_header(&mut r, path)?;
        if header.encoding == Encoding::Ascii {
            return Ok(None);
        }
        let layout = header::layout(&header, path)?;
        if layout.variant.is_some() {
            // Non-standard layouts are read whole: points get their scales from their
            // neighbours (the whole cloud), and consumers of this stream copy records as
            // they are, which must be the standard layout.
            return Ok(None);
        }
        let data_len = file_len.saturating_sub(header.len);
        let stride = header.stride as u64;
        match header.vertex_count.checked_mul(stride) {
            Some(need) if need <= data_len => {}
            need => {
                return Err(SceneError::format(
                    path,
                    format!(
                        "header declares {} vertices of {stride} bytes ({} bytes) but only {data_len} bytes follow the header (truncated file or wrong count)",
                        header.vertex_count,
                        need.map_or_else(|| "more than 2^64".to_string(), |b| b.to_string())
                    ),
                ))
            }
        }
        Ok(Some(PlyStream {
            path: path.to_path_buf(),
            header,
            layout,
            r,
            done: 0,
            drop_invalid,
            dropped: 0,
            buf: Vec::new(),
        }))
    }

    /// Records the header declares (valid or not).
    pub fn len(&self) -> usize {
        self.header.vertex_count as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn sh_degree(&self) -> u8 {
        self.layout.sh_degree
    }

    /// Bytes per record.
    pub fn stride(&self) -> usize {
        self.header.stride
    }

    /// Invalid Gaussians dropped so far.
    pub fn dropped(&self) -> usize {
        self.dropped
    }

    /// The next up to `max` records (≥ 1) as Gaussians, without the invalid ones (dropped, or
    /// an error without `drop_invalid`); `None` after the last record. With `raw`, the kept
    /// records' bytes are appended to it in the same order (for [`PlyStream::decode`]).
    pub fn next_chunk(
        &mut self,
        max: usize,
        raw: Option<&mut Vec<u8>>,
    ) -> Result<Option<GaussianCloud>> {
        let m = max.max(1).min(self.len() - self.done);
        if m == 0 {
            return Ok(None);
        }
        let stride = self.stride();
        self.buf.resize(m * stride, 0);
        self.r.read_exact(&mut self.buf).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                SceneError::format(
                    &self.path,
                    format!(
                        "vertex data ends inside vertices {}..{} (the file shrank while being read?)",
                        self.done,
                        self.done + m
                    ),
                )
            } else {
                SceneError::io(&self.path, e)
            }
        })?;
        let (mut cloud, suspect) = binary::read_binary(
            &mut &self.buf[..],
            &self.path,
            &self.header,
            &self.layout,
            m,
        )?;
        let mut keep: Option<Vec<bool>> = None;
        if suspect {
            for i in 0..cloud.len() {
                if let Some(reason) = cloud.invalid_reason(i) {
                    if !self.drop_invalid {
                        return Err(SceneError::format(
                            &self.path,
                            format!(
                                "vertex {}: {} ({reason}; drop invalid Gaussians with --drop-invalid)",
                                self.done + i,
                                describe_invalid(&cloud, i, reason)
                            ),
                        ));
                    }
                    keep.get_or_insert_with(|| vec![true; m])[i] = false;
                }
            }
        }
        if let Some(keep) = &keep {
            self.dropped += keep.iter().filter(|&&k| !k).count();
            cloud.retain_indices(|i| keep[i]);
        }
        if let Some(raw) = raw {
            match &keep {
                None => raw.extend_from_slice(&self.buf),
                Some(keep) => {
                    for (rec, _) in self.buf.chunks_exact(stride).zip(keep).filter(|(_, &k)| k) {
                        raw.extend_from_slice(rec);
                    }
                }
            }
        }
        self.done += m;
        Ok(Some(cloud))
    }

    /// Decode whole records handed out by [`PlyStream::next_chunk`] (`bytes.len()` a multiple
    /// of the stride; they were valid when handed out).
    pub fn decode(&self, bytes: &[u8], what: &Path) -> Result<GaussianCloud> {
        let stride = self.stride();
        if !bytes.len().is_multiple_of(stride) {
            return Err(SceneError::format(
                what,
                format!(
                    "{} bytes is not a whole number of {stride}-byte records",
                    bytes.len()
                ),
            ));
        }
        let n = bytes.len() / stride;
        let (cloud, _) = binary::read_binary(&mut &bytes[..], what, &self.header, &self.layout, n)?;
        Ok(cloud)
    }
}
