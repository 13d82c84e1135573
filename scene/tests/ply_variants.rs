//! PLY layouts besides the standard 3DGS one (`scene/src/ply/variant.rs`): `red green blue`
//! colours instead of `f_dc_*`, points without Gaussian parameters, Mip-Splatting's
//! `filter_3D` folded in as its loader does, and 2DGS surfels (`scale_0 scale_1` only).
//! Each is checked against the formula it follows, evaluated here independently in f64.

use std::path::{Path, PathBuf};

use glam::Vec3;
use splatbridge_scene::formats::load_cloud;
use splatbridge_scene::gaussians::sigmoid;
use splatbridge_scene::ply::{
    read_ply, write_ply, GaussianKind, PlyFormat, ReadOptions, POINT_OPACITY, SURFEL_THICKNESS,
};
use splatbridge_scene::GaussianCloud;

/// 3DGS's C0 (`utils/sh_utils.py`), written out here rather than taken from the crate.
const C0: f64 = 0.282_094_791_773_878_14;

/// One property: name, PLY type, a value per vertex.
#[derive(Clone)]
struct Prop {
    name: &'static str,
    ty: &'static str,
    values: Vec<f64>,
}

fn prop(name: &'static str, ty: &'static str, values: &[f64]) -> Prop {
    Prop {
        name,
        ty,
        values: values.to_vec(),
    }
}

/// A PLY of these properties, binary little endian or ASCII.
fn ply_bytes(props: &[Prop], ascii: bool) -> Vec<u8> {
    let n = props[0].values.len();
    let mut h = format!(
        "ply\nformat {} 1.0\nelement vertex {n}\n",
        if ascii {
            "ascii"
        } else {
            "binary_little_endian"
        }
    );
    for p in props {
        h += &format!("property {} {}\n", p.ty, p.name);
    }
    h += "end_header\n";
    let mut out = h.into_bytes();
    for i in 0..n {
        let mut line = Vec::new();
        for p in props {
            let v = p.values[i];
            if ascii {
                line.push(format!("{v}"));
                continue;
            }
            match p.ty {
                "uchar" => out.push(v as u8),
                "ushort" => out.extend((v as u16).to_le_bytes()),
                "int" => out.extend((v as i32).to_le_bytes()),
                "float" => out.extend((v as f32).to_le_bytes()),
                "double" => out.extend(v.to_le_bytes()),
                t => panic!("type {t}"),
            }
        }
        if ascii {
            out.extend(line.join(" ").into_bytes());
            out.push(b'\n');
        }
    }
    out
}

fn write(dir: &Path, name: &str, props: &[Prop], ascii: bool) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, ply_bytes(props, ascii)).unwrap();
    p
}

/// `red green blue` of two points, of the given property types.
fn rgb2(r: &'static str, g: &'static str, b: &'static str) -> Vec<Prop> {
    vec![
        prop("red", r, &[1.0, 2.0]),
        prop("green", g, &[1.0, 2.0]),
        prop("blue", b, &[1.0, 2.0]),
    ]
}

fn xyz(n: usize) -> Vec<Prop> {
    let c = |k: usize| {
        (0..n)
            .map(|i| (i * 7 + k * 3) as f64 * 0.1)
            .collect::<Vec<_>>()
    };
    vec![
        prop("x", "float", &c(0)),
        prop("y", "float", &c(1)),
        prop("z", "float", &c(2)),
    ]
}

fn gaussian_props(n: usize, three_scales: bool) -> Vec<Prop> {
    let v = |a: f64, step: f64| (0..n).map(|i| a + step * i as f64).collect::<Vec<_>>();
    let mut p = vec![
        prop("scale_0", "float", &v(-3.0, 0.1)),
        prop("scale_1", "float", &v(-4.0, 0.2)),
    ];
    if three_scales {
        p.push(prop("scale_2", "float", &v(-5.0, 0.05)));
    }
    p.extend([
        prop("rot_0", "float", &v(1.0, 0.0)),
        prop("rot_1", "float", &v(0.1, 0.05)),
        prop("rot_2", "float", &v(-0.2, 0.0)),
        prop("rot_3", "float", &v(0.3, 0.0)),
        prop("opacity", "float", &v(-1.0, 0.5)),
    ]);
    p
}

