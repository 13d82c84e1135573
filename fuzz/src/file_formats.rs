//! Fuzz entry points for the readers added for the files users bring: GaussianSplats3D's
//! `.ksplat` (raw bytes; a structure-aware variant that writes plausible headers, section
//! headers and bucket tables with counts that may lie; and a round trip through the writer at
//! every level), and the PLY layouts beside the standard 3DGS one (`red green blue` colours,
//! 2DGS `scale_0 scale_1`, Mip-Splatting's `filter_3D`, points without Gaussian parameters),
//! and 2DGS surfels end to end: any values through the 2DGS writer, the reader and the 2DGS
//! renderer (finite pixels, alpha in [0, 1], the two scales and the rotation kept bit for bit),
//! and the 4D readers (SpacetimeGaussians PLY, `.splatv`, `params.npz`, frame sequences),
//! each model sampled at a few times.
//!
//! Included by path from `tests/fuzz_regressions.rs`, so it depends only on crates that the
//! root package also has.

use std::path::Path;

use arbitrary::{Arbitrary, Unstructured};
use splatbridge_scene::formats::ksplat::{self, KsplatOptions};
use splatbridge_scene::ply::ReadOptions;

use crate::entries::with_file;
use crate::splat_formats::load_both;

/// Every target of this module.
pub const TARGETS: &[(&str, crate::entries::Entry)] = &[
    ("ksplat", ksplat_raw),
    ("ksplat_structured", ksplat_structured),
    ("ksplat_roundtrip", ksplat_roundtrip),
    ("ply_variants", ply_variants),
    ("surfels_2d", surfels_2d),
    ("spacetime_ply", |d| four_d(0, d)),
    ("splatv", |d| four_d(1, d)),
    ("npz", |d| four_d(2, d)),
    ("ply_sequence", |d| four_d(3, d)),
];

pub fn ksplat_raw(data: &[u8]) {
    let _ = ksplat::decode_ksplat(data, Path::new("fuzz.ksplat"));
    with_file(data, ".ksplat", load_both);
}

#[derive(Arbitrary, Debug)]
struct SectionIn {
    count: u16,
    total_extra: u8,
    bucket_size: u16,
    buckets: u8,
    full: u8,
    partial: u8,
    block: f32,
    bucket_bytes: u8,
    range: u16,
    degree: u8,
    lengths: Vec<u16>,
}

#[derive(Arbitrary, Debug)]
struct KsplatIn {
    minor: u8,
    level: u8,
    declared_delta: i8,
    sh_range: (f32, f32),
    sections: Vec<SectionIn>,
    body: Vec<u8>,
    truncate: u16,
}

/// A file with a real header and section headers whose numbers may disagree with each other
/// and with the data that follows.
pub fn ksplat_structured(data: &[u8]) {
    let Ok(k) = KsplatIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let secs = &k.sections[..k.sections.len().min(4)];
    let mut out = vec![0u8; ksplat::HEADER + ksplat::SECTION_HEADER * secs.len()];
    out[1] = k.minor % 3;
    let put = |o: &mut Vec<u8>, at: usize, v: u32| o[at..at + 4].copy_from_slice(&v.to_le_bytes());
    put(&mut out, 4, secs.len() as u32);
    put(&mut out, 8, secs.len() as u32);
    let total: i64 = secs.iter().map(|s| s.count as i64).sum();
    let declared = (total + k.declared_delta as i64).max(0) as u32;
    put(&mut out, 12, declared);
    put(&mut out, 16, declared);
    out[20] = k.level % 4;
    out[36..40].copy_from_slice(&k.sh_range.0.to_le_bytes());
    out[40..44].copy_from_slice(&k.sh_range.1.to_le_bytes());
    let mut body = Vec::new();
    for (i, s) in secs.iter().enumerate() {
        let h = ksplat::HEADER + i * ksplat::SECTION_HEADER;
        put(&mut out, h, s.count as u32);
        put(&mut out, h + 4, s.count as u32 + s.total_extra as u32);
        put(&mut out, h + 8, s.bucket_size as u32);
        put(&mut out, h + 12, s.buckets as u32);
        out[h + 16..h + 20].copy_from_slice(&s.block.to_le_bytes());
        out[h + 20] = s.bucket_bytes;
        put(&mut out, h + 24, s.range as u32);
        put(&mut out, h + 32, s.full as u32);
        put(&mut out, h + 36, s.partial as u32);
        out[h + 40] = s.degree % 5;
        for l in s.lengths.iter().take(s.partial as usize) {
            body.extend_from_slice(&(*l as u32).to_le_bytes());
        }
    }
    out.extend_from_slice(&body);
    // The data: the fuzzer's bytes repeated to about the size the headers imply.
    let want: usize = secs
        .iter()
        .map(|s| {
            (s.count as usize + s.total_extra as usize)
                * ksplat::record_bytes(k.level % 3, s.degree % 4)
                + 12 * s.buckets as usize
        })
        .sum();
    if !k.body.is_empty() {
        out.extend(k.body.iter().cycle().take(want.min(1 << 22)));
    }
    let keep = out.len().saturating_sub(k.truncate as usize % 64);
    out.truncate(keep);
    ksplat_raw(&out);
}

