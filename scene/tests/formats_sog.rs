//! PlayCanvas SOG reading: against the reference decoder, within the format's quantisation,
//! and on malformed input.
//!
//! Fixtures (`fixtures/formats/sog/`, see its `README.md`): `source.ply` is 300
//! Gaussians (SH degree 3) cut from `fourth_st.ply` with splat-transform; `v2.sog`,
//! `v2_unbundled/` and `v2_sh0.sog` are splat-transform 3.7.0's encodings of it, and each
//! `*.ref.ply` is splat-transform's own decoding of that file (the reference decoder's columns).
//! `v1/` is a version-1 SOG written by [`write_v1`] below (no published tool writes v1 any
//! more), and `v1.ref.ply` is splat-transform 3.7.0's decoding of it.

use std::io::Write;
use std::path::{Path, PathBuf};

use glam::Vec3;
use splatbridge_scene::formats::sog::{read_sog, read_sog_with_summary};
use splatbridge_scene::gaussians::{sh_coeffs, sigmoid};
use splatbridge_scene::ply::{read_ply, ReadOptions};
use splatbridge_scene::GaussianCloud;

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/formats/sog")
}

fn ply(p: &Path) -> GaussianCloud {
    read_ply(p, &ReadOptions::default()).unwrap().0
}

/// Largest |a − b| / max(1, |b|) over a pair of equal-length slices of f32s.
fn max_rel(a: impl Iterator<Item = f32>, b: impl Iterator<Item = f32>) -> f32 {
    a.zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs().max(1.0))
        .fold(0.0, f32::max)
}

fn flat3(v: &[Vec3]) -> impl Iterator<Item = f32> + '_ {
    v.iter().flat_map(|x| x.to_array())
}

/// Our decoding against the reference decoder's. Both compute in f64 from the same bytes and
/// round to f32; they can differ only where V8's `Math.exp`/`Math.log` and Rust's libm round
/// differently (≤ 1 ulp in f64), which survives the f32 rounding as at most 1 f32 ulp
/// (2⁻²³ relative); 4 ulps of slack cover a double rounding at a tie.
const REF_TOL: f32 = 4.0 / (1 << 23) as f32;

fn assert_matches_reference(ours: &GaussianCloud, reference: &GaussianCloud) {
    assert_eq!(ours.len(), reference.len());
    assert_eq!(ours.sh_degree, reference.sh_degree);
    let e = max_rel(flat3(&ours.means), flat3(&reference.means));
    assert!(e <= REF_TOL, "means differ by {e}");
    let e = max_rel(flat3(&ours.log_scales), flat3(&reference.log_scales));
    assert!(e <= REF_TOL, "log-scales differ by {e}");
    let e = max_rel(
        ours.rotations.iter().flat_map(|q| q.to_array()),
        reference.rotations.iter().flat_map(|q| q.to_array()),
    );
    assert!(e <= REF_TOL, "rotations differ by {e}");
    let e = max_rel(
        ours.opacity_logits.iter().copied(),
        reference.opacity_logits.iter().copied(),
    );
    assert!(e <= REF_TOL, "opacity logits differ by {e}");
    let e = max_rel(flat3(&ours.sh), flat3(&reference.sh));
    assert!(e <= REF_TOL, "SH differ by {e}");
}

#[test]
fn v2_bundled_matches_reference_decoder() {
    let (c, s) = read_sog_with_summary(&dir().join("v2.sog")).unwrap();
    assert_eq!(
        (s.version, s.bundled, s.count, s.sh_degree),
        (2, true, 300, 3)
    );
    assert_matches_reference(&c, &ply(&dir().join("v2.sog.ref.ply")));
}

#[test]
fn v2_unbundled_matches_reference_decoder() {
    let (c, s) = read_sog_with_summary(&dir().join("v2_unbundled/meta.json")).unwrap();
    assert_eq!((s.version, s.bundled), (2, false));
    assert_matches_reference(&c, &ply(&dir().join("v2_unbundled.ref.ply")));
}

#[test]
fn v2_without_sh_matches_reference_decoder() {
    let c = read_sog(&dir().join("v2_sh0.sog")).unwrap();
    assert_eq!(c.sh_degree, 0);
    assert_matches_reference(&c, &ply(&dir().join("v2_sh0.sog.ref.ply")));
}

#[test]
fn v1_matches_reference_decoder() {
    let (c, s) = read_sog_with_summary(&dir().join("v1/meta.json")).unwrap();
    assert_eq!((s.version, s.bundled, s.sh_degree), (1, false, 3));
    assert_matches_reference(&c, &ply(&dir().join("v1.ref.ply")));
}

