//! The parity pipeline: render native splatting (the reference), the GES hybrid, the ray-traced
//! Gaussians, and the ray-traced mesh of each converter profile *read back from the exported
//! file*, at the same cameras and times, and measure each against the reference.
//!
//! Stages never see each other: this module (in the CLI crate) converts with `convert`, writes
//! the file, loads it with `raytrace`, and compares frames with `scene::metrics`.

use std::borrow::Cow;
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

use crate::measure::frame_store::FrameStore;
use crate::measure::report::Record;
use crate::pipeline::{Renderer, SurfelSplit};

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
    pub clients: Vec<crate::measure::clients::Client>,
    /// The client dispatcher (`scripts/client-render.sh`).
    pub client_script: PathBuf,
    /// Skip a Gaussian-trace or mesh stage whose estimated peak (`budget.rs`) is over this many
    /// bytes, with a note in the report (`None`: run every stage).
    pub max_memory: Option<u64>,
    /// The reference is 2D Gaussian Splatting's rasterizer (2DGS surfels) instead of 3DGS's.
    pub surfels_2d: bool,
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
            ges: crate::pipeline::split_auto::default_ges_options(),
            split: SplitParams::default(),
            clients: Vec::new(),
            client_script: crate::measure::clients::default_script(),
            max_memory: None,
            surfels_2d: false,
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

