//! 3D Tiles output (`convert --tiles`, `splatbridge::pipeline::tiles`): a structural check of the
//! tileset (every content file exists and is a valid GLB that reads back, bounding volumes
//! contain their content's centres, child errors below their parent's, each Gaussian in
//! exactly one leaf), the atomic write, the CLI, and, with chromium and the npm packages
//! (`cfg(web_clients)`), CesiumJS rendering the tileset against native splatting.

use std::path::{Path, PathBuf};
use std::process::Command;

mod tiles_common;
use tiles_common::{clusters_seeded, files};

use glam::{Quat, Vec3};
use serde_json::Value;
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::tiles::{capture_to_tileset, TileContent, TileOptions, TILE_GZIP_LEVEL};
use splatbridge_convert::ConvertOptions;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::GaussianCloud;

const BIN: &str = env!("CARGO_BIN_EXE_splatbridge");

/// The shared test cloud with the seed these tests' measured figures were taken with.
fn clusters(n: usize) -> GaussianCloud {
    clusters_seeded(n, 42)
}

fn options(content: TileContent, compression: KhrCompression, max: usize) -> TileOptions {
    TileOptions {
        max_per_tile: max,
        content,
        origin: None,
        convert: ConvertOptions::default(),
        compression,
        gzip_level: TILE_GZIP_LEVEL,
    }
}

/// A GLB's header and JSON chunk, checked: magic, version 2, declared length = file size.
fn glb_json(path: &Path) -> Value {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(b.len() >= 20, "{}: too short for a GLB", path.display());
    assert_eq!(&b[0..4], b"glTF", "{}: GLB magic", path.display());
    assert_eq!(u32::from_le_bytes(b[4..8].try_into().unwrap()), 2);
    assert_eq!(
        u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize,
        b.len()
    );
    let len = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    assert_eq!(&b[16..20], b"JSON");
    serde_json::from_slice(&b[20..20 + len]).unwrap()
}

struct Walk {
    /// Leaf Gaussians' positions (capture frame, read back from the files).
    leaf_points: Vec<Vec3>,
    tiles: usize,
}