fn read(p: &Path) -> (GaussianCloud, splatbridge_scene::ply::ReadReport) {
    read_ply(p, &ReadOptions::default()).unwrap()
}

/// f32 rounding of a value computed in f64: a few ulps (2⁻²³ relative each).
fn close(a: f32, b: f64) -> bool {
    (a as f64 - b).abs() <= 4.0 * f32::EPSILON as f64 * b.abs().max(1.0)
}

#[test]
fn uchar_and_float_colours_become_the_dc_term() {
    let tmp = tempfile::tempdir().unwrap();
    let reds = [0.0, 128.0, 255.0, 17.0];
    for (ty, scale) in [
        ("uchar", 255.0),
        ("ushort", 65535.0),
        ("float", 1.0),
        ("double", 1.0),
    ] {
        for ascii in [false, true] {
            let mut props = xyz(4);
            props.extend(gaussian_props(4, true));
            let vals = |k: f64| {
                reds.iter()
                    .map(|r| ((r + k) % 256.0) / 255.0 * scale)
                    .collect::<Vec<_>>()
            };
            props.extend([
                prop("red", ty, &vals(0.0)),
                prop("green", ty, &vals(40.0)),
                prop("blue", ty, &vals(90.0)),
            ]);
            let p = write(tmp.path(), "c.ply", &props, ascii);
            let (c, report) = read(&p);
            assert_eq!(report.kind, GaussianKind::Gaussians3D);
            assert!(report.warnings.iter().any(|w| w.contains("red green blue")));
            assert!(report.ignored_properties.is_empty(), "{report:?}");
            for i in 0..4 {
                for (k, prop) in props[props.len() - 3..].iter().enumerate() {
                    let c01 = match ty {
                        "uchar" | "ushort" => prop.values[i].trunc() / scale,
                        _ => prop.values[i] as f32 as f64,
                    };
                    let want = (c01 - 0.5) / C0;
                    assert!(
                        close(c.sh[i][k], want),
                        "{ty} {i} {k}: {} vs {want}",
                        c.sh[i][k]
                    );
                }
            }
        }
    }
}

#[test]
fn f_dc_wins_over_red_green_blue() {
    let tmp = tempfile::tempdir().unwrap();
    let mut props = xyz(2);
    props.extend(gaussian_props(2, true));
    props.extend([
        prop("f_dc_0", "float", &[0.5, 0.25]),
        prop("f_dc_1", "float", &[0.5, 0.25]),
        prop("f_dc_2", "float", &[0.5, 0.25]),
        prop("red", "uchar", &[1.0, 2.0]),
        prop("green", "uchar", &[1.0, 2.0]),
        prop("blue", "uchar", &[1.0, 2.0]),
    ]);
    let (c, report) = read(&write(tmp.path(), "c.ply", &props, false));
    assert_eq!(c.sh[1], Vec3::splat(0.25));
    assert_eq!(report.ignored_properties, ["red", "green", "blue"]);
}

#[test]
fn points_get_3dgs_initial_gaussians() {
    let tmp = tempfile::tempdir().unwrap();
    // Four points on a line 1 apart, and two far ones 10 apart.
    let xs = [0.0, 1.0, 2.0, 3.0, 100.0, 110.0];
    let zero = [0.0; 6];
    let props = vec![
        prop("x", "float", &xs),
        prop("y", "float", &zero),
        prop("z", "float", &zero),
        prop("red", "uchar", &[255.0; 6]),
        prop("green", "uchar", &[0.0; 6]),
        prop("blue", "uchar", &[0.0; 6]),
    ];
    let (c, report) = read(&write(tmp.path(), "p.ply", &props, false));
    assert_eq!(report.kind, GaussianKind::Points);
    assert_eq!(c.len(), 6);
    // Mean squared distance to the 3 nearest, by hand: point 0 → 1, 2, 3 → (1+4+9)/3.
    let want0 = ((1.0f64 + 4.0 + 9.0) / 3.0).sqrt();
    assert!(close(c.scale(0).x, want0), "{} vs {want0}", c.scale(0).x);
    // Point 1 → 0, 2, 3 → (1+1+4)/3.
    let want1 = 2.0f64.sqrt();
    assert!(close(c.scale(1).y, want1));
    for i in 0..6 {
        assert_eq!(c.rotations[i], glam::Quat::IDENTITY);
        assert!((c.opacity(i) - POINT_OPACITY).abs() < 1e-6);
        assert!(c.log_scales[i].is_finite());
    }
    assert!(close(c.sh[0].x, (1.0 - 0.5) / C0));
}

