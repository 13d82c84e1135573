//! The demo on a real capture: load it, export it the ways a user takes it away (the default
//! texture GLB, a distilled GLB, `KHR_gaussian_splatting` GLB and `.spz` splats), render native
//! splatting (the reference), the hybrid, the traced Gaussians and the traced exports at views
//! half-way between the distillation's fitting views, and measure each against native.
//!
//! Everything goes through the library the commands use: `parity` renders and measures,
//! `distill::run::distill_export` fits (what `convert --distill` runs), the converter writes
//! the files and the tracer reads them back as a viewer would.

use std::path::{Path, PathBuf};

use anyhow::Context;
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::ConvertOptions;
use splatbridge_raytrace::{
    BackendKind, BuildPreset, GaussianTracer, RenderOptions as TraceOptions,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::spz::SpzOptions;
use splatbridge_scene::formats::{write_cloud, CloudFormat};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::surfels::SplitParams;
use splatbridge_scene::{metrics, Camera, Frame};

use super::stages::Stages;
use crate::distill::run::{distill_export, Outcome, ViewRequest};
use crate::distill::DistillOptions;
use crate::measure::parity;
use crate::measure::report::Record;
use crate::pipeline::Renderer;

/// The capture shipped with the project (`fixtures/real/`, PDAL's test data, BSD-3-Clause).
pub const SHIPPED_CAPTURE: &str = "fixtures/real/fourth_st.spz";

/// The shipped capture: relative to the working directory when run from a checkout, else
/// where the crate was built from.
pub fn default_capture() -> PathBuf {
    let here = PathBuf::from(SHIPPED_CAPTURE);
    if here.exists() {
        here
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(SHIPPED_CAPTURE)
    }
}

/// What the capture part of the demo runs, and at what size.
#[derive(Clone, Debug)]
pub struct CaptureConfig {
    pub input: PathBuf,
    /// Keep only the first N Gaussians (a cut, for tests).
    pub first: Option<usize>,
    /// Size of every image: the fitting views and the measured views alike (a distilled
    /// export is made for the size it is fitted at; docs/distill.md).
    pub width: u32,
    pub height: u32,
    /// Fitting views of the distillation (`orbit:N`).
    pub fit_views: usize,
    /// Adam steps of the distillation.
    pub iterations: usize,
    /// Measured views, half-way between fitting views (never fitted). The first is the
    /// picture's.
    pub views: usize,
    /// k-buffer of the tracers (the parity pipeline's 16).
    pub k: usize,
}

impl Default for CaptureConfig {
    fn default() -> Self {
        // Sized so the whole demo stays within about a minute of wall time on a quiet
        // 2-core machine (the report's stage table has the measured costs): the tracer costs
        // about 2 s of CPU per 160×120 view of the default GLB of `fourth_st`, and the
        // distilled GLB, made of Gaussians widened for these views, about four times that.
        // 8 fitting views and 15 steps are a sixth of `convert --distill`'s 48 views and a
        // quarter of its 60 steps; on `fourth_st` they lift the measured views from about
        // 23.7 to 32.8 dB (measured with this demo).
        CaptureConfig {
            input: default_capture(),
            first: None,
            width: 160,
            height: 120,
            fit_views: 8,
            iterations: 15,
            views: 2,
            k: 16,
        }
    }
}

/// One output of the demo: a file a user takes away, or a renderer of the Gaussians.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Output {
    /// Stable key: `native`, `glb`, `distilled`, `khr`, `spz`, `hybrid`, `trace-gaussian`.
    pub key: &'static str,
    /// What it is, as the picture's caption says it.
    pub title: String,
    /// The file, relative to the report (exports only).
    pub file: Option<String>,
    pub bytes: Option<u64>,
    pub triangles: Option<u64>,
    /// PSNR against native per measured view (dB; +inf for an identical image).
    pub psnr: Vec<f64>,
    /// Render time per view (ms).
    pub milliseconds: Vec<f64>,
}

