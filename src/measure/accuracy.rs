//! The accuracy sweep behind `splatbridge accuracy`: the named knobs one at a time around the
//! defaults (meshing profile, segments, extent, k-buffer size, native extent, SH degree, file
//! format quantisation, hybrid split, the ray-traced Gaussians' footprint and samples), each measured against the reference (native splatting,
//! reference settings) at the same cameras, with time; then `accuracy.json`, `accuracy.md`
//! and plots of PSNR against time and against triangles with the Pareto front and the
//! MeshSplats default marked.

use std::path::Path;

use anyhow::Context;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_hybrid::ges::GesOptions;
use splatbridge_hybrid::native::RenderOptions as NativeOptions;
use splatbridge_hybrid::project::Extent;
use splatbridge_raytrace::{
    Footprint, GaussianTracer, HitOrder, RenderOptions as TraceOptions, SampleFootprint,
    ShDirection,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::spz::SpzOptions;
use splatbridge_scene::formats::write::{write_cloud, CloudFormat};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::surfels::SplitParams;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::measure::parity::{self, CompareConfig};
use crate::measure::report::plot::{self, Point};
use crate::measure::report::{markdown_table, Record};

/// One knob setting to measure.
pub enum Setting {
    Mesh(Box<ConvertOptions>, usize),
    Native(NativeOptions),
    Hybrid(SplitParams),
    /// The hybrid with this split and these options (the blend rows, a chosen `--split`).
    HybridWith(SplitParams, GesOptions),
    /// Write the cloud in this format, read it back, render natively.
    Format(CloudFormat),
    /// Ray-trace the Gaussians with these tracer options (footprint, spp).
    Gaussian(TraceOptions),
    /// Convert, read back and trace the mesh with these tracer options (spp).
    MeshWith(Box<ConvertOptions>, TraceOptions),
}

/// A file name ending for a single-cloud format (the loader detects by content; the name is
/// for a person looking at the folder).
fn format_ending(f: &CloudFormat) -> &'static str {
    match f {
        CloudFormat::Ply => "ply",
        CloudFormat::CompressedPly => "compressed.ply",
        CloudFormat::Splat => "splat",
        CloudFormat::Spz(_) => "spz",
        CloudFormat::Ksplat(_) => "ksplat",
    }
}

fn mesh(profile: Profile, segments: Option<usize>, rings: usize) -> ConvertOptions {
    ConvertOptions {
        profile,
        segments,
        rings,
        ..ConvertOptions::default()
    }
}

