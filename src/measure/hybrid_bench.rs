//! The measurements of `bench hybrid`: native splatting and the GES hybrid timed on the same
//! cloud and camera in one run, and the sweep of split thresholds and pass knobs, each row
//! with its surfel count, median render time and PSNR against native.
//!
//! Every timing is the median of `repeat` runs after one untimed warm-up. Native and hybrid
//! renders alternate, so load from other processes hits both alike.

use std::time::{Duration, Instant};

use splatbridge_hybrid::ges::{render_ges, Blend, GesOptions, GesStats};
use splatbridge_hybrid::{render, RenderOptions, RenderStats};
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::surfels::{split, SplitParams, SurfelCloud};
use splatbridge_scene::{Camera, Frame, GaussianCloud};

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// Median time of `repeat` runs of `f` after one warm-up; returns the last output.
fn timed<T>(
    repeat: usize,
    mut f: impl FnMut() -> anyhow::Result<T>,
) -> anyhow::Result<(Duration, T)> {
    let mut out = f()?;
    let mut times = Vec::with_capacity(repeat);
    for _ in 0..repeat.max(1) {
        let t0 = Instant::now();
        out = f()?;
        times.push(t0.elapsed());
    }
    Ok((median(times), out))
}

/// Native and the hybrid, alternated.
pub struct HeadToHead {
    pub native: Frame,
    pub native_stats: RenderStats,
    pub native_time: Duration,
    pub hybrid: Frame,
    pub hybrid_stats: GesStats,
    pub hybrid_time: Duration,
}

/// Time native splatting of `cloud` against the hybrid of its split `(surfels, gaussians)`.
pub fn head_to_head(
    cloud: &GaussianCloud,
    (s, g): (&SurfelCloud, &GaussianCloud),
    cam: &Camera,
    nopts: &RenderOptions,
    opts: &GesOptions,
    repeat: usize,
) -> anyhow::Result<HeadToHead> {
    let (mut native, mut nstats) = render(cloud, cam, nopts)?;
    let (mut hframe, mut hs) = render_ges(s, g, cam, opts)?;
    let (mut tn, mut th) = (Vec::new(), Vec::new());
    for _ in 0..repeat.max(1) {
        let t0 = Instant::now();
        (native, nstats) = render(cloud, cam, nopts)?;
        tn.push(t0.elapsed());
        let t0 = Instant::now();
        (hframe, hs) = render_ges(s, g, cam, opts)?;
        th.push(t0.elapsed());
    }
    Ok(HeadToHead {
        native,
        native_stats: nstats,
        native_time: median(tn),
        hybrid: hframe,
        hybrid_stats: hs,
        hybrid_time: median(th),
    })
}

/// One setting of the sweep.
pub struct Row {
    pub label: String,
    pub surfels: usize,
    pub gaussians: usize,
    /// Median render time (the split excluded).
    pub ms: f64,
    pub psnr: f64,
    pub stats: GesStats,
}

/// Split `cloud` by `p` and time the hybrid with `opts` against `native`.
pub fn hybrid_row(
    label: String,
    cloud: &GaussianCloud,
    p: &SplitParams,
    cam: &Camera,
    opts: &GesOptions,
    native: &Frame,
    repeat: usize,
) -> anyhow::Result<Row> {
    let (s, g) = split(cloud, p);
    let (t, (frame, stats)) = timed(repeat, || Ok(render_ges(&s, &g, cam, opts)?))?;
    Ok(Row {
        label,
        surfels: s.len(),
        gaussians: g.len(),
        ms: t.as_secs_f64() * 1e3,
        psnr: psnr(&frame, native)?,
        stats,
    })
}

/// The pass knobs varied one at a time from `opts` at the benchmarked thresholds: the other
/// blend, the other surfel footprint (GES's rim or the √2σ disc), blur, supersampling and the
/// ε factor.
pub fn knob_variants(opts: &GesOptions) -> [(&'static str, GesOptions); 7] {
    let opts = *opts;
    let (fp_label, fp) = if opts.footprint_sigmas == std::f32::consts::SQRT_2 {
        (
            "defaults, footprint 3.33σ",
            splatbridge_scene::surfels::FOOTPRINT_SIGMAS,
        )
    } else {
        ("defaults, footprint 1.41σ", std::f32::consts::SQRT_2)
    };
    let other = match opts.blend {
        Blend::Sorted => ("defaults, unsorted blend", Blend::Unsorted),
        Blend::Unsorted => ("defaults, sorted blend", Blend::Sorted),
    };
    let with = |f: &dyn Fn(&mut GesOptions)| {
        let mut o = opts;
        f(&mut o);
        o
    };
    [
        (other.0, with(&|o| o.blend = other.1)),
        (fp_label, with(&|o| o.footprint_sigmas = fp)),
        ("defaults, blur on", with(&|o| o.blur = true)),
        ("defaults, supersample 4", with(&|o| o.supersample = 4)),
        ("defaults, ε factor 2", with(&|o| o.epsilon_factor = 2.0)),
        ("defaults, ε factor 10", with(&|o| o.epsilon_factor = 10.0)),
        ("defaults, ε factor 0", with(&|o| o.epsilon_factor = 0.0)),
    ]
}

/// The whole sweep: no surfels, every opacity × flatness pair over `p`, then
/// [`knob_variants`] at `p`; each row goes to `row` as it is measured.
pub fn sweep(
    cloud: &GaussianCloud,
    p: &SplitParams,
    cam: &Camera,
    opts: &GesOptions,
    native: &Frame,
    (opacities, flatnesses): (&[f32], &[f32]),
    repeat: usize,
    row: &mut dyn FnMut(Row),
) -> anyhow::Result<()> {
    let none = SplitParams::none();
    row(hybrid_row(
        "no surfels (pass 2 only)".into(),
        cloud,
        &none,
        cam,
        opts,
        native,
        repeat,
    )?);
    for &a in opacities {
        for &r in flatnesses {
            let sp = SplitParams {
                min_opacity: a,
                max_flatness: r,
                ..*p
            };
            let label = format!("A={a} R={r}");
            row(hybrid_row(label, cloud, &sp, cam, opts, native, repeat)?);
        }
    }
    for (label, o) in knob_variants(opts) {
        row(hybrid_row(label.into(), cloud, p, cam, &o, native, repeat)?);
    }
    Ok(())
}
