//! Exports that viewers open on the right view and draw right.
//!
//! - `convert --camera SPEC` embeds cameras for any input (here the street fixture's static
//!   PLY, which has no cameras of its own): read back from the GLB through its root node,
//!   each equals the camera `render --camera SPEC` resolves.
//! - The arrangement for viewers (chunks, ordered, both windings, no NORMAL) is what the
//!   tracer reads too: tracing it through the embedded camera gives the image the input
//!   layout gives, within rounding.
//! - With chromium and the npm packages installed (`cfg(web_clients)`, `scripts/setup.sh`),
//!   stock three.js and Babylon.js render the exports through `scripts/client-render.sh`
//!   within a PSNR floor of native splatting.

mod cli_common;

use std::path::{Path, PathBuf};
use std::process::Command;

use cli_common::ok as run;

use splatbridge_scene::camera_spec::{CameraRequest, CameraSource};
use splatbridge_scene::Camera;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/street")
        .join(name)
}

fn resolve(spec: &str, input: &Path, w: u32, h: u32) -> Camera {
    let (scene, _) = splatbridge_scene::manifest::load_scene(input, &Default::default()).unwrap();
    let cloud = scene.composite(scene.time.start);
    let mut req = CameraRequest::new(spec.parse().unwrap());
    req.width = Some(w);
    req.height = Some(h);
    req.resolve(CameraSource {
        cloud: &cloud,
        own: &scene.cameras,
    })
    .unwrap()
}

fn embedded(glb: &Path) -> Vec<Camera> {
    let mut tri = splatbridge_raytrace::scene_load::load_path(glb).unwrap();
    tri.to_capture_frame();
    tri.cameras(0.0)
}

#[test]
fn convert_embeds_cameras_for_a_ply() {
    let dir = tempfile::tempdir().unwrap();
    let ply = fixture("static.ply");
    let glb = dir.path().join("s.glb");
    let p = ply.to_str().unwrap();
    run(&[
        "convert",
        p,
        "-o",
        glb.to_str().unwrap(),
        "--camera",
        "orbit:4:1",
        "--camera",
        "orbit:8",
    ]);
    let got = embedded(&glb);
    let mut want = vec![resolve("orbit:4:1", &ply, 640, 480)];
    want.extend((0..8).map(|i| resolve(&format!("orbit:8:{i}"), &ply, 640, 480)));
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        // Tolerances: glTF stores translations and rotations as f32 and the root node's half
        // turn is applied and undone in f32 (relative error ~1e-7 of coordinates ~30 m).
        let scale = w.centre.length().max(1.0);
        assert!(
            (g.centre - w.centre).length() < 1e-5 * scale,
            "{} vs {}",
            g.centre,
            w.centre
        );
        let r = g.cam_to_world() - w.cam_to_world();
        let err = r.x_axis.length() + r.y_axis.length() + r.z_axis.length();
        assert!(err < 1e-5, "rotation differs by {err}");
        assert_eq!((g.width, g.height), (w.width, w.height));
        // fx round-trips through yfov = 2·atan(h / 2fy) in f64.
        assert!((g.fy - w.fy).abs() < 1e-6 * w.fy, "{} vs {}", g.fy, w.fy);
    }
}

fn psnr(a: &Path, b: &Path) -> f64 {
    let a = splatbridge_scene::image_io::load_png(a).unwrap();
    let b = splatbridge_scene::image_io::load_png(b).unwrap();
    splatbridge_scene::metrics::psnr(&a, &b).unwrap()
}

#[test]
fn tracer_reads_the_viewer_arrangement_like_the_input_layout() {
    let dir = tempfile::tempdir().unwrap();
    let scene = fixture("scene.json");
    let s = scene.to_str().unwrap();
    let d = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let cam = ["--camera", "scene:0", "--width", "80", "--height", "60"];
    run(&["convert", s, "-o", &d("in.glb"), "--layout", "input"]);
    // Small chunks, so the static part spans many nodes.
    run(&["convert", s, "-o", &d("vw.glb"), "--chunk-size", "256"]);
    for (glb, png) in [("in.glb", "in.png"), ("vw.glb", "vw.png")] {
        let (g, p) = (d(glb), d(png));
        let mut a = vec!["trace", g.as_str(), "-o", p.as_str()];
        a.extend_from_slice(&cam);
        run(&a);
    }
    // The same triangles (each written twice, one copy facing away) in other nodes and order:
    // a ray meets the same hits. The floor allows the k-buffer's order of exactly equal
    // distances between different Gaussians (ids are kept, so ties order alike) and f32
    // rounding of vertices moved into chunk nodes (none: nodes carry no transform); measured
    // +∞ (identical) on this fixture, 60 dB keeps room for rounding only.
    let p = psnr(&dir.path().join("in.png"), &dir.path().join("vw.png"));
    assert!(p >= 60.0, "tracer PSNR between layouts {p:.2} dB");
}