/// Check one tile and its subtree; returns its geometric error.
fn walk(dir: &Path, tile: &Value, frame: &glam::Mat3, opts: &TileOptions, w: &mut Walk) -> f64 {
    let content = opts.content;
    w.tiles += 1;
    let err = tile["geometricError"].as_f64().expect("geometricError");
    let bx: Vec<f64> = tile["boundingVolume"]["box"]
        .as_array()
        .expect("boundingVolume.box")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(bx.len(), 12);
    let children = tile["children"].as_array().cloned().unwrap_or_default();
    if let Some(uri) = tile["content"]["uri"].as_str() {
        let path = dir.join(uri);
        let doc = glb_json(&path);
        assert_eq!(doc["asset"]["version"], "2.0");
        if content == TileContent::Splats {
            let scene = splatbridge_scene::formats::gltf_khr::read_gltf_splats(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let mut cloud = scene.static_gaussians;
            // The reader follows the extension's text (stream packed from LUF); CesiumJS's
            // variant holds the glTF frame itself, so undo the reader's half turn.
            if opts.compression == KhrCompression::SpzCesium {
                splatbridge_scene::formats::gltf_khr::spz::flip_xz(&mut cloud);
            }
            assert!(!cloud.is_empty());
            // Box axes here are axis-aligned (the frame maps axes onto axes), so containment
            // is a per-axis test; slack: 1e-4 of the box's half size, for f32 positions and
            // SPZ's 12-fractional-bit fixed point (2.4e-4 m) when compressed.
            let c = Vec3::new(bx[0] as f32, bx[1] as f32, bx[2] as f32);
            let h = Vec3::new(
                (bx[3].abs() + bx[6].abs() + bx[9].abs()) as f32,
                (bx[4].abs() + bx[7].abs() + bx[10].abs()) as f32,
                (bx[5].abs() + bx[8].abs() + bx[11].abs()) as f32,
            );
            let slack = h * 1e-4 + Vec3::splat(3e-4);
            for &p in &cloud.means {
                let q = *frame * p;
                assert!(
                    (q - c).abs().cmple(h + slack).all(),
                    "{uri}: centre {q} outside box {c} ± {h}"
                );
            }
            if children.is_empty() {
                w.leaf_points.extend_from_slice(&cloud.means);
            }
        }
    } else {
        assert!(
            !children.is_empty(),
            "a tile without content must have children"
        );
    }
    if children.is_empty() {
        assert_eq!(err, 0.0, "leaves have no error");
    } else {
        let refine = tile["refine"].as_str().unwrap();
        assert_eq!(
            refine,
            if content == TileContent::Splats {
                "REPLACE"
            } else {
                "ADD"
            }
        );
    }
    for ch in &children {
        let ce = walk(dir, ch, frame, opts, w);
        assert!(ce < err, "child error {ce} not below its parent's {err}");
    }
    err
}

fn check_tileset(dir: &Path, opts: &TileOptions, input: &GaussianCloud) -> Walk {
    let ts: Value =
        serde_json::from_slice(&std::fs::read(dir.join("tileset.json")).unwrap()).unwrap();
    assert_eq!(ts["asset"]["version"], "1.1");
    let transform = ts["root"]["transform"].as_array().unwrap();
    assert_eq!(transform.len(), 16);
    let frame = capture_to_tileset(&opts.convert);
    let mut w = Walk {
        leaf_points: Vec::new(),
        tiles: 0,
    };
    let root_err = walk(dir, &ts["root"], &frame, opts, &mut w);
    assert!(ts["geometricError"].as_f64().unwrap() > root_err);
    let files = std::fs::read_dir(dir).unwrap().count();
    if opts.content == TileContent::Splats {
        assert_eq!(files, w.tiles + 1, "one GLB per tile plus tileset.json");
        assert_eq!(
            w.leaf_points.len(),
            input.len(),
            "every Gaussian in one leaf"
        );
    }
    w
}

#[test]
fn splat_tileset_is_structurally_sound_and_partitions_the_gaussians() {
    let cloud = clusters(3000);
    let dir = tempfile::tempdir().unwrap();
    let opts = options(TileContent::Splats, KhrCompression::None, 300);
    let scene = DynamicScene::from_static(cloud.clone());
    let rep = splatbridge::pipeline::tiles::write_tiles(dir.path(), &scene, &opts).unwrap();
    assert!(rep.leaves >= 10 && rep.tiles > rep.leaves);
    let w = check_tileset(dir.path(), &opts, &cloud);
    // Lossless float attributes: the leaves hold exactly the input's centres, each once.
    let key = |p: &Vec3| p.to_array().map(f32::to_bits);
    let mut a: Vec<_> = w.leaf_points.iter().map(key).collect();
    let mut b: Vec<_> = cloud.means.iter().map(key).collect();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b);
    // No staging directory or temporary is left behind.
    for e in std::fs::read_dir(dir.path()).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        assert!(!name.starts_with('.'), "leftover {name}");
    }
}

#[test]
fn spz_and_mesh_tilesets_are_structurally_sound() {
    let cloud = clusters(1200);
    let scene = DynamicScene::from_static(cloud.clone());
    // Both SPZ frames: the clusters sit at x 0..40, so a stream read with the wrong half
    // turn (x and z negated) puts every centre outside its tile's box.
    for compression in [KhrCompression::SpzCesium, KhrCompression::Spz] {
        let dir = tempfile::tempdir().unwrap();
        let opts = options(TileContent::Splats, compression, 200);
        splatbridge::pipeline::tiles::write_tiles(dir.path(), &scene, &opts).unwrap();
        check_tileset(dir.path(), &opts, &cloud);
        let ts: Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("tileset.json")).unwrap())
                .unwrap();
        assert_eq!(
            ts["extensions"]["3DTILES_content_gltf"]["extensionsRequired"],
            serde_json::json!([
                "KHR_gaussian_splatting",
                "KHR_gaussian_splatting_compression_spz_2"
            ])
        );
        assert_eq!(
            ts["asset"]["extras"]["splatbridge"]["khrCompression"],
            compression.name()
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let opts = options(TileContent::Mesh, KhrCompression::None, 200);
    splatbridge::pipeline::tiles::write_tiles(dir.path(), &scene, &opts).unwrap();
    check_tileset(dir.path(), &opts, &cloud);
}

