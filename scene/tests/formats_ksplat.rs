//! `.ksplat` (GaussianSplats3D) reading and writing: every compression level (0, 1, 2) and SH
//! degree 0–3 round-trips within the level's quantisation, checked value by value against a
//! slow per-field reference of what each level stores; splat-transform 3.7.0's reader decodes
//! our files as we do (`fixtures/formats/cut100.l*.ksplat` and their `.st.ply`, see
//! `fixtures/formats/README.md`); malformed files fail naming the file.

mod formats_common;

use formats_common::{fixtures, max_err, random_cloud};
use glam::Vec3;
use half::f16;
use splatbridge_scene::formats::ksplat::{
    bucket_order, decode_ksplat, encode_ksplat, record_bytes, KsplatOptions, HEADER, SECTION_HEADER,
};
use splatbridge_scene::formats::{detect, load_cloud, SplatFormat};
use splatbridge_scene::gaussians::{sh_coeffs, sigmoid};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::GaussianCloud;
use std::path::Path;

const C0: f32 = 0.282_094_8;

fn opts(level: u8) -> KsplatOptions {
    KsplatOptions {
        level,
        ..KsplatOptions::default()
    }
}

/// What a level stores of one value, by the format's definition (the slow reference).
fn stored_half(x: f32) -> f32 {
    f16::from_f32(x).to_f32()
}

fn permuted(c: &GaussianCloud, order: &[usize]) -> GaussianCloud {
    let mut out = GaussianCloud::with_capacity(c.sh_degree, c.len());
    for &i in order {
        out.push(
            c.means[i],
            c.log_scales[i],
            c.rotations[i],
            c.opacity_logits[i],
            c.sh_of(i),
        );
    }
    out
}