/// The committed v1 fixture is exactly what [`write_v1`] makes of `source.ply`, so the
/// encoder below and the files cannot drift apart. Regenerate with
/// `SPLATBRIDGE_REGEN_FIXTURES=1 cargo test -p splatbridge-scene --test formats_sog`.
#[test]
fn v1_fixture_is_write_v1_of_source() {
    let src = ply(&dir().join("source.ply"));
    let files = write_v1(&src);
    let out = dir().join("v1");
    if std::env::var_os("SPLATBRIDGE_REGEN_FIXTURES").is_some() {
        std::fs::create_dir_all(&out).unwrap();
        for (name, bytes) in &files {
            std::fs::write(out.join(name), bytes).unwrap();
        }
    }
    for (name, bytes) in &files {
        assert_eq!(&std::fs::read(out.join(name)).unwrap(), bytes, "{name}");
    }
}

/// Nearest-bracket bound for a codebook value: the decoded value lies within the gap
/// between the two codebook entries around the original (k-means assigns each value to a
/// centroid next to it; its last assignment may predate the last centroid update, so not
/// always the nearest, but never past a neighbour).
fn codebook_gap(sorted: &[f32], x: f32) -> f32 {
    let i = sorted.partition_point(|&c| c < x);
    let lo = sorted[i.saturating_sub(1)];
    let hi = sorted[i.min(sorted.len() - 1)];
    (hi - lo).max((x - lo).abs()).max((hi - x).abs())
}

/// splat-transform's encoding decoded by us, against the original, within what SOG v2
/// quantises away. Every bound is derived from the encoder (write-sog.ts).
#[test]
fn v2_round_trip_within_quantisation() {
    let src = ply(&dir().join("source.ply"));
    let dec = read_sog(&dir().join("v2.sog")).unwrap();
    // SOG reorders Gaussians (Morton order); match each decoded one to its source by
    // position (positions are distinct at 300 points).
    let order: Vec<usize> = dec
        .means
        .iter()
        .map(|p| {
            (0..src.len())
                .min_by(|&a, &b| {
                    (src.means[a] - *p)
                        .length()
                        .total_cmp(&(src.means[b] - *p).length())
                })
                .unwrap()
        })
        .collect();
    let log_t = |x: f32| x.signum() * (x.abs() + 1.0).ln();
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for p in &src.means {
        let l = Vec3::new(log_t(p.x), log_t(p.y), log_t(p.z));
        lo = lo.min(l);
        hi = hi.max(l);
    }
    // 16 bits over the log-transformed range, truncated: one step in log space, which is
    // (|x| + 1)·(e^step − 1) in position; ×1.01 for f32 arithmetic in the bound itself.
    let step = (hi - lo) / 65535.0;
    for (i, &j) in order.iter().enumerate() {
        for a in 0..3 {
            let x = src.means[j][a];
            let bound = (x.abs() + 1.0) * step[a].exp_m1() * 1.01;
            assert!((dec.means[i][a] - x).abs() <= bound, "mean {i}.{a}");
        }
        // Smallest-three at 8 bits: each stored component is truncated to a 2/255 step of
        // [−1, 1] before the 1/√2 scale, so it is off by < √2/255; the largest is rebuilt
        // from the other three. |q·q'| ≥ 1 − ‖Δ‖²/2 with ‖Δ‖ < 2·√3·√2/255 (three small
        // components plus the rebuilt one), i.e. 1 − |q·q'| < 3.7e-4.
        let d = dec.rotations[i].dot(src.unit_rotation(j)).abs();
        assert!(1.0 - d < 3.7e-4, "rotation {i}: |dot| = {d}");
        // Opacity: sigmoid stored in 1/255 steps, truncated (plus the ±1e-6 clamp).
        let da = (sigmoid(dec.opacity_logits[i]) - src.opacity(j)).abs();
        assert!(da <= 1.0 / 255.0 + 1e-6, "opacity {i}: {da}");
    }
    // Scales and DC colour: one 256-entry k-means codebook per group; the decoded values are
    // the codebook entries in use.
    let mut scales: Vec<f32> = flat3(&dec.log_scales).collect();
    scales.sort_by(f32::total_cmp);
    scales.dedup();
    assert!(
        scales.len() <= 256,
        "scales use {} codebook values",
        scales.len()
    );
    let k = sh_coeffs(3);
    let mut dc: Vec<f32> = (0..dec.len())
        .flat_map(|i| dec.sh[i * k].to_array())
        .collect();
    dc.sort_by(f32::total_cmp);
    dc.dedup();
    assert!(dc.len() <= 256, "DC uses {} codebook values", dc.len());
    for (i, &j) in order.iter().enumerate() {
        for a in 0..3 {
            let x = src.log_scales[j][a];
            let g = codebook_gap(&scales, x);
            assert!((dec.log_scales[i][a] - x).abs() <= g, "log-scale {i}.{a}");
            let x = src.sh[j * k][a];
            let g = codebook_gap(&dc, x);
            assert!((dec.sh[i * k][a] - x).abs() <= g, "DC {i}.{a}");
        }
    }
}

