//! The demo's one picture: native splatting and each output side by side, each with a caption
//! under it (what it is, its PSNR against native, the file's size for exports). The images are
//! copied pixel for pixel into one RGB buffer; the captions are drawn into the same buffer with
//! `plotters` and the embedded font of the report plots (`report::plot`).

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use splatbridge_scene::image_io::{to_u8, Rgb8Image};
use splatbridge_scene::Frame;

/// One image of the picture with its two caption lines.
pub struct Panel<'a> {
    pub frame: &'a Frame,
    pub title: String,
    pub caption: String,
}

/// White space between panels and around the picture, in pixels.
pub const GAP: u32 = 4;
/// Height of the caption strip under the images: two lines of 13 px text with spacing.
pub const CAPTION: u32 = 40;
const FONT_PX: f64 = 13.0;

/// The picture's size for `panels` (all images drawn at their own size, top-aligned).
pub fn size(panels: &[Panel<'_>]) -> (u32, u32) {
    let w = panels.iter().map(|p| p.frame.width + GAP).sum::<u32>() + GAP;
    let h = panels.iter().map(|p| p.frame.height).max().unwrap_or(0) + CAPTION + GAP;
    (w, h)
}

/// Compose `panels` left to right on white with their captions centred under them.
pub fn compose(panels: &[Panel<'_>]) -> anyhow::Result<Rgb8Image> {
    let (w, h) = size(panels);
    let mut data = vec![255u8; 3 * (w as usize) * (h as usize)];
    let mut x0 = GAP;
    for p in panels {
        let f = p.frame;
        for y in 0..f.height {
            let src = 3 * (y * f.width) as usize;
            let dst = 3 * ((GAP + y) * w + x0) as usize;
            for (d, s) in data[dst..dst + 3 * f.width as usize]
                .iter_mut()
                .zip(&f.rgb[src..src + 3 * f.width as usize])
            {
                *d = to_u8(*s);
            }
        }
        x0 += f.width + GAP;
    }
    crate::measure::report::plot::register_font();
    {
        let root = BitMapBackend::with_buffer(&mut data, (w, h)).into_drawing_area();
        let image_h = panels.iter().map(|p| p.frame.height).max().unwrap_or(0);
        let style = ("sans-serif", FONT_PX)
            .into_font()
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Top));
        let mut x0 = GAP;
        for p in panels {
            let cx = (x0 + p.frame.width / 2) as i32;
            let y = (GAP + image_h + 4) as i32;
            for (i, line) in [&p.title, &p.caption].into_iter().enumerate() {
                root.draw(&Text::new(line.clone(), (cx, y + 17 * i as i32), &style))
                    .map_err(|e| anyhow::anyhow!("drawing the caption '{line}': {e:?}"))?;
            }
            x0 += p.frame.width + GAP;
        }
        root.present()
            .map_err(|e| anyhow::anyhow!("drawing the captions: {e:?}"))?;
    }
    Ok(Rgb8Image {
        width: w,
        height: h,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(w: u32, h: u32, v: f32) -> Frame {
        let mut f = Frame::new(w, h);
        f.rgb.iter_mut().for_each(|x| *x = v);
        f
    }

    #[test]
    fn panels_are_copied_side_by_side_with_captions_under_them() {
        let (a, b) = (flat(20, 10, 0.0), flat(30, 12, 1.0));
        let panels = [
            Panel {
                frame: &a,
                title: "native".into(),
                caption: "reference".into(),
            },
            Panel {
                frame: &b,
                title: "mesh".into(),
                caption: "30.00 dB".into(),
            },
        ];
        let img = compose(&panels).unwrap();
        assert_eq!(
            (img.width, img.height),
            (GAP + 20 + GAP + 30 + GAP, 12 + CAPTION + GAP)
        );
        let px = |x: u32, y: u32| {
            let i = 3 * (y * img.width + x) as usize;
            [img.data[i], img.data[i + 1], img.data[i + 2]]
        };
        // The first panel is black, the second white, the gap between them white.
        assert_eq!(px(GAP + 5, GAP + 5), [0, 0, 0]);
        assert_eq!(px(GAP + 20 + GAP + 5, GAP + 5), [255, 255, 255]);
        assert_eq!(px(GAP + 20 + 1, GAP + 5), [255, 255, 255]);
        // The captions put dark pixels into the strip under the images.
        let strip = (GAP + 12)..img.height;
        let dark = strip
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .filter(|&(x, y)| px(x, y)[0] < 128)
            .count();
        assert!(dark > 20, "captions drew {dark} dark pixels");
    }
}