#[test]
fn every_level_and_degree_round_trips_within_its_quantisation() {
    let p = Path::new("mem.ksplat");
    for degree in 0..=3u8 {
        // Positions over ±12 so several 5-unit blocks and partially filled buckets occur.
        let c = random_cloud(11 + degree as u64, 700, degree, 12.0);
        for level in 0..=2u8 {
            let o = opts(level);
            let bytes = encode_ksplat(&c, &o).unwrap();
            let rec = record_bytes(level, degree);
            let (order, centres, lengths, _) = bucket_order(&c, &o);
            let buckets = if level == 0 {
                0
            } else {
                centres.len() * 12 + lengths.len() * 4
            };
            assert_eq!(
                bytes.len(),
                HEADER + SECTION_HEADER + buckets + rec * c.len()
            );
            let back = decode_ksplat(&bytes, p).unwrap();
            assert_eq!(back.sh_degree, degree);
            let want = if level == 0 {
                c.clone()
            } else {
                permuted(&c, &order)
            };
            let k = sh_coeffs(degree);
            let sh_all: Vec<f32> =
                c.sh.iter()
                    .enumerate()
                    .filter(|(i, _)| i % k != 0)
                    .flat_map(|(_, v)| v.to_array())
                    .collect();
            let lo = sh_all.iter().copied().fold(f32::INFINITY, f32::min);
            let hi = sh_all.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            for i in 0..c.len() {
                // Positions: exact at level 0; within half a quantisation step (block/2/32767)
                // plus f32 rounding of the bucket centre sum at levels 1, 2.
                let step = 2.5 / 32767.0;
                let dp = (back.means[i] - want.means[i]).abs().max_element();
                let tol = if level == 0 { 0.0 } else { 0.5 * step + 4e-6 };
                assert!(dp <= tol, "L{level} d{degree} {i}: position off by {dp}");
                // Scales and rotations: what the level stores, read back exactly.
                let s = want.scale(i);
                let q = want.unit_rotation(i);
                let (ws, wq) = if level == 0 {
                    (s, [q.w, q.x, q.y, q.z])
                } else {
                    (
                        Vec3::new(stored_half(s.x), stored_half(s.y), stored_half(s.z)),
                        [q.w, q.x, q.y, q.z].map(stored_half),
                    )
                };
                for a in 0..3 {
                    let got = back.log_scales[i][a];
                    assert!((got - ws[a].ln()).abs() <= 1e-6, "L{level} {i}: scale");
                }
                let bq = back.rotations[i];
                assert_eq!([bq.w, bq.x, bq.y, bq.z], wq, "L{level} {i}: rotation");
                // Colour and opacity: 8-bit, rounded: half a step.
                let dc = (back.sh[i * k] - want.sh[i * k]).abs().max_element() * C0;
                assert!(
                    dc <= 0.5 / 255.0 + 1e-5 || (want.sh[i * k] * C0).abs().max_element() > 0.5
                );
                let da = (back.opacity(i) - want.opacity(i)).abs();
                assert!(
                    da <= 0.5 / 255.0 + 1e-6,
                    "L{level} {i}: opacity off by {da}"
                );
                // Higher SH: exact (0), half float (1), 8 bits over [lo, hi] (2).
                for j in 1..k {
                    for ch in 0..3 {
                        let w = want.sh[i * k + j][ch];
                        let got = back.sh[i * k + j][ch];
                        let tol = match level {
                            0 => 0.0,
                            1 => (stored_half(w) - w).abs() + 0.0,
                            _ => 0.5 * (hi - lo) / 255.0 + 1e-6,
                        };
                        if level == 1 {
                            assert_eq!(got, stored_half(w));
                        }
                        assert!(
                            (got - w).abs() <= tol,
                            "L{level} d{degree} {i} sh{j}: {got} vs {w}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn colours_out_of_the_display_range_clamp_as_the_format_does() {
    let mut c = random_cloud(3, 4, 0, 1.0);
    c.sh[0] = Vec3::new(5.0, -5.0, 0.0);
    c.opacity_logits[1] = f32::INFINITY;
    c.opacity_logits[2] = f32::NEG_INFINITY;
    let back = decode_ksplat(&encode_ksplat(&c, &opts(0)).unwrap(), Path::new("x")).unwrap();
    assert_eq!(back.sh[0].x, (1.0 - 0.5) / C0);
    assert_eq!(back.sh[0].y, (0.0 - 0.5) / C0);
    assert_eq!(back.opacity(1), 1.0);
    assert_eq!(back.opacity(2), 0.0);
    assert!(sigmoid(back.opacity_logits[3]).is_finite());
}

#[test]
fn detected_by_content_and_extension() {
    let tmp = tempfile::tempdir().unwrap();
    let c = random_cloud(5, 50, 1, 2.0);
    for level in 0..=2u8 {
        let p = tmp.path().join(format!("x{level}.bin"));
        std::fs::write(&p, encode_ksplat(&c, &opts(level)).unwrap()).unwrap();
        assert_eq!(detect(&p).unwrap(), SplatFormat::Ksplat { level });
        let (cloud, info) = load_cloud(&p, &ReadOptions::default()).unwrap();
        assert_eq!(cloud.len(), 50);
        assert_eq!(info.format.name(), "ksplat");
    }
}

/// splat-transform 3.7.0's decoding of our files: positions, scales and rotations agree to
/// f32 rounding of the same formulas, colours and opacities to its clamped logit.
#[test]
fn splat_transform_reads_our_files_as_we_do() {
    for (name, degree) in [
        ("cut100.l0.ksplat", 3u8),
        ("cut100.l1.ksplat", 3),
        ("cut100.l2.ksplat", 3),
    ] {
        let p = fixtures().join(name);
        let ours = load_cloud(&p, &ReadOptions::default()).unwrap().0;
        assert_eq!(ours.sh_degree, degree);
        let st = fixtures().join(format!("{name}.st.ply"));
        let reference = load_cloud(&st, &ReadOptions::default()).unwrap().0;
        let e = max_err(&ours, &reference);
        println!("{name}, ours vs splat-transform's reader: {e:?}");
        // Both compute the same expressions, in f32 (ours) and f64 rounded to f32 (theirs).
        assert!(e.pos <= 1e-5, "{name}: {e:?}");
        assert!(e.log_scale <= 1e-5, "{name}: {e:?}");
        // Rotations as stored, component by component (the angle of `max_err` is 2·acos of an
        // f32 dot product, which reads 6.9e-4 one ulp below 1): the same numbers.
        for (a, b) in ours.rotations.iter().zip(&reference.rotations) {
            assert_eq!(a.to_array(), b.to_array(), "{name}");
        }
        assert!(e.colour <= 1e-5, "{name}: {e:?}");
        assert!(e.sh_rest <= 1e-5, "{name}: {e:?}");
        // splat-transform clamps alpha to [1e-6, 1 − 1e-6] before its logit.
        assert!(e.opacity <= 1e-6, "{name}: {e:?}");
    }
}

#[test]
fn malformed_files_fail_naming_the_file() {
    let c = random_cloud(9, 300, 2, 8.0);
    let good = encode_ksplat(&c, &opts(1)).unwrap();
    let set32 =
        |b: &mut Vec<u8>, at: usize, v: u32| b[at..at + 4].copy_from_slice(&v.to_le_bytes());
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (good[..100].to_vec(), "ends inside its 4096-byte header"),
        (good[..good.len() - 10].to_vec(), "runs past the end"),
        (
            {
                let mut b = good.clone();
                b[1] = 0;
                b
            },
            "version 0.0",
        ),
        (
            {
                let mut b = good.clone();
                b[20] = 3;
                b
            },
            "compression level 3",
        ),
        (
            {
                let mut b = good.clone();
                set32(&mut b, 4, u32::MAX);
                b
            },
            "sections",
        ),
        (
            {
                let mut b = good.clone();
                set32(&mut b, HEADER + 4, u32::MAX);
                set32(&mut b, HEADER, u32::MAX);
                b
            },
            "runs past the end",
        ),
        (
            {
                let mut b = good.clone();
                set32(&mut b, HEADER, 301);
                b
            },
            "301 Gaussians loaded of a section of 300",
        ),
        (
            {
                let mut b = good.clone();
                set32(&mut b, 16, 7);
                b
            },
            "declares 7 Gaussians but its sections hold 300",
        ),
        (
            {
                let mut b = good.clone();
                b[HEADER + 40] = 4;
                b
            },
            "SH degree 4",
        ),
        (
            {
                let mut b = good.clone();
                set32(&mut b, HEADER + 32, 1);
                b
            },
            "full and",
        ),
        (
            {
                let mut b = good.clone();
                b[HEADER + 20] = 16;
                b
            },
            "buckets of 16 bytes",
        ),
        (
            {
                let mut b = good.clone();
                b[HEADER + 16..HEADER + 20].copy_from_slice(&f32::NAN.to_le_bytes());
                b
            },
            "block size",
        ),
    ];
    let tmp = tempfile::tempdir().unwrap();
    for (k, (bytes, expect)) in cases.into_iter().enumerate() {
        let p = tmp.path().join(format!("bad{k}.ksplat"));
        std::fs::write(&p, &bytes).unwrap();
        let err = match load_cloud(&p, &ReadOptions::default()) {
            Ok(_) => panic!("case {k} ('{expect}') read without error"),
            Err(e) => e.to_string(),
        };
        assert!(err.starts_with(&p.display().to_string()), "{k}: {err}");
        assert!(
            err.contains(expect),
            "case {k}: expected '{expect}' in {err}"
        );
    }
}

/// GaussianSplats3D's own generator's files (`fixtures/formats/ksplat/`, `cut300.ply` at SH
/// degree 2) read within the quantisation its generator applies, which truncates where ours
/// rounds: one 8-bit step for colour, opacity and SH at level 2.
#[test]
fn gaussian_splats_3d_files_read_within_their_quantisation() {
    let original = load_cloud(&fixtures().join("cut300.ply"), &ReadOptions::default())
        .unwrap()
        .0;
    let k3 = original.coeffs();
    for level in 0..=2u8 {
        let p = fixtures().join(format!("ksplat/gs3d_l{level}.ksplat"));
        assert_eq!(detect(&p).unwrap(), SplatFormat::Ksplat { level });
        let ours = load_cloud(&p, &ReadOptions::default()).unwrap().0;
        assert_eq!(ours.len(), original.len());
        assert_eq!(ours.sh_degree, 2);
        let k = ours.coeffs();
        // The 8-bit SH range the generator wrote (header bytes 36..44).
        let bytes = std::fs::read(&p).unwrap();
        let f = |i: usize| f32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
        let sh_step = (f(40) - f(36)) / 255.0;
        let mut used = vec![false; original.len()];
        for i in 0..ours.len() {
            // The generator reorders into buckets: the original is the nearest unused mean.
            let j = (0..original.len())
                .filter(|&j| !used[j])
                .min_by(|&a, &b| {
                    let da = (original.means[a] - ours.means[i]).length_squared();
                    let db = (original.means[b] - ours.means[i]).length_squared();
                    da.total_cmp(&db)
                })
                .unwrap();
            used[j] = true;
            let dp = (ours.means[i] - original.means[j]).abs().max_element();
            // Level 0: float32 as is; 1, 2: half a step of 2.5/32767 plus rounding.
            let tol = if level == 0 {
                0.0
            } else {
                0.5 * 2.5 / 32767.0 + 4e-6
            };
            assert!(dp <= tol, "L{level} {i}: position off by {dp}");
            let s = original.scale(j);
            let got = ours.scale(i);
            for a in 0..3 {
                // exp in f64 then f32 (theirs) against exp in f32 (ours): 1e-6 relative; half
                // floats from three.js's `toHalfFloat`, which truncates the mantissa: one step
                // of 10 bits (2⁻¹⁰ relative) above 6.1e-5, an absolute 2⁻²⁴ below.
                let tol = if level == 0 {
                    1e-6 * s[a]
                } else {
                    s[a] / 1024.0 + 6e-8
                };
                assert!(
                    (got[a] - s[a]).abs() <= tol,
                    "L{level} {i}: scale {} vs {}",
                    got[a],
                    s[a]
                );
            }
            let (a, b) = (ours.unit_rotation(i), original.unit_rotation(j));
            assert!(a.dot(b).abs() >= 1.0 - 2e-6, "L{level} {i}: rotation");
            // Truncated to 8 bits: one step.
            let dc = ((ours.sh[i * k] - original.sh[j * k3]) * C0)
                .abs()
                .max_element();
            let clamped = (original.sh[j * k3] * C0).abs().max_element() >= 0.5;
            assert!(
                dc <= 1.0 / 255.0 + 1e-6 || clamped,
                "L{level} {i}: colour off by {dc}"
            );
            let da = (ours.opacity(i) - original.opacity(j)).abs();
            assert!(
                da <= 1.0 / 255.0 + 1e-6,
                "L{level} {i}: opacity off by {da}"
            );
            for c in 1..k {
                for ch in 0..3 {
                    let w = original.sh[j * k3 + c][ch];
                    let g = ours.sh[i * k + c][ch];
                    let tol = match level {
                        0 => 0.0,
                        1 => w.abs() / 1024.0 + 6e-8,
                        _ => sh_step + 1e-6,
                    };
                    assert!((g - w).abs() <= tol, "L{level} {i} sh{c}/{ch}: {g} vs {w}");
                }
            }
        }
    }
}