impl Output {
    /// Mean of the finite PSNRs (+inf when every image equals the reference).
    pub fn mean_psnr(&self) -> f64 {
        let f: Vec<f64> = self
            .psnr
            .iter()
            .copied()
            .filter(|p| p.is_finite())
            .collect();
        if f.is_empty() {
            f64::INFINITY
        } else {
            f.iter().sum::<f64>() / f.len() as f64
        }
    }

    pub fn worst_psnr(&self) -> f64 {
        self.psnr.iter().copied().fold(f64::INFINITY, f64::min)
    }
}

/// What the capture part measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CaptureRun {
    /// The capture's file name.
    pub name: String,
    pub input: PathBuf,
    pub input_bytes: u64,
    pub gaussians: usize,
    pub sh_degree: u8,
    pub width: u32,
    pub height: u32,
    pub fit_views: usize,
    /// Names of the measured views.
    pub views: Vec<String>,
    pub outputs: Vec<Output>,
    /// Every measured image, for the per-image table (paths relative to the report).
    pub records: Vec<Record>,
    pub distill: Outcome,
    pub stages: Stages,
}

impl CaptureRun {
    pub fn output(&self, key: &str) -> Option<&Output> {
        self.outputs.iter().find(|o| o.key == key)
    }
}

/// The images of the picture's view, by output key.
pub type PictureFrames = Vec<(&'static str, Frame)>;

/// Run the capture part into `dir`: exports next to the report, images in `dir/images`.
/// Returns the measurements and the picture view's frames.
pub fn run(
    cfg: &CaptureConfig,
    dir: &Path,
    progress: &dyn Fn(&str),
) -> anyhow::Result<(CaptureRun, PictureFrames)> {
    let images = dir.join("images");
    std::fs::create_dir_all(&images)
        .with_context(|| format!("{}: cannot create the output folder", images.display()))?;
    let mut stages = Stages::default();
    let name = cfg
        .input
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "capture".into());
    progress(&format!("load {}", cfg.input.display()));
    let input_bytes = std::fs::metadata(&cfg.input)
        .with_context(|| format!("{}: cannot read the capture", cfg.input.display()))?
        .len();
    let scene = stages.time(&format!("load `{name}`"), || -> anyhow::Result<_> {
        let (mut scene, _warnings) =
            splatbridge_scene::manifest::load_scene(&cfg.input, &ReadOptions::default())
                .with_context(|| cfg.input.display().to_string())?;
        if let Some(n) = cfg.first {
            scene.static_gaussians.retain_indices(|i| i < n);
        }
        Ok(scene)
    })?;
    if scene.is_dynamic() {
        anyhow::bail!(
            "{}: the capture part of the demo takes a static capture (the street shows the dynamic part)",
            cfg.input.display()
        );
    }
    let t = scene.time.start;
    // The fitting views are the distillation's own (`distill_export` resolves the same spec);
    // the measured views are the held-back ones between them.
    let cams: Vec<Camera> = crate::distill::run::resolve_views(
        &scene,
        t,
        &ViewRequest {
            spec: format!("orbit:{}", cfg.fit_views),
            width: cfg.width,
            height: cfg.height,
            held_back: cfg.views,
            validation: 0,
            validation_fine: 0,
            times: 1,
            ..ViewRequest::default()
        },
    )?
    .held
    .into_iter()
    .map(|h| h.camera)
    .collect();
    let mut m = Measure::new(&images, &cams);

    // The reference, and the two renderers of the Gaussians that need no export.
    let refs = stages.time(
        &format!("native splatting, {} views", cams.len()),
        || -> anyhow::Result<Vec<Frame>> {
            let opts = Default::default();
            let mut out = Vec::new();
            for cam in &cams {
                progress(&format!("native {}", cam.name));
                let r = parity::render_native(&scene.static_gaussians, cam, &opts)?;
                out.push(r.frame);
                m.ms.push(r.ms);
            }
            Ok(out)
        },
    )?;
    let native_ms = std::mem::take(&mut m.ms);
    let mut outputs = vec![m.output(
        "native",
        "native splatting",
        None,
        None,
        &refs,
        &refs,
        native_ms,
        Record {
            renderer: "native".into(),
            ..Record::default()
        },
    )?];
    let hybrid = stages.time(
        &format!("hybrid, {} views", cams.len()),
        || -> anyhow::Result<Vec<Frame>> {
            let ges = crate::pipeline::split_auto::default_ges_options();
            let mut out = Vec::new();
            for cam in &cams {
                progress(&format!("hybrid {}", cam.name));
                let r = parity::render_hybrid(
                    &scene.static_gaussians,
                    cam,
                    SplitParams::default(),
                    &ges,
                )?;
                out.push(r.frame);
                m.ms.push(r.ms);
            }
            Ok(out)
        },
    )?;
    let hybrid_ms = std::mem::take(&mut m.ms);

    // The default export: what `convert CAPTURE -o OUT.glb` writes (texture profile, laid out
    // for stock viewers, coplanar step on), read back and traced as a viewer loads it.
    let base_opts = ConvertOptions {
        coplanar_offset: true,
        ..ConvertOptions::default()
    }
    .for_viewers();
    let glb = dir.join(format!("{name}.glb"));
    let (glb_frames, glb_mesh) = stages.time(
        &format!("export and trace the default GLB, {} views", cams.len()),
        || trace_export(&scene, &base_opts, &glb, &cams, t, cfg.k, progress),
    )?;

    // The distilled export: `convert --distill` with a small budget.
    let mut distilled_scene = scene.clone();
    let mut distilled_opts = base_opts.clone();
    let outcome = stages.time(
        &format!(
            "distil (orbit:{} at {}×{}, {} steps)",
            cfg.fit_views, cfg.width, cfg.height, cfg.iterations
        ),
        || -> anyhow::Result<Outcome> {
            progress("distil");
            let req = ViewRequest {
                spec: format!("orbit:{}", cfg.fit_views),
                width: cfg.width,
                height: cfg.height,
                // Measured here on the demo's own views instead.
                held_back: 0,
                // The demo's figures are of the orbit fit as its report states it.
                validation: 0,
                validation_fine: 0,
                times: 1,
                ..ViewRequest::default()
            };
            let opts = DistillOptions {
                iterations: cfg.iterations,
                k: cfg.k,
                ..DistillOptions::default()
            };
            Ok(distill_export(
                &mut distilled_scene,
                &mut distilled_opts,
                &req,
                &opts,
                |p| progress(&format!("distil step {}", p.iteration)),
            )?)
        },
    )?;
    let dglb = dir.join(format!("{name}_distilled.glb"));
    let (dist_frames, dist_mesh) = stages.time(
        &format!("export and trace the distilled GLB, {} views", cams.len()),
        || {
            trace_export(
                &distilled_scene,
                &distilled_opts,
                &dglb,
                &cams,
                t,
                cfg.k,
                progress,
            )
        },
    )?;
    drop(distilled_scene);

    // Splat exports: the same Gaussians for splat viewers, read back and splatted natively,
    // so the figure is what the file's encoding costs.
    let khr = dir.join(format!("{name}_splats.glb"));
    let spz = dir.join(format!("{name}.spz"));
    let (khr_frames, spz_frames, khr_bytes, spz_bytes) = stages.time(
        "splat exports (KHR GLB, SPZ), read back and splatted",
        || -> anyhow::Result<_> {
            progress("splat exports");
            splatbridge_convert::splats_gltf::write_file_with(
                &khr,
                &scene,
                &ConvertOptions::default(),
                KhrCompression::None,
            )?;
            write_cloud(
                &spz,
                &scene.static_gaussians,
                CloudFormat::Spz(SpzOptions::default()),
            )?;
            let mut frames = Vec::new();
            for path in [&khr, &spz] {
                let (back, _) = splatbridge_scene::formats::load(path, &ReadOptions::default())
                    .with_context(|| path.display().to_string())?;
                let cloud = back.composite(back.time.start);
                let opts = Default::default();
                let mut f = Vec::new();
                for cam in &cams {
                    f.push(parity::render_native(&cloud, cam, &opts)?);
                }
                frames.push(f);
            }
            let spz_f = frames.pop().unwrap_or_default();
            let khr_f = frames.pop().unwrap_or_default();
            Ok((khr_f, spz_f, file_len(&khr), file_len(&spz)))
        },
    )?;

    // The Gaussians themselves, ray-traced (the tracer's parity mode).
    let traced = stages.time(
        &format!("trace the Gaussians (BVH and {} views)", cams.len()),
        || -> anyhow::Result<Vec<parity::Rendered>> {
            progress("trace gaussians");
            let g =
                GaussianTracer::for_scene(&scene, t, BackendKind::Obvhs, BuildPreset::default())?;
            let mut r = Renderer::Gaussian {
                tracer: g,
                options: TraceOptions::default(),
            };
            let mut out = Vec::new();
            for cam in &cams {
                progress(&format!("trace gaussians {}", cam.name));
                out.push(parity::render_gaussians(&mut r, cam, cfg.k)?);
            }
            Ok(out)
        },
    )?;

    // Measure everything against the reference (cheap; part of writing the report).
    let frames_of = |v: &[parity::Rendered]| -> (Vec<Frame>, Vec<f64>) {
        (
            v.iter().map(|r| r.frame.clone()).collect(),
            v.iter().map(|r| r.ms).collect(),
        )
    };
    let measured = stages.time("measure and save the images", || -> anyhow::Result<_> {
        let mut outs = Vec::new();
        let mesh_rec = |profile: &str, tm: &MeshFile| Record {
            renderer: "trace-mesh".into(),
            profile: profile.into(),
            format: "glb".into(),
            triangles: tm.triangles,
            bytes: tm.bytes,
            ..Record::default()
        };
        let (f, ms) = frames_of(&glb_frames);
        outs.push(m.output(
            "glb",
            "default GLB, traced",
            Some(rel(dir, &glb)),
            Some((glb_mesh.bytes, glb_mesh.triangles)),
            &refs,
            &f,
            ms,
            mesh_rec("texture", &glb_mesh),
        )?);
        let (f, ms) = frames_of(&dist_frames);
        outs.push(m.output(
            "distilled",
            "distilled GLB, traced",
            Some(rel(dir, &dglb)),
            Some((dist_mesh.bytes, dist_mesh.triangles)),
            &refs,
            &f,
            ms,
            mesh_rec("texture, distilled", &dist_mesh),
        )?);
        outs.push(m.output(
            "hybrid",
            "hybrid",
            None,
            None,
            &refs,
            &hybrid,
            hybrid_ms,
            Record {
                renderer: "hybrid".into(),
                ..Record::default()
            },
        )?);
        let (f, ms) = frames_of(&traced);
        outs.push(m.output(
            "trace-gaussian",
            "traced Gaussians",
            None,
            None,
            &refs,
            &f,
            ms,
            Record {
                renderer: "trace-gaussian".into(),
                ..Record::default()
            },
        )?);
        let splat_rec = |format: &str, bytes: u64| Record {
            renderer: "native".into(),
            profile: "splats".into(),
            format: format.into(),
            bytes,
            ..Record::default()
        };
        let (f, ms) = frames_of(&khr_frames);
        outs.push(m.output(
            "khr",
            "KHR splat GLB, splatted",
            Some(rel(dir, &khr)),
            Some((khr_bytes, 0)),
            &refs,
            &f,
            ms,
            splat_rec("glb", khr_bytes),
        )?);
        let (f, ms) = frames_of(&spz_frames);
        outs.push(m.output(
            "spz",
            "SPZ, splatted",
            Some(rel(dir, &spz)),
            Some((spz_bytes, 0)),
            &refs,
            &f,
            ms,
            splat_rec("spz", spz_bytes),
        )?);
        Ok(outs)
    })?;
    outputs.extend(measured);

    let picture: PictureFrames = vec![
        ("native", refs[0].clone()),
        ("glb", glb_frames[0].frame.clone()),
        ("distilled", dist_frames[0].frame.clone()),
        ("hybrid", hybrid[0].clone()),
        ("trace-gaussian", traced[0].frame.clone()),
    ];
    let run = CaptureRun {
        name,
        input: cfg.input.clone(),
        input_bytes,
        gaussians: scene.static_gaussians.len(),
        sh_degree: scene.static_gaussians.sh_degree,
        width: cfg.width,
        height: cfg.height,
        fit_views: cfg.fit_views,
        views: cams.iter().map(|c| c.name.clone()).collect(),
        outputs,
        records: std::mem::take(&mut m.records),
        distill: outcome,
        stages,
    };
    Ok((run, picture))
}

