//! Streaming decode of SPZ's attribute planes straight into the cloud's arrays.
//!
//! The planes (positions, alphas, colours, scales, rotations, SH; see the parent module) are
//! read block by block from the decompressor and dequantised into [`GaussianCloud`]'s
//! structure of arrays as they arrive, so the decompressed payload is never held whole: the
//! peak is the cloud, the DC colour bytes (3 per Gaussian, kept until the SH plane, since
//! the cloud interleaves DC and higher SH) and one block. Every 8-bit attribute goes through
//! a 256-entry table filled with the very expression the per-value code evaluated, so the
//! results are bit-identical to it (the slow reference `unpack_reference` in the tests).
//!
//! Allocation: the arrays are reserved for the header's count with `try_reserve_exact`
//! (the count is already bounded by what the compressed size can hold); reserved pages are
//! only touched as decompressed data fills them, so a stream that lies about its count
//! costs no more resident memory than the data it really holds.

use std::io::{self, Read};

use glam::{Quat, Vec3};

use super::{half_to_f32, unpack_smallest_three, SpzHeader, COLOR_SCALE, SH_FLIP};
use crate::gaussians::{logit, sh_coeffs};
use crate::GaussianCloud;

/// Bytes decompressed per block at most: large enough that per-block costs vanish, and
/// L2-sized, so a block is dequantised while still in cache. Small clouds use a smaller block
/// (`prefetch::block_for` of the payload), so the block stays small next to their data.
const BLOCK: usize = 256 << 10;

/// Number of attribute planes.
pub(super) const PLANES: usize = 6;

/// The decoder's state between planes.
pub(super) struct PlaneDecoder {
    version: u32,
    n: usize,
    flip: bool,
    unit: f32,
    /// SH coefficients per Gaussian after DC in the file, and kept in the cloud.
    file_rest: usize,
    keep_rest: usize,
    cloud: GaussianCloud,
    colours: Vec<u8>,
    block: Vec<u8>,
    /// Bytes read per block.
    block_bytes: usize,
    /// Payload bytes consumed so far (for truncation messages).
    pub got: u64,
    opacity_lut: [f32; 256],
    scale_lut: [f32; 256],
    colour_lut: [f32; 256],
    rot8_lut: [f32; 256],
    sh_lut: [f32; 256],
}

/// Why a plane could not be read.
pub(super) enum PlaneError {
    /// The decompressor failed (corrupt data, bad checksum, zstd error).
    Io(io::Error),
    /// The stream ended early; `got` payload bytes were read in all.
    Short,
}

/// Allocation failure of the cloud's arrays, reported by the caller with the count.
pub(super) struct AllocError;

fn reserve<T>(v: &mut Vec<T>, n: usize) -> Result<(), AllocError> {
    v.try_reserve_exact(n).map_err(|_| AllocError)
}

fn lut(f: impl Fn(u8) -> f32) -> [f32; 256] {
    std::array::from_fn(|b| f(b as u8))
}