#[test]
fn colourless_or_badly_typed_files_name_the_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let cases: Vec<(Vec<Prop>, &str)> = vec![
        (
            xyz(2),
            "'f_dc_0' is missing (and there is no 'red green blue'",
        ),
        (
            [xyz(2), rgb2("int", "int", "int")].concat(),
            "colour property 'red' has type int",
        ),
        (
            [xyz(2), rgb2("uchar", "float", "uchar")].concat(),
            "different types",
        ),
        (
            {
                // Scales without rotations: not points, not Gaussians.
                let mut p = xyz(2);
                p.extend(
                    gaussian_props(2, true)
                        .into_iter()
                        .filter(|p| !p.name.starts_with("rot")),
                );
                p.extend(rgb2("uchar", "uchar", "uchar"));
                p
            },
            "'rot_0' is missing",
        ),
        (
            {
                let mut p = xyz(2);
                p.push(prop("scale_0", "float", &[0.0, 0.0]));
                p.extend(rgb2("uchar", "uchar", "uchar"));
                p
            },
            "'scale_1' is missing",
        ),
    ];
    for (k, (props, expect)) in cases.iter().enumerate() {
        let p = write(tmp.path(), &format!("bad{k}.ply"), props, false);
        let err = read_ply(&p, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(err.starts_with(&p.display().to_string()), "{err}");
        assert!(err.contains(expect), "case {k}: {err}");
    }
}

/// Mip-Splatting's `get_scaling_with_3D_filter` and `get_opacity_with_3D_filter`, in f64.
fn mip_reference(log_s: [f64; 3], logit: f64, f: f64) -> ([f64; 3], f64) {
    let s2 = log_s.map(|l| (2.0 * l).exp());
    let after = s2.map(|x| x + f * f);
    let coef = ((s2[0] * s2[1] * s2[2]) / (after[0] * after[1] * after[2])).sqrt();
    (after.map(f64::sqrt), 1.0 / (1.0 + (-logit).exp()) * coef)
}

#[test]
fn filter_3d_is_folded_in_as_mip_splatting_loads_it() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 5;
    let mut props = xyz(n);
    props.extend(gaussian_props(n, true));
    props.extend([
        prop("f_dc_0", "float", &[0.1; 5]),
        prop("f_dc_1", "float", &[0.2; 5]),
        prop("f_dc_2", "float", &[0.3; 5]),
    ]);
    let filters = [0.0, 0.001, 0.01, 0.05, 1.0];
    props.push(prop("filter_3D", "float", &filters));
    let (c, report) = read(&write(tmp.path(), "mip.ply", &props, false));
    assert_eq!(report.kind, GaussianKind::Gaussians3D);
    assert!(report.ignored_properties.is_empty());
    assert!(report.warnings.iter().any(|w| w.contains("filter_3D")));
    for i in 0..n {
        let ls = [0, 1, 2].map(|k| props[3 + k].values[i] as f32 as f64);
        let logit = props[10].values[i] as f32 as f64;
        let (s, alpha) = mip_reference(ls, logit, filters[i] as f32 as f64);
        let got = c.scale(i);
        for k in 0..3 {
            assert!(close(got[k], s[k]), "{i} {k}: {} vs {}", got[k], s[k]);
        }
        // Through exp/ln and logit/sigmoid in f32: 1e-6 absolute on an opacity in [0, 1].
        assert!(
            (c.opacity(i) as f64 - alpha).abs() < 1e-6,
            "{i}: {} vs {alpha}",
            c.opacity(i)
        );
    }
    // A zero filter changes nothing (beyond f32 rounding through the fold).
    let plain = sigmoid(props[10].values[0] as f32);
    assert!((c.opacity(0) - plain).abs() < 1e-6);
    // The fold is what is written: a round trip through the writer keeps it, filter gone.
    let out = tmp.path().join("out.ply");
    write_ply(&out, &c, PlyFormat::BinaryLittleEndian).unwrap();
    let (back, r2) = read(&out);
    assert_eq!(back, c);
    assert_eq!(r2.kind, GaussianKind::Gaussians3D);
}

