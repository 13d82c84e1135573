//! Shared test helpers: a slow per-pixel f64 reference of the 3DGS forward pass, written
//! independently of the fast renderer's code, and synthetic scenes.
#![allow(dead_code)]

use std::path::PathBuf;

use glam::{DVec3, Quat, Vec3};
use splatbridge_hybrid::{Extent, RenderOptions};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{sh, Camera, GaussianCloud};

/// f64 image planes.
pub struct RefImage {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<f64>,
    pub alpha: Vec<f64>,
    pub depth: Vec<f64>,
    /// Per pixel: how many decisions (the 1/255 skip, the 1e-4 stop) were taken within
    /// [`AMBIGUITY`] of their threshold, where an f32 renderer may legitimately decide the other way.
    pub ambiguous: Vec<u32>,
}

/// Relative band around a threshold inside which f32 arithmetic can flip a decision. The f32
/// screen position is rounded by up to 2e-6 px per axis at x < 64 (half an ulp of 64), and
/// `|∇power| ≤ sqrt(2·|power|·λmax(conic)) ≤ sqrt(2·5.6·3.4) ≈ 6` per pixel at the 1/255
/// threshold (|power| ≤ ln 255, conic ≤ 1/0.3 by the dilation), so α moves by ≤ 2.4e-5
/// relative; 1e-4 leaves a factor of four. Tests using it stay at images ≤ 100 px wide.
pub const AMBIGUITY: f64 = 1e-4;

struct RefGaussian {
    x: f64,
    y: f64,
    conic: [f64; 3],
    opacity: f64,
    color: DVec3,
    depth: f64,
    rect: [i64; 4],
    index: usize,
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                m[i][j] += a[i][k] * b[k][j];
            }
        }
    }
    m
}

fn transpose(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = a[j][i];
        }
    }
    m
}