/// Read until `buf` is full or the stream ends; returns the bytes read.
fn fill<R: Read + ?Sized>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut at = 0;
    while at < buf.len() {
        match r.read(&mut buf[at..]) {
            Ok(0) => break,
            Ok(k) => at += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(at)
}

impl PlaneDecoder {
    /// A decoder for the Gaussians `h` declares; `flip`: convert RUB → RDF.
    pub(super) fn new(h: &SpzHeader, flip: bool) -> Result<Self, AllocError> {
        let n = h.count as usize;
        let degree = h.sh_degree.min(3);
        let mut cloud = GaussianCloud::new(degree);
        reserve(&mut cloud.means, n)?;
        reserve(&mut cloud.log_scales, n)?;
        reserve(&mut cloud.rotations, n)?;
        reserve(&mut cloud.opacity_logits, n)?;
        reserve(&mut cloud.sh, n.saturating_mul(sh_coeffs(degree)))?;
        // Colours wait for the SH plane only when there is one (see `decode_block`).
        let mut colours = Vec::new();
        if sh_coeffs(h.sh_degree) > 1 {
            reserve(&mut colours, n.saturating_mul(3))?;
        }
        Ok(PlaneDecoder {
            version: h.version,
            n,
            flip,
            unit: 1.0 / (1u32 << h.fractional_bits) as f32,
            file_rest: sh_coeffs(h.sh_degree) - 1,
            keep_rest: sh_coeffs(degree) - 1,
            cloud,
            colours,
            block: Vec::new(),
            block_bytes: super::super::prefetch::block_for(h.payload_len()).min(BLOCK),
            got: 0,
            opacity_lut: lut(|a| logit(a as f32 / 255.0)),
            scale_lut: lut(|b| b as f32 / 16.0 - 10.0),
            colour_lut: lut(|b| (b as f32 / 255.0 - 0.5) / COLOR_SCALE),
            rot8_lut: lut(|b| b as f32 / 127.5 - 1.0),
            sh_lut: lut(|b| (b as f32 - 128.0) / 128.0),
        })
    }

    /// Bytes per Gaussian of plane `p` (0 for an empty SH plane).
    pub(super) fn stride(&self, p: usize) -> usize {
        match p {
            0 if self.version == 1 => 6,
            0 => 9,
            1 => 1,
            2 | 3 => 3,
            4 if self.version >= 3 => 4,
            4 => 3,
            _ => 3 * self.file_rest,
        }
    }

    /// Read plane `p` (exactly `n · stride` bytes) from `r` and decode it.
    pub(super) fn read_plane<R: Read + ?Sized>(
        &mut self,
        p: usize,
        r: &mut R,
    ) -> Result<(), PlaneError> {
        let stride = self.stride(p);
        if stride == 0 || self.n == 0 {
            return Ok(());
        }
        let per_block = (self.block_bytes / stride).max(1);
        let mut block = std::mem::take(&mut self.block);
        let mut done = 0;
        while done < self.n {
            let m = per_block.min(self.n - done);
            block.resize(m * stride, 0);
            let k = fill(r, &mut block).map_err(PlaneError::Io)?;
            self.got += k as u64;
            if k < block.len() {
                return Err(PlaneError::Short);
            }
            self.decode_block(p, done, &block);
            done += m;
        }
        self.block = block;
        Ok(())
    }

    /// Dequantise one block of plane `p` whose first Gaussian is `first`.
    fn decode_block(&mut self, p: usize, first: usize, b: &[u8]) {
        let f = if self.flip { -1.0 } else { 1.0 };
        let c = &mut self.cloud;
        match p {
            0 if self.version == 1 => c.means.extend(b.chunks_exact(6).map(|e| {
                let h = |j: usize| half_to_f32(u16::from_le_bytes([e[2 * j], e[2 * j + 1]]));
                Vec3::new(h(0), f * h(1), f * h(2))
            })),
            0 => {
                let unit = self.unit;
                c.means.extend(b.chunks_exact(9).map(|e| {
                    // Sign-extend each 24-bit value.
                    let v = |j: usize| {
                        let v = i32::from_le_bytes([0, e[3 * j], e[3 * j + 1], e[3 * j + 2]]);
                        (v >> 8) as f32 * unit
                    };
                    Vec3::new(v(0), f * v(1), f * v(2))
                }))
            }
            1 => {
                let t = &self.opacity_lut;
                c.opacity_logits.extend(b.iter().map(|&a| t[a as usize]));
            }
            // Without higher SH the colours are the whole SH array, in order: no buffer.
            2 if self.file_rest == 0 => {
                let t = &self.colour_lut;
                c.sh.extend(
                    b.chunks_exact(3)
                        .map(|e| Vec3::new(t[e[0] as usize], t[e[1] as usize], t[e[2] as usize])),
                )
            }
            2 => self.colours.extend_from_slice(b),
            3 => {
                let t = &self.scale_lut;
                c.log_scales.extend(
                    b.chunks_exact(3)
                        .map(|e| Vec3::new(t[e[0] as usize], t[e[1] as usize], t[e[2] as usize])),
                )
            }
            4 if self.version >= 3 => c.rotations.extend(b.chunks_exact(4).map(|e| {
                let q = unpack_smallest_three(u32::from_le_bytes([e[0], e[1], e[2], e[3]]));
                // RUB → RDF: conjugating by a half turn about x negates y and z.
                Quat::from_xyzw(q[0], f * q[1], f * q[2], q[3])
            })),
            4 => {
                let t = &self.rot8_lut;
                c.rotations.extend(b.chunks_exact(3).map(|e| {
                    let xyz = Vec3::new(t[e[0] as usize], t[e[1] as usize], t[e[2] as usize]);
                    let w = (1.0 - xyz.length_squared()).max(0.0).sqrt();
                    Quat::from_xyzw(xyz.x, f * xyz.y, f * xyz.z, w)
                }))
            }
            _ => {
                let per = 3 * self.file_rest;
                for (i, e) in b.chunks_exact(per).enumerate() {
                    push_dc(c, &self.colour_lut, &self.colours, first + i);
                    let t = &self.sh_lut;
                    c.sh.extend(e[..3 * self.keep_rest].chunks_exact(3).enumerate().map(
                        |(j, v)| {
                            let s = if self.flip { SH_FLIP[j] } else { 1.0 };
                            Vec3::new(t[v[0] as usize], t[v[1] as usize], t[v[2] as usize]) * s
                        },
                    ));
                }
            }
        }
    }

    /// The cloud, once every plane has been read.
    pub(super) fn finish(self) -> GaussianCloud {
        self.cloud
    }
}

fn push_dc(c: &mut GaussianCloud, t: &[f32; 256], colours: &[u8], i: usize) {
    let e = &colours[3 * i..3 * i + 3];
    c.sh.push(Vec3::new(
        t[e[0] as usize],
        t[e[1] as usize],
        t[e[2] as usize],
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slow, per-value reference: the whole payload held, each value computed from its
    /// bytes by the expressions of nianticlabs/spz `load-spz.cc`.
    fn unpack_reference(h: &SpzHeader, p: &[u8], flip: bool) -> GaussianCloud {
        let f = if flip { -1.0 } else { 1.0 };
        let sh_flip = |j: usize| if flip { SH_FLIP[j] } else { 1.0 };
        let n = h.count as usize;
        let pos_len = n * h.position_bytes() as usize;
        let (positions, p) = p.split_at(pos_len);
        let (alphas, p) = p.split_at(n);
        let (colors, p) = p.split_at(3 * n);
        let (scales, p) = p.split_at(3 * n);
        let (rotations, sh) = p.split_at(n * h.rotation_bytes() as usize);
        let file_rest = sh_coeffs(h.sh_degree) - 1;
        let degree = h.sh_degree.min(3);
        let k = sh_coeffs(degree);
        let mut cloud = GaussianCloud::with_capacity(degree, n);
        let unit = 1.0 / (1u32 << h.fractional_bits) as f32;
        for i in 0..n {
            let pos = if h.version == 1 {
                let c = |j: usize| {
                    let o = i * 6 + 2 * j;
                    half_to_f32(u16::from_le_bytes([positions[o], positions[o + 1]]))
                };
                Vec3::new(c(0), c(1), c(2))
            } else {
                let c = |j: usize| {
                    let o = i * 9 + 3 * j;
                    let v =
                        i32::from_le_bytes([positions[o], positions[o + 1], positions[o + 2], 0]);
                    ((v << 8) >> 8) as f32 * unit
                };
                Vec3::new(c(0), c(1), c(2))
            };
            cloud.means.push(Vec3::new(pos.x, f * pos.y, f * pos.z));
            let s = |j: usize| scales[3 * i + j] as f32 / 16.0 - 10.0;
            cloud.log_scales.push(Vec3::new(s(0), s(1), s(2)));
            let q = if h.version >= 3 {
                let o = 4 * i;
                unpack_smallest_three(u32::from_le_bytes([
                    rotations[o],
                    rotations[o + 1],
                    rotations[o + 2],
                    rotations[o + 3],
                ]))
            } else {
                let c = |j: usize| rotations[3 * i + j] as f32 / 127.5 - 1.0;
                let xyz = Vec3::new(c(0), c(1), c(2));
                [
                    xyz.x,
                    xyz.y,
                    xyz.z,
                    (1.0 - xyz.length_squared()).max(0.0).sqrt(),
                ]
            };
            cloud
                .rotations
                .push(Quat::from_xyzw(q[0], f * q[1], f * q[2], q[3]));
            cloud.opacity_logits.push(logit(alphas[i] as f32 / 255.0));
            let c = |j: usize| (colors[3 * i + j] as f32 / 255.0 - 0.5) / COLOR_SCALE;
            cloud.sh.push(Vec3::new(c(0), c(1), c(2)));
            let base = i * file_rest * 3;
            for j in 0..k - 1 {
                let v = |ch: usize| (sh[base + 3 * j + ch] as f32 - 128.0) / 128.0;
                cloud.sh.push(Vec3::new(v(0), v(1), v(2)) * sh_flip(j));
            }
        }
        cloud
    }

    fn bits(c: &GaussianCloud) -> Vec<u32> {
        let mut v = Vec::new();
        v.extend(c.means.iter().flat_map(|m| m.to_array()).map(f32::to_bits));
        v.extend(
            c.log_scales
                .iter()
                .flat_map(|m| m.to_array())
                .map(f32::to_bits),
        );
        v.extend(
            c.rotations
                .iter()
                .flat_map(|q| q.to_array())
                .map(f32::to_bits),
        );
        v.extend(c.opacity_logits.iter().map(|x| x.to_bits()));
        v.extend(c.sh.iter().flat_map(|m| m.to_array()).map(f32::to_bits));
        v
    }

    /// A reader that hands out at most 7 bytes per call, so blocks are filled piecewise.
    struct Trickle<'a>(&'a [u8]);
    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let k = buf.len().min(self.0.len()).min(7);
            buf[..k].copy_from_slice(&self.0[..k]);
            self.0 = &self.0[k..];
            Ok(k)
        }
    }

    #[test]
    fn streaming_decode_is_bit_identical_to_the_reference() {
        // Every version, SH degree 0..=4, both axis conventions, counts around a block
        // boundary of the widest plane; every byte value occurs (xorshift bytes).
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut byte = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 24) as u8
        };
        for version in 1..=3u32 {
            for sh_degree in 0..=4u8 {
                for flip in [false, true] {
                    let per_block_sh = (BLOCK / (3 * (sh_coeffs(sh_degree) - 1)).max(1)).max(1);
                    for count in [0u32, 1, 300, per_block_sh as u32 + 5] {
                        let h = SpzHeader {
                            version,
                            count,
                            sh_degree,
                            fractional_bits: 12,
                            flags: 0,
                        };
                        let payload: Vec<u8> = (0..h.payload_len()).map(|_| byte()).collect();
                        let want = unpack_reference(&h, &payload, flip);
                        let Ok(mut dec) = PlaneDecoder::new(&h, flip) else {
                            panic!("allocation failed");
                        };
                        let mut r = Trickle(&payload);
                        for p in 0..PLANES {
                            assert!(dec.read_plane(p, &mut r).is_ok());
                        }
                        assert_eq!(dec.got, h.payload_len());
                        let got = dec.finish();
                        assert_eq!(got.sh_degree, want.sh_degree);
                        assert_eq!(
                            bits(&got),
                            bits(&want),
                            "v{version} degree {sh_degree} flip {flip} count {count}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn short_stream_reports_bytes_read() {
        let h = SpzHeader {
            version: 3,
            count: 10,
            sh_degree: 0,
            fractional_bits: 12,
            flags: 0,
        };
        let Ok(mut dec) = PlaneDecoder::new(&h, true) else {
            panic!("allocation failed");
        };
        let mut r: &[u8] = &[0u8; 95];
        assert!(dec.read_plane(0, &mut r).is_ok());
        assert!(matches!(dec.read_plane(1, &mut r), Err(PlaneError::Short)));
        assert_eq!(dec.got, 95);
    }
}