/// Render `glb` in `client` through its camera 0 at 160×120 and return the PSNR against
/// `reference`.
#[cfg_attr(not(web_clients), allow(dead_code))]
fn client_psnr(client: &str, glb: &Path, reference: &Path, out: &Path) -> f64 {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/client-render.sh");
    let st = Command::new(script)
        .args([client, glb.to_str().unwrap(), out.to_str().unwrap()])
        .args(["--camera", "0", "--size", "160x120"])
        .status()
        .unwrap();
    assert!(st.success(), "{client} failed");
    psnr(reference, out)
}

#[test]
#[cfg_attr(
    not(web_clients),
    ignore = "needs chromium and the npm packages of scripts/package.json (scripts/setup.sh)"
)]
fn stock_web_viewers_draw_the_exports_close_to_native() {
    let dir = tempfile::tempdir().unwrap();
    let scene = fixture("scene.json");
    let s = scene.to_str().unwrap();
    let d = |n: &str| dir.path().join(n);
    let ds = |n: &str| d(n).to_str().unwrap().to_string();
    run(&[
        "render",
        s,
        "--camera",
        "orbit:4:0",
        "--width",
        "160",
        "--height",
        "120",
        "-o",
        &ds("native.png"),
    ]);
    run(&["convert", s, "-o", &ds("mesh.glb"), "--camera", "orbit:4:0"]);
    run(&[
        "convert",
        s,
        "--splats",
        "-o",
        &ds("splats.glb"),
        "--camera",
        "orbit:4:0",
    ]);
    let three = client_psnr("three", &d("mesh.glb"), &d("native.png"), &d("three.png"));
    let babylon = client_psnr(
        "babylon",
        &d("splats.glb"),
        &d("native.png"),
        &d("babylon.png"),
    );
    // Floors: measured on this fixture and camera at 160×120 with three.js 0.187 and
    // Babylon.js 9.35 on SwiftShader (docs/viewers.md, viewer check): three.js 26.14 dB (the input
    // layout 25.76, our tracer 26.97), Babylon.js splats 32.68 dB; less 0.5 dB for three.js
    // (a deterministic rasteriser) and 1 dB for Babylon.js, whose splat sort runs on a worker
    // and may settle one frame later.
    assert!(three >= THREE_FLOOR, "three.js {three:.2} dB");
    assert!(
        babylon >= BABYLON_FLOOR,
        "Babylon.js splats {babylon:.2} dB"
    );
}

/// See `stock_web_viewers_draw_the_exports_close_to_native`.
#[cfg_attr(not(web_clients), allow(dead_code))]
const THREE_FLOOR: f64 = 25.6;
#[cfg_attr(not(web_clients), allow(dead_code))]
const BABYLON_FLOOR: f64 = 31.6;

