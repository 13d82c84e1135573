//! 4D readers: every value at every tested time equals the reference implementation's formula
//! (see each module's docs for the code followed), computed here by hand from small inputs.
//!
//! Tolerances: positions and rotations go through a few f32 operations (≤ 4 roundings of values
//! ≤ 4), so 2e-6 absolute; opacity goes through `logit` (stored) and `sigmoid` (read), each
//! within a few ulps of 1, so 2e-6 absolute; colours through `(rgb − 0.5)/C0` and back, 1e-6.

use std::io::Write;
use std::path::Path;

use glam::{Quat, Vec3};
use splatbridge_scene::formats::{detect, load, SplatFormat};
use splatbridge_scene::fourd::{self, FourDForm};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::sh::SH_C0;
use splatbridge_scene::GaussianCloud;

const POS_TOL: f32 = 2e-6;
const OPACITY_TOL: f32 = 2e-6;
const COLOR_TOL: f32 = 1e-6;

/// Write a binary little-endian PLY with float properties `names` and rows `rows`.
fn write_float_ply(path: &Path, names: &[String], rows: &[Vec<f32>]) {
    let mut f = std::fs::File::create(path).unwrap();
    write!(
        f,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n",
        rows.len()
    )
    .unwrap();
    for n in names {
        writeln!(f, "property float {n}").unwrap();
    }
    f.write_all(b"end_header\n").unwrap();
    for r in rows {
        assert_eq!(r.len(), names.len());
        for v in r {
            f.write_all(&v.to_le_bytes()).unwrap();
        }
    }
}

fn stg_names(features: usize) -> Vec<String> {
    let mut n: Vec<String> = ["x", "y", "z", "trbf_center", "trbf_scale", "nx", "ny", "nz"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    n.extend((0..9).map(|i| format!("motion_{i}")));
    n.extend((0..features).map(|i| format!("f_dc_{i}")));
    n.push("opacity".into());
    n.extend((0..3).map(|i| format!("scale_{i}")));
    n.extend((0..4).map(|i| format!("rot_{i}")));
    n.extend((0..4).map(|i| format!("omega_{i}")));
    n
}

/// One STG Gaussian: xyz, trbf centre and log-width, motion 0..8, rgb, opacity logit,
/// log-scales, rotation w,x,y,z, omega w,x,y,z (normals zero, as `save_ply` writes them).
#[allow(clippy::too_many_arguments)]
fn stg_row(
    xyz: [f32; 3],
    center: f32,
    log_width: f32,
    motion: [f32; 9],
    rgb: [f32; 3],
    opacity: f32,
    log_scale: [f32; 3],
    rot: [f32; 4],
    omega: [f32; 4],
) -> Vec<f32> {
    let mut r = vec![xyz[0], xyz[1], xyz[2], center, log_width, 0.0, 0.0, 0.0];
    r.extend(motion);
    r.extend(rgb);
    r.push(opacity);
    r.extend(log_scale);
    r.extend(rot);
    r.extend(omega);
    r
}

fn assert_close(what: &str, got: f32, want: f32, tol: f32) {
    assert!(
        (got - want).abs() <= tol,
        "{what}: got {got}, want {want} (tolerance {tol})"
    );
}

fn rgb_of(c: &GaussianCloud, i: usize) -> Vec3 {
    Vec3::splat(0.5) + c.sh[i] * SH_C0
}

fn check_gaussian(
    c: &GaussianCloud,
    i: usize,
    mean: [f32; 3],
    rot_wxyz: [f32; 4],
    opacity: f32,
    rgb: [f32; 3],
) {
    for k in 0..3 {
        assert_close(
            &format!("mean[{k}] of {i}"),
            c.means[i][k],
            mean[k],
            POS_TOL,
        );
        assert_close(
            &format!("rgb[{k}] of {i}"),
            rgb_of(c, i)[k],
            rgb[k],
            COLOR_TOL,
        );
    }
    let q = c.unit_rotation(i);
    let got = [q.w, q.x, q.y, q.z];
    for k in 0..4 {
        assert_close(
            &format!("rotation[{k}] of {i}"),
            got[k],
            rot_wxyz[k],
            POS_TOL,
        );
    }
    assert_close(
        &format!("opacity of {i}"),
        c.opacity(i),
        opacity,
        OPACITY_TOL,
    );
}

/// Two Gaussians whose values at t = 0.75, 0.5 and 0.0 are worked out by hand in the tests.
fn stg_rows() -> Vec<Vec<f32>> {
    vec![
        // Centre 0.5, width exp(ln 0.25) = 0.25; velocity x 0.1, acceleration y 0.2, jerk z 0.4.
        stg_row(
            [1.0, 2.0, 3.0],
            0.5,
            0.25f32.ln(),
            [0.1, 0.0, 0.0, 0.0, 0.2, 0.0, 0.0, 0.0, 0.4],
            [0.2, 0.4, 0.6],
            0.0,
            [-2.0, -3.0, -4.0],
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.4, 0.0, 0.0],
        ),
        // Centre 0, width 1; motion on every axis; rotation velocity along w.
        stg_row(
            [-1.0, 0.0, 0.5],
            0.0,
            0.0,
            [1.0, -1.0, 0.5, 0.0, 2.0, 0.0, 0.0, 0.0, -3.0],
            [1.0, 0.0, 0.25],
            2.0,
            [-1.0, -1.0, -1.0],
            [0.0, 0.0, 2.0, 0.0],
            [4.0, 0.0, 0.0, 0.0],
        ),
    ]
}