/// The sweep: (family, value label, setting, is the MeshSplats default). `only` names the
/// families to keep (all when empty).
pub fn settings(only: &[String]) -> Vec<(&'static str, String, Setting, bool)> {
    let want = |f: &str| only.is_empty() || only.iter().any(|o| o == f);
    let mut v = Vec::new();
    let base = ConvertOptions::default();
    if want("profile") {
        v.push((
            "profile",
            "meshsplats".into(),
            Setting::Mesh(Box::new(mesh(Profile::MeshSplats, None, base.rings)), 16),
            true,
        ));
        for m in 1..=4 {
            v.push((
                "profile",
                format!("rings m={m}"),
                Setting::Mesh(Box::new(mesh(Profile::Rings, None, m)), 16),
                false,
            ));
        }
        v.push((
            "profile",
            "texture".into(),
            Setting::Mesh(Box::new(mesh(Profile::Texture, None, base.rings)), 16),
            false,
        ));
    }
    if want("segments") {
        for n in [4, 6, 8, 12, 16, 32] {
            v.push((
                "segments",
                format!("rings n={n}"),
                Setting::Mesh(Box::new(mesh(Profile::Rings, Some(n), base.rings)), 16),
                false,
            ));
        }
    }
    if want("extent") {
        // The 2.7σ cut against the 1/255 footprint, both as single-ring fans.
        v.push((
            "extent",
            "2.7σ (meshsplats)".into(),
            Setting::Mesh(Box::new(mesh(Profile::MeshSplats, None, 1)), 16),
            false,
        ));
        v.push((
            "extent",
            "1/255 footprint (rings m=1)".into(),
            Setting::Mesh(Box::new(mesh(Profile::Rings, None, 1)), 16),
            false,
        ));
    }
    if want("k") {
        for k in [4, 8, 16, 32] {
            v.push((
                "k",
                format!("k={k}"),
                Setting::Mesh(Box::new(base.clone()), k),
                false,
            ));
        }
    }
    if want("native-extent") {
        v.push((
            "native-extent",
            "3σ".into(),
            Setting::Native(NativeOptions::default()),
            false,
        ));
        v.push((
            "native-extent",
            "alpha".into(),
            Setting::Native(NativeOptions {
                extent: Extent::Alpha,
                ..NativeOptions::default()
            }),
            false,
        ));
    }
    if want("sh-degree") {
        for d in 0..=3u8 {
            v.push((
                "sh-degree",
                format!("SH ≤ {d}"),
                Setting::Native(NativeOptions {
                    sh_degree_cap: d,
                    ..NativeOptions::default()
                }),
                false,
            ));
        }
    }
    if want("format") {
        // What each lossy file format costs: the 3DGS PLY is the lossless control.
        let spz = |version| {
            CloudFormat::Spz(SpzOptions {
                version,
                ..SpzOptions::default()
            })
        };
        for (label, f) in [
            ("3DGS PLY", CloudFormat::Ply),
            ("compressed PLY", CloudFormat::CompressedPly),
            (".splat", CloudFormat::Splat),
            ("SPZ v3", spz(3)),
            ("SPZ v2", spz(2)),
        ] {
            v.push(("format", label.into(), Setting::Format(f), false));
        }
    }
    if want("footprint") {
        footprint_rows(&mut v, FOOTPRINT);
    }
    if want("footprint-spp") {
        footprint_rows(&mut v, FOOTPRINT_SPP);
    }
    if want("footprint-causes") {
        footprint_rows(&mut v, FOOTPRINT_CAUSES);
    }
    // `trace`'s default for mode gaussian alone (footprint on, mean-depth order, SH toward the
    // mean), only when named: the one row to measure on large scenes and at large sizes.
    if only.iter().any(|o| o == "footprint-default") {
        footprint_rows(
            &mut v,
            &[(
                "on + both (trace's default)",
                Footprint::On,
                1,
                SUB,
                HitOrder::MeanDepth,
                ShDirection::Mean,
            )],
        );
    }
    if want("mesh-spp") {
        // The default profile's mesh traced with 1 and 4 samples per pixel: triangles get no
        // footprint, so supersampling is the mesh's only filter.
        for spp in [1, 4] {
            v.push((
                "mesh-spp",
                format!("{} spp={spp}", base.profile.name()),
                Setting::MeshWith(
                    Box::new(base.clone()),
                    TraceOptions {
                        spp,
                        ..TraceOptions::default()
                    },
                ),
                false,
            ));
        }
    }
    if want("hybrid") {
        // Around the defaults (opacity ≥ 0.8, flatness ≤ 0.3), including GES's own 0.8 rule
        // with a stricter flatness and the setting that ignores flatness.
        for (a, r) in [(0.5, 0.3), (0.8, 0.1), (0.8, 0.3), (0.9, 0.5), (0.95, 1.0)] {
            v.push((
                "hybrid",
                format!("opacity≥{a} flat≤{r}"),
                Setting::Hybrid(SplitParams::guarded(a, r)),
                false,
            ));
        }
        v.extend(crate::pipeline::split_auto::accuracy_rows());
    }
    if want("hybrid") || want("blend") {
        v.extend(crate::pipeline::split_auto::blend_accuracy_rows());
    }
    v
}

/// One footprint row: label, footprint, spp, sample footprint, hit order, SH direction.
type FootprintRow = (
    &'static str,
    Footprint,
    u32,
    SampleFootprint,
    HitOrder,
    ShDirection,
);

const SUB: SampleFootprint = SampleFootprint::Subpixel;