/// A v1 file written here (exact ranges, rounding) decodes within half a step of each
/// channel's range; the SH palette has one entry per Gaussian, so its only loss is the 8-bit
/// range of all SH values.
#[test]
fn v1_round_trip_within_quantisation() {
    let src = ply(&dir().join("source.ply"));
    let dec = read_sog(&dir().join("v1/meta.json")).unwrap();
    let k = sh_coeffs(3);
    let range = |v: &mut dyn Iterator<Item = f32>| {
        v.fold((f32::MAX, f32::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)))
    };
    let (slo, shi) = range(&mut flat3(&src.log_scales));
    let (olo, ohi) = range(&mut src.opacity_logits.iter().copied());
    let rest: Vec<f32> = (0..src.len())
        .flat_map(|i| flat3(&src.sh[i * k + 1..(i + 1) * k]).collect::<Vec<_>>())
        .collect();
    let (rlo, rhi) = range(&mut rest.iter().copied());
    // Half an 8-bit step of the widest channel range (the writer rounds), ×1.01 for f32.
    let half = |lo: f32, hi: f32| (hi - lo) / 255.0 / 2.0 * 1.01;
    for i in 0..src.len() {
        for a in 0..3 {
            let e = (dec.log_scales[i][a] - src.log_scales[i][a]).abs();
            assert!(e <= half(slo, shi), "log-scale {i}.{a}: {e}");
        }
        let e = (dec.opacity_logits[i] - src.opacity_logits[i]).abs();
        assert!(e <= half(olo, ohi), "opacity {i}: {e}");
        for j in 1..k {
            let e = (dec.sh[i * k + j] - src.sh[i * k + j]).abs().max_element();
            assert!(e <= half(rlo, rhi), "SH {i}.{j}: {e}");
        }
    }
}

// ------------------------------------------------------------------ a v1 writer for tests

fn webp(rgba: &[u8], w: u32, h: u32) -> Vec<u8> {
    let mut out = Vec::new();
    image_webp::WebPEncoder::new(&mut out)
        .encode(rgba, w, h, image_webp::ColorType::Rgba8)
        .unwrap();
    out
}