#[test]
fn a_failed_tileset_leaves_the_directory_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tileset.json"), b"old").unwrap();
    let scene = DynamicScene::from_static(clusters(500));
    let opts = options(TileContent::Splats, KhrCompression::None, 100);
    // Tiles are measured on the worker threads: one measurement of several fails.
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let meter = |_: &GaussianCloud, _: &GaussianCloud, _: &splatbridge_scene::blocks::Aabb| {
        if calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 1 {
            Ok(f64::NAN)
        } else {
            Ok(0.5)
        }
    };
    let err =
        splatbridge_convert::tiles::write_tileset(dir.path(), &scene, &opts, &meter).unwrap_err();
    assert!(err.to_string().contains("geometric error"), "{err}");
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names, vec!["tileset.json".to_string()]);
    assert_eq!(
        std::fs::read(dir.path().join("tileset.json")).unwrap(),
        b"old"
    );
}

fn cli(args: &[&str]) -> std::process::Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("splatbridge runs")
}

#[test]
fn cli_writes_tiles_and_reports_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("in.ply");
    splatbridge_scene::ply::write_ply(
        &ply,
        &clusters(900),
        splatbridge_scene::ply::PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    let p = ply.to_str().unwrap();
    let out = dir.path().join("tiles");
    let o = out.to_str().unwrap();
    let r = cli(&[
        "convert",
        p,
        "--tiles",
        o,
        "--max-gaussians-per-tile",
        "150",
        "--json",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let rep: Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(rep["gaussians"], 900);
    assert!(out.join("tileset.json").is_file());
    let r = cli(&[
        "info",
        p,
        "--blocks",
        "--max-gaussians-per-tile",
        "150",
        "--json",
    ]);
    assert!(r.status.success());
    let info: Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(info["blocks"]["leaves"], rep["leaves"]);
    assert_eq!(info["blocks"]["leaves_over_budget"], 0);
    // -o and --tiles together, and a zero budget, are usage errors (exit 2).
    let r = cli(&["convert", p, "--tiles", o, "-o", "x.glb"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).starts_with("error:"));
    let r = cli(&["convert", p, "--tiles", o, "--max-gaussians-per-tile", "0"]);
    assert_eq!(r.status.code(), Some(2));
}

/// Render the tileset in `dir` with `client` (`cesium` or `3d-tiles-renderer`) into `out` at
/// 320×240, a 50° camera `[eye, target, up]` given in capture coordinates (mapped into the
/// tileset's frame as the content and the root transform are: the up-axis rotation, then a
/// geolocated tileset's east-north-up → ECEF transform), every tile refined (`--sse 0`).
#[cfg_attr(not(web_clients), allow(dead_code))]
fn render_tileset(
    client: &str,
    dir: &Path,
    out: &Path,
    opts: &TileOptions,
    [eye, target, up]: [glam::DVec3; 3],
) {
    let m = capture_to_tileset(&opts.convert).as_dmat3();
    let root = match opts.origin {
        Some([lon, lat, h]) => {
            glam::DMat4::from_cols_array(&splatbridge_convert::tiles::enu_to_ecef(lon, lat, h))
        }
        None => glam::DMat4::IDENTITY,
    };
    let point = |v: glam::DVec3| root.transform_point3(m * v);
    let dir3 = |v: glam::DVec3| root.transform_vector3(m * v);
    let f = |t: glam::DVec3| format!("{},{},{}", t.x, t.y, t.z);
    let st = Command::new("node")
        .arg(script("tiles-render.mjs"))
        .args([
            client,
            dir.join("tileset.json").to_str().unwrap(),
            out.to_str().unwrap(),
        ])
        .args(["--eye", &f(point(eye)), "--target", &f(point(target))])
        .args(["--up", &f(dir3(up))])
        .args(["--fov", "50", "--size", "320x240", "--sse", "0"])
        .status()
        .unwrap();
    assert!(st.success(), "{client} failed");
}

#[cfg_attr(not(web_clients), allow(dead_code))]
fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scripts")
        .join(name)
}

/// CesiumJS renders the splat tileset through a stated camera; Babylon.js renders the same
/// Gaussians as one `KHR_gaussian_splatting` file through the same camera; both are measured
/// against native splatting of the whole scene. Returns (CesiumJS, Babylon.js) PSNR in dB.
#[cfg_attr(not(web_clients), allow(dead_code))]
fn cesium_and_babylon_against_native() -> (f64, f64) {
    // A camera above the strip, looking down at 45° (capture up is −y).
    let eye = glam::DVec3::new(20.0, -25.0, -22.0);
    let target = glam::DVec3::new(20.0, 0.0, 3.0);
    cesium_and_babylon_on(clusters(3000), [eye, target, glam::DVec3::NEG_Y], 400, None)
}

/// [`cesium_and_babylon_against_native`] for any cloud, camera `[eye, target, up]` (50°,
/// 320×240) and tile budget.
#[cfg_attr(not(web_clients), allow(dead_code))]
fn cesium_and_babylon_on(
    cloud: GaussianCloud,
    [eye, target, up]: [glam::DVec3; 3],
    max_per_tile: usize,
    origin: Option<[f64; 3]>,
) -> (f64, f64) {
    use splatbridge_scene::camera::Camera;
    // SPLATBRIDGE_KEEP_TEST_DIR=1 keeps the tileset and the images for a look.
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    if std::env::var_os("SPLATBRIDGE_KEEP_TEST_DIR").is_some() {
        println!("images in {}", tmp.keep().display());
    }
    let scene = DynamicScene::from_static(cloud.clone());
    let opts = TileOptions {
        origin,
        ..options(TileContent::Splats, KhrCompression::SpzCesium, max_per_tile)
    };
    splatbridge::pipeline::tiles::write_tiles(root.as_path(), &scene, &opts).unwrap();
    let (w, h) = (320u32, 240u32);
    let cam = Camera::look_at(eye, target, up, 50.0, w, h).unwrap();
    let (native, _) =
        splatbridge_hybrid::native::render(&cloud, &cam, &Default::default()).unwrap();
    // What SPZ's quantisation alone costs (the tiles' SPZ stream, the float KHR file
    // Babylon.js reads does not have it): native splatting of the decoded cloud.
    {
        use splatbridge_scene::formats::spz::{decode_spz_with, encode_spz, SpzAxes, SpzOptions};
        let o = SpzOptions {
            axes: SpzAxes::AsStored,
            ..SpzOptions::default()
        };
        let q = decode_spz_with(&encode_spz(&cloud, &o).unwrap(), root.as_path(), o.axes).unwrap();
        let (nq, _) = splatbridge_hybrid::native::render(&q, &cam, &Default::default()).unwrap();
        let pq = splatbridge_scene::metrics::psnr(&native, &nq).unwrap();
        println!("SPZ quantisation alone: {pq:.2} dB against native");
    }
    let native_png = root.as_path().join("native.png");
    splatbridge_scene::image_io::save_frame(&native_png, &native).unwrap();
    let out = root.as_path().join("cesium.png");
    render_tileset("cesium", root.as_path(), &out, &opts, [eye, target, up]);
    // The same Gaussians as one float KHR file with the camera embedded, in Babylon.js.
    let mut one = scene.clone();
    one.cameras = vec![cam.clone()];
    let khr = root.as_path().join("one.glb");
    splatbridge_convert::splats_gltf::write_file_with(
        &khr,
        &one,
        &Default::default(),
        KhrCompression::None,
    )
    .unwrap();
    let bab = root.as_path().join("babylon.png");
    let st = Command::new(script("client-render.sh"))
        .args(["babylon", khr.to_str().unwrap(), bab.to_str().unwrap()])
        .args(["--camera", "0", "--size", "320x240"])
        .status()
        .unwrap();
    assert!(st.success(), "Babylon.js failed");
    let a = splatbridge_scene::image_io::load_png(&native_png).unwrap();
    let b = splatbridge_scene::image_io::load_png(&out).unwrap();
    assert_eq!((b.width, b.height), (w, h), "CesiumJS image size");
    let p = splatbridge_scene::metrics::psnr(&a, &b).unwrap();
    let pb =
        splatbridge_scene::metrics::psnr(&a, &splatbridge_scene::image_io::load_png(&bab).unwrap())
            .unwrap();
    println!("CesiumJS tileset {p:.2} dB, Babylon.js one KHR file {pb:.2} dB against native");
    // One rule of CesiumJS 1.145's splat vertex shader (PrimitiveGaussianSplatVS.glsl, with
    // the 4·Σ its texture generator stores): a splat is not drawn when both screen axes
    // `sqrt(2·λ)` of `4·Σ₂ᴅ + 0.3` are under 2 pixels, i.e. when the largest eigenvalue of the
    // undilated 2D covariance is under (2 − 0.3)/4 = 0.425 px² (σ < 0.65 px). Native
    // splatting without those Gaussians tells what the rule alone costs.
    let culled = {
        use splatbridge_hybrid::project::{covariance_2d, covariance_3d, ViewParams, DILATION};
        let view = ViewParams::new(&cam, 0.2);
        let mut keep = cloud.clone();
        let small: Vec<bool> = (0..cloud.len())
            .map(|i| {
                let t = cam.world_to_cam * (cloud.means[i].as_dvec3() - cam.centre);
                let [a, b, c] = covariance_2d(&view, t, &covariance_3d(&cloud, i));
                let (a, c) = (a - DILATION, c - DILATION);
                let lmax = 0.5 * (a + c) + (0.25 * (a - c) * (a - c) + b * b).sqrt();
                lmax < 0.425
            })
            .collect();
        keep.retain_indices(|i| !small[i]);
        println!(
            "CesiumJS's small-splat rule drops {} of {} Gaussians at this camera",
            cloud.len() - keep.len(),
            cloud.len()
        );
        splatbridge_hybrid::native::render(&keep, &cam, &Default::default())
            .unwrap()
            .0
    };
    let culled_png = root.as_path().join("native_small_culled.png");
    splatbridge_scene::image_io::save_frame(&culled_png, &culled).unwrap();
    let culled = splatbridge_scene::image_io::load_png(&culled_png).unwrap();
    println!(
        "native without them: {:.2} dB against native, CesiumJS {:.2} dB against it",
        splatbridge_scene::metrics::psnr(&a, &culled).unwrap(),
        splatbridge_scene::metrics::psnr(&culled, &b).unwrap()
    );
    // The same Gaussians as a one-tile tileset (no levels of detail) in CesiumJS, to tell
    // the tiling from CesiumJS's splat renderer.
    let one_dir = root.join("one_tile");
    let opts1 = TileOptions {
        origin,
        ..options(TileContent::Splats, KhrCompression::SpzCesium, 1 << 20)
    };
    splatbridge::pipeline::tiles::write_tiles(&one_dir, &scene, &opts1).unwrap();
    let out1 = root.join("cesium_one_tile.png");
    render_tileset("cesium", &one_dir, &out1, &opts1, [eye, target, up]);
    let p1 = splatbridge_scene::metrics::psnr(
        &a,
        &splatbridge_scene::image_io::load_png(&out1).unwrap(),
    )
    .unwrap();
    println!("CesiumJS one tile {p1:.2} dB against native");
    (p, pb)
}

/// CesiumJS draws the splat tileset in place: a floor measured with the tiles in place.
#[test]
#[cfg_attr(
    not(web_clients),
    ignore = "needs chromium and the npm packages of scripts/package.json (scripts/setup.sh)"
)]
fn cesium_renders_the_splat_tileset_in_place() {
    let (p, _) = cesium_and_babylon_against_native();
    assert!(
        p >= CESIUM_FLOOR,
        "CesiumJS tileset {p:.2} dB against native"
    );
}

