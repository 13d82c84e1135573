//! Image output (8-bit PNG, float OpenEXR with RGBA and depth), PNG input, and atomic file
//! writing.
//!
//! PNG stores RGB only, 8 bits per channel, values clamped to [0, 1] (NaN as 0) and rounded to
//! the nearest of 255 levels, with no gamma applied: the renderers' colours are already display
//! values as 3DGS trains them. OpenEXR stores the frame losslessly as 32-bit float channels
//! R, G, B, A (alpha = 1 − T) and Z (expected view-space depth, 0 where empty), in one
//! unnamed layer, rows top first.

use std::io::Write;
use std::path::Path;

use crate::error::{Result, SceneError};
use crate::output::OutputSet;
use crate::Frame;

/// Write `bytes` to `path` atomically: a one-file [`OutputSet`], so a failure never leaves a
/// partial file at the target, and stale temporaries of killed runs are cleaned.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    with_atomic_writer(path, |w| w.write_all(bytes))
}

/// Stream into `path` atomically through a buffered writer; the target appears only if `f`
/// and the final flush succeed.
pub fn with_atomic_writer<F>(path: &Path, f: F) -> Result<()>
where
    F: FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    let mut set = OutputSet::new();
    set.write_with(path, f)?;
    set.commit()
}

/// An 8-bit RGB image (heat-maps, thumbnails), rows top first.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgb8Image {
    pub width: u32,
    pub height: u32,
    /// Interleaved RGB, `3·width·height` bytes.
    pub data: Vec<u8>,
}

impl Rgb8Image {
    /// Save as PNG (atomically).
    pub fn save_png(&self, path: &Path) -> Result<()> {
        save_rgb8_png(path, self.width, self.height, &self.data)
    }
}

/// Quantise a display value to 8 bits: clamp to [0, 1] (NaN → 0), round to nearest.
#[inline]
pub fn to_u8(v: f32) -> u8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

fn check_planes(path: &Path, frame: &Frame) -> Result<()> {
    let n = frame.pixels();
    if frame.rgb.len() != 3 * n || frame.alpha.len() != n || frame.depth.len() != n {
        return Err(SceneError::format(
            path,
            format!(
                "cannot write a {}×{} frame with {} RGB, {} alpha and {} depth values",
                frame.width,
                frame.height,
                frame.rgb.len(),
                frame.alpha.len(),
                frame.depth.len()
            ),
        ));
    }
    if n == 0 {
        return Err(SceneError::format(
            path,
            "cannot write an empty (0-pixel) image",
        ));
    }
    Ok(())
}

/// Save a frame by extension (case-insensitive): `.png` (8-bit RGB) or `.exr` (float R, G, B,
/// A and a `Z` depth channel); see the module docs. Written atomically.
pub fn save_frame(path: &Path, frame: &Frame) -> Result<()> {
    write_atomic(path, &encode_frame(path, frame)?)
}

/// Stage a frame in an output set (a `--frames` sequence commits as one); as [`save_frame`].
pub fn stage_frame(set: &mut OutputSet, path: &Path, frame: &Frame) -> Result<()> {
    set.write(path, &encode_frame(path, frame)?)
}

/// The bytes [`save_frame`] writes for `path`'s extension.
pub fn encode_frame(path: &Path, frame: &Frame) -> Result<Vec<u8>> {
    check_planes(path, frame)?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "png" => {
            let data: Vec<u8> = frame.rgb.iter().map(|&v| to_u8(v)).collect();
            encode_rgb8_png(path, frame.width, frame.height, &data)
        }
        "exr" => encode_exr(path, frame),
        _ => Err(SceneError::format(
            path,
            format!("unsupported image extension '{ext}' (use .png or .exr)"),
        )),
    }
}

/// Save interleaved 8-bit RGB as PNG (atomically).
pub fn save_rgb8_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    write_atomic(path, &encode_rgb8_png(path, width, height, rgb)?)
}

/// Interleaved 8-bit RGB as PNG bytes; `path` names the output in errors.
pub fn encode_rgb8_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>> {
    use image::ImageEncoder;
    if rgb.len() != 3 * width as usize * height as usize || rgb.is_empty() {
        return Err(SceneError::format(
            path,
            format!(
                "cannot write a {width}×{height} RGB image from {} bytes",
                rgb.len()
            ),
        ));
    }
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| SceneError::format(path, format!("PNG encoding failed: {e}")))?;
    Ok(png)
}

fn encode_exr(path: &Path, frame: &Frame) -> Result<Vec<u8>> {
    use exr::prelude::*;
    let n = frame.pixels();
    let plane = |c: usize| -> Vec<f32> { (0..n).map(|i| frame.rgb[3 * i + c]).collect() };
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![
        AnyChannel::new("R", FlatSamples::F32(plane(0))),
        AnyChannel::new("G", FlatSamples::F32(plane(1))),
        AnyChannel::new("B", FlatSamples::F32(plane(2))),
        AnyChannel::new("A", FlatSamples::F32(frame.alpha.clone())),
        AnyChannel::new("Z", FlatSamples::F32(frame.depth.clone())),
    ]));
    let layer = Layer::new(
        (frame.width as usize, frame.height as usize),
        LayerAttributes::default(),
        // Increasing line order: with `Unspecified` (FAST_LOSSLESS's) the parallel compressor
        // writes blocks in the order its threads finish, so the same frame gave different
        // bytes from run to run (same pixels); outputs must be byte-reproducible
        // (`scripts/hash-outputs.sh`).
        Encoding {
            line_order: LineOrder::Increasing,
            ..Encoding::FAST_LOSSLESS
        },
        channels,
    );
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| SceneError::format(path, format!("OpenEXR encoding failed: {e}")))?;
    Ok(bytes.into_inner())
}

/// Load a PNG (8- or 16-bit, grey or RGB, with or without alpha) as a frame: RGB and alpha in
/// [0, 1] (alpha 1 when the file has none), depth 0.
pub fn load_png(path: &Path) -> Result<Frame> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .map_err(|e| SceneError::format(path, format!("not a readable PNG: {e}")))?;
    let rgba = img.to_rgba32f();
    let (w, h) = rgba.dimensions();
    let mut frame = Frame::new(w, h);
    for (i, p) in rgba.pixels().enumerate() {
        frame.rgb[3 * i..3 * i + 3].copy_from_slice(&p.0[..3]);
        frame.alpha[i] = p.0[3];
    }
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_bytes_are_the_same_every_time() {
        // 512 lines of RLE blocks compressed on every core: with an unspecified line order
        // the block order followed thread timing, and repeated encodes differed.
        let (w, h) = (64u32, 512u32);
        let mut frame = Frame::new(w, h);
        for (i, v) in frame.rgb.iter_mut().enumerate() {
            *v = ((i * 2_654_435_761) % 1000) as f32 / 1000.0;
        }
        let first = encode_exr(Path::new("t.exr"), &frame).unwrap();
        for _ in 0..16 {
            assert!(encode_exr(Path::new("t.exr"), &frame).unwrap() == first);
        }
    }

    #[test]
    fn quantisation_clamps_rounds_and_maps_nan_to_zero() {
        assert_eq!(to_u8(-0.5), 0);
        assert_eq!(to_u8(f32::NAN), 0);
        assert_eq!(to_u8(2.0), 255);
        assert_eq!(to_u8(f32::INFINITY), 255);
        // 0.5·255 = 127.5 rounds away from zero.
        assert_eq!(to_u8(0.5), 128);
        assert_eq!(to_u8(10.0 / 255.0), 10);
    }
}
