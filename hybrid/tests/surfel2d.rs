//! The 2DGS renderer against a slow per-pixel reference computed straight from the 2DGS
//! paper's formulas (Huang et al. 2024, Sec. 4): a world-space ray per pixel, its intersection
//! with each surfel's plane, `(u, v)` from the tangent axes, `G = exp(−(u² + v²)/2)`, the
//! object-space low-pass `max(G(u, v), G((x − c)/σ))` with `σ = √2/2` and `c` the projected
//! centre (Eq. 11), front-to-back compositing in centre-depth order with 3DGS's 0.99 clamp,
//! 1/255 skip and 1e-4 stop. No homogeneous transform, no tiles, no bounding boxes. The
//! renderer's two named departures are checked against the same formulas with the same
//! departure: no low-pass (`LowPassCentre::Off`, `G = G(u, v)`) and per-pixel hit-depth order
//! (`SurfelOrder::HitDepth`, each pixel's surfels sorted by the ray parameter of their plane hit).

mod common;

use common::*;
use glam::{DMat3, DVec3, Quat, Vec3};
use splatbridge_hybrid::bin::stored_cmp;
use splatbridge_hybrid::surfel2d::{render_surfels, LowPassCentre, SurfelOrder, SurfelRenderer};
use splatbridge_hybrid::RenderOptions;
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{metrics, sh, Camera, Frame, GaussianCloud};

/// Centre of the screen ellipse that is the image of the surfel's unit circle: from the dual
/// conic `H·diag(1, 1, −1)·Hᵀ` of the homography `H = K·[s_u·t_u, s_v·t_v, c]` (camera space),
/// the centre being `(C*₀₂, C*₁₂)/C*₂₂`. Used only to check the rasterizer's own low-pass centre.
fn circle_image_centre(cam: &Camera, a_u: DVec3, a_v: DVec3, c: DVec3) -> [f64; 2] {
    let k = DMat3::from_cols(
        DVec3::new(cam.fx, 0.0, 0.0),
        DVec3::new(0.0, cam.fy, 0.0),
        DVec3::new(cam.cx, cam.cy, 1.0),
    );
    let h = k * DMat3::from_cols(a_u, a_v, c);
    let dual = h * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)) * h.transpose();
    [dual.z_axis.x / dual.z_axis.z, dual.z_axis.y / dual.z_axis.z]
}