fn file_len(p: &Path) -> u64 {
    std::fs::metadata(p).map(|m| m.len()).unwrap_or(0)
}

/// `p` relative to `dir` (its file name when it is inside).
fn rel(dir: &Path, p: &Path) -> String {
    p.strip_prefix(dir)
        .unwrap_or(p)
        .to_string_lossy()
        .into_owned()
}

/// What a traced export was.
struct MeshFile {
    bytes: u64,
    triangles: u64,
}

/// Write `scene` with `opts` to `path`, read the file back and trace it at every camera.
fn trace_export(
    scene: &DynamicScene,
    opts: &ConvertOptions,
    path: &Path,
    cams: &[Camera],
    t: f64,
    k: usize,
    progress: &dyn Fn(&str),
) -> anyhow::Result<(Vec<parity::Rendered>, MeshFile)> {
    progress(&format!("export {}", path.display()));
    let mut mesh = parity::export_and_load(
        scene,
        opts,
        path,
        BackendKind::Obvhs,
        BuildPreset::default(),
    )?;
    let mut out = Vec::new();
    for cam in cams {
        progress(&format!("trace {} {}", path.display(), cam.name));
        out.push(parity::render_mesh(&mut mesh, cam, t, k)?);
    }
    let file = MeshFile {
        bytes: mesh.bytes,
        triangles: mesh.triangles,
    };
    Ok((out, file))
}