/// One Gaussian: mean, log-scales, quaternion, opacity logit, DC colour.
type GaussianIn = ([f32; 3], [f32; 3], [f32; 4], f32, [f32; 3]);

#[derive(Arbitrary, Debug)]
struct CloudIn {
    level: u8,
    degree: u8,
    block: f32,
    bucket: u16,
    splats: Vec<GaussianIn>,
    sh: Vec<f32>,
}

/// Any finite cloud written at any level reads back with the same count and degree.
pub fn ksplat_roundtrip(data: &[u8]) {
    let Ok(c) = CloudIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let degree = c.degree % 4;
    let mut cloud = splatbridge_scene::GaussianCloud::new(degree);
    let k = cloud.coeffs();
    let mut sh = c.sh.iter().cycle();
    for (m, s, q, o, dc) in c.splats.iter().take(2000) {
        let mut coeffs = vec![glam::Vec3::from(*dc)];
        for _ in 1..k {
            let mut v = [0.0f32; 3];
            for x in &mut v {
                *x = sh.next().copied().unwrap_or(0.0);
            }
            coeffs.push(glam::Vec3::from(v));
        }
        cloud.push(
            glam::Vec3::from(*m),
            glam::Vec3::from(*s),
            glam::Quat::from_array(*q),
            *o,
            &coeffs,
        );
    }
    let opts = KsplatOptions {
        level: c.level % 3,
        block_size: c.block,
        bucket_size: c.bucket as u32,
    };
    let Ok(bytes) = ksplat::encode_ksplat(&cloud, &opts) else {
        return;
    };
    let back = ksplat::decode_ksplat(&bytes, Path::new("fuzz.ksplat"))
        .expect("a file the writer wrote reads back");
    assert_eq!(back.len(), cloud.len());
    assert_eq!(back.sh_degree, degree);
}

const NAMES: &[&str] = &[
    "x",
    "y",
    "z",
    "scale_0",
    "scale_1",
    "scale_2",
    "rot_0",
    "rot_1",
    "rot_2",
    "rot_3",
    "opacity",
    "f_dc_0",
    "f_dc_1",
    "f_dc_2",
    "red",
    "green",
    "blue",
    "filter_3D",
    "f_rest_0",
    "nx",
];
const TYPES: &[&str] = &["float", "double", "uchar", "ushort", "int", "char"];

#[derive(Arbitrary, Debug)]
struct PlyIn {
    ascii: bool,
    /// Which of the known names to declare (bit per name) and each one's type.
    present: u32,
    types: Vec<u8>,
    count: u8,
    values: Vec<f32>,
}

/// PLYs drawn from every layout the reader knows, with any subset of the properties.
pub fn ply_variants(data: &[u8]) {
    let Ok(p) = PlyIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let props: Vec<(&str, &str)> = NAMES
        .iter()
        .enumerate()
        .filter(|(i, _)| p.present >> i & 1 == 1)
        .map(|(i, n)| {
            let t = p.types.get(i).map_or(0, |t| *t as usize % TYPES.len());
            (*n, TYPES[t])
        })
        .collect();
    if props.is_empty() {
        return;
    }
    let enc = if p.ascii {
        "ascii"
    } else {
        "binary_little_endian"
    };
    let mut out = format!("ply\nformat {enc} 1.0\nelement vertex {}\n", p.count);
    for (n, t) in &props {
        out.push_str(&format!("property {t} {n}\n"));
    }
    out.push_str("end_header\n");
    let mut bytes = out.into_bytes();
    let mut vals = p.values.iter().cycle();
    for _ in 0..p.count {
        for (_, t) in &props {
            let v = vals.next().copied().unwrap_or(0.5);
            if p.ascii {
                bytes.extend_from_slice(format!("{v} ").as_bytes());
                continue;
            }
            match *t {
                "double" => bytes.extend_from_slice(&(v as f64).to_le_bytes()),
                "uchar" | "char" => bytes.push(v as u8),
                "ushort" => bytes.extend_from_slice(&(v as u16).to_le_bytes()),
                "int" => bytes.extend_from_slice(&(v as i32).to_le_bytes()),
                _ => bytes.extend_from_slice(&v.to_le_bytes()),
            }
        }
        if p.ascii {
            bytes.push(b'\n');
        }
    }
    with_file(&bytes, ".ply", |path| {
        for drop_invalid in [false, true] {
            let _ = splatbridge_scene::ply::read_ply(path, &ReadOptions { drop_invalid });
        }
        load_both(path);
    });
}