/// The paper's forward model, per pixel, in f64, its low-pass centred on the projected surfel
/// centre (`centre == Projected`, Eq. 11) or on the image of the unit circle (`Code`), or
/// without it (`Off`); blended in centre-depth order or, per pixel, in hit order (`blend_order`).
fn paper_render(
    cloud: &GaussianCloud,
    cam: &Camera,
    opts: &RenderOptions,
    centre: LowPassCentre,
    blend_order: SurfelOrder,
) -> Frame {
    let w = cam.world_to_cam;
    let wt = w.transpose();
    let degree = cloud.sh_degree.min(opts.sh_degree_cap);
    // (index, camera-space centre) of the surfels in front of the near plane, by centre depth.
    let mut order: Vec<(usize, DVec3)> = (0..cloud.len())
        .map(|i| (i, w * (cloud.means[i].as_dvec3() - cam.centre)))
        .filter(|(_, c)| c.z > opts.near as f64)
        .collect();
    order.sort_by(|a, b| {
        (a.1.z as f32)
            .total_cmp(&(b.1.z as f32))
            .then_with(|| stored_cmp(cloud, a.0, b.0))
    });
    struct S {
        p: DVec3,
        tu: DVec3,
        tv: DVec3,
        n: DVec3,
        s: [f64; 2],
        proj: [f64; 2],
        z: f64,
        o: f64,
        col: DVec3,
    }
    let surfels: Vec<S> = order
        .iter()
        .map(|&(i, c)| {
            let r = DMat3::from_quat(cloud.unit_rotation(i).as_dquat());
            let s = cloud.scale(i).as_dvec3();
            let p = cloud.means[i].as_dvec3();
            S {
                p,
                tu: r.x_axis,
                tv: r.y_axis,
                n: r.z_axis,
                s: [s.x, s.y],
                proj: match centre {
                    LowPassCentre::Projected => {
                        [cam.fx * c.x / c.z + cam.cx, cam.fy * c.y / c.z + cam.cy]
                    }
                    LowPassCentre::Code => {
                        circle_image_centre(cam, w * r.x_axis * s.x, w * r.y_axis * s.y, c)
                    }
                    LowPassCentre::Off => [f64::NAN; 2],
                },
                z: c.z,
                o: cloud.opacity(i) as f64,
                col: sh::eval_color_f64(degree, cloud.sh_of(i), (p - cam.centre).normalize()),
            }
        })
        .collect();
    let mut f = Frame::new(cam.width, cam.height);
    let sigma2 = 0.5f64; // (√2/2)²
    for py in 0..cam.height {
        for px in 0..cam.width {
            let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
            // The ray through the pixel centre, in world space, with camera-z component 1.
            let d = wt * DVec3::new((x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, 1.0);
            let o = cam.centre;
            // (ray parameter of the plane hit, α, depth, colour) of every surfel that passes
            // the 1/255 cut, in centre-depth order.
            let mut hits: Vec<(f64, f64, f64, DVec3)> = Vec::new();
            for s in &surfels {
                let den = s.n.dot(d);
                if den == 0.0 {
                    continue;
                }
                let t = s.n.dot(s.p - o) / den;
                let hit = o + t * d - s.p;
                let (u, v) = (s.tu.dot(hit) / s.s[0], s.tv.dot(hit) / s.s[1]);
                let rho3d = u * u + v * v;
                let (g, depth) = if centre == LowPassCentre::Off {
                    ((-0.5 * rho3d).exp(), t)
                } else {
                    let (ex, ey) = (x - s.proj[0], y - s.proj[1]);
                    let rho2d = (ex * ex + ey * ey) / sigma2;
                    let g = (-0.5 * rho3d).exp().max((-0.5 * rho2d).exp());
                    (g, if rho3d <= rho2d { t } else { s.z })
                };
                let alpha = (s.o * g).min(opts.alpha_clamp as f64);
                if alpha < 1.0 / 255.0 {
                    continue;
                }
                hits.push((t, alpha, depth, s.col));
            }
            if blend_order == SurfelOrder::HitDepth {
                hits.sort_by(|a, b| a.0.total_cmp(&b.0));
            }
            let (mut t_acc, mut c, mut dz, mut wsum) = (1.0f64, DVec3::ZERO, 0.0, 0.0);
            for &(_, alpha, depth, col) in &hits {
                let next = t_acc * (1.0 - alpha);
                if next < 1e-4 {
                    break;
                }
                c += col * alpha * t_acc;
                dz += depth * alpha * t_acc;
                wsum += alpha * t_acc;
                t_acc = next;
            }
            let bg = DVec3::from_array(opts.background.map(|v| v as f64));
            let rgb = c + t_acc * bg;
            let p = (py * cam.width + px) as usize;
            f.rgb[3 * p..3 * p + 3].copy_from_slice(&rgb.as_vec3().to_array());
            f.alpha[p] = (1.0 - t_acc) as f32;
            f.depth[p] = if wsum > 0.0 { (dz / wsum) as f32 } else { 0.0 };
        }
    }
    f
}

/// Random surfels in front of [`front_camera`]: discs of 0.01–0.3 units at all orientations
/// (some nearly edge-on), opacities across the range, SH degree 3.
fn random_surfels(n: usize, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::new(3);
    for _ in 0..n {
        let mean = Vec3::new(
            rng.range(-2.0, 2.0),
            rng.range(-1.5, 1.5),
            rng.range(2.0, 8.0),
        );
        let (a, b) = (rng.range(-4.5, -1.2), rng.range(-4.5, -1.2));
        let ls = Vec3::new(a, b, a.min(b) - 6.9);
        let q = Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal());
        let logit = rng.range(-4.0, 6.0);
        let sh: Vec<Vec3> = (0..16)
            .map(|k| {
                Vec3::new(rng.normal(), rng.normal(), rng.normal()) * if k == 0 { 1.5 } else { 0.3 }
            })
            .collect();
        c.push(mean, ls, q, logit, &sh);
    }
    c
}

// The bar: ≥ 50 dB against the paper's formulas with the same low-pass centre. What remains
// is the rasterizer's footprint cut (pixels outside the tiles of its 3σ-ish square never see a
// surfel, where the paper's Gaussian still has α ≥ 1/255 up to 3.33σ): up to ~0.011 in α on
// the pixels just outside the cut, which only large close-up surfels make common (observed
// 52.1 dB close-up, 63–82 dB elsewhere).
const MIN_PSNR: f64 = 50.0;