/// The ray-traced Gaussians with and without the pixel footprint.
const FOOTPRINT: &[FootprintRow] = &[
    (
        "off spp=1",
        Footprint::Off,
        1,
        SUB,
        HitOrder::Hit,
        ShDirection::Ray,
    ),
    (
        "on spp=1",
        Footprint::On,
        1,
        SUB,
        HitOrder::Hit,
        ShDirection::Ray,
    ),
];

/// At 4 samples per pixel: without the footprint, with the sub-pixel's footprint, and with
/// the whole pixel's on every sample.
const FOOTPRINT_SPP: &[FootprintRow] = &[
    (
        "off spp=4",
        Footprint::Off,
        4,
        SUB,
        HitOrder::Hit,
        ShDirection::Ray,
    ),
    (
        "on spp=4 subpixel",
        Footprint::On,
        4,
        SUB,
        HitOrder::Hit,
        ShDirection::Ray,
    ),
    (
        "on spp=4 pixel",
        Footprint::On,
        4,
        SampleFootprint::Pixel,
        HitOrder::Hit,
        ShDirection::Ray,
    ),
];

/// What the 3-D footprint cannot remove, one native rule at a time (native's hit order, its
/// SH direction), and the projected mode (native's 2-D conic) with both.
const FOOTPRINT_CAUSES: &[FootprintRow] = &[
    (
        "on + mean-depth order",
        Footprint::On,
        1,
        SUB,
        HitOrder::MeanDepth,
        ShDirection::Ray,
    ),
    (
        "on + SH toward mean",
        Footprint::On,
        1,
        SUB,
        HitOrder::Hit,
        ShDirection::Mean,
    ),
    (
        "on + both",
        Footprint::On,
        1,
        SUB,
        HitOrder::MeanDepth,
        ShDirection::Mean,
    ),
    (
        "projected",
        Footprint::Projected,
        1,
        SUB,
        HitOrder::MeanDepth,
        ShDirection::Mean,
    ),
];

