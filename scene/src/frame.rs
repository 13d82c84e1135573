//! A rendered frame: RGB, alpha (1 − T) and depth planes, row-major, top row first.
//!
//! Depth is the blended expected view-space depth `Σ wᵢ zᵢ / Σ wᵢ` with wᵢ = αᵢ·Tᵢ (0 where
//! nothing contributed); renderers that compute it otherwise say so in their docs.

/// RGB, alpha and depth planes of one image.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// Interleaved linear RGB, `3·width·height` values.
    pub rgb: Vec<f32>,
    /// Opacity `1 − T` per pixel.
    pub alpha: Vec<f32>,
    /// Expected view-space depth per pixel (0 where empty).
    pub depth: Vec<f32>,
}

impl Frame {
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Frame {
            width,
            height,
            rgb: vec![0.0; 3 * n],
            alpha: vec![0.0; n],
            depth: vec![0.0; n],
        }
    }

    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    #[inline]
    pub fn rgb_at(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// The `w`×`h` window at (`x0`, `y0`); None unless it lies within the frame.
    pub fn crop(&self, x0: u32, y0: u32, w: u32, h: u32) -> Option<Frame> {
        let fits = |a: u32, n: u32, of: u32| a.checked_add(n).is_some_and(|e| e <= of);
        if !(fits(x0, w, self.width) && fits(y0, h, self.height)) {
            return None;
        }
        let mut out = Frame::new(w, h);
        let (fw, n) = (self.width as usize, w as usize);
        for y in 0..h as usize {
            let src = (y + y0 as usize) * fw + x0 as usize;
            let dst = y * n;
            out.rgb[3 * dst..3 * (dst + n)].copy_from_slice(&self.rgb[3 * src..3 * (src + n)]);
            out.alpha[dst..dst + n].copy_from_slice(&self.alpha[src..src + n]);
            out.depth[dst..dst + n].copy_from_slice(&self.depth[src..src + n]);
        }
        Some(out)
    }

    /// True when every value of every plane is finite.
    pub fn is_finite(&self) -> bool {
        self.rgb
            .iter()
            .chain(&self.alpha)
            .chain(&self.depth)
            .all(|v| v.is_finite())
    }

    /// Largest absolute per-channel RGB difference to `other`; frames of different sizes
    /// differ without bound (+inf).
    pub fn max_rgb_diff(&self, other: &Frame) -> f32 {
        if (self.width, self.height) != (other.width, other.height) {
            return f32::INFINITY;
        }
        self.rgb
            .iter()
            .zip(&other.rgb)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max)
    }
}