fn check(cloud: &GaussianCloud, cam: &Camera, opts: &RenderOptions, what: &str) -> f64 {
    let p = check_centre(cloud, cam, opts, LowPassCentre::Projected, what);
    check_centre(cloud, cam, opts, LowPassCentre::Code, what);
    p
}

fn check_centre(
    cloud: &GaussianCloud,
    cam: &Camera,
    opts: &RenderOptions,
    centre: LowPassCentre,
    what: &str,
) -> f64 {
    let what = &format!("{what} ({centre:?} low-pass centre)");
    let mut r = SurfelRenderer::new();
    r.low_pass = centre;
    let (frame, stats) = r.render(cloud, cam, opts).unwrap();
    assert!(frame.is_finite(), "{what}: non-finite pixels");
    assert!(
        stats.blends > 0,
        "{what}: nothing blended, the comparison would be empty"
    );
    let reference = paper_render(cloud, cam, opts, centre, SurfelOrder::CentreDepth);
    let psnr = metrics::psnr(&frame, &reference).unwrap();
    let alpha_err = frame
        .alpha
        .iter()
        .zip(&reference.alpha)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    println!(
        "{what}: {} projected, {} blends, PSNR {psnr:.2} dB, max |Δα| {alpha_err:.2e}",
        stats.projected, stats.blends
    );
    assert!(
        psnr >= MIN_PSNR,
        "{what}: {psnr:.2} dB against the paper's formulas"
    );
    psnr
}

#[test]
fn random_scenes_match_the_papers_formulas() {
    for (seed, n, w, h) in [
        (1u64, 300usize, 96u32, 72u32),
        (2, 800, 67, 45),
        (3, 150, 128, 96),
    ] {
        let cloud = random_surfels(n, seed);
        let opts = RenderOptions {
            background: [0.2, 0.3, 0.1],
            ..Default::default()
        };
        check(&cloud, &front_camera(w, h), &opts, &format!("seed {seed}"));
    }
}

#[test]
fn departures_match_the_papers_formulas_with_the_same_departure() {
    // No low-pass and per-pixel hit order (the approximations fans are measured against,
    // docs/formats.md#2dgs-surfels), each against the per-pixel formulas with the same change:
    // the same bar as the reference renderer (MIN_PSNR), and each must change the image (else
    // the comparison would not test the knob).
    for (seed, n, w, h) in [(1u64, 300usize, 96u32, 72u32), (2, 800, 67, 45)] {
        let cloud = random_surfels(n, seed);
        let cam = front_camera(w, h);
        let opts = RenderOptions {
            background: [0.2, 0.3, 0.1],
            ..Default::default()
        };
        let (default, _) = render_surfels(&cloud, &cam, &opts).unwrap();
        for (centre, order) in [
            (LowPassCentre::Off, SurfelOrder::CentreDepth),
            (LowPassCentre::Code, SurfelOrder::HitDepth),
            (LowPassCentre::Off, SurfelOrder::HitDepth),
        ] {
            let what = format!("seed {seed}, {centre:?} low-pass, {order:?} order");
            let mut r = SurfelRenderer::new();
            r.low_pass = centre;
            r.blend_order = order;
            let (frame, _) = r.render(&cloud, &cam, &opts).unwrap();
            assert!(frame.is_finite(), "{what}: non-finite pixels");
            let reference = paper_render(&cloud, &cam, &opts, centre, order);
            let psnr = metrics::psnr(&frame, &reference).unwrap();
            let change = metrics::psnr(&frame, &default).unwrap();
            println!("{what}: {psnr:.2} dB against the formulas, {change:.2} dB from the default");
            assert!(
                psnr >= MIN_PSNR,
                "{what}: {psnr:.2} dB against the formulas"
            );
            assert!(
                change < psnr,
                "{what}: the knob changed nothing ({change:.2} dB from the default)"
            );
        }
    }
}

