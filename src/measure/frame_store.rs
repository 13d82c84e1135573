//! Reference frames kept on disk instead of in memory: a comparison renders each camera's
//! reference once and measures every renderer against it, stage by stage (one export and its
//! BVH at a time), so the references of all cameras outlive any one stage. Holding them in
//! memory would make the peak grow with the number of cameras × times; here they go to an
//! anonymous temporary file (removed by the OS when the store is dropped, even on a crash)
//! and one is read back at a time, bit for bit.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};

use anyhow::Context;
use splatbridge_scene::Frame;

/// Frames written once and read back by slot.
pub struct FrameStore {
    file: File,
    /// Per slot: (offset, width, height), or None when the slot was never written.
    slots: Vec<Option<(u64, u32, u32)>>,
    end: u64,
}

fn put(w: &mut impl Write, v: &[f32]) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(v.len() * 4);
    for x in v {
        buf.extend_from_slice(&x.to_le_bytes());
    }
    w.write_all(&buf)
}

fn get(r: &mut impl Read, n: usize) -> std::io::Result<Vec<f32>> {
    let mut buf = vec![0u8; n * 4];
    r.read_exact(&mut buf)?;
    Ok(buf
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

impl FrameStore {
    /// A store of `slots` frames in a fresh temporary file.
    pub fn new(slots: usize) -> anyhow::Result<Self> {
        let file =
            tempfile::tempfile().context("cannot create a temporary file for reference frames")?;
        Ok(FrameStore {
            file,
            slots: vec![None; slots],
            end: 0,
        })
    }

    /// Write `frame` as slot `i` (appended; a slot is written once).
    pub fn put(&mut self, i: usize, frame: &Frame) -> anyhow::Result<()> {
        let slot = self
            .slots
            .get_mut(i)
            .with_context(|| format!("reference slot {i} out of range"))?;
        let offset = self.end;
        (|| -> std::io::Result<()> {
            self.file.seek(SeekFrom::Start(offset))?;
            let mut w = std::io::BufWriter::new(&self.file);
            put(&mut w, &frame.rgb)?;
            put(&mut w, &frame.alpha)?;
            put(&mut w, &frame.depth)?;
            w.flush()
        })()
        .context("cannot write a reference frame to the temporary file")?;
        *slot = Some((offset, frame.width, frame.height));
        self.end += 4 * (frame.rgb.len() + frame.alpha.len() + frame.depth.len()) as u64;
        Ok(())
    }

    /// Read slot `i` back (the frame put there, bit for bit).
    pub fn get(&mut self, i: usize) -> anyhow::Result<Frame> {
        let (offset, width, height) = self
            .slots
            .get(i)
            .copied()
            .flatten()
            .with_context(|| format!("reference slot {i} was never rendered"))?;
        let n = width as usize * height as usize;
        (|| -> std::io::Result<Frame> {
            self.file.seek(SeekFrom::Start(offset))?;
            let mut r = std::io::BufReader::new(&self.file);
            let rgb = get(&mut r, 3 * n)?;
            let alpha = get(&mut r, n)?;
            let depth = get(&mut r, n)?;
            Ok(Frame {
                width,
                height,
                rgb,
                alpha,
                depth,
            })
        })()
        .context("cannot read a reference frame back from the temporary file")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_come_back_bit_for_bit() {
        let mut s = FrameStore::new(3).unwrap();
        let mk = |w: u32, h: u32, k: f32| {
            let n = (w * h) as usize;
            Frame {
                width: w,
                height: h,
                rgb: (0..3 * n)
                    .map(|i| i as f32 * k + f32::MIN_POSITIVE)
                    .collect(),
                alpha: (0..n).map(|i| (i as f32 * k).sin()).collect(),
                depth: (0..n).map(|i| -(i as f32) / k).collect(),
            }
        };
        let a = mk(5, 3, 0.37);
        let b = mk(2, 7, 1.9);
        s.put(2, &a).unwrap();
        s.put(0, &b).unwrap();
        for (i, f) in [(2, &a), (0, &b)] {
            let g = s.get(i).unwrap();
            assert_eq!((g.width, g.height), (f.width, f.height));
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&g.rgb), bits(&f.rgb));
            assert_eq!(bits(&g.alpha), bits(&f.alpha));
            assert_eq!(bits(&g.depth), bits(&f.depth));
        }
        assert!(s.get(1).is_err());
        assert!(s.put(3, &a).is_err());
    }
}