/// The tiles goal: CesiumJS within 1 dB of Babylon.js on the same Gaussians and camera.
#[test]
#[ignore = "goal not met: CesiumJS 28.1 dB against native where Babylon.js scores 31.0 dB; a one-tile tileset also scores 28.1 dB, SPZ quantisation alone 65.6 dB, and CesiumJS's rule of not drawing splats under 0.65 px drops 1,677 of 3,000 Gaussians here (27.7 dB alone): the gap is CesiumJS's splat renderer (docs/tiles.md)"]
fn cesium_renders_the_splat_tileset_within_1_db_of_babylon() {
    let (p, pb) = cesium_and_babylon_against_native();
    assert!(
        p >= pb - 1.0,
        "CesiumJS {p:.2} dB is more than 1 dB below Babylon.js's {pb:.2} dB"
    );
}

/// Measured: CesiumJS 1.145 on SwiftShader scores 28.14 dB here (twice, 320×240) with every
/// tile in place; less 1 dB for its worker-side sort. The misplaced tileset (stream packed
/// from LUF, turned 180°) scored 20.6–25.3 dB, and a tileset with its side leaves missing
/// (foveated loading) 26.5 dB, so this floor catches both.
#[cfg_attr(not(web_clients), allow(dead_code))]
const CESIUM_FLOOR: f64 = 27.0;