#[test]
fn spacetime_lite_matches_the_reference_formulas() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("point_cloud.ply");
    write_float_ply(&p, &stg_names(3), &stg_rows());
    assert_eq!(
        detect(&p).unwrap(),
        SplatFormat::FourD(FourDForm::SpacetimeLite)
    );
    let (scene, _) = load(&p, &ReadOptions::default()).unwrap();
    let range = scene.time;
    assert_eq!((range.start, range.end), (0.0, 1.0));
    let sig2 = 1.0 / (1.0 + (-2.0f32).exp()); // sigmoid(2) = 0.880797

    // t = 0.75. Gaussian 0: dt = 0.25: x = 1 + 0.1·0.25, y = 2 + 0.2·0.0625,
    // z = 3 + 0.4·0.015625; rotation (1, 0.1, 0, 0)/√1.01; opacity 0.5·exp(−(0.25/0.25)²).
    // Gaussian 1: dt = 0.75: x = −1 + 0.75, y = −0.75 + 2·0.5625 = 0.375,
    // z = 0.5 + 0.375 − 3·0.421875 = −0.390625; rotation (3, 0, 2, 0)/√13;
    // opacity sigmoid(2)·exp(−0.5625).
    let c = scene.composite(0.75);
    let s = 1.01f32.sqrt();
    check_gaussian(
        &c,
        0,
        [1.025, 2.0125, 3.00625],
        [1.0 / s, 0.1 / s, 0.0, 0.0],
        0.5 * (-1.0f32).exp(),
        [0.2, 0.4, 0.6],
    );
    let s13 = 13f32.sqrt();
    check_gaussian(
        &c,
        1,
        [-0.25, 0.375, -0.390625],
        [3.0 / s13, 0.0, 2.0 / s13, 0.0],
        sig2 * (-0.5625f32).exp(),
        [1.0, 0.0, 0.25],
    );
    // Scales are constant in time.
    assert_eq!(c.log_scales[0], Vec3::new(-2.0, -3.0, -4.0));

    // t = 0.5: Gaussian 0 at its centre (dt = 0: stored values, full opacity 0.5);
    // Gaussian 1: dt = 0.5: x = −0.5, y = −0.5 + 0.5 = 0, z = 0.5 + 0.25 − 0.375 = 0.375;
    // rotation (2, 0, 2, 0)/√8; opacity sigmoid(2)·exp(−0.25).
    let c = scene.composite(0.5);
    check_gaussian(
        &c,
        0,
        [1.0, 2.0, 3.0],
        [1.0, 0.0, 0.0, 0.0],
        0.5,
        [0.2, 0.4, 0.6],
    );
    let s8 = 8f32.sqrt();
    check_gaussian(
        &c,
        1,
        [-0.5, 0.0, 0.375],
        [2.0 / s8, 0.0, 2.0 / s8, 0.0],
        sig2 * (-0.25f32).exp(),
        [1.0, 0.0, 0.25],
    );

    // t = 0: Gaussian 0: dt = −0.5: x = 0.95, y = 2.05, z = 3 − 0.05 = 2.95; rotation
    // (1, −0.2, 0, 0)/√1.04; opacity 0.5·exp(−4). Gaussian 1 at its centre.
    let c = scene.composite(0.0);
    let s104 = 1.04f32.sqrt();
    check_gaussian(
        &c,
        0,
        [0.95, 2.05, 2.95],
        [1.0 / s104, -0.2 / s104, 0.0, 0.0],
        0.5 * (-4.0f32).exp(),
        [0.2, 0.4, 0.6],
    );
    check_gaussian(
        &c,
        1,
        [-1.0, 0.0, 0.5],
        [0.0, 0.0, 1.0, 0.0],
        sig2,
        [1.0, 0.0, 0.25],
    );
}