fn footprint_rows(v: &mut Vec<(&'static str, String, Setting, bool)>, rows: &[FootprintRow]) {
    for &(label, footprint, spp, sample_footprint, order, sh_direction) in rows {
        v.push((
            "footprint",
            label.into(),
            Setting::Gaussian(TraceOptions {
                footprint,
                spp,
                sample_footprint,
                order,
                sh_direction,
                ..TraceOptions::default()
            }),
            false,
        ));
    }
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// The MeshSplats default, marked on the plots.
fn is_baseline(r: &Record) -> bool {
    r.knob == "profile" && r.value == "meshsplats"
}

/// Plot points from the records: every setting against time; against triangles only the knobs
/// that change the mesh's shape (the k-buffer changes time only, and the extent rows are the
/// same meshes as two profile rows, so they would sit on top of other points).
fn points(records: &[Record]) -> (Vec<Point>, Vec<Point>) {
    let point = |r: &Record, cost: f64| Point {
        label: r.value.clone(),
        series: r.knob.clone(),
        cost,
        psnr: r.psnr,
        baseline: is_baseline(r),
    };
    let time = records.iter().map(|r| point(r, r.milliseconds)).collect();
    let tris = records
        .iter()
        .filter(|r| r.triangles > 0 && (r.knob == "profile" || r.knob == "segments"))
        .map(|r| point(r, r.triangles as f64))
        .collect();
    (time, tris)
}

/// Plots and `accuracy.md` in `out` (a staging folder, see [`commit_outputs`]) from the
/// records (also what `--replot` redraws); `what` describes the measurement in the table's
/// heading.
fn write_outputs(out: &Path, what: &str, records: &[Record]) -> anyhow::Result<()> {
    let (points_time, points_tris) = points(records);
    plot::plot(
        &points_time,
        "milliseconds per frame (log)",
        "PSNR against time",
        &out.join("psnr_vs_time"),
    )?;
    if !points_tris.is_empty() {
        plot::plot(
            &points_tris,
            "triangles (log)",
            "PSNR against triangles",
            &out.join("psnr_vs_triangles"),
        )?;
    }
    let front: Vec<String> = plot::pareto_front(&points_tris)
        .into_iter()
        .map(|i| points_tris[i].label.clone())
        .collect();
    let md = format!(
        "# Accuracy against cost\n\n{what}. Reference: native splatting, reference settings. \
         Each row changes one knob from the defaults; PSNR is the mean over cameras; milliseconds are \
         render (trace) times on a shared 2-core machine, so compare them within one run only.\n\n\
         ![PSNR against triangles](psnr_vs_triangles.png)\n![PSNR against time](psnr_vs_time.png)\n\n\
         Pareto front (PSNR against triangles): {}\n\n{}",
        front.join(", "),
        markdown_table(records, false)
    );
    std::fs::write(out.join("accuracy.md"), md.as_bytes())
        .with_context(|| out.join("accuracy.md").display().to_string())?;
    Ok(())
}

/// Write `accuracy.json`, the plots and `accuracy.md` into `out` as one set: all are made in a
/// staging folder and move in together, so a failure leaves the previous set as it was.
pub fn commit_outputs(out: &Path, what: &str, records: &[Record]) -> anyhow::Result<()> {
    let mut set = splatbridge_scene::output::OutputSet::new();
    let stage = set.stage_dir(out)?;
    write_staged(&stage, what, records)?;
    set.commit()?;
    Ok(())
}

/// Write `accuracy.json`, `accuracy.md` and the plots into a staging folder (a merge of
/// sharded sweeps writes them this way too).
pub fn write_staged(stage: &Path, what: &str, records: &[Record]) -> anyhow::Result<()> {
    write_records(stage, records)?;
    write_outputs(stage, what, records)
}

/// What one sweep measures: the cloud (as a static scene, so exports read it in place rather
/// than from a copy), the cameras and their reference frames, the time written into the
/// records, and where temporary exports go.
pub struct Sweep<'a> {
    pub scene: &'a DynamicScene,
    pub cameras: &'a [Camera],
    pub references: &'a [Frame],
    pub time: f64,
    pub work_dir: &'a Path,
    pub drop_invalid: bool,
}

impl Sweep<'_> {
    /// The swept cloud.
    pub fn cloud(&self) -> &GaussianCloud {
        &self.scene.static_gaussians
    }
}

/// The reference frames: native splatting with reference settings at every camera.
pub fn reference_frames(cloud: &GaussianCloud, cameras: &[Camera]) -> anyhow::Result<Vec<Frame>> {
    cameras
        .iter()
        .map(|c| parity::render_native(cloud, c, &NativeOptions::default()).map(|r| r.frame))
        .collect()
}

/// Export `opts` of the sweep's cloud, read the file back and trace it through every sweep
/// camera with `trace`, handing each image to `push` (frame, reference, ms, camera, triangles,
/// bytes). The `trace-mesh` rows of both mesh settings.
fn trace_sweep_mesh(
    s: &Sweep<'_>,
    cfg: &CompareConfig,
    index: usize,
    opts: &ConvertOptions,
    trace: TraceOptions,
    push: &mut impl FnMut(&Frame, &Frame, f64, &Camera, u64, u64) -> anyhow::Result<()>,
) -> anyhow::Result<&'static str> {
    let path = s.work_dir.join(format!("sweep_{index}.glb"));
    let mut m = parity::export_and_load(s.scene, opts, &path, cfg.backend, cfg.preset)?;
    for (c, reference) in s.cameras.iter().zip(s.references) {
        let img = parity::render_mesh_with(&mut m, c, 0.0, trace.clone())?;
        push(&img.frame, reference, img.ms, c, m.triangles, m.bytes)?;
    }
    let _ = std::fs::remove_file(&path);
    Ok("trace-mesh")
}