/// 3d-tiles-renderer (three.js) renders the mesh tileset through a stated camera; three.js
/// renders the same Gaussians meshed as one GLB through the same camera; both are measured
/// against native splatting, and the two client images must agree (the tileset is the one
/// file's meshes partitioned into tiles, so only the draw order of coincident fragments may
/// differ).
#[test]
#[cfg_attr(
    not(web_clients),
    ignore = "needs chromium and the npm packages of scripts/package.json (scripts/setup.sh)"
)]
fn three_tiles_renderer_draws_the_mesh_tileset_like_one_file() {
    use splatbridge_scene::camera::Camera;
    let dir = tempfile::tempdir().unwrap();
    let cloud = clusters(1200);
    let scene = DynamicScene::from_static(cloud.clone());
    let opts = options(TileContent::Mesh, KhrCompression::None, 200);
    let rep = splatbridge::pipeline::tiles::write_tiles(dir.path(), &scene, &opts).unwrap();
    assert!(rep.leaves > 1, "the check needs several content tiles");
    let (w, h) = (320u32, 240u32);
    let eye = glam::DVec3::new(20.0, -25.0, -22.0);
    let target = glam::DVec3::new(20.0, 0.0, 3.0);
    let up = glam::DVec3::NEG_Y;
    let cam = Camera::look_at(eye, target, up, 50.0, w, h).unwrap();
    let (native, _) =
        splatbridge_hybrid::native::render(&cloud, &cam, &Default::default()).unwrap();
    let native_png = dir.path().join("native.png");
    splatbridge_scene::image_io::save_frame(&native_png, &native).unwrap();
    let tiles_png = dir.path().join("tiles.png");
    render_tileset(
        "3d-tiles-renderer",
        dir.path(),
        &tiles_png,
        &opts,
        [eye, target, up],
    );
    let mut one = scene.clone();
    one.cameras = vec![cam.clone()];
    let glb = dir.path().join("one.glb");
    let mut file = std::io::BufWriter::new(std::fs::File::create(&glb).unwrap());
    splatbridge_convert::write_glb(&mut file, &one, None, &opts.convert).unwrap();
    std::io::Write::flush(&mut file).unwrap();
    drop(file);
    let one_png = dir.path().join("three.png");
    let st = Command::new(script("client-render.sh"))
        .args(["three", glb.to_str().unwrap(), one_png.to_str().unwrap()])
        .args(["--camera", "0", "--size", "320x240"])
        .status()
        .unwrap();
    assert!(st.success(), "three.js failed");
    let load = |p: &Path| splatbridge_scene::image_io::load_png(p).unwrap();
    let (a, t, o) = (load(&native_png), load(&tiles_png), load(&one_png));
    assert_eq!((t.width, t.height), (w, h), "3d-tiles-renderer image size");
    let pt = splatbridge_scene::metrics::psnr(&a, &t).unwrap();
    let po = splatbridge_scene::metrics::psnr(&a, &o).unwrap();
    let between = splatbridge_scene::metrics::psnr(&o, &t).unwrap();
    println!(
        "3d-tiles-renderer tileset {pt:.2} dB, three.js one GLB {po:.2} dB against native; {between:.2} dB between them"
    );
    assert!(
        between >= THREE_TILES_AGREEMENT,
        "3d-tiles-renderer and three.js differ: {between:.2} dB"
    );
    assert!(
        pt >= po - 0.5,
        "3d-tiles-renderer {pt:.2} dB is more than 0.5 dB below three.js's {po:.2} dB"
    );
}