/// The reference of a comparison: native splatting, or the 2DGS renderer with `surfels_2d`.
pub fn render_reference(
    cloud: &GaussianCloud,
    cam: &Camera,
    opts: &NativeOptions,
    surfels_2d: bool,
) -> anyhow::Result<Rendered> {
    if !surfels_2d {
        return render_native(cloud, cam, opts);
    }
    let mut r = Renderer::surfels_2d(*opts)?;
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
    if let Renderer::Mesh { tracer, .. } = r {
        // A morphed mesh takes its shape at `time` (a no-op without morph targets).
        tracer.set_time(time)?;
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
/// each time (`Renderer::set_time`), with the pixel footprint on, native's hit order and
/// native's SH direction (the parity mode, as `trace --mode gaussian` defaults to).
pub fn render_gaussians(tracer: &mut Renderer, cam: &Camera, k: usize) -> anyhow::Result<Rendered> {
    let opts = TraceOptions {
        k,
        footprint: splatbridge_raytrace::Footprint::On,
        order: splatbridge_raytrace::HitOrder::MeanDepth,
        sh_direction: splatbridge_raytrace::ShDirection::for_footprint(
            splatbridge_raytrace::Footprint::On,
        ),
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

/// A record with its place in the unsharded run's `report.json`: `(time index, camera index,
/// slot, sub-slot)`, where slots are 0 native, 1 hybrid, 2 Gaussian trace, 3 viewer clients
/// (sub-slot: the result's index), then one per traced mesh file. Records of one comparison
/// sort by it into the order of the loop `for time { for camera { for renderer } }`, whatever
/// order the stages ran in and however the work was sharded.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Placed {
    pub order: [u64; 4],
    /// A viewer client reported as unavailable (listed after every measured record, once per
    /// client: the first by `order`).
    #[serde(default)]
    pub skipped: bool,
    pub record: Record,
}

/// The records of a comparison in report order: measured ones by `order`, then the first
/// skipped note per (renderer, profile, format): a client that is not installed, a stage over
/// the memory budget. `placed` may come from several shards.
pub fn report_order(mut placed: Vec<Placed>) -> Vec<Record> {
    placed.sort_by_key(|p| p.order);
    let (skipped, measured): (Vec<Placed>, Vec<Placed>) =
        placed.into_iter().partition(|p| p.skipped);
    let mut out: Vec<Record> = measured.into_iter().map(|p| p.record).collect();
    let mut seen: Vec<(String, String, String)> = Vec::new();
    for p in skipped {
        let key = (
            p.record.renderer.clone(),
            p.record.profile.clone(),
            p.record.format.clone(),
        );
        if !seen.contains(&key) {
            seen.push(key);
            out.push(p.record);
        }
    }
    out
}

/// Run the comparison over every camera × time; images and heat-maps go to `dir`.
pub fn compare(
    scene: &mut DynamicScene,
    cams: &[Camera],
    times: &[f64],
    dir: &Path,
    cfg: &CompareConfig,
    progress: &dyn Fn(&str),
) -> anyhow::Result<Vec<Record>> {
    let placed = compare_selected(scene, cams, times, dir, cfg, &|_, _| true, progress)?;
    Ok(report_order(placed))
}

/// The comparison of the (time index, camera index) items `owned` accepts (a shard's part).
///
/// Memory stays that of one stage, whatever the number of cameras, times and profiles: native
/// references are rendered once per item and kept in a [`FrameStore`] on disk; then the
/// Gaussian tracer is built, traces every item and is dropped; then each profile's GLB (and
/// OBJ) is exported, loaded with its BVH, traces every item and is dropped before the next.
/// Every image and heat-map is written as soon as it is measured. The scene's cloud is never
/// copied for a static scene (its composite is its static cloud); a dynamic scene's composite
/// exists for one time at a time. The Gaussian tracer borrows the scene's clouds (moved in,
/// given back after its stage, also when it fails), so they are held once.
#[allow(clippy::too_many_arguments)]
pub fn compare_selected(
    scene: &mut DynamicScene,
    cams: &[Camera],
    times: &[f64],
    dir: &Path,
    cfg: &CompareConfig,
    owned: &dyn Fn(usize, usize) -> bool,
    progress: &dyn Fn(&str),
) -> anyhow::Result<Vec<Placed>> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the output folder", dir.display()))?;
    let items: Vec<(usize, usize)> = (0..times.len())
        .flat_map(|ti| (0..cams.len()).map(move |ci| (ti, ci)))
        .filter(|&(ti, ci)| owned(ti, ci))
        .collect();
    let mut placed = Vec::new();
    if items.is_empty() {
        return Ok(placed);
    }
    let dynamic = !scene.objects.is_empty() || scene.four_d.is_some();
    let tag = |ti: usize, ci: usize| format!("c{ci}_t{:.2}", times[ti]);
    let slot = |ti: usize, ci: usize| ti * cams.len() + ci;
    let named = |renderer: &str, ms: f64| Record {
        renderer: renderer.into(),
        milliseconds: ms,
        ..Record::default()
    };
    // Measure `img` against the reference, save it and its heat-map as `name`, place the record.
    let emit = |placed: &mut Vec<Placed>,
                reference: &Frame,
                (ti, ci): (usize, usize),
                (s, sub): (u64, u64),
                name: String,
                img: &Frame,
                r: Record|
     -> anyhow::Result<()> {
        let mut r = measure(
            reference,
            img,
            Record {
                camera: cams[ci].name.clone(),
                time: times[ti],
                ..r
            },
        )?;
        save_pair(dir, &name, reference, img, &mut r)?;
        r.peak_memory_bytes = crate::measure::memory::peak_bytes().unwrap_or(0);
        placed.push(Placed {
            order: [ti as u64, ci as u64, s, sub],
            skipped: false,
            record: r,
        });
        Ok(())
    };
    // The budget's text when `estimate` is over it (`None`: the stage fits or there is none).
    let over_budget = |estimate: u64| match cfg.max_memory {
        Some(b) if estimate > b => Some(crate::measure::budget::gb(b)),
        _ => None,
    };
    // A stage left out for the budget: one note, placed at the first item (each shard places
    // the same one; `report_order` keeps one per renderer, profile and format).
    let (first_t, first_c) = items[0];
    let skip = |placed: &mut Vec<Placed>,
                (renderer, profile, format): (&str, &str, &str),
                s: u64,
                note: String| {
        placed.push(Placed {
            order: [first_t as u64, first_c as u64, s, 0],
            skipped: true,
            record: Record {
                renderer: renderer.into(),
                profile: profile.into(),
                format: format.into(),
                camera: cams[first_c].name.clone(),
                time: times[first_t],
                psnr: f64::NAN,
                note,
                ..Record::default()
            },
        });
    };
    // Mesh files traced for every item: (profile, format) in the order they are traced.
    let mut mesh_files: Vec<(Profile, &'static str)> = Vec::new();
    let mut obj_profiles: Vec<Profile> = Vec::new();
    for &p in &cfg.profiles {
        mesh_files.push((p, "glb"));
        if cfg.obj && !dynamic {
            mesh_files.push((p, "obj"));
        } else if cfg.obj {
            obj_profiles.push(p);
        }
    }
    let client_files = if cfg.clients.is_empty() {
        None
    } else {
        progress("export for clients");
        Some(crate::measure::clients::export(
            scene,
            cams,
            &cfg.clients,
            dir,
        )?)
    };

    // Stage 1, per time: the composite, then per camera the reference (stored), the hybrid,
    // the viewer clients and a dynamic scene's per-frame OBJs, which all draw that composite.
    let mut refs = FrameStore::new(times.len() * cams.len())?;
    let mut unavailable: Vec<crate::measure::clients::Client> = Vec::new();
    for (ti, &t) in times.iter().enumerate() {
        if !items.iter().any(|&(i, _)| i == ti) {
            continue;
        }
        let cloud: Cow<'_, GaussianCloud> = if dynamic {
            Cow::Owned(scene.composite(t))
        } else {
            Cow::Borrowed(&scene.static_gaussians)
        };
        for &(_, ci) in items.iter().filter(|&&(i, _)| i == ti) {
            let cam = &cams[ci];
            let tag = tag(ti, ci);
            progress(&format!("native {tag}"));
            let reference = render_reference(&cloud, cam, &cfg.native, cfg.surfels_2d)?;
            let reference_frame = &reference.frame;
            emit(
                &mut placed,
                reference_frame,
                (ti, ci),
                (0, 0),
                format!("native_{tag}"),
                reference_frame,
                named(
                    if cfg.surfels_2d {
                        "native-2dgs"
                    } else {
                        "native"
                    },
                    reference.ms,
                ),
            )?;
            if cfg.surfels_2d {
                // The same surfels through 3DGS splatting (discs 1000× thinner than wide).
                progress(&format!("3dgs {tag}"));
                let g = render_native(&cloud, cam, &cfg.native)?;
                emit(
                    &mut placed,
                    reference_frame,
                    (ti, ci),
                    (1, 1),
                    format!("native3dgs_{tag}"),
                    &g.frame,
                    named("native-3dgs", g.ms),
                )?;
            }
            if cfg.hybrid {
                progress(&format!("hybrid {tag}"));
                let h = render_hybrid(&cloud, cam, cfg.split, &cfg.ges)?;
                emit(
                    &mut placed,
                    reference_frame,
                    (ti, ci),
                    (1, 0),
                    format!("hybrid_{tag}"),
                    &h.frame,
                    named("hybrid", h.ms),
                )?;
            }
            if let (Some(files), 0) = (&client_files, ti) {
                let active: Vec<_> = cfg
                    .clients
                    .iter()
                    .copied()
                    .filter(|c| !unavailable.contains(c))
                    .collect();
                let results = crate::measure::clients::render_all(
                    &cfg.client_script,
                    &active,
                    files,
                    dir,
                    ci,
                    cam,
                    progress,
                )?;
                for (sub, res) in results.into_iter().enumerate() {
                    let r = Record {
                        profile: res.kind.name().into(),
                        format: res.kind.format().into(),
                        bytes: res.bytes,
                        ..named(res.client.name(), res.ms)
                    };
                    match res.outcome {
                        crate::measure::clients::Outcome::Image(img) => emit(
                            &mut placed,
                            reference_frame,
                            (ti, ci),
                            (3, sub as u64),
                            format!("client_{}_{}_{tag}", res.client.name(), res.kind.name()),
                            &img,
                            r,
                        )?,
                        crate::measure::clients::Outcome::Unavailable(why) => {
                            if !unavailable.contains(&res.client) {
                                unavailable.push(res.client);
                                placed.push(Placed {
                                    order: [ti as u64, ci as u64, 3, sub as u64],
                                    skipped: true,
                                    record: Record {
                                        camera: cam.name.clone(),
                                        time: t,
                                        psnr: f64::NAN,
                                        note: format!("skipped: {why}"),
                                        ..r
                                    },
                                });
                            }
                        }
                    }
                }
            }
            // Dynamic scenes: OBJ has no animation, so the frame's own OBJ is exported and traced.
            for (pi, &p) in obj_profiles.iter().enumerate() {
                let opts = ConvertOptions {
                    profile: p,
                    ..ConvertOptions::default()
                };
                let frame_scene = DynamicScene::from_static(cloud.clone().into_owned());
                let size = crate::measure::budget::mesh_size(&frame_scene, &opts)?;
                // The frame's OBJ stage holds the scene and the frame's copy of its composite.
                let estimate = crate::measure::budget::mesh_stage_bytes(&frame_scene, size, "obj")
                    + crate::measure::budget::scene_bytes(scene);
                if let Some(budget) = over_budget(estimate) {
                    let why = mesh_skip_note(size, estimate, &budget);
                    let s = 4 + (mesh_files.len() + pi) as u64;
                    skip(&mut placed, ("trace-mesh", p.name(), "obj"), s, why);
                    continue;
                }
                let obj = dir.join(format!("mesh_{}_{tag}.obj", p.name()));
                let mut m = export_and_load(&frame_scene, &opts, &obj, cfg.backend, cfg.preset)?;
                drop(frame_scene);
                let img = render_mesh(&mut m, cam, 0.0, cfg.k)?;
                let r = Record {
                    memory_estimate_bytes: estimate,
                    ..mesh_record(p.name(), "obj", img.ms, &m)
                };
                emit(
                    &mut placed,
                    reference_frame,
                    (ti, ci),
                    (4 + (mesh_files.len() + pi) as u64, 0),
                    format!("mesh_{}_obj_{tag}", p.name()),
                    &img.frame,
                    r,
                )?;
                // Per-frame OBJs are intermediates of the measurement (one per camera × time);
                // the record keeps their size. Removing them keeps a comparison's folder small.
                let _ = std::fs::remove_file(&obj);
                let _ = std::fs::remove_file(obj.with_extension("mtl"));
            }
            refs.put(slot(ti, ci), reference_frame)?;
        }
    }

    // Stage 2: one BVH per part of the scene for every time and camera (times re-pose the
    // objects), dropped before the meshes are built.
    let gaussian_estimate = crate::measure::budget::gaussian_stage_bytes(scene);
    let gaussian_fits = cfg.gaussian_trace
        && match over_budget(gaussian_estimate) {
            None => true,
            Some(budget) => {
                let why = format!(
                    "skipped: tracing {} Gaussians needs about {}, over the memory budget of {budget} (--max-memory)",
                    crate::measure::budget::scene_gaussians(scene),
                    crate::measure::budget::gb(gaussian_estimate)
                );
                skip(&mut placed, ("trace-gaussian", "", ""), 2, why);
                false
            }
        };
    if gaussian_fits {
        let g =
            GaussianTracer::for_scene_taking(scene, times[items[0].0], cfg.backend, cfg.preset)?;
        let mut tracer = Renderer::Gaussian {
            tracer: g,
            options: TraceOptions::default(),
        };
        let traced = (|| -> anyhow::Result<()> {
            for &(ti, ci) in &items {
                tracer.set_time(times[ti])?;
                let tag = tag(ti, ci);
                progress(&format!("trace gaussians {tag}"));
                let g = render_gaussians(&mut tracer, &cams[ci], cfg.k)?;
                let reference = refs.get(slot(ti, ci))?;
                emit(
                    &mut placed,
                    &reference,
                    (ti, ci),
                    (2, 0),
                    format!("tracegauss_{tag}"),
                    &g.frame,
                    Record {
                        memory_estimate_bytes: gaussian_estimate,
                        ..named("trace-gaussian", g.ms)
                    },
                )?;
            }
            Ok(())
        })();
        if let Renderer::Gaussian { tracer, .. } = tracer {
            tracer.give_back(scene);
        }
        traced?;
    }

    // Stage 3: each mesh file exported, read back, traced at every item, then dropped.
    for (mi, &(p, format)) in mesh_files.iter().enumerate() {
        progress(&format!("export {} {format}", p.name()));
        let opts = ConvertOptions {
            profile: p,
            ..ConvertOptions::default()
        };
        let size = crate::measure::budget::mesh_size(scene, &opts)?;
        let format = crate::measure::budget::export_format(size, format);
        let estimate = crate::measure::budget::mesh_stage_bytes(scene, size, format);
        if let Some(budget) = over_budget(estimate) {
            let why = mesh_skip_note(size, estimate, &budget);
            skip(
                &mut placed,
                ("trace-mesh", p.name(), format),
                4 + mi as u64,
                why,
            );
            continue;
        }
        let path = dir.join(format!("mesh_{}.{format}", p.name()));
        let mut m = export_and_load(scene, &opts, &path, cfg.backend, cfg.preset)?;
        for &(ti, ci) in &items {
            let tag = tag(ti, ci);
            progress(&format!("trace {}.{format} {tag}", p.name()));
            let img = render_mesh(&mut m, &cams[ci], times[ti], cfg.k)?;
            let r = Record {
                memory_estimate_bytes: estimate,
                ..mesh_record(p.name(), format, img.ms, &m)
            };
            let reference = refs.get(slot(ti, ci))?;
            emit(
                &mut placed,
                &reference,
                (ti, ci),
                (4 + mi as u64, 0),
                format!("mesh_{}_{format}_{tag}", p.name()),
                &img.frame,
                r,
            )?;
        }
    }
    Ok(placed)
}

/// Why a mesh stage was left out: its size and estimated peak against the budget.
fn mesh_skip_note(size: crate::measure::budget::MeshSize, estimate: u64, budget: &str) -> String {
    format!(
        "skipped: {:.1} M vertices and {:.1} M triangles need about {} traced, over the memory budget of {budget} (--max-memory)",
        size.vertices as f64 / 1e6,
        size.triangles as f64 / 1e6,
        crate::measure::budget::gb(estimate)
    )
}

/// The record of a traced mesh file (measured fields filled by `emit`).
fn mesh_record(profile: &str, format: &str, ms: f64, m: &TracedMesh) -> Record {
    Record {
        renderer: "trace-mesh".into(),
        profile: profile.into(),
        format: format.into(),
        triangles: m.triangles,
        bytes: m.bytes,
        milliseconds: ms,
        ..Record::default()
    }
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
    use crate::measure::report::summary;
    summary::colour_bar(256, 16).save_png(&dir.join(summary::COLOUR_BAR))?;
    let mut md = format!(
        "# {title}\n\n{preamble}\n\n{}\n## All images\n\n{}",
        summary::markdown_summary(&measured, Some(summary::COLOUR_BAR)),
        crate::measure::report::markdown_table(&measured, true)
    );
    if !skipped.is_empty() {
        md.push_str("\nSkipped:\n\n");
        for r in &skipped {
            let what = [r.profile.as_str(), r.format.as_str()]
                .iter()
                .filter(|s| !s.is_empty())
                .copied()
                .collect::<Vec<_>>()
                .join(" ");
            md.push_str(&format!("- {} ({what}): {}\n", r.renderer, r.note));
        }
    }
    splatbridge_scene::image_io::write_atomic(&dir.join("report.md"), md.as_bytes())?;
    Ok(())
}
