//! Accuracy-against-cost plots (PSNR against time, PSNR against triangles) with the Pareto front
//! and the baseline marked, written as PNG and SVG with `plotters`. The font is embedded (the
//! Ubuntu font shipped by `epaint_default_fonts`), so plots render on machines with no fonts.

use std::path::Path;
use std::sync::Once;

use anyhow::Context;
use plotters::prelude::*;
use plotters::style::FontStyle;

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct Point {
    /// The knob setting, e.g. "rings m=2".
    pub label: String,
    /// The knob family the point belongs to (one colour per series), e.g. "profile".
    pub series: String,
    /// Cost (milliseconds or triangles): lower is better.
    pub cost: f64,
    /// Accuracy (PSNR, dB): higher is better.
    pub psnr: f64,
    /// The baseline (MeshSplats default) is drawn as a star and labelled.
    pub baseline: bool,
}

/// Points of `pts` on the Pareto front: no other point has lower-or-equal cost and
/// higher-or-equal PSNR with one of them strict. Returned as indices sorted by cost.
pub fn pareto_front(pts: &[Point]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..pts.len())
        .filter(|&i| pts[i].cost.is_finite() && pts[i].psnr.is_finite())
        .collect();
    idx.sort_by(|&a, &b| {
        pts[a]
            .cost
            .total_cmp(&pts[b].cost)
            .then(pts[b].psnr.total_cmp(&pts[a].psnr))
    });
    let mut front = Vec::new();
    let mut best = f64::NEG_INFINITY;
    for i in idx {
        if pts[i].psnr > best {
            best = pts[i].psnr;
            front.push(i);
        }
    }
    front
}

/// Axis labels for costs spanning decades: 750k, 2.8M, 12 (no trailing ".0").
fn si(v: f64) -> String {
    let trim = |x: f64| {
        let t = format!("{x:.3}");
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    };
    let a = v.abs();
    if a >= 1e6 {
        format!("{}M", trim(v / 1e6))
    } else if a >= 1e3 {
        format!("{}k", trim(v / 1e3))
    } else {
        trim(v)
    }
}

static FONT: Once = Once::new();

pub(crate) fn register_font() {
    FONT.call_once(|| {
        // The Ubuntu font is a valid OpenType file; a failure here would only lose the labels.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

/// PSNR values of identical images are +inf; plots cap them here (and say so in the legend).
const PSNR_CAP: f64 = 80.0;

/// Write `stem.png` and `stem.svg`: cost on a log x axis, PSNR on y, one colour per series,
/// the Pareto front as a line, the baseline as a labelled star.
pub fn plot(pts: &[Point], x_label: &str, title: &str, stem: &Path) -> anyhow::Result<()> {
    register_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, (960, 640)).into_drawing_area();
        draw(&root, pts, x_label, title)
            .with_context(|| format!("{}: drawing the plot", png.display()))?;
        root.present()
            .with_context(|| format!("{}: writing", png.display()))?;
    }
    {
        let root = SVGBackend::new(&svg, (960, 640)).into_drawing_area();
        draw(&root, pts, x_label, title)
            .with_context(|| format!("{}: drawing the plot", svg.display()))?;
        root.present()
            .with_context(|| format!("{}: writing", svg.display()))?;
    }
    Ok(())
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    pts: &[Point],
    x_label: &str,
    title: &str,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let finite: Vec<&Point> = pts
        .iter()
        .filter(|p| p.cost.is_finite() && p.cost > 0.0)
        .collect();
    if finite.is_empty() {
        return Ok(());
    }
    let y = |p: &Point| p.psnr.min(PSNR_CAP);
    let (mut x0, mut x1) = finite.iter().fold((f64::MAX, f64::MIN), |(a, b), p| {
        (a.min(p.cost), b.max(p.cost))
    });
    let (mut y0, mut y1) = finite
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(y(p)), b.max(y(p))));
    if x1 <= x0 {
        x1 = x0 * 2.0;
    }
    x0 /= 1.3;
    x1 *= 1.3;
    let pad = ((y1 - y0) * 0.1).max(0.5);
    y0 -= pad;
    y1 += pad;
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 24))
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(56)
        .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    chart
        .configure_mesh()
        .x_label_formatter(&|v| si(*v))
        .x_desc(x_label)
        .y_desc("PSNR against native splatting (dB)")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut series: Vec<&str> = pts.iter().map(|p| p.series.as_str()).collect();
    series.sort_unstable();
    series.dedup();
    for (si, s) in series.iter().enumerate() {
        let colour = Palette99::pick(si).to_rgba();
        let members: Vec<&Point> = finite
            .iter()
            .copied()
            .filter(|p| p.series == *s && !p.baseline)
            .collect();
        chart
            .draw_series(
                members
                    .iter()
                    .map(|p| Circle::new((p.cost, y(p)), 5, colour.filled())),
            )
            .map_err(|e| anyhow::anyhow!("{e:?}"))?
            .label(*s)
            .legend(move |(x, yy)| Circle::new((x, yy), 5, colour.filled()));
        chart
            .draw_series(members.iter().map(|p| {
                Text::new(
                    p.label.clone(),
                    (p.cost, y(p)),
                    ("sans-serif", 12).into_font().color(&BLACK),
                )
            }))
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    }
    let front: Vec<(f64, f64)> = pareto_front(pts)
        .into_iter()
        .filter(|&i| pts[i].cost > 0.0)
        .map(|i| (pts[i].cost, y(&pts[i])))
        .collect();
    chart
        .draw_series(LineSeries::new(front, BLACK.stroke_width(2)))
        .map_err(|e| anyhow::anyhow!("{e:?}"))?
        .label("Pareto front")
        .legend(|(x, yy)| PathElement::new(vec![(x, yy), (x + 16, yy)], BLACK.stroke_width(2)));
    for p in finite.iter().filter(|p| p.baseline) {
        chart
            .draw_series(std::iter::once(TriangleMarker::new(
                (p.cost, y(p)),
                9,
                RED.filled(),
            )))
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        chart
            .draw_series(std::iter::once(Text::new(
                format!("{} (MeshSplats default)", p.label),
                (p.cost, y(p)),
                ("sans-serif", 14).into_font().color(&RED),
            )))
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(cost: f64, psnr: f64) -> Point {
        Point {
            label: String::new(),
            series: "s".into(),
            cost,
            psnr,
            baseline: false,
        }
    }

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        let pts = vec![
            p(1.0, 20.0),
            p(2.0, 19.0),
            p(2.0, 25.0),
            p(3.0, 24.0),
            p(4.0, 30.0),
            p(0.5, f64::NAN),
        ];
        assert_eq!(pareto_front(&pts), vec![0, 2, 4]);
    }

    #[test]
    fn si_labels() {
        assert_eq!(si(2_830_200.0), "2.83M");
        assert_eq!(si(707_550.0), "707.55k");
        assert_eq!(si(1e6), "1M");
        assert_eq!(si(12.0), "12");
    }

    #[test]
    fn plots_are_written_as_png_and_svg() {
        let dir = tempfile::tempdir().unwrap();
        let mut pts = vec![p(10.0, 25.0), p(20.0, 28.0), p(40.0, f64::INFINITY)];
        pts[0].baseline = true;
        pts[0].label = "meshsplats".into();
        plot(&pts, "triangles", "test", &dir.path().join("x")).unwrap();
        let png = std::fs::metadata(dir.path().join("x.png")).unwrap().len();
        let svg = std::fs::read_to_string(dir.path().join("x.svg")).unwrap();
        assert!(png > 1000);
        assert!(svg.contains("MeshSplats default"));
    }
}