/// See `three_tiles_renderer_draws_the_mesh_tileset_like_one_file`: PSNR between the
/// tileset's and the one file's three.js images: measured 52.27 dB (three 0.187 on
/// SwiftShader; 29.05 and 29.04 dB against native), less about 2 dB for coincident
/// fragments whose draw order differs between one mesh and several.
#[cfg_attr(not(web_clients), allow(dead_code))]
const THREE_TILES_AGREEMENT: f64 = 50.0;

/// The streamed tileset of a binary PLY (partition pass, bucket pass) is the in-memory
/// tileset of the same file, byte for byte, including with invalid Gaussians dropped; without
/// `--drop-invalid` an invalid Gaussian is an error naming its vertex, as when reading whole.
#[test]
fn streamed_tileset_is_byte_identical_to_the_in_memory_one() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("in.ply");
    let mut cloud = clusters(1500);
    // Two invalid Gaussians (a NaN centre, a zero quaternion) in different chunks of records.
    cloud.means[7] = Vec3::new(f32::NAN, 0.0, 0.0);
    cloud.rotations[1100] = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    splatbridge_scene::ply::write_ply(
        &ply,
        &cloud,
        splatbridge_scene::ply::PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    for compression in [KhrCompression::SpzCesium, KhrCompression::None] {
        let opts = options(TileContent::Splats, compression, 150);
        let (read, _) = splatbridge_scene::ply::read_ply(
            &ply,
            &splatbridge_scene::ply::ReadOptions { drop_invalid: true },
        )
        .unwrap();
        let whole = dir.path().join("whole");
        let rep_a = splatbridge::pipeline::tiles::write_tiles(
            &whole,
            &DynamicScene::from_static(read),
            &opts,
        )
        .unwrap();
        let streamed = dir.path().join("streamed");
        let rep_b =
            splatbridge::pipeline::tiles::write_tiles_from_ply(&streamed, &ply, true, &opts)
                .unwrap()
                .expect("a binary PLY streams");
        assert_eq!(rep_a.gaussians, 1498);
        assert_eq!((rep_a.tiles, rep_a.bytes), (rep_b.tiles, rep_b.bytes));
        let (a, b) = (files(&whole), files(&streamed));
        assert!(a.len() > 10, "several tiles");
        assert_eq!(a.len(), b.len());
        for ((na, da), (nb, db)) in a.iter().zip(&b) {
            assert_eq!(na, nb);
            assert!(da == db, "{na} differs between the two paths");
        }
        std::fs::remove_dir_all(&whole).unwrap();
        std::fs::remove_dir_all(&streamed).unwrap();
    }
    let opts = options(TileContent::Splats, KhrCompression::SpzCesium, 150);
    let err = splatbridge::pipeline::tiles::write_tiles_from_ply(
        &dir.path().join("t"),
        &ply,
        false,
        &opts,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("vertex 7"), "{err}");
    assert!(!dir.path().join("t").join("tileset.json").exists());
}

