//! PLY write→read is bit-exact for every SH degree and every encoding, and the reader maps
//! hand-built files (any property order, no normals, doubles, extra properties) to the values
//! they hold, with `f_rest` reordered from channel-major to coefficient-major.

use glam::{Quat, Vec3};
use splatbridge_scene::ply::{read_ply, write_ply, PlyFormat, ReadOptions};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::GaussianCloud;

const FORMATS: [PlyFormat; 3] = [
    PlyFormat::BinaryLittleEndian,
    PlyFormat::BinaryBigEndian,
    PlyFormat::Ascii,
];

/// Values whose decimal spelling or bit pattern is easy to get wrong.
const AWKWARD: [f32; 12] = [
    0.0,
    -0.0,
    1e-45,             // smallest subnormal
    f32::MIN_POSITIVE, // smallest normal
    f32::MIN,          // most negative finite
    0.1,
    1.0 / 3.0,
    16777217.0, // rounds to 2^24
    -23.0,      // the log-scale real files hold
    1e-5,
    123456.79,
    9.999999e6,
];

fn random_cloud(degree: u8, n: usize, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let pick = |rng: &mut Rng| -> f32 {
        if rng.below(4) == 0 {
            AWKWARD[rng.below(AWKWARD.len() as u64) as usize]
        } else {
            // Random bit patterns of finite floats cover every exponent.
            loop {
                let v = f32::from_bits(rng.next_u64() as u32);
                if v.is_finite() {
                    return v;
                }
            }
        }
    };
    let mut c = GaussianCloud::new(degree);
    let k = c.coeffs();
    for i in 0..n {
        let mean = Vec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng));
        let log_scale = Vec3::new(pick(&mut rng), pick(&mut rng), -23.0);
        let mut q = Quat::from_xyzw(
            pick(&mut rng),
            pick(&mut rng),
            pick(&mut rng),
            pick(&mut rng),
        );
        if q.length_squared() == 0.0 {
            q = Quat::from_xyzw(0.0, 0.0, 0.0, 3.2);
        }
        let opacity = match i % 5 {
            0 => f32::INFINITY,
            1 => f32::NEG_INFINITY,
            _ => pick(&mut rng),
        };
        let sh: Vec<Vec3> = (0..k)
            .map(|_| Vec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng)))
            .collect();
        c.push(mean, log_scale, q, opacity, &sh);
    }
    c
}

fn bits(c: &GaussianCloud) -> Vec<u32> {
    let mut v = Vec::new();
    for i in 0..c.len() {
        v.extend(c.means[i].to_array().map(f32::to_bits));
        v.extend(c.log_scales[i].to_array().map(f32::to_bits));
        v.extend(c.rotations[i].to_array().map(f32::to_bits));
        v.push(c.opacity_logits[i].to_bits());
        v.extend(
            c.sh_of(i)
                .iter()
                .flat_map(|s| s.to_array().map(f32::to_bits)),
        );
    }
    v
}

#[test]
fn write_read_is_bit_exact_for_all_degrees_and_formats() {
    let dir = tempfile::tempdir().unwrap();
    for degree in 0..=3u8 {
        let cloud = random_cloud(degree, 300, 17 + degree as u64);
        for format in FORMATS {
            let path = dir.path().join(format!("d{degree}_{format:?}.ply"));
            write_ply(&path, &cloud, format).unwrap();
            let (back, report) = read_ply(&path, &ReadOptions::default()).unwrap();
            assert_eq!(back.sh_degree, degree, "{format:?}");
            assert_eq!(back.len(), cloud.len(), "{format:?}");
            assert!(
                report.warnings.is_empty(),
                "{format:?}: {:?}",
                report.warnings
            );
            assert_eq!(bits(&back), bits(&cloud), "degree {degree} {format:?}");
        }
    }
}

#[test]
fn empty_cloud_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    for format in FORMATS {
        let path = dir.path().join("empty.ply");
        write_ply(&path, &GaussianCloud::new(2), format).unwrap();
        let (back, _) = read_ply(&path, &ReadOptions::default()).unwrap();
        assert_eq!((back.len(), back.sh_degree), (0, 2));
    }
}