#[derive(Arbitrary, Debug)]
struct SurfelIn {
    /// Per surfel: x y z, f_dc 0..2, opacity logit, scale_0 scale_1, rot 0..3.
    values: Vec<[f32; 12]>,
    /// Camera: eye offset and field of view.
    eye: [f32; 3],
    fov: u8,
}

/// 2DGS surfels with any values: written as a 2DGS PLY, read back (Surfels2D, scales and
/// rotations bit-exact when valid), and rendered by the 2DGS renderer at 13×9 (finite
/// pixels, alpha in [0, 1]) or refused with an error.
pub fn surfels_2d(data: &[u8]) {
    use glam::{DVec3, Quat, Vec3};
    use splatbridge_scene::ply::{read_ply, write_ply_2dgs, GaussianKind};
    use splatbridge_scene::{Camera, GaussianCloud};

    let Ok(p) = SurfelIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let mut cloud = GaussianCloud::new(0);
    for v in p.values.iter().take(64) {
        cloud.push(
            Vec3::new(v[0], v[1], v[2]),
            Vec3::new(v[7], v[8], v[7].min(v[8]) - 6.9),
            Quat::from_xyzw(v[10], v[11], v[9], 1.0),
            v[6],
            &[Vec3::new(v[3], v[4], v[5])],
        );
    }
    let Ok(dir) = tempfile::tempdir() else {
        return;
    };
    let path = dir.path().join("surfels.ply");
    if write_ply_2dgs(&path, &cloud).is_err() {
        return;
    }
    let Ok((read, report)) = read_ply(&path, &ReadOptions { drop_invalid: true }) else {
        return;
    };
    assert_eq!(
        report.kind,
        GaussianKind::Surfels2D,
        "a 2DGS PLY read as something else"
    );
    if report.dropped_total() == 0 {
        for i in 0..read.len() {
            let (a, b) = (read.log_scales[i], cloud.log_scales[i]);
            assert_eq!(
                (a.x.to_bits(), a.y.to_bits()),
                (b.x.to_bits(), b.y.to_bits())
            );
            assert_eq!(read.rotations[i], cloud.rotations[i]);
        }
    }
    let e = p.eye.map(|v| if v.is_finite() { v as f64 } else { 0.0 });
    let Ok(cam) = Camera::look_at(
        DVec3::new(e[0], e[1], e[2] - 5.0),
        DVec3::new(e[0], e[1], e[2]),
        DVec3::NEG_Y,
        10.0 + (p.fov % 150) as f64,
        13,
        9,
    ) else {
        return;
    };
    let opts = splatbridge_hybrid::RenderOptions::default();
    if let Ok((frame, _)) = splatbridge_hybrid::surfel2d::render_surfels(&read, &cam, &opts) {
        assert!(frame.is_finite(), "non-finite 2DGS pixels");
        assert!(frame.alpha.iter().all(|a| (0.0..=1.0).contains(a)));
    }
}

/// The 4D readers: `sel` picks the form (SpacetimeGaussians PLY, `.splatv`, `params.npz`, a
/// two-frame sequence split at the input's first byte); every model read is sampled at a few
/// times, as `render --time` would.
fn four_d(sel: u8, rest: &[u8]) {
    use splatbridge_scene::fourd::{self, FourDForm};
    let sample = |m: &fourd::FourD| {
        for t in [0.0, 0.37, 1.0, -5.0, f64::NAN, 1e30] {
            let _ = m.sample(t);
        }
        let _ = m.displacement();
    };
    let form = match sel % 4 {
        0 => FourDForm::SpacetimeLite,
        1 => FourDForm::Splatv,
        2 => FourDForm::Npz,
        _ => FourDForm::Sequence,
    };
    if form == FourDForm::Sequence {
        let Ok(dir) = tempfile::tempdir() else {
            return;
        };
        let cut = rest.first().map_or(0, |&b| b as usize).min(rest.len());
        let (a, b) = rest.split_at(cut);
        for (i, part) in [a, b].iter().enumerate() {
            if std::fs::write(dir.path().join(format!("f_{i:04}.ply")), part).is_err() {
                return;
            }
        }
        if let Ok(m) = fourd::load(dir.path(), form, 30.0) {
            sample(&m);
        }
        load_both(dir.path());
        return;
    }
    let ext = [".ply", ".splatv", ".npz", ""][sel as usize % 4];
    with_file(rest, ext, |p| {
        if let Ok(m) = fourd::load(p, form, 24.0) {
            sample(&m);
        }
        load_both(p);
    });
}