/// Measure one setting at every camera: one record (the first camera's, with PSNR and
/// milliseconds the means over cameras). `index` names its temporary files.
pub fn measure_setting(
    s: &Sweep<'_>,
    index: usize,
    family: &str,
    value: &str,
    setting: &Setting,
) -> anyhow::Result<Record> {
    let cfg = CompareConfig::default();
    let mut psnr = Vec::new();
    let mut ms = Vec::new();
    let mut first: Option<Record> = None;
    let mut push = |img: &Frame,
                    reference: &Frame,
                    t_ms: f64,
                    cam: &Camera,
                    tris: u64,
                    b: u64|
     -> anyhow::Result<()> {
        let r = parity::measure(
            reference,
            img,
            Record {
                renderer: String::new(),
                knob: family.into(),
                value: value.into(),
                camera: cam.name.clone(),
                time: s.time,
                milliseconds: t_ms,
                triangles: tris,
                bytes: b,
                ..Record::default()
            },
        )?;
        psnr.push(r.psnr);
        ms.push(t_ms);
        if first.is_none() {
            first = Some(r);
        }
        Ok(())
    };
    let views = s.cameras.iter().zip(s.references);
    let renderer = match setting {
        Setting::Mesh(opts, k) => {
            let o = TraceOptions {
                k: *k,
                ..TraceOptions::default()
            };
            trace_sweep_mesh(s, &cfg, index, opts, o, &mut push)?
        }
        Setting::Native(o) => {
            for (c, reference) in views {
                let img = parity::render_native(s.cloud(), c, o)?;
                push(&img.frame, reference, img.ms, c, 0, 0)?;
            }
            "native"
        }
        Setting::Format(f) => {
            let path = s
                .work_dir
                .join(format!("sweep_{index}.{}", format_ending(f)));
            let bytes = write_cloud(&path, s.cloud(), *f)?;
            let read = ReadOptions {
                drop_invalid: s.drop_invalid,
            };
            let decoded = splatbridge_scene::formats::load_cloud(&path, &read);
            let _ = std::fs::remove_file(&path);
            let (decoded, _) = decoded?;
            for (c, reference) in views {
                let img = parity::render_native(&decoded, c, &NativeOptions::default())?;
                push(&img.frame, reference, img.ms, c, 0, bytes)?;
            }
            "native"
        }
        Setting::MeshWith(opts, o) => trace_sweep_mesh(s, &cfg, index, opts, o.clone(), &mut push)?,
        Setting::Gaussian(o) => {
            let tracer = GaussianTracer::new(s.cloud().clone(), cfg.backend, cfg.preset)?;
            let mut r = crate::pipeline::Renderer::Gaussian {
                tracer,
                options: o.clone(),
            };
            for (c, reference) in views {
                let img = parity::render_gaussians_with(&mut r, c, o.clone())?;
                push(&img.frame, reference, img.ms, c, 0, 0)?;
            }
            "trace-gaussian"
        }
        Setting::Hybrid(split) => {
            for (c, reference) in views {
                let img = parity::render_hybrid(s.cloud(), c, *split, &cfg.ges)?;
                push(&img.frame, reference, img.ms, c, 0, 0)?;
            }
            "hybrid"
        }
        Setting::HybridWith(split, ges) => {
            for (c, reference) in views {
                let img = parity::render_hybrid(s.cloud(), c, *split, ges)?;
                push(&img.frame, reference, img.ms, c, 0, 0)?;
            }
            "hybrid"
        }
    };
    let mut r = first.context("no camera")?;
    r.renderer = renderer.into();
    r.psnr = mean(&psnr);
    r.milliseconds = mean(&ms);
    r.camera = format!("mean of {}", s.cameras.len());
    Ok(r)
}

/// Write `accuracy.json` in `out` (a staging folder, see [`commit_outputs`]).
fn write_records(out: &Path, records: &[Record]) -> anyhow::Result<()> {
    let json = serde_json::to_string_pretty(records)?;
    std::fs::write(out.join("accuracy.json"), json.as_bytes())
        .with_context(|| out.join("accuracy.json").display().to_string())?;
    Ok(())
}

/// Read `accuracy.json` back from `out` (for `--replot`).
pub fn read_records(out: &Path) -> anyhow::Result<Vec<Record>> {
    let path = out.join("accuracy.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not an accuracy report", path.display()))
}