#[test]
fn spacetime_full_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("full.ply");
    let rows: Vec<Vec<f32>> = stg_rows()
        .into_iter()
        .map(|mut r| {
            // Six more feature channels after f_dc_2 (index 8 + 9 + 3 = 20).
            for _ in 0..6 {
                r.insert(20, 0.0);
            }
            r
        })
        .collect();
    write_float_ply(&p, &stg_names(9), &rows);
    let e = load(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("full model") && e.contains("full.ply"), "{e}");
}

#[test]
fn spacetime_truncated_is_an_error_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("cut.ply");
    write_float_ply(&p, &stg_names(3), &stg_rows());
    let text = std::fs::read(&p).unwrap();
    // Claim a billion vertices in the same short file.
    let s =
        String::from_utf8_lossy(&text).replacen("element vertex 2", "element vertex 1000000000", 1);
    let mut bytes = s.as_bytes()[..s.find("end_header\n").unwrap() + 11].to_vec();
    bytes.extend_from_slice(
        &text[text.windows(11).position(|w| w == b"end_header\n").unwrap() + 11..],
    );
    std::fs::write(&p, bytes).unwrap();
    let e = load(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("1000000000 vertices"), "{e}");
}

// ---------- .splatv ----------

fn half2(a: f32, b: f32) -> u32 {
    half::f16::from_f32(a).to_bits() as u32 | (half::f16::from_f32(b).to_bits() as u32) << 16
}

/// Pack Gaussians as splaTV's PLY converter does (`main.js::processPlyBuffer`): a Gaussian is
/// (xyz, rot wxyz, log-scales, f_dc rgb, opacity logit, motion 0..8, omega wxyz, centre,
/// log-width).
struct Packed {
    xyz: [f32; 3],
    rot: [f32; 4],
    log_scale: [f32; 3],
    rgb: [f32; 3],
    opacity: f32,
    motion: [f32; 9],
    omega: [f32; 4],
    center: f32,
    log_width: f32,
}