#[test]
fn the_codes_low_pass_centre_departs_from_the_papers() {
    // The rasterizer (default) against the paper's projected centre: what following the code
    // costs. Measured 49.4 / 44.2 dB (seeds 1, 2; paper centre 79.9 / 72.9); the bound only says the gap exists and
    // stays of that order: above 40 dB, and below the paper-centred renderer's figure.
    for seed in [1u64, 2] {
        let cloud = random_surfels([300, 800][seed as usize - 1], seed);
        let cam = front_camera([96, 67][seed as usize - 1], [72, 45][seed as usize - 1]);
        let opts = RenderOptions::default();
        let (code, _) = render_surfels(&cloud, &cam, &opts).unwrap();
        let paper = paper_render(
            &cloud,
            &cam,
            &opts,
            LowPassCentre::Projected,
            SurfelOrder::CentreDepth,
        );
        let gap = metrics::psnr(&code, &paper).unwrap();
        let mut r = SurfelRenderer::new();
        r.low_pass = LowPassCentre::Projected;
        let same = metrics::psnr(&r.render(&cloud, &cam, &opts).unwrap().0, &paper).unwrap();
        println!("seed {seed}: code centre {gap:.2} dB, paper centre {same:.2} dB");
        assert!(
            gap > 40.0 && gap < same,
            "seed {seed}: {gap:.2} vs {same:.2} dB"
        );
    }
}

#[test]
fn close_up_and_grazing_surfels_match() {
    // Large discs close to the camera, including ones seen at 1–5° from edge-on, where the
    // homogeneous intersection is most sensitive.
    let mut c = GaussianCloud::new(0);
    let mut rng = Rng::new(7);
    for k in 0..40 {
        let mean = Vec3::new(
            rng.range(-0.8, 0.8),
            rng.range(-0.6, 0.6),
            rng.range(0.6, 3.0),
        );
        let tilt = if k % 3 == 0 {
            rng.range(1.0, 5.0)
        } else {
            rng.range(0.0, 90.0)
        };
        // Normal nearly perpendicular to the view ray for the grazing ones.
        let q = Quat::from_rotation_y(rng.range(0.0, std::f32::consts::TAU))
            * Quat::from_rotation_x((90.0 - tilt).to_radians());
        c.push_activated(
            mean,
            Vec3::new(rng.range(0.05, 0.4), rng.range(0.05, 0.4), 1e-4),
            q,
            rng.range(0.3, 0.99),
            Vec3::new(rng.f32(), rng.f32(), rng.f32()),
        );
    }
    check(
        &c,
        &front_camera(80, 60),
        &RenderOptions::default(),
        "close-up",
    );
}

#[test]
fn tiny_surfels_are_carried_by_the_low_pass() {
    // Discs far below a pixel: the object-space Gaussian alone would vanish between pixel
    // centres; the low-pass keeps each one a ≥ 1-pixel blob.
    let mut c = GaussianCloud::new(0);
    let mut rng = Rng::new(11);
    for _ in 0..200 {
        c.push_activated(
            Vec3::new(
                rng.range(-1.5, 1.5),
                rng.range(-1.0, 1.0),
                rng.range(3.0, 6.0),
            ),
            Vec3::new(1e-4, 2e-4, 1e-7),
            Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal()).normalize(),
            0.9,
            Vec3::new(1.0, 0.5, 0.2),
        );
    }
    let (frame, _) = render_surfels(&c, &front_camera(64, 48), &RenderOptions::default()).unwrap();
    let covered = frame.alpha.iter().filter(|&&a| a > 0.3).count();
    assert!(
        covered >= 150,
        "only {covered} pixels covered by 200 low-passed surfels"
    );
    check(&c, &front_camera(64, 48), &RenderOptions::default(), "tiny");
}

#[test]
fn flattened_real_capture_matches() {
    let path = real_data("fourth_st.ply");
    if !path.exists() {
        eprintln!("skipped: {} not present", path.display());
        return;
    }
    let (cloud, _) = splatbridge_scene::ply::read_ply(&path, &Default::default()).unwrap();
    let surfels = splatbridge_scene::ply::flatten_to_surfels(&cloud);
    let rig = OrbitRig::default();
    for k in [0usize, 3] {
        let cam = rig.camera(&surfels, 8, k).unwrap().resized(64, 48);
        check(
            &surfels,
            &cam,
            &RenderOptions::default(),
            &format!("fourth_st orbit {k}"),
        );
    }
}

#[test]
fn third_scale_is_not_read() {
    let mut a = random_surfels(100, 5);
    let (fa, _) = render_surfels(&a, &front_camera(40, 30), &RenderOptions::default()).unwrap();
    for l in &mut a.log_scales {
        l.z += 3.0;
    }
    let (fb, _) = render_surfels(&a, &front_camera(40, 30), &RenderOptions::default()).unwrap();
    assert!(fa == fb, "the third scale changed a 2DGS image");
}