#[test]
fn two_d_gaussian_surfels_are_thin_discs() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 4;
    for ascii in [false, true] {
        let mut props = xyz(n);
        props.extend(gaussian_props(n, false));
        props.extend([
            prop("f_dc_0", "float", &[0.1; 4]),
            prop("f_dc_1", "float", &[0.2; 4]),
            prop("f_dc_2", "float", &[0.3; 4]),
        ]);
        let p = write(tmp.path(), "2dgs.ply", &props, ascii);
        let (c, report) = read(&p);
        assert_eq!(report.kind, GaussianKind::Surfels2D);
        for i in 0..n {
            let l = c.log_scales[i];
            assert_eq!(l.x, props[3].values[i] as f32);
            assert_eq!(l.y, props[4].values[i] as f32);
            let want = l.x.min(l.y) as f64 + (SURFEL_THICKNESS as f64).ln();
            assert!(close(l.z, want), "{} vs {want}", l.z);
            // The normal (third axis of the rotation) is the thin axis.
            let s = c.scale(i);
            assert!(s.z <= SURFEL_THICKNESS * s.x.min(s.y) * 1.0001);
        }
        // Every command's loader reads it.
        let (cloud, info) = load_cloud(&p, &ReadOptions::default()).unwrap();
        assert_eq!(cloud, c);
        assert_eq!(info.kind, GaussianKind::Surfels2D);
    }
    // Mip-Splatting's 3D filter is not defined for surfels.
    let mut props = xyz(n);
    props.extend(gaussian_props(n, false));
    props.extend([
        prop("f_dc_0", "float", &[0.1; 4]),
        prop("f_dc_1", "float", &[0.2; 4]),
        prop("f_dc_2", "float", &[0.3; 4]),
        prop("filter_3D", "float", &[0.1; 4]),
    ]);
    let p = write(tmp.path(), "2dgs_mip.ply", &props, false);
    let err = read_ply(&p, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("'filter_3D'") && err.contains("2DGS"), "{err}");
}

/// Every stored value of a cloud as bits (so −0.0 and +0.0 differ).
fn cloud_bits(c: &GaussianCloud) -> Vec<u32> {
    let mut b: Vec<u32> = Vec::new();
    for i in 0..c.len() {
        b.extend(c.means[i].to_array().map(f32::to_bits));
        b.extend(c.log_scales[i].to_array().map(f32::to_bits));
        b.extend(c.rotations[i].to_array().map(f32::to_bits));
        b.push(c.opacity_logits[i].to_bits());
    }
    b.extend(c.sh.iter().flat_map(|v| v.to_array().map(f32::to_bits)));
    b.push(c.sh_degree as u32);
    b
}