/// Write `c` as a version-1 SOG (PlayCanvas SOGS layout: per-channel ranges, an SH palette
/// with one entry per Gaussian). Returns (file name, bytes) pairs, `meta.json` last.
fn write_v1(c: &GaussianCloud) -> Vec<(String, Vec<u8>)> {
    let n = c.len();
    let w = (n as f64).sqrt().ceil() as u32;
    let h = (n as u32).div_ceil(w);
    let px = (w * h) as usize;
    let q8 = |x: f32, lo: f32, hi: f32| {
        if hi > lo {
            ((x - lo) / (hi - lo) * 255.0).round().clamp(0.0, 255.0) as u8
        } else {
            0
        }
    };
    let lt = |x: f32| x.signum() * (x.abs() + 1.0).ln();
    let mut files = Vec::new();
    let ranges = |vals: &dyn Fn(usize) -> Vec<f32>, m: usize| -> (Vec<f32>, Vec<f32>) {
        let mut lo = vec![f32::MAX; m];
        let mut hi = vec![f32::MIN; m];
        for i in 0..n {
            for (a, x) in vals(i).into_iter().enumerate() {
                lo[a] = lo[a].min(x);
                hi[a] = hi[a].max(x);
            }
        }
        (lo, hi)
    };
    // means: 16 bits over the log-transformed range
    let (mlo, mhi) = ranges(&|i| c.means[i].to_array().map(lt).to_vec(), 3);
    let mut l = vec![255u8; px * 4];
    let mut u = vec![255u8; px * 4];
    for i in 0..n {
        for a in 0..3 {
            let v = lt(c.means[i][a]);
            let q = ((v - mlo[a]) / (mhi[a] - mlo[a]) * 65535.0).round() as u32;
            l[i * 4 + a] = (q & 255) as u8;
            u[i * 4 + a] = (q >> 8) as u8;
        }
    }
    files.push(("means_l.webp".to_string(), webp(&l, w, h)));
    files.push(("means_u.webp".to_string(), webp(&u, w, h)));
    // quats: smallest three
    let mut qb = vec![255u8; px * 4];
    for i in 0..n {
        let q = c.unit_rotation(i);
        let wxyz = [q.w, q.x, q.y, q.z];
        let m = (0..4)
            .max_by(|&a, &b| wxyz[a].abs().total_cmp(&wxyz[b].abs()))
            .unwrap();
        let s = if wxyz[m] < 0.0 { -1.0 } else { 1.0 };
        let mut k = 0;
        for (a, &x) in wxyz.iter().enumerate() {
            if a != m {
                qb[i * 4 + k] = ((x * s * std::f32::consts::SQRT_2 * 0.5 + 0.5) * 255.0)
                    .round()
                    .clamp(0.0, 255.0) as u8;
                k += 1;
            }
        }
        qb[i * 4 + 3] = 252 + m as u8;
    }
    files.push(("quats.webp".to_string(), webp(&qb, w, h)));
    let (slo, shi) = ranges(&|i| c.log_scales[i].to_array().to_vec(), 3);
    let mut sb = vec![255u8; px * 4];
    for i in 0..n {
        for a in 0..3 {
            sb[i * 4 + a] = q8(c.log_scales[i][a], slo[a], shi[a]);
        }
    }
    files.push(("scales.webp".to_string(), webp(&sb, w, h)));
    let k = c.coeffs();
    let dc4 = |i: usize| {
        let d = c.sh[i * k];
        vec![d.x, d.y, d.z, c.opacity_logits[i]]
    };
    let (clo, chi) = ranges(&dc4, 4);
    let mut cb = vec![255u8; px * 4];
    for i in 0..n {
        for (a, x) in dc4(i).into_iter().enumerate() {
            cb[i * 4 + a] = q8(x, clo[a], chi[a]);
        }
    }
    files.push(("sh0.webp".to_string(), webp(&cb, w, h)));
    // SH palette: entry i is Gaussian i; 64 entries per row, (k − 1) pixels each.
    let coeffs = k - 1;
    let (mut rlo, mut rhi) = (f32::MAX, f32::MIN);
    for i in 0..n {
        for j in 1..k {
            rlo = rlo.min(c.sh[i * k + j].min_element());
            rhi = rhi.max(c.sh[i * k + j].max_element());
        }
    }
    let rows = n.div_ceil(64);
    let cw = 64 * coeffs;
    let mut cen = vec![255u8; cw * rows * 4];
    let mut lab = vec![255u8; px * 4];
    for i in 0..n {
        for j in 0..coeffs {
            let o = ((i / 64) * cw + (i % 64) * coeffs + j) * 4;
            let v = c.sh[i * k + 1 + j];
            cen[o] = q8(v.x, rlo, rhi);
            cen[o + 1] = q8(v.y, rlo, rhi);
            cen[o + 2] = q8(v.z, rlo, rhi);
        }
        lab[i * 4] = (i & 255) as u8;
        lab[i * 4 + 1] = (i >> 8) as u8;
        lab[i * 4 + 2] = 0;
    }
    files.push((
        "shN_centroids.webp".to_string(),
        webp(&cen, cw as u32, rows as u32),
    ));
    files.push(("shN_labels.webp".to_string(), webp(&lab, w, h)));
    let meta = serde_json::json!({
        "means": {"shape": [n, 3], "dtype": "float32", "mins": mlo, "maxs": mhi,
                  "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"shape": [n, 3], "dtype": "float32", "mins": slo, "maxs": shi,
                   "files": ["scales.webp"]},
        "quats": {"shape": [n, 4], "dtype": "uint8", "encoding": "quaternion_packed",
                  "files": ["quats.webp"]},
        "sh0": {"shape": [n, 1, 4], "dtype": "float32", "mins": clo, "maxs": chi,
                "files": ["sh0.webp"]},
        "shN": {"shape": [n, coeffs], "dtype": "float32", "mins": rlo, "maxs": rhi,
                "quantization": 8, "files": ["shN_centroids.webp", "shN_labels.webp"]},
    });
    files.push(("meta.json".to_string(), serde_json::to_vec(&meta).unwrap()));
    files
}

