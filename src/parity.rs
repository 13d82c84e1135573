//! The parity pipeline: render native splatting (the reference), the GES hybrid, the ray-traced
//! Gaussians, and the ray-traced mesh of each converter profile *read back from the exported
//! file*, at the same cameras and times, and measure each against the reference.
//!
//! Stages never see each other: this module (in the CLI crate) converts with `convert`, writes
//! the file, loads it with `raytrace`, and compares frames with `scene::metrics`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_hybrid::ges::GesOptions;
use splatbridge_hybrid::native::RenderOptions as NativeOptions;
use splatbridge_raytrace::{
    BackendKind, BuildPreset, GaussianTracer, MeshTracer, RenderOptions as TraceOptions,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::surfels::SplitParams;
use splatbridge_scene::{metrics, Camera, Frame, GaussianCloud};

use crate::pipeline::{Renderer, SurfelSplit};
use crate::report::Record;

/// Which renderers and profiles a comparison runs, and how.
#[derive(Clone, Debug)]
pub struct CompareConfig {
    pub profiles: Vec<Profile>,
    /// Also trace each profile's OBJ export (no alpha) to show what losing alpha costs.
    pub obj: bool,
    pub hybrid: bool,
    pub gaussian_trace: bool,
    pub backend: BackendKind,
    pub preset: BuildPreset,
    pub k: usize,
    pub native: NativeOptions,
    pub ges: GesOptions,
    pub split: SplitParams,
    /// Viewer clients to render the exports in (`clients.rs`), at the first time only.
    pub clients: Vec<crate::clients::Client>,
    /// The client dispatcher (`scripts/client-render.sh`).
    pub client_script: PathBuf,
}

impl Default for CompareConfig {
    fn default() -> Self {
        CompareConfig {
            profiles: vec![Profile::MeshSplats, Profile::Rings, Profile::Texture],
            obj: true,
            hybrid: true,
            gaussian_trace: true,
            backend: BackendKind::Obvhs,
            preset: BuildPreset::default(),
            k: 16,
            native: NativeOptions::default(),
            ges: GesOptions::default(),
            split: SplitParams::default(),
            clients: Vec::new(),
            client_script: crate::clients::default_script(),
        }
    }
}

/// A rendered image with what it cost.
pub struct Rendered {
    pub frame: Frame,
    pub ms: f64,
}

/// Native splatting of `cloud` (the reference when `opts` is the default).
pub fn render_native(
    cloud: &GaussianCloud,
    cam: &Camera,
    opts: &NativeOptions,
) -> anyhow::Result<Rendered> {
    let mut r = Renderer::native(*opts)?;
    let t0 = Instant::now();
    let (frame, _) = r.render_cloud(cloud, cam)?;
    Ok(Rendered {
        frame,
        ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// The GES hybrid with a threshold split (timed with the split, as a viewer would pay it).
pub fn render_hybrid(
    cloud: &GaussianCloud,
    cam: &Camera,
    split: SplitParams,
    opts: &GesOptions,
) -> anyhow::Result<Rendered> {
    let split = SurfelSplit {
        params: split,
        ges_ply: false,
        detect_ges: false,
    };
    let mut r = Renderer::hybrid(*opts, split)?;
    let t0 = Instant::now();
    let (frame, _) = r.render_cloud(cloud, cam)?;
    Ok(Rendered {
        frame,
        ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// A converted file loaded back for tracing.
pub struct TracedMesh {
    /// A mesh tracer (`Renderer::Mesh`).
    pub tracer: Renderer,
    pub path: PathBuf,
    pub triangles: u64,
    pub bytes: u64,
    pub build_ms: f64,
    pub convert_ms: f64,
}

/// Convert `scene` to `path` (GLB/glTF/OBJ by extension) and load the file back into a tracer.
/// OBJ cannot animate: callers pass a static scene (one frame's composite) for OBJ.
pub fn export_and_load(
    scene: &DynamicScene,
    opts: &ConvertOptions,
    path: &Path,
    backend: BackendKind,
    preset: BuildPreset,
) -> anyhow::Result<TracedMesh> {
    let t0 = Instant::now();
    let report = splatbridge_convert::convert_to_file(path, scene, None, opts, false)?;
    let convert_ms = t0.elapsed().as_secs_f64() * 1e3;
    let load = path.to_path_buf();
    let mut tri = splatbridge_raytrace::scene_load::load_path(&load)?;
    tri.to_capture_frame();
    let bytes = std::fs::metadata(&load)
        .map(|m| m.len())
        .unwrap_or(report.bytes);
    let triangles = tri.triangle_count() as u64;
    let t1 = Instant::now();
    let tracer = Renderer::Mesh {
        tracer: MeshTracer::new(tri, backend, preset)?,
        options: TraceOptions::default(),
    };
    Ok(TracedMesh {
        tracer,
        path: load,
        triangles,
        bytes,
        build_ms: t1.elapsed().as_secs_f64() * 1e3,
        convert_ms,
    })
}

/// Trace a renderer's prebuilt scene at (camera, time) with a k-buffer of `k` hits.
fn render_traced(r: &mut Renderer, cam: &Camera, time: f64, k: usize) -> anyhow::Result<Rendered> {
    let opts = TraceOptions {
        k,
        ..TraceOptions::default()
    };
    render_traced_with(r, cam, time, opts)
}

/// Trace a renderer's prebuilt scene at (camera, time) with `opts`.
fn render_traced_with(
    r: &mut Renderer,
    cam: &Camera,
    time: f64,
    opts: TraceOptions,
) -> anyhow::Result<Rendered> {
    if let Some(o) = r.trace_options_mut() {
        *o = opts;
    }
    let t0 = Instant::now();
    let (frame, _) = r.render_traced(cam, time)?;
    Ok(Rendered {
        frame,
        ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// Trace a loaded mesh at (camera, time).
pub fn render_mesh(
    m: &mut TracedMesh,
    cam: &Camera,
    time: f64,
    k: usize,
) -> anyhow::Result<Rendered> {
    render_traced(&mut m.tracer, cam, time, k)
}

/// As [`render_mesh`] with every tracer option given (spp).
pub fn render_mesh_with(
    m: &mut TracedMesh,
    cam: &Camera,
    time: f64,
    opts: TraceOptions,
) -> anyhow::Result<Rendered> {
    render_traced_with(&mut m.tracer, cam, time, opts)
}

/// Ray-trace the Gaussians themselves (3DGRT-style) with a tracer built once and posed at
/// each time (`Renderer::set_time`), with the pixel footprint on and native's hit order (the
/// parity mode, as `trace --mode gaussian` defaults to).
pub fn render_gaussians(tracer: &mut Renderer, cam: &Camera, k: usize) -> anyhow::Result<Rendered> {
    let opts = TraceOptions {
        k,
        footprint: splatbridge_raytrace::Footprint::On,
        order: splatbridge_raytrace::HitOrder::MeanDepth,
        ..TraceOptions::default()
    };
    render_traced_with(tracer, cam, 0.0, opts)
}

/// As [`render_gaussians`] with every tracer option given (footprint, spp).
pub fn render_gaussians_with(
    tracer: &mut Renderer,
    cam: &Camera,
    opts: TraceOptions,
) -> anyhow::Result<Rendered> {
    render_traced_with(tracer, cam, 0.0, opts)
}

/// Fill the metric fields of `r` from `img` against `reference`.
pub fn measure(reference: &Frame, img: &Frame, mut r: Record) -> anyhow::Result<Record> {
    r.psnr = metrics::psnr(reference, img)?;
    r.ssim = metrics::ssim(reference, img)?;
    r.tile_ssim = metrics::tile_ssim(reference, img, 16)?;
    r.max_error = metrics::max_abs_error(reference, img)? as f64;
    Ok(r)
}

/// Save `img` and its heat-map against `reference` under `dir`, recording relative paths.
fn save_pair(
    dir: &Path,
    name: &str,
    reference: &Frame,
    img: &Frame,
    r: &mut Record,
) -> anyhow::Result<()> {
    let image = format!("{name}.png");
    splatbridge_scene::image_io::save_frame(&dir.join(&image), img)?;
    let heat = format!("{name}_diff.png");
    metrics::heatmap(reference, img)?.save_png(&dir.join(&heat))?;
    r.image = image;
    r.heatmap = heat;
    Ok(())
}

/// Run the comparison over every camera × time; images and heat-maps go to `dir`.
pub fn compare(
    scene: &DynamicScene,
    cams: &[Camera],
    times: &[f64],
    dir: &Path,
    cfg: &CompareConfig,
    progress: &dyn Fn(&str),
) -> anyhow::Result<Vec<Record>> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the output folder", dir.display()))?;
    let mut records = Vec::new();
    let dynamic = !scene.objects.is_empty();
    // Export every profile once; the files are what gets traced.
    let mut meshes: Vec<(String, String, TracedMesh)> = Vec::new();
    let mut obj_profiles: Vec<Profile> = Vec::new();
    for &p in &cfg.profiles {
        progress(&format!("export {}", p.name()));
        let opts = ConvertOptions {
            profile: p,
            ..ConvertOptions::default()
        };
        let glb = dir.join(format!("mesh_{}.glb", p.name()));
        meshes.push((
            p.name().into(),
            "glb".into(),
            export_and_load(scene, &opts, &glb, cfg.backend, cfg.preset)?,
        ));
        if cfg.obj && !dynamic {
            let obj = dir.join(format!("mesh_{}.obj", p.name()));
            meshes.push((
                p.name().into(),
                "obj".into(),
                export_and_load(scene, &opts, &obj, cfg.backend, cfg.preset)?,
            ));
        } else if cfg.obj {
            obj_profiles.push(p);
        }
    }
    // One BVH per part of the scene for every time and camera: times re-pose the objects.
    let mut gaussians = cfg
        .gaussian_trace
        .then(|| {
            GaussianTracer::for_scene(
                scene,
                times.first().copied().unwrap_or(0.0),
                cfg.backend,
                cfg.preset,
            )
            .map(|tracer| Renderer::Gaussian {
                tracer,
                options: TraceOptions::default(),
            })
        })
        .transpose()?;
    let client_files = if cfg.clients.is_empty() {
        None
    } else {
        progress("export for clients");
        Some(crate::clients::export(scene, cams, &cfg.clients, dir)?)
    };
    let mut unavailable: Vec<crate::clients::Client> = Vec::new();
    let mut skipped: Vec<Record> = Vec::new();
    for (ti, &t) in times.iter().enumerate() {
        let cloud = scene.composite(t);
        if let Some(g) = &mut gaussians {
            g.set_time(t);
        }
        for (ci, cam) in cams.iter().enumerate() {
            let tag = format!("c{ci}_t{t:.2}");
            progress(&format!("native {tag}"));
            let reference = render_native(&cloud, cam, &cfg.native)?;
            // Measure `img` against the reference, save it and its heat-map as `name`, record it.
            let mut emit = |name: String, img: &Frame, r: Record| -> anyhow::Result<()> {
                let mut r = measure(
                    &reference.frame,
                    img,
                    Record {
                        camera: cam.name.clone(),
                        time: t,
                        ..r
                    },
                )?;
                save_pair(dir, &name, &reference.frame, img, &mut r)?;
                records.push(r);
                Ok(())
            };
            let named = |renderer: &str, ms: f64| Record {
                renderer: renderer.into(),
                milliseconds: ms,
                ..Record::default()
            };
            emit(
                format!("native_{tag}"),
                &reference.frame,
                named("native", reference.ms),
            )?;
            if cfg.hybrid {
                progress(&format!("hybrid {tag}"));
                let h = render_hybrid(&cloud, cam, cfg.split, &cfg.ges)?;
                emit(format!("hybrid_{tag}"), &h.frame, named("hybrid", h.ms))?;
            }
            if let Some(tracer) = &mut gaussians {
                progress(&format!("trace gaussians {tag}"));
                let g = render_gaussians(tracer, cam, cfg.k)?;
                emit(
                    format!("tracegauss_{tag}"),
                    &g.frame,
                    named("trace-gaussian", g.ms),
                )?;
            }
            let mesh_record = |profile: &str, format: &str, ms: f64, m: &TracedMesh| Record {
                profile: profile.into(),
                format: format.into(),
                triangles: m.triangles,
                bytes: m.bytes,
                ..named("trace-mesh", ms)
            };
            if let (Some(files), 0) = (&client_files, ti) {
                let active: Vec<_> = cfg
                    .clients
                    .iter()
                    .copied()
                    .filter(|c| !unavailable.contains(c))
                    .collect();
                let results = crate::clients::render_all(
                    &cfg.client_script,
                    &active,
                    files,
                    dir,
                    ci,
                    cam,
                    progress,
                )?;
                for res in results {
                    let r = Record {
                        profile: res.kind.into(),
                        format: "glb".into(),
                        bytes: res.bytes,
                        ..named(res.client.name(), res.ms)
                    };
                    match res.outcome {
                        crate::clients::Outcome::Image(img) => emit(
                            format!("client_{}_{}_{tag}", res.client.name(), res.kind),
                            &img,
                            r,
                        )?,
                        crate::clients::Outcome::Unavailable(why) => {
                            if !unavailable.contains(&res.client) {
                                unavailable.push(res.client);
                                skipped.push(Record {
                                    camera: cam.name.clone(),
                                    time: t,
                                    psnr: f64::NAN,
                                    note: format!("skipped: {why}"),
                                    ..r
                                });
                            }
                        }
                    }
                }
            }
            for (profile, format, m) in &mut meshes {
                progress(&format!("trace {profile}.{format} {tag}"));
                let img = render_mesh(m, cam, t, cfg.k)?;
                let r = mesh_record(profile, format, img.ms, m);
                emit(format!("mesh_{profile}_{format}_{tag}"), &img.frame, r)?;
            }
            // Dynamic scenes: OBJ has no animation, so the frame's own OBJ is exported and traced.
            for &p in &obj_profiles {
                let opts = ConvertOptions {
                    profile: p,
                    ..ConvertOptions::default()
                };
                let frame_scene = DynamicScene::from_static(cloud.clone());
                let obj = dir.join(format!("mesh_{}_{tag}.obj", p.name()));
                let mut m = export_and_load(&frame_scene, &opts, &obj, cfg.backend, cfg.preset)?;
                let img = render_mesh(&mut m, cam, 0.0, cfg.k)?;
                let r = mesh_record(p.name(), "obj", img.ms, &m);
                emit(format!("mesh_{}_obj_{tag}", p.name()), &img.frame, r)?;
                // Per-frame OBJs are intermediates of the measurement (one per camera × time);
                // the record keeps their size. Removing them keeps a comparison's folder small.
                let _ = std::fs::remove_file(&obj);
                let _ = std::fs::remove_file(obj.with_extension("mtl"));
            }
        }
    }
    records.append(&mut skipped);
    Ok(records)
}

/// Write `report.json` and `report.md` for `records` into `dir`.
pub fn write_reports(
    dir: &Path,
    title: &str,
    preamble: &str,
    records: &[Record],
) -> anyhow::Result<()> {
    let json = serde_json::to_string_pretty(records)?;
    splatbridge_scene::image_io::write_atomic(&dir.join("report.json"), json.as_bytes())?;
    let (skipped, measured): (Vec<Record>, Vec<Record>) =
        records.iter().cloned().partition(|r| !r.note.is_empty());
    use crate::report::summary;
    summary::colour_bar(256, 16).save_png(&dir.join(summary::COLOUR_BAR))?;
    let mut md = format!(
        "# {title}\n\n{preamble}\n\n{}\n## All images\n\n{}",
        summary::markdown_summary(&measured, Some(summary::COLOUR_BAR)),
        crate::report::markdown_table(&measured, true)
    );
    if !skipped.is_empty() {
        md.push_str("\nSkipped clients:\n\n");
        for r in &skipped {
            md.push_str(&format!("- {} ({}): {}\n", r.renderer, r.profile, r.note));
        }
    }
    splatbridge_scene::image_io::write_atomic(&dir.join("report.md"), md.as_bytes())?;
    Ok(())
}