/// The binary reader of non-standard layouts (each slot resolved to a load on the record's
/// bytes) against the ASCII reader's per-property path (`Variant::assemble`, the reference):
/// the same values in both encodings give the same cloud bit for bit, for every layout and
/// colour type, with −0.0 among the values.
#[test]
fn binary_variant_path_matches_the_per_property_reference() {
    let tmp = tempfile::tempdir().unwrap();
    // Records of about 100 bytes: the binary reader's 64 KiB chunks then hold about 700, so
    // 3001 records make several chunks, each decoded in two parallel tasks of at most 512
    // records (`append_parallel`) with a short last one.
    let n = 3001;
    let rng = std::cell::RefCell::new(splatbridge_scene::rng::Rng::new(7));
    // Values exactly representable in f32 (the binary files store float32), one in 16 a −0.0.
    let mut floats = |lo: f64, hi: f64| -> Vec<f64> {
        let mut r = rng.borrow_mut();
        (0..n)
            .map(|_| {
                if r.range(0.0, 1.0) < 1.0 / 16.0 {
                    -0.0
                } else {
                    r.range(lo as f32, hi as f32) as f64
                }
            })
            .collect()
    };
    let ints = |hi: f64| -> Vec<f64> {
        let mut r = rng.borrow_mut();
        (0..n)
            .map(|_| (r.range(0.0, 1.0) as f64 * hi).floor().min(hi - 1.0))
            .collect()
    };
    let base = |f: &mut dyn FnMut(f64, f64) -> Vec<f64>, scales: usize| {
        let mut p = vec![
            Prop {
                name: "x",
                ty: "float",
                values: f(-2.0, 2.0),
            },
            Prop {
                name: "y",
                ty: "float",
                values: f(-2.0, 2.0),
            },
            Prop {
                name: "z",
                ty: "float",
                values: f(-2.0, 2.0),
            },
        ];
        for name in ["scale_0", "scale_1", "scale_2"].into_iter().take(scales) {
            p.push(Prop {
                name,
                ty: "float",
                values: f(-5.0, -1.0),
            });
        }
        for name in ["rot_0", "rot_1", "rot_2", "rot_3"] {
            p.push(Prop {
                name,
                ty: "float",
                values: f(0.1, 1.0),
            });
        }
        p.push(Prop {
            name: "opacity",
            ty: "float",
            values: f(-2.0, 3.0),
        });
        for name in [
            "f_rest_0", "f_rest_1", "f_rest_2", "f_rest_3", "f_rest_4", "f_rest_5", "f_rest_6",
            "f_rest_7", "f_rest_8",
        ] {
            p.push(Prop {
                name,
                ty: "float",
                values: f(-0.3, 0.3),
            });
        }
        p
    };
    let mut layouts: Vec<(&str, Vec<Prop>)> = Vec::new();
    let dc = |f: &mut dyn FnMut(f64, f64) -> Vec<f64>| {
        ["f_dc_0", "f_dc_1", "f_dc_2"].map(|name| Prop {
            name,
            ty: "float",
            values: f(-1.0, 1.0),
        })
    };
    // Colour as uchar, ushort, float and double instead of f_dc.
    for (ty, hi) in [
        ("uchar", 256.0),
        ("ushort", 65536.0),
        ("float", 0.0),
        ("double", 0.0),
    ] {
        let mut p = base(&mut floats, 3);
        for name in ["red", "green", "blue"] {
            let values = if hi > 0.0 { ints(hi) } else { floats(0.0, 1.0) };
            p.push(Prop { name, ty, values });
        }
        layouts.push((ty, p));
    }
    // 2DGS: two scales.
    let mut p = base(&mut floats, 2);
    p.extend(dc(&mut floats));
    layouts.push(("2dgs", p));
    // Mip-Splatting: filter_3D, as float and as double.
    for ty in ["float", "double"] {
        let mut p = base(&mut floats, 3);
        p.extend(dc(&mut floats));
        p.push(Prop {
            name: "filter_3D",
            ty,
            values: floats(0.0, 0.02),
        });
        layouts.push(("mip", p));
    }
    for (k, (name, props)) in layouts.iter().enumerate() {
        let b = write(tmp.path(), &format!("{k}b.ply"), props, false);
        let a = write(tmp.path(), &format!("{k}a.ply"), props, true);
        let (cb, rb) = read(&b);
        let (ca, ra) = read(&a);
        assert_eq!(rb.kind, ra.kind, "{name}");
        assert_eq!(cb.len(), n, "{name}");
        assert!(
            cloud_bits(&cb) == cloud_bits(&ca),
            "{name} ({k}): the binary and the per-property paths differ"
        );
    }
}