/// Leaves are loaded and encoded on worker threads and LOD merges computed in parallel; the
/// tileset written on two threads is the one written on one (the sequential walk), byte for
/// byte, in memory and streamed.
#[test]
fn parallel_tileset_is_byte_identical_to_the_one_thread_one() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("in.ply");
    let cloud = clusters(1500);
    splatbridge_scene::ply::write_ply(
        &ply,
        &cloud,
        splatbridge_scene::ply::PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    let opts = options(TileContent::Splats, KhrCompression::SpzCesium, 150);
    let run = |threads: usize, name: &str, streamed: bool| {
        let out = dir.path().join(name);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            if streamed {
                splatbridge::pipeline::tiles::write_tiles_from_ply(&out, &ply, false, &opts)
                    .unwrap()
                    .expect("a binary PLY streams");
            } else {
                let scene = DynamicScene::from_static(cloud.clone());
                splatbridge::pipeline::tiles::write_tiles(&out, &scene, &opts).unwrap();
            }
        });
        files(&out)
    };
    for streamed in [false, true] {
        let one = run(1, &format!("one_{streamed}"), streamed);
        let two = run(2, &format!("two_{streamed}"), streamed);
        assert!(one.len() > 10, "several tiles");
        assert_eq!(one.len(), two.len());
        for ((na, da), (nb, db)) in one.iter().zip(&two) {
            assert_eq!(na, nb);
            assert!(da == db, "{na} differs between one and two threads");
        }
    }
}