/// Rotation matrix of the quaternion (w, x, y, z) after normalisation (the reference's
/// `computeCov3D`).
fn rotation(q: Quat) -> [[f64; 3]; 3] {
    let (w, x, y, z) = (q.w as f64, q.x as f64, q.y as f64, q.z as f64);
    let n = (w * w + x * x + y * y + z * z).sqrt();
    let (r, x, y, z) = (w / n, x / n, y / n, z / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - r * z),
            2.0 * (x * z + r * y),
        ],
        [
            2.0 * (x * y + r * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - r * x),
        ],
        [
            2.0 * (x * z - r * y),
            2.0 * (y * z + r * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

fn project(
    cloud: &GaussianCloud,
    i: usize,
    cam: &Camera,
    opts: &RenderOptions,
) -> Option<RefGaussian> {
    let w2c = cam.world_to_cam;
    let wm = [
        [w2c.x_axis.x, w2c.y_axis.x, w2c.z_axis.x],
        [w2c.x_axis.y, w2c.y_axis.y, w2c.z_axis.y],
        [w2c.x_axis.z, w2c.y_axis.z, w2c.z_axis.z],
    ];
    let rel = cloud.means[i].as_dvec3() - cam.centre;
    let t = [
        wm[0][0] * rel.x + wm[0][1] * rel.y + wm[0][2] * rel.z,
        wm[1][0] * rel.x + wm[1][1] * rel.y + wm[1][2] * rel.z,
        wm[2][0] * rel.x + wm[2][1] * rel.y + wm[2][2] * rel.z,
    ];
    if t[2] <= opts.near as f64 {
        return None;
    }
    let opacity = 1.0 / (1.0 + (-(cloud.opacity_logits[i] as f64)).exp());
    let ls = cloud.log_scales[i].as_dvec3();
    let s = [ls.x.exp(), ls.y.exp(), ls.z.exp()];
    let r = rotation(cloud.rotations[i]);
    let mut m = r;
    for row in m.iter_mut() {
        for (j, v) in row.iter_mut().enumerate() {
            *v *= s[j];
        }
    }
    let sigma = mat_mul(&m, &transpose(&m));
    let tan_x = 0.5 * cam.width as f64 / cam.fx;
    let tan_y = 0.5 * cam.height as f64 / cam.fy;
    let tx = (t[0] / t[2]).clamp(-1.3 * tan_x, 1.3 * tan_x) * t[2];
    let ty = (t[1] / t[2]).clamp(-1.3 * tan_y, 1.3 * tan_y) * t[2];
    let j = [
        [cam.fx / t[2], 0.0, -cam.fx * tx / (t[2] * t[2])],
        [0.0, cam.fy / t[2], -cam.fy * ty / (t[2] * t[2])],
        [0.0, 0.0, 0.0],
    ];
    let jw = mat_mul(&j, &wm);
    let cov = mat_mul(&mat_mul(&jw, &sigma), &transpose(&jw));
    let (a, b, c) = (cov[0][0] + 0.3, cov[0][1], cov[1][1] + 0.3);
    let det = a * c - b * b;
    if det == 0.0 {
        return None;
    }
    let conic = [c / det, -b / det, a / det];
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let k = match opts.extent {
        Extent::Sigma3 => 3.0,
        Extent::Alpha => {
            if opacity < 1.0 / 255.0 {
                return None;
            }
            (2.0 * (255.0 * opacity).ln()).sqrt()
        }
    };
    let radius = (k * lambda.sqrt()).ceil();
    let x = cam.fx * t[0] / t[2] + cam.cx - 0.5;
    let y = cam.fy * t[1] / t[2] + cam.cy - 0.5;
    let gx = cam.width.div_ceil(16) as i64;
    let gy = cam.height.div_ceil(16) as i64;
    let rect = [
        (((x - radius) / 16.0).trunc() as i64).clamp(0, gx),
        (((y - radius) / 16.0).trunc() as i64).clamp(0, gy),
        (((x + radius + 15.0) / 16.0).trunc() as i64).clamp(0, gx),
        (((y + radius + 15.0) / 16.0).trunc() as i64).clamp(0, gy),
    ];
    if (rect[2] - rect[0]) * (rect[3] - rect[1]) == 0 {
        return None;
    }
    let degree = cloud.sh_degree.min(opts.sh_degree_cap);
    let dir = rel.normalize();
    let color = sh::eval_color_f64(degree, cloud.sh_of(i), dir);
    Some(RefGaussian {
        x,
        y,
        conic,
        opacity,
        color,
        depth: t[2],
        rect,
        index: i,
    })
}

/// Slow reference: every pixel walks the depth-sorted Gaussians whose tile rectangle contains
/// the pixel's tile, with the reference's skips and stop, in f64.
pub fn reference_render(cloud: &GaussianCloud, cam: &Camera, opts: &RenderOptions) -> RefImage {
    let mut gs: Vec<RefGaussian> = (0..cloud.len())
        .filter_map(|i| project(cloud, i, cam, opts))
        .collect();
    // The renderer's documented order: f32 view depth, exact ties by the stored values.
    gs.sort_by(|a, b| {
        (a.depth as f32)
            .total_cmp(&(b.depth as f32))
            .then_with(|| splatbridge_hybrid::bin::stored_cmp(cloud, a.index, b.index))
    });
    let (w, h) = (cam.width as usize, cam.height as usize);
    let gx = w.div_ceil(16);
    let gy = h.div_ceil(16);
    // The same inclusion rule, grouped per tile only to keep the test fast.
    let mut tiles: Vec<Vec<usize>> = vec![Vec::new(); gx * gy];
    for (k, g) in gs.iter().enumerate() {
        for ty in g.rect[1]..g.rect[3] {
            for tx in g.rect[0]..g.rect[2] {
                tiles[ty as usize * gx + tx as usize].push(k);
            }
        }
    }
    let mut img = RefImage {
        width: cam.width,
        height: cam.height,
        rgb: vec![0.0; 3 * w * h],
        alpha: vec![0.0; w * h],
        depth: vec![0.0; w * h],
        ambiguous: vec![0; w * h],
    };
    let bg = DVec3::from_array(opts.background.map(|v| v as f64));
    for py in 0..h {
        for px in 0..w {
            let mut t = 1.0f64;
            let mut c = DVec3::ZERO;
            let (mut dz, mut ws) = (0.0, 0.0);
            let mut amb = 0;
            for &k in &tiles[(py / 16) * gx + px / 16] {
                let g = &gs[k];
                let (dx, dy) = (g.x - px as f64, g.y - py as f64);
                let power =
                    -0.5 * (g.conic[0] * dx * dx + g.conic[2] * dy * dy) - g.conic[1] * dx * dy;
                if power > 0.0 {
                    continue;
                }
                let a = (g.opacity * power.exp()).min(opts.alpha_clamp as f64);
                amb += ((a * 255.0 - 1.0).abs() < AMBIGUITY) as u32;
                if a < 1.0 / 255.0 {
                    continue;
                }
                let test_t = t * (1.0 - a);
                amb += ((test_t * 1e4 - 1.0).abs() < AMBIGUITY) as u32;
                if test_t < 1e-4 {
                    break;
                }
                c += g.color * a * t;
                dz += g.depth * a * t;
                ws += a * t;
                t = test_t;
            }
            let i = py * w + px;
            let o = c + t * bg;
            img.rgb[3 * i..3 * i + 3].copy_from_slice(&o.to_array());
            img.alpha[i] = 1.0 - t;
            img.depth[i] = if ws > 0.0 { dz / ws } else { 0.0 };
            img.ambiguous[i] = amb;
        }
    }
    img
}

/// Differences between a frame and the reference.
#[derive(Debug, Default)]
pub struct Diffs {
    /// Largest per-channel differences over unambiguous pixels (rgb, alpha, depth relative to
    /// max(depth, 1)).
    pub rgb: f64,
    pub alpha: f64,
    pub depth: f64,
    /// Pixels with at least one near-threshold decision, and the largest rgb/alpha difference
    /// there divided by the number of such decisions.
    pub ambiguous_pixels: usize,
    pub ambiguous_per_event: f64,
}

pub fn diffs(frame: &splatbridge_scene::Frame, r: &RefImage) -> Diffs {
    let mut d = Diffs::default();
    for i in 0..r.alpha.len() {
        let rgb = (0..3)
            .map(|c| (frame.rgb[3 * i + c] as f64 - r.rgb[3 * i + c]).abs())
            .fold(0.0, f64::max);
        let alpha = (frame.alpha[i] as f64 - r.alpha[i]).abs();
        if r.ambiguous[i] > 0 {
            d.ambiguous_pixels += 1;
            d.ambiguous_per_event = d
                .ambiguous_per_event
                .max(rgb.max(alpha) / r.ambiguous[i] as f64);
            continue;
        }
        d.rgb = d.rgb.max(rgb);
        d.alpha = d.alpha.max(alpha);
        d.depth = d
            .depth
            .max((frame.depth[i] as f64 - r.depth[i]).abs() / r.depth[i].abs().max(1.0));
    }
    d
}

/// A random scene of `n` anisotropic Gaussians with SH degree 3 in a box in front of the
/// default camera (camera at the origin looking along +z, y down).
pub fn random_cloud(n: usize, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::new(3);
    for _ in 0..n {
        let mean = Vec3::new(
            rng.range(-2.0, 2.0),
            rng.range(-1.5, 1.5),
            rng.range(2.0, 8.0),
        );
        let ls = Vec3::new(
            rng.range(-4.5, -1.5),
            rng.range(-4.5, -1.5),
            rng.range(-4.5, -1.5),
        );
        let q = Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal());
        let logit = rng.range(-4.0, 6.0);
        let sh: Vec<Vec3> = (0..16)
            .map(|k| {
                let s = if k == 0 { 1.5 } else { 0.3 };
                Vec3::new(rng.normal(), rng.normal(), rng.normal()) * s
            })
            .collect();
        c.push(mean, ls, q, logit, &sh);
    }
    c
}

/// Camera at the origin looking down +z (world frame = camera frame), vertical fov 60°.
pub fn front_camera(w: u32, h: u32) -> Camera {
    Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 60.0, w, h).unwrap()
}

/// `../shared/data/real/NAME` relative to the repository root.
pub fn real_data(name: &str) -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/data/real"
    ))
    .join(name)
}
