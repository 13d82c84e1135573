//! How close a view-independent export can come to native splatting at distillation's
//! held-back views: the measurement behind `docs/distill.md`, "What one colour a point can
//! reach".
//!
//! `cargo run --release --example sh_ceiling -- SCENE [WxH,…]` takes the held-back views
//! `accuracy --only distill` measures (one per class of `views::HELD_BACK_CLASSES` and size,
//! apart from the default fitting and validation views) and prints, per view, the PSNR
//! against native splatting (full SH) of: the undistilled MeshSplats default, the
//! undistilled default export (texture profile), and native splatting with SH clipped to
//! degree 0. The last is the same Gaussians drawn by the same renderer with one colour a
//! Gaussian, the mean of its view-dependent colour over all directions (the SH functions of
//! degree ≥ 1 integrate to zero over the sphere). Over views spread around a scene no colour
//! fixed per point does much better on average: the per-point colour that minimises the mean
//! squared error over directions is that mean. So "SH0 − MeshSplats" bounds what fitting one
//! colour (and opacity) a vertex can gain on average over the views, whatever the mesh's
//! shape error, unless the fit also removes error native-with-SH0 keeps (footprint, shape:
//! both are native's own here).
//!
//! The last columns bound an export with a colour a side: the viewer layout already writes
//! each triangle in both windings, so a file could give each side of a Gaussian's plane (the
//! plane of its two largest axes, the texture profile's quad) its own colour, which a viewer
//! shows from that side. Its per-side counterpart of the DC term is the mean of the SH colour
//! over the hemisphere of view directions that see that side: by the Funk–Hecke theorem the
//! hemisphere mean of a degree-l harmonic about axis `a` is `Y_lm(a)·∫₀¹ P_l`, that is
//! `Y_lm(a)` times 1, 1/2, 0 and −1/8 for l = 0…3. "Native, a colour a side" draws each
//! Gaussian with the colour of the side the camera is on (the side of its centre's view
//! direction, the direction native evaluates SH in).
//!
//! An example rather than a CLI subcommand: it is an instrument of the documentation.

use std::path::PathBuf;
use std::process::ExitCode;

use splatbridge::distill::{native_targets_sh, render_native};
use splatbridge::measure::accuracy_distill::{plain_export_psnr, sweep_views, DistillSweep};
use splatbridge_convert::classify::Frame;
use splatbridge_convert::Profile;
use splatbridge_hybrid::native::RenderOptions as NativeOptions;
use splatbridge_scene::formats::load;
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::sh::{hemisphere_mean_raw, SH_C0};
use splatbridge_scene::{Camera, Frame as Image, GaussianCloud};

/// `cloud` with SH degree 0 and each Gaussian's DC term the hemisphere mean of its SH colour
/// on the side of its plane that `cam` sees.
fn side_colours(cloud: &GaussianCloud, cam: &Camera) -> GaussianCloud {
    let centre = cam.centre.as_vec3();
    let degree = cloud.sh_degree;
    let sh = (0..cloud.len())
        .map(|i| {
            // The normal of the plane the converter puts the Gaussian's quad in.
            let n = Frame::of(cloud, i).normal();
            // The view direction native's SH takes, centre to mean: the hemisphere of
            // directions on its side of the plane is the one about ±n it falls in.
            let a = if n.dot(cloud.means[i] - centre) >= 0.0 {
                n
            } else {
                -n
            };
            hemisphere_mean_raw(degree, cloud.sh_of(i), a) / SH_C0
        })
        .collect();
    GaussianCloud {
        sh_degree: 0,
        sh,
        ..cloud.clone()
    }
}

/// Native renders of `cloud` at `cams`, each Gaussian with the colour of the side it shows.
fn native_sides(cloud: &GaussianCloud, cams: &[Camera], near: f32) -> anyhow::Result<Vec<Image>> {
    let opts = NativeOptions {
        sh_degree_cap: 0,
        near,
        ..NativeOptions::default()
    };
    let mut r = splatbridge_hybrid::native::Renderer::new();
    cams.iter()
        .map(|c| Ok(render_native(&mut r, &side_colours(cloud, c), c, &opts)?))
        .collect()
}