// ------------------------------------------------------------------ malformed input

/// The entries of the reference `v2.sog`, meta.json parsed.
fn v2_entries() -> (serde_json::Value, Vec<(String, Vec<u8>)>) {
    use std::io::Read;
    let f = std::fs::File::open(dir().join("v2.sog")).unwrap();
    let mut z = zip::ZipArchive::new(f).unwrap();
    let mut out = Vec::new();
    let mut meta = serde_json::Value::Null;
    for i in 0..z.len() {
        let mut e = z.by_index(i).unwrap();
        let mut b = Vec::new();
        e.read_to_end(&mut b).unwrap();
        if e.name() == "meta.json" {
            meta = serde_json::from_slice(&b).unwrap();
        } else {
            out.push((e.name().to_string(), b));
        }
    }
    (meta, out)
}

fn zip_bytes(entries: &[(String, Vec<u8>)], deflate: bool) -> Vec<u8> {
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut z = zip::ZipWriter::new(&mut buf);
        let method = if deflate {
            zip::CompressionMethod::Deflated
        } else {
            zip::CompressionMethod::Stored
        };
        let opts = zip::write::SimpleFileOptions::default().compression_method(method);
        for (name, b) in entries {
            z.start_file(name.as_str(), opts).unwrap();
            z.write_all(b).unwrap();
        }
        z.finish().unwrap();
    }
    buf.into_inner()
}

/// A `.sog` built from the reference entries with `edit` applied to meta and entries.
fn sog_with(edit: impl FnOnce(&mut serde_json::Value, &mut Vec<(String, Vec<u8>)>)) -> Vec<u8> {
    let (mut meta, mut entries) = v2_entries();
    edit(&mut meta, &mut entries);
    if !meta.is_null() {
        entries.push(("meta.json".into(), serde_json::to_vec(&meta).unwrap()));
    }
    zip_bytes(&entries, false)
}

fn set_entry(entries: &mut [(String, Vec<u8>)], name: &str, bytes: Vec<u8>) {
    entries.iter_mut().find(|e| e.0 == name).unwrap().1 = bytes;
}

/// Replace every occurrence of the 4 bytes `from` by `to` (a little-endian u32 field).
fn patch_u32(bytes: &mut [u8], from: u32, to: u32) -> usize {
    let (f, t) = (from.to_le_bytes(), to.to_le_bytes());
    let mut n = 0;
    for i in 0..bytes.len().saturating_sub(3) {
        if bytes[i..i + 4] == f {
            bytes[i..i + 4].copy_from_slice(&t);
            n += 1;
        }
    }
    n
}

struct Case {
    name: &'static str,
    bytes: Vec<u8>,
    expect: &'static str,
}