fn splatv_bytes(gs: &[Packed], padding: usize) -> Vec<u8> {
    let mut tex: Vec<u32> = Vec::new();
    for g in gs {
        tex.extend(g.xyz.map(f32::to_bits));
        tex.push(half2(g.rot[0], g.rot[1]));
        tex.push(half2(g.rot[2], g.rot[3]));
        tex.push(half2(g.log_scale[0].exp(), g.log_scale[1].exp()));
        tex.push(half2(g.log_scale[2].exp(), 0.0));
        let c = |v: f32| (v * 255.0).clamp(0.0, 255.0) as u8;
        let a = ((1.0 / (1.0 + (-g.opacity).exp())) * 255.0) as u8;
        tex.push(u32::from_le_bytes([
            c(g.rgb[0]),
            c(g.rgb[1]),
            c(g.rgb[2]),
            a,
        ]));
        for j in 0..4 {
            tex.push(half2(g.motion[2 * j], g.motion[2 * j + 1]));
        }
        tex.push(half2(g.motion[8], 0.0));
        tex.push(half2(g.omega[0], g.omega[1]));
        tex.push(half2(g.omega[2], g.omega[3]));
        tex.push(half2(g.center, g.log_width.exp()));
    }
    tex.extend(std::iter::repeat_n(0, 16 * padding));
    let size = tex.len() * 4;
    let json =
        format!(r#"[{{"type":"splat","size":{size},"texwidth":4096,"texheight":1,"cameras":[]}}]"#);
    let mut out = Vec::new();
    out.extend(0x674bu32.to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(json.as_bytes());
    for w in tex {
        out.extend(w.to_le_bytes());
    }
    out
}

#[test]
fn splatv_matches_the_viewer_shader() {
    // Values exact in float16 so the hand computation needs no half rounding; colour bytes
    // 51, 102, 153 (0.2, 0.4, 0.6 × 255); alpha byte trunc(sigmoid(0)·255) = 127.
    let g = Packed {
        xyz: [1.0, 2.0, 3.0],
        rot: [1.0, 0.0, 0.0, 0.0],
        log_scale: [0.0, 0.5f32.ln(), 0.25f32.ln()],
        rgb: [0.2, 0.4, 0.6],
        opacity: 0.0,
        motion: [0.5, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 2.0],
        omega: [0.0, 0.5, 0.0, 0.0],
        center: 0.5,
        log_width: 0.25f32.ln(),
    };
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("model.splatv");
    std::fs::write(&p, splatv_bytes(&[g], 3)).unwrap();
    assert_eq!(detect(&p).unwrap(), SplatFormat::FourD(FourDForm::Splatv));
    let (scene, _) = load(&p, &ReadOptions::default()).unwrap();
    // Padding records are not Gaussians.
    assert_eq!(scene.composite(0.5).len(), 1);
    let alpha = 127.0 / 255.0;
    let rgb = [51.0 / 255.0, 102.0 / 255.0, 153.0 / 255.0];
    // t = 0.75, dt = 0.25: tpos = (0.125, 0.25·0.0625, 2·0.015625); rot (1, 0.125, 0, 0)/‖·‖;
    // topacity = exp(−(0.25/0.25)²) = e^-1.
    let c = scene.composite(0.75);
    let n = (1.0f32 + 0.015625).sqrt();
    check_gaussian(
        &c,
        0,
        [1.125, 2.015625, 3.03125],
        [1.0 / n, 0.125 / n, 0.0, 0.0],
        alpha * (-1.0f32).exp(),
        rgb,
    );
    let s = c.scale(0);
    assert_close("scale y", s.y, 0.5, 1e-6);
    assert_close("scale z", s.z, 0.25, 1e-6);
    // t = 0.5: at the centre.
    let c = scene.composite(0.5);
    check_gaussian(&c, 0, [1.0, 2.0, 3.0], [1.0, 0.0, 0.0, 0.0], alpha, rgb);
    // t = 1.0, dt = 0.5: topacity = exp(−4) = 0.0183 < 0.02: the shader skips the Gaussian.
    let c = scene.composite(1.0);
    assert_eq!(c.opacity(0), 0.0);
    // t = 0.0, dt = −0.5: exp(−4) again, skipped; position still evaluated:
    // (1 − 0.25, 2 + 0.25·0.25, 3 − 2·0.125).
    let c = scene.composite(0.0);
    assert_eq!(c.opacity(0), 0.0);
    assert_close("x at 0", c.means[0].x, 0.75, POS_TOL);
    assert_close("y at 0", c.means[0].y, 2.0625, POS_TOL);
    assert_close("z at 0", c.means[0].z, 2.75, POS_TOL);
}

#[test]
fn splatv_sizes_are_checked_against_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.splatv");
    let g = Packed {
        xyz: [0.0; 3],
        rot: [1.0, 0.0, 0.0, 0.0],
        log_scale: [0.0; 3],
        rgb: [0.5; 3],
        opacity: 0.0,
        motion: [0.0; 9],
        omega: [0.0; 4],
        center: 0.0,
        log_width: 0.0,
    };
    let good = splatv_bytes(&[g], 0);
    // Chunk list longer than the file.
    let mut b = good.clone();
    b[4..8].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
    std::fs::write(&p, &b).unwrap();
    let e = load(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("chunk list declared as 2147483647 bytes"), "{e}");
    // Splat chunk past the end.
    let b = &good[..good.len() - 10];
    std::fs::write(&p, b).unwrap();
    let e = load(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("declares 64 bytes"), "{e}");
}

// ---------- params.npz ----------

#[path = "fourd/npz_frames.rs"]
mod npz_frames;

fn npy(shape: &[usize], data: &[f32]) -> Vec<u8> {
    npy_with(shape, data, "<f4")
}

/// A `.npy` of `data` as `descr` (`<f4`, `>f8`, `<f2`, …), padded as NumPy pads it.
fn npy_with(shape: &[usize], data: &[f32], descr: &str) -> Vec<u8> {
    let shape_txt = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_txt}, }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((h.len() as u16).to_le_bytes());
    out.extend(h.as_bytes());
    for &v in data {
        match descr {
            "<f4" => out.extend(v.to_le_bytes()),
            ">f8" => out.extend((v as f64).to_be_bytes()),
            "<f2" => out.extend(half::f16::from_f32(v).to_le_bytes()),
            other => panic!("descr {other}"),
        }
    }
    out
}