/// The same check on a real capture: the first 20,000 Gaussians of `fourth_st` (a cut keeps
/// the browser run to seconds), three.js on the default mesh export against our tracer on
/// the same file (the goal: within 1 dB), Babylon.js on the `--splats` export against a floor.
#[test]
#[cfg_attr(
    not(all(web_clients, real_data)),
    ignore = "needs chromium, the npm packages of scripts/package.json (scripts/setup.sh) and ../shared/data/real"
)]
fn stock_web_viewers_draw_a_real_capture_close_to_native() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n);
    let ds = |n: &str| d(n).to_str().unwrap().to_string();
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/fourth_st.ply");
    let real = real.to_str().unwrap();
    let cut = ds("cut.ply");
    run(&["convert", real, "--splats", "--first", "20000", "-o", &cut]);
    let size = ["--width", "160", "--height", "120"];
    let mut a = vec!["render", cut.as_str(), "--camera", "orbit:4:0", "-o"];
    let native = ds("native.png");
    a.push(&native);
    a.extend_from_slice(&size);
    run(&a);
    run(&[
        "convert",
        &cut,
        "-o",
        &ds("mesh.glb"),
        "--camera",
        "orbit:4:0",
    ]);
    let (mesh, trace) = (ds("mesh.glb"), ds("trace.png"));
    let mut a = vec![
        "trace",
        mesh.as_str(),
        "--camera",
        "scene:0",
        "-o",
        trace.as_str(),
    ];
    a.extend_from_slice(&size);
    run(&a);
    let splats = ds("splats.glb");
    run(&[
        "convert",
        &cut,
        "--splats",
        "-o",
        &splats,
        "--camera",
        "orbit:4:0",
    ]);
    let tracer = psnr(&d("native.png"), &d("trace.png"));
    let three = client_psnr("three", &d("mesh.glb"), &d("native.png"), &d("three.png"));
    let babylon = client_psnr(
        "babylon",
        &d("splats.glb"),
        &d("native.png"),
        &d("babylon.png"),
    );
    println!("tracer {tracer:.2} dB, three.js {three:.2} dB, Babylon.js splats {babylon:.2} dB");
    // Measured at 160×120 (SwiftShader): tracer 22.88 dB, three.js 22.83 dB; the 1 dB is the
    // viewers goal itself. Babylon.js splats 27.01 dB, less 1 dB as for the street floor.
    assert!(
        three >= tracer - 1.0,
        "three.js {three:.2} dB is more than 1 dB below our tracer's {tracer:.2} dB"
    );
    assert!(babylon >= 26.0, "Babylon.js splats {babylon:.2} dB");
}

/// The diagonal in pixels of the box around the pixels of `png` brighter than a tenth in
/// some channel (the background is black).
fn drawn_extent(png: &Path) -> f64 {
    let f = splatbridge_scene::image_io::load_png(png).unwrap();
    let (mut lo, mut hi) = ((u32::MAX, u32::MAX), (0u32, 0u32));
    for (k, p) in f.rgb.chunks_exact(3).enumerate() {
        if p.iter().any(|&c| c > 0.1) {
            let (x, y) = (k as u32 % f.width, k as u32 / f.width);
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
    }
    if lo.0 > hi.0 {
        return 0.0;
    }
    (((hi.0 - lo.0 + 1).pow(2) + (hi.1 - lo.1 + 1).pow(2)) as f64).sqrt()
}

/// An export's `orbit:N:I` camera frames what its triangles cover, as the same spec frames the
/// Gaussians it came from: a small scene (0.3 units across, far below the 3-unit reach a unit
/// σ would have given its vertices) is drawn about as large in the traced image as in native's.
#[test]
fn an_exports_orbit_frames_its_triangles() {
    use glam::{Quat, Vec3};
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let mut cloud = splatbridge_scene::GaussianCloud::new(0);
    for i in 0..64 {
        let g = Vec3::new((i % 4) as f32, (i / 4 % 4) as f32, (i / 16) as f32);
        let rgb = Vec3::new(0.9, 0.3 + 0.2 * g.y, 0.2 + 0.2 * g.z);
        cloud.push_activated(g * 0.1, Vec3::splat(0.015), Quat::IDENTITY, 0.9, rgb);
    }
    let ply = d("small.ply");
    splatbridge_scene::ply::write_ply(
        Path::new(&ply),
        &cloud,
        splatbridge_scene::ply::PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    run(&["convert", &ply, "-o", &d("small.glb")]);
    let size = ["--camera", "orbit:4:1", "--width", "80", "--height", "60"];
    let (glb, t, n) = (d("small.glb"), d("t.png"), d("n.png"));
    let mut a = vec!["trace", glb.as_str(), "-o", t.as_str()];
    a.extend_from_slice(&size);
    run(&a);
    let mut a = vec!["render", ply.as_str(), "-o", n.as_str()];
    a.extend_from_slice(&size);
    run(&a);
    let (traced, native) = (drawn_extent(Path::new(&t)), drawn_extent(Path::new(&n)));
    // The vertices reach 3σ (0.045) past the means, so the export's orbit stands about 1.3×
    // as far (0.39 against 0.3 across) and draws the scene about 0.77× as large (measured:
    // 49.5 against 69.4 pixels, 0.71×, the isotropic Gaussians' crossed quads drawing less
    // of their rim than native's blobs); 0.6 is the floor for that, against the 5.7 pixels
    // the 3-unit reach gave.
    assert!(
        native > 40.0,
        "native draws the scene {native:.1} pixels across"
    );
    assert!(
        traced >= 0.6 * native,
        "the traced export is drawn {traced:.1} pixels across, native {native:.1}"
    );
}