/// Measures images against the references and saves them with their heat-maps.
struct Measure<'a> {
    images: &'a Path,
    cams: &'a [Camera],
    records: Vec<Record>,
    /// Render times collected by the stage being run.
    ms: Vec<f64>,
}

impl<'a> Measure<'a> {
    fn new(images: &'a Path, cams: &'a [Camera]) -> Self {
        Measure {
            images,
            cams,
            records: Vec::new(),
            ms: Vec::new(),
        }
    }

    /// One output over every view: PSNR per view, the images saved, the records kept.
    #[allow(clippy::too_many_arguments)]
    fn output(
        &mut self,
        key: &'static str,
        title: &str,
        file: Option<String>,
        size: Option<(u64, u64)>,
        refs: &[Frame],
        frames: &[Frame],
        ms: Vec<f64>,
        template: Record,
    ) -> anyhow::Result<Output> {
        let mut psnr = Vec::new();
        for (i, (reference, img)) in refs.iter().zip(frames).enumerate() {
            let mut r = parity::measure(
                reference,
                img,
                Record {
                    camera: self.cams[i].name.clone(),
                    milliseconds: ms.get(i).copied().unwrap_or(0.0),
                    ..template.clone()
                },
            )?;
            let stem = format!("{key}_v{i}");
            splatbridge_scene::image_io::save_frame(&self.images.join(format!("{stem}.png")), img)?;
            metrics::heatmap(reference, img)?
                .save_png(&self.images.join(format!("{stem}_diff.png")))?;
            r.image = format!("images/{stem}.png");
            r.heatmap = format!("images/{stem}_diff.png");
            psnr.push(r.psnr);
            self.records.push(r);
        }
        Ok(Output {
            key,
            title: title.to_string(),
            file,
            bytes: size.map(|s| s.0),
            triangles: size.map(|s| s.1).filter(|&t| t > 0),
            psnr,
            milliseconds: ms,
        })
    }
}