fn write_npz(path: &Path, arrays: &[(&str, Vec<usize>, Vec<f32>)], deflate: bool) {
    let members: Vec<(String, Vec<u8>)> = arrays
        .iter()
        .map(|(name, shape, data)| (format!("{name}.npy"), npy(shape, data)))
        .collect();
    write_npz_members(path, &members, deflate);
}

/// A zip of named members, stored (`np.savez`) or deflated (`np.savez_compressed`).
fn write_npz_members(path: &Path, members: &[(String, Vec<u8>)], deflate: bool) {
    let f = std::fs::File::create(path).unwrap();
    let mut z = zip::ZipWriter::new(f);
    let method = if deflate {
        zip::CompressionMethod::Deflated
    } else {
        zip::CompressionMethod::Stored
    };
    let opts = zip::write::SimpleFileOptions::default().compression_method(method);
    for (name, bytes) in members {
        z.start_file(name.as_str(), opts).unwrap();
        z.write_all(bytes).unwrap();
    }
    z.finish().unwrap();
}

/// Three timesteps of two Gaussians: Gaussian 0 moves +1 in x per step, Gaussian 1 turns.
fn d3dgs_arrays() -> Vec<(&'static str, Vec<usize>, Vec<f32>)> {
    let mut means = Vec::new();
    let mut rots = Vec::new();
    let mut cols = Vec::new();
    for t in 0..3 {
        let t = t as f32;
        means.extend([t, 0.0, 0.0, 5.0, 5.0, 5.0]);
        rots.extend([2.0, 0.0, 0.0, 0.0, 1.0, t, 0.0, 0.0]);
        cols.extend([0.1 * t, 0.5, 0.9, 1.0, 1.0, 1.0]);
    }
    vec![
        ("means3D", vec![3, 2, 3], means),
        ("rgb_colors", vec![3, 2, 3], cols),
        ("seg_colors", vec![2, 3], vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
        ("unnorm_rotations", vec![3, 2, 4], rots),
        ("logit_opacities", vec![2, 1], vec![0.0, 2.0]),
        (
            "log_scales",
            vec![2, 3],
            vec![-1.0, -2.0, -3.0, -4.0, -4.0, -4.0],
        ),
    ]
}

#[test]
fn npz_frames_are_shown_at_i_over_fps() {
    for deflate in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("params.npz");
        write_npz(&p, &d3dgs_arrays(), deflate);
        assert_eq!(detect(&p).unwrap(), SplatFormat::FourD(FourDForm::Npz));
        let model = fourd::load(&p, FourDForm::Npz, 30.0).unwrap();
        assert_eq!(model.frame_times(), vec![0.0, 1.0 / 30.0, 2.0 / 30.0]);
        let sig2 = 1.0 / (1.0 + (-2.0f32).exp());
        for (t, frame) in [
            (0.0, 0),
            (1.0 / 30.0, 1),
            (0.05, 1),
            (2.0 / 30.0, 2),
            (9.0, 2),
        ] {
            let c = model.sample(t).unwrap();
            let f = frame as f32;
            // visualize.py: means3D[t]; F.normalize(unnorm_rotations[t]); sigmoid(logit);
            // exp(log_scales); colors_precomp = rgb_colors[t].
            let n1 = (1.0 + f * f).sqrt();
            check_gaussian(
                &c,
                0,
                [f, 0.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
                0.5,
                [0.1 * f, 0.5, 0.9],
            );
            check_gaussian(
                &c,
                1,
                [5.0, 5.0, 5.0],
                [1.0 / n1, f / n1, 0.0, 0.0],
                sig2,
                [1.0, 1.0, 1.0],
            );
            assert_eq!(c.log_scales[0], Vec3::new(-1.0, -2.0, -3.0), "t = {t}");
        }
        let d = model.displacement().unwrap().unwrap();
        assert_eq!(d.max, 2.0);
    }
}

#[test]
fn npz_bad_shapes_and_sizes_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("params.npz");
    let mut a = d3dgs_arrays();
    a[3].1 = vec![3, 2, 3];
    a[3].2.truncate(18);
    write_npz(&p, &a, false);
    let e = fourd::load(&p, FourDForm::Npz, 30.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unnorm_rotations has shape (3, 2, 3)"), "{e}");
    // A header whose shape claims more data than the entry holds.
    let mut a = d3dgs_arrays();
    a[0].1 = vec![3000000, 2, 3];
    write_npz(&p, &a, true);
    let e = fourd::load(&p, FourDForm::Npz, 30.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("means3D") && e.contains("needs 72000000 bytes"),
        "{e}"
    );
}

// ---------- numbered sequences ----------

fn frame_cloud(n: usize, x: f32) -> GaussianCloud {
    let mut c = GaussianCloud::new(0);
    for i in 0..n {
        c.push_activated(
            Vec3::new(x, i as f32, 0.0),
            Vec3::splat(0.1),
            Quat::IDENTITY,
            0.5,
            Vec3::new(0.2, 0.3, 0.4),
        );
    }
    c
}

#[test]
fn sequences_from_a_folder_or_a_pattern() {
    let dir = tempfile::tempdir().unwrap();
    // Unpadded numbers: frame 10 comes after frame 9 (numbers compared by value).
    for (i, n) in [(1, 3), (2, 3), (9, 4), (10, 2)] {
        let c = frame_cloud(n, i as f32);
        splatbridge_scene::ply::write_ply(
            &dir.path().join(format!("shot_{i}.ply")),
            &c,
            Default::default(),
        )
        .unwrap();
    }
    std::fs::write(dir.path().join("notes.txt"), "not a frame").unwrap();
    for spec in [
        dir.path().to_path_buf(),
        dir.path().join("shot_*.ply"),
        dir.path().join("shot_%d.ply"),
    ] {
        assert_eq!(
            detect(&spec).unwrap(),
            SplatFormat::FourD(FourDForm::Sequence),
            "{spec:?}"
        );
        let model = fourd::load(&spec, FourDForm::Sequence, 10.0).unwrap();
        assert_eq!(model.frame_count(), 4);
        assert!(!model.same_count());
        assert_eq!(model.max_count(), 4);
        let r = model.time_range();
        assert!((r.end - 0.3).abs() < 1e-12);
        for (t, x, n) in [
            (0.0, 1.0, 3),
            (0.1, 2.0, 3),
            (0.2, 9.0, 4),
            (0.25, 9.0, 4),
            (0.3, 10.0, 2),
        ] {
            let c = model.sample(t).unwrap();
            assert_eq!(c.len(), n, "t = {t}");
            assert_eq!(c.means[0].x, x, "t = {t}");
        }
        // Varying counts: no per-Gaussian displacement.
        assert!(model.displacement().unwrap().is_none());
    }
    let e = fourd::load(&dir.path().join("none_*.ply"), FourDForm::Sequence, 30.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no frame files found"), "{e}");
}

#[test]
fn a_sequence_frame_that_lies_about_its_size_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    for i in 0..2 {
        splatbridge_scene::ply::write_ply(
            &dir.path().join(format!("f_{i:04}.ply")),
            &frame_cloud(3, 0.0),
            Default::default(),
        )
        .unwrap();
    }
    let f1 = dir.path().join("f_0001.ply");
    let b = std::fs::read(&f1).unwrap();
    std::fs::write(&f1, &b[..b.len() - 8]).unwrap();
    let e = fourd::load(dir.path(), FourDForm::Sequence, 30.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("f_0001.ply") && e.contains("3 vertices"), "{e}");
}