/// CesiumJS against Babylon.js on the shared real captures, each through camera 0 of an
/// 8-camera orbit around its robust bounds (50°, 320×240), the tileset geolocated (any place
/// on WGS84; here 8.55° E, 47.37° N, 400 m): the tiles goal measured where the Gaussians are
/// trained, not synthetic. Prints the figures; asserts the goal.
///
/// Measured (CesiumJS / Babylon.js against native): tile_lod1 26.48 / 28.90 dB, donut
/// 29.20 / 31.40, plant 25.17 / 27.67. The small-splat rule costs little here (native without
/// those Gaussians: 37.7, 35.4, 35.7 dB), a one-tile tileset scores the same, and the scenes
/// scaled by 100 (covariances far from half float's limits) score within 0.1 dB. Left at the
/// Earth's centre (no origin), CesiumJS draws plant about 11 pixels low (16.07 dB; tile_lod1
/// and donut in place), and moving the scene and camera 0.3 m from there puts it in place.
#[test]
#[ignore = "goal not met on real captures either: CesiumJS 2.4-2.5 dB below Babylon.js on tile_lod1, donut and plant, a one-tile tileset the same (docs/tiles.md); needs chromium, the npm packages and ../shared/data/real"]
fn cesium_within_1_db_of_babylon_on_real_captures() {
    use splatbridge_scene::camera_spec::{CameraRequest, CameraSource, CameraSpec};
    let mut short = Vec::new();
    for name in ["tile_lod1", "donut", "plant"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/real")
            .join(format!("{name}.ply"));
        let (cloud, _) =
            splatbridge_scene::formats::load_cloud(&path, &Default::default()).unwrap();
        let orbit = CameraRequest::new(CameraSpec::Orbit { n: 8, index: 0 })
            .resolve(CameraSource {
                cloud: &cloud,
                own: &[],
            })
            .unwrap();
        let r = orbit.world_to_cam;
        let look = [orbit.centre, orbit.centre + r.row(2), -r.row(1)];
        // Geolocated, as CesiumJS scenes are: a tileset left at the Earth's centre is drawn
        // misplaced (see the doc comment).
        let origin = Some([8.55, 47.37, 400.0]);
        let (p, pb) = cesium_and_babylon_on(cloud, look, 20_000, origin);
        println!("{name}: CesiumJS {p:.2} dB, Babylon.js {pb:.2} dB against native");
        if p < pb - 1.0 {
            short.push(format!("{name}: CesiumJS {p:.2} dB, Babylon.js {pb:.2} dB"));
        }
    }
    assert!(short.is_empty(), "{}", short.join("; "));
}