#[test]
fn binary_encodings_match_a_hand_serialised_record() {
    // One degree-1 Gaussian with distinct values, serialised by hand in the reference order.
    let mut c = GaussianCloud::new(1);
    let sh: Vec<Vec3> = (0..4)
        .map(|j| Vec3::new(10.0 + j as f32, 20.0 + j as f32, 30.0 + j as f32))
        .collect();
    c.push(
        Vec3::new(1.0, 2.0, 3.0),
        Vec3::new(4.0, 5.0, 6.0),
        Quat::from_xyzw(8.0, 9.0, 10.0, 7.0),
        11.0,
        &sh,
    );
    // x y z nx ny nz f_dc(0..3) f_rest channel-major (R1 R2 R3 G1 G2 G3 B1 B2 B3) opacity scale rot(w x y z)
    let expected: [f32; 26] = [
        1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 10.0, 20.0, 30.0, 11.0, 12.0, 13.0, 21.0, 22.0, 23.0, 31.0,
        32.0, 33.0, 11.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0,
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("one.ply");
    for (format, to_bytes) in [
        (
            PlyFormat::BinaryLittleEndian,
            f32::to_le_bytes as fn(f32) -> [u8; 4],
        ),
        (PlyFormat::BinaryBigEndian, f32::to_be_bytes),
    ] {
        write_ply(&path, &c, format).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let body: Vec<u8> = expected.iter().flat_map(|&v| to_bytes(v)).collect();
        assert!(bytes.ends_with(&body), "{format:?}");
        let header = std::str::from_utf8(&bytes[..bytes.len() - body.len()]).unwrap();
        assert!(
            header.ends_with("property float rot_3\nend_header\n"),
            "{header}"
        );
        assert!(header.contains("element vertex 1\n"));
    }
}

/// Build an ASCII PLY from property names and rows.
fn ascii_ply(props: &[(&str, &str)], rows: &[Vec<String>]) -> String {
    let mut s = format!("ply\nformat ascii 1.0\nelement vertex {}\n", rows.len());
    for (ty, name) in props {
        s += &format!("property {ty} {name}\n");
    }
    s += "end_header\n";
    for r in rows {
        s += &r.join(" ");
        s += "\n";
    }
    s
}

#[test]
fn properties_are_found_by_name_in_any_order_without_normals() {
    // Degree 1: f_rest_j holds 100 + j, so channel ch, coefficient c (1..=3) must read
    // 100 + ch*3 + (c-1).
    let mut props: Vec<(String, String)> = Vec::new();
    let mut vals: Vec<String> = Vec::new();
    let mut add = |ty: &str, name: String, v: f64| {
        props.push((ty.into(), name));
        vals.push(format!("{v}"));
    };
    for j in (0..9).rev() {
        add("float", format!("f_rest_{j}"), 100.0 + j as f64);
    }
    add("double", "rot_3".into(), 0.25);
    add("float", "opacity".into(), -1.5);
    add("uchar", "red".into(), 200.0);
    add("float32", "z".into(), 3.0);
    add("float", "rot_0".into(), 0.5);
    add("float", "scale_2".into(), -2.0);
    add("float", "f_dc_2".into(), 0.3);
    add("float", "y".into(), 2.0);
    add("float", "scale_0".into(), -4.0);
    add("float64", "rot_1".into(), -0.75);
    add("float", "f_dc_0".into(), 0.1);
    add("float", "x".into(), 1.0);
    add("float", "rot_2".into(), 0.125);
    add("float", "f_dc_1".into(), 0.2);
    add("float", "scale_1".into(), -3.0);
    let props_ref: Vec<(&str, &str)> = props
        .iter()
        .map(|(a, b)| (a.as_str(), b.as_str()))
        .collect();
    let text = ascii_ply(&props_ref, &[vals]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shuffled.ply");
    std::fs::write(&path, text).unwrap();
    let (c, report) = read_ply(&path, &ReadOptions::default()).unwrap();
    assert_eq!(c.sh_degree, 1);
    assert_eq!(c.means[0], Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(c.log_scales[0], Vec3::new(-4.0, -3.0, -2.0));
    assert_eq!(c.rotations[0].to_array(), [-0.75, 0.125, 0.25, 0.5]); // x y z w
    assert_eq!(c.opacity_logits[0], -1.5);
    assert_eq!(c.sh[0], Vec3::new(0.1, 0.2, 0.3));
    for coeff in 1..4 {
        for ch in 0..3 {
            assert_eq!(
                c.sh[coeff][ch],
                100.0 + (ch * 3 + coeff - 1) as f32,
                "coefficient {coeff} channel {ch}"
            );
        }
    }
    assert_eq!(report.ignored_properties, vec!["red".to_string()]);
    assert_eq!(report.warnings.len(), 1);
    assert!(report.warnings[0].contains("red"), "{:?}", report.warnings);
}

#[test]
fn binary_big_endian_with_doubles_and_extra_properties_reads_the_same_values() {
    // A degree-0 record: double x, float others, an int property in the middle.
    let names = [
        "x", "y", "z", "idx", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1",
        "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ];
    let mut header =
        "ply\nformat binary_big_endian 1.0\ncomment hand-built\nelement vertex 2\n".to_string();
    for n in names {
        let ty = match n {
            "x" => "double",
            "idx" => "int",
            _ => "float",
        };
        header += &format!("property {ty} {n}\n");
    }
    header += "end_header\n";
    let mut bytes = header.into_bytes();
    for g in 0..2i32 {
        for (j, n) in names.iter().enumerate() {
            let v = g as f64 * 100.0 + j as f64 + 0.5;
            match *n {
                "x" => bytes.extend(v.to_be_bytes()),
                "idx" => bytes.extend(g.to_be_bytes()),
                _ => bytes.extend((v as f32).to_be_bytes()),
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("be.ply");
    std::fs::write(&path, &bytes).unwrap();
    let (c, report) = read_ply(&path, &ReadOptions::default()).unwrap();
    assert_eq!(c.len(), 2);
    assert_eq!(report.ignored_properties, vec!["idx".to_string()]);
    for g in 0..2 {
        let v = |j: usize| (g as f64 * 100.0 + j as f64 + 0.5) as f32;
        assert_eq!(c.means[g], Vec3::new(v(0), v(1), v(2)));
        assert_eq!(c.sh[g], Vec3::new(v(4), v(5), v(6)));
        assert_eq!(c.opacity_logits[g], v(7));
        assert_eq!(c.log_scales[g], Vec3::new(v(8), v(9), v(10)));
        assert_eq!(c.rotations[g].to_array(), [v(12), v(13), v(14), v(11)]);
    }
}