fn cases() -> Vec<Case> {
    let good = std::fs::read(dir().join("v2.sog")).unwrap();
    let mut v = vec![
        Case {
            name: "truncated.sog",
            bytes: good[..good.len() / 2].to_vec(),
            expect: "zip",
        },
        Case {
            name: "bad_magic.sog",
            bytes: {
                let mut b = b"PK\x03\x04".to_vec();
                b.extend(std::iter::repeat_n(0x5a, 200));
                b
            },
            expect: "zip",
        },
        Case {
            name: "no_meta.sog",
            bytes: sog_with(|m, _| *m = serde_json::Value::Null),
            expect: "meta.json",
        },
        Case {
            name: "missing_count.sog",
            bytes: sog_with(|m, _| {
                m.as_object_mut().unwrap().remove("count");
            }),
            expect: "count is missing",
        },
        Case {
            name: "missing_means_mins.sog",
            bytes: sog_with(|m, _| {
                m["means"].as_object_mut().unwrap().remove("mins");
            }),
            expect: "means.mins",
        },
        Case {
            name: "null_in_codebook.sog",
            // JSON.stringify writes NaN as null.
            bytes: sog_with(|m, _| m["scales"]["codebook"][7] = serde_json::Value::Null),
            expect: "scales.codebook[7]",
        },
        Case {
            name: "short_codebook.sog",
            bytes: sog_with(|m, _| {
                m["sh0"]["codebook"].as_array_mut().unwrap().truncate(100);
            }),
            expect: "256",
        },
        Case {
            name: "count_too_big_for_images.sog",
            bytes: sog_with(|m, _| m["count"] = 1000.into()),
            expect: "disagrees with meta.json",
        },
        Case {
            name: "count_bomb.sog",
            bytes: sog_with(|m, _| m["count"] = 200_000_000u64.into()),
            expect: "decompression bomb",
        },
        Case {
            name: "wrong_size_webp.sog",
            bytes: sog_with(|_, e| set_entry(e, "quats.webp", webp(&[255; 4 * 16], 4, 4))),
            expect: "quats.webp",
        },
        Case {
            name: "not_webp.sog",
            bytes: sog_with(|_, e| set_entry(e, "scales.webp", b"RIFF....WEBPjunk".to_vec())),
            expect: "scales.webp",
        },
        Case {
            name: "label_beyond_palette.sog",
            bytes: sog_with(|m, _| m["shN"]["count"] = 3.into()),
            expect: "palette label",
        },
        Case {
            name: "version_3.sog",
            bytes: sog_with(|m, _| m["version"] = 3.into()),
            expect: "version 3",
        },
        Case {
            name: "missing_image.sog",
            bytes: sog_with(|_, e| e.retain(|x| x.0 != "sh0.webp")),
            expect: "sh0.webp",
        },
        Case {
            name: "zip_bomb_entry.sog",
            // 8 MB of zeros deflates to a few KB; 300 Gaussians need < 1 MB per image.
            bytes: {
                let (meta, mut entries) = v2_entries();
                set_entry(&mut entries, "means_l.webp", vec![0; 8 << 20]);
                entries.push(("meta.json".into(), serde_json::to_vec(&meta).unwrap()));
                zip_bytes(&entries, true)
            },
            expect: "declares",
        },
        Case {
            name: "zip_lying_size.sog",
            // The same bomb with its declared size patched down to 2000 bytes: the real
            // inflated size is still capped.
            bytes: {
                let (meta, mut entries) = v2_entries();
                set_entry(&mut entries, "means_l.webp", vec![0; 8 << 20]);
                entries.push(("meta.json".into(), serde_json::to_vec(&meta).unwrap()));
                let mut b = zip_bytes(&entries, true);
                assert!(patch_u32(&mut b, 8 << 20, 2000) >= 1);
                b
            },
            expect: "means_l.webp",
        },
    ];
    v.push(Case {
        name: "nan_text.json.sog",
        bytes: {
            let (meta, mut entries) = v2_entries();
            let text =
                serde_json::to_string(&meta)
                    .unwrap()
                    .replacen("\"mins\":[", "\"mins\":[NaN,", 1);
            entries.push(("meta.json".into(), text.into_bytes()));
            zip_bytes(&entries, false)
        },
        expect: "NaN",
    });
    v
}

#[test]
fn malformed_sog_files_fail_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = cases();
    assert!(cases.len() >= 8);
    for c in cases {
        let p = tmp.path().join(c.name);
        std::fs::write(&p, &c.bytes).unwrap();
        let r = std::panic::catch_unwind(|| read_sog(&p));
        let err = match r {
            Ok(Err(e)) => e.to_string(),
            Ok(Ok(cloud)) => panic!("{}: read {} Gaussians", c.name, cloud.len()),
            Err(_) => panic!("{}: panicked", c.name),
        };
        assert!(
            err.contains(c.name),
            "{}: error does not name the file: {err}",
            c.name
        );
        assert!(
            err.contains(c.expect),
            "{}: expected {:?} in: {err}",
            c.name,
            c.expect
        );
    }
}

#[test]
fn unbundled_meta_cannot_name_files_outside_its_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir().join("v2_unbundled/meta.json")).unwrap())
            .unwrap();
    meta["quats"]["files"][0] = "../../etc/passwd".into();
    for e in std::fs::read_dir(dir().join("v2_unbundled")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), tmp.path().join(e.file_name())).unwrap();
    }
    let p = tmp.path().join("meta.json");
    std::fs::write(&p, serde_json::to_vec(&meta).unwrap()).unwrap();
    let err = read_sog(&p).unwrap_err().to_string();
    assert!(
        err.contains("meta.json") && err.contains("plain relative path"),
        "{err}"
    );
}

#[cfg(unix)]
#[test]
fn a_fifo_is_refused_without_blocking() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("meta.json");
    // mkfifo is POSIX (coreutils): on a unix host its absence is a broken machine, not a skip.
    let ok = std::process::Command::new("mkfifo").arg(&p).status();
    assert!(matches!(ok, Ok(s) if s.success()), "mkfifo failed");
    let err = read_sog(&p).unwrap_err().to_string();
    assert!(err.contains("regular file"), "{err}");
}