fn run(args: &[String]) -> anyhow::Result<()> {
    anyhow::ensure!(!args.is_empty(), "usage: SCENE [WxH,…]");
    let sizes: Vec<(u32, u32)> = match args.get(1) {
        Some(s) => s
            .split(',')
            .map(|wh| {
                let (w, h) = wh
                    .split_once('x')
                    .ok_or_else(|| anyhow::anyhow!("size {wh}"))?;
                Ok((w.parse()?, h.parse()?))
            })
            .collect::<anyhow::Result<_>>()?,
        None => vec![(320, 240), (640, 480), (1920, 1080)],
    };
    let (scene, _) = load(&PathBuf::from(&args[0]), &ReadOptions::default())?;
    let cloud = scene.composite(0.0);
    // The held-back views `accuracy --only distill` measures at its defaults.
    let sweep = DistillSweep {
        sizes: sizes.clone(),
        ..DistillSweep::default()
    };
    let held = sweep_views(&cloud, &sweep)?.held;
    let cams: Vec<Camera> = held.iter().map(|h| h.camera.clone()).collect();
    let times = vec![0.0; cams.len()];
    let near = splatbridge_hybrid::native::NEAR_REFERENCE;
    let full = native_targets_sh(&scene, &cams, &times, 3, near)?;
    let dc = native_targets_sh(&scene, &cams, &times, 0, near)?;
    let ms = plain_export_psnr(&scene, Profile::MeshSplats, &cams, &full)?;
    // The same against native at the exported cameras' near plane (0.01): what the
    // reference's near cull at 0.2 scene units takes out of close views.
    let znear = splatbridge_convert::gltf_doc::CAMERA_ZNEAR as f32;
    let full_near = native_targets_sh(&scene, &cams, &times, 3, znear)?;
    let dc_near = native_targets_sh(&scene, &cams, &times, 0, znear)?;
    let ms_near = plain_export_psnr(&scene, Profile::MeshSplats, &cams, &full_near)?;
    let tex = plain_export_psnr(&scene, Profile::Texture, &cams, &full)?;
    let sides = native_sides(&cloud, &cams, near)?;
    let sides_near = native_sides(&cloud, &cams, znear)?;
    println!(
        "view\tmeshsplats\ttexture\tnative SH0\tnative a colour a side\t| near 0.01: meshsplats\tnative SH0\tnative a colour a side"
    );
    let mut rows: [Vec<f64>; 4] = Default::default();
    for (i, h) in held.iter().enumerate() {
        let sh0 = psnr(&dc[i], &full[i])?;
        let side = psnr(&sides[i], &full[i])?;
        let sh0_near = psnr(&dc_near[i], &full_near[i])?;
        let side_near = psnr(&sides_near[i], &full_near[i])?;
        rows[0].push(sh0 - ms[i]);
        rows[1].push(side - ms[i]);
        rows[2].push(sh0_near - ms_near[i]);
        rows[3].push(side_near - ms_near[i]);
        println!(
            "{}\t{:.2}\t{:.2}\t{:.2}\t{:.2}\t| {:.2}\t{:.2}\t{:.2}",
            h.camera.name, ms[i], tex[i], sh0, side, ms_near[i], sh0_near, side_near
        );
    }
    let whats = [
        "native SH0, near 0.2",
        "native a colour a side, near 0.2",
        "native SH0, near 0.01",
        "native a colour a side, near 0.01",
    ];
    for (what, mut h) in whats.into_iter().zip(rows) {
        h.sort_by(f64::total_cmp);
        let under = h.iter().filter(|&&x| x < 3.0).count();
        println!(
            "{what} over the MeshSplats default: worst {:+.2}, median {:+.2}, best {:+.2} dB; under +3 dB at {under} of {}",
            h[0],
            h[h.len() / 2],
            h[h.len() - 1],
            h.len()
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
