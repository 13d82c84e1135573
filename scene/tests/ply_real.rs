//! The real trained scenes in `../shared/data/real` load with the counts and SH degrees their
//! README lists, and contain the values the README says they contain. Ignored (with the
//! reason) when the folder is absent (`build.rs` sets `cfg(real_data)`).

use std::path::PathBuf;

use splatbridge_scene::ply::{read_ply, write_ply, PlyFormat, ReadOptions};

fn real_dir() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/data/real"
    ))
}

/// (file, Gaussians, SH degree) from `shared/data/real/README.md`.
const TABLE: [(&str, usize, u8); 5] = [
    ("fourth_st.ply", 131_199, 3),
    ("plant.ply", 113_648, 0),
    ("pc_short.ply", 100, 3),
    ("donut.ply", 45_624, 0),
    ("tile_lod1.ply", 14_051, 3),
];

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn real_files_load_with_readme_counts_and_degrees() {
    let dir = real_dir();
    for (name, count, degree) in TABLE {
        let path = dir.join(name);
        let (cloud, report) =
            read_ply(&path, &ReadOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(cloud.len(), count, "{name}");
        assert_eq!(cloud.sh_degree, degree, "{name}");
        cloud.check_shape().unwrap();
        assert!(report.dropped.is_empty(), "{name}");
        assert!(
            report.ignored_properties.is_empty(),
            "{name}: {:?}",
            report.ignored_properties
        );
        for i in 0..cloud.len() {
            assert_eq!(cloud.invalid_reason(i), None, "{name} vertex {i}");
        }
    }
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn fourth_st_has_positive_infinite_opacity_logits() {
    let dir = real_dir();
    let (cloud, _) = read_ply(&dir.join("fourth_st.ply"), &ReadOptions::default()).unwrap();
    let n_inf = cloud
        .opacity_logits
        .iter()
        .filter(|&&l| l == f32::INFINITY)
        .count();
    assert!(n_inf > 0, "README says fourth_st has +inf opacity logits");
    // The sigmoid of +inf is exactly 1, so these are fully opaque, not NaN.
    let i = cloud
        .opacity_logits
        .iter()
        .position(|&l| l == f32::INFINITY)
        .unwrap();
    assert_eq!(cloud.opacity(i), 1.0);
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn unnormalised_quaternions_and_tiny_log_scales_are_kept_as_stored() {
    let dir = real_dir();
    for name in ["pc_short.ply", "donut.ply", "tile_lod1.ply"] {
        let (cloud, _) = read_ply(&dir.join(name), &ReadOptions::default()).unwrap();
        let (lo, hi) = cloud
            .rotations
            .iter()
            .map(|q| q.length())
            .fold((f32::MAX, 0f32), |(lo, hi), n| (lo.min(n), hi.max(n)));
        // README: norms from about 0.5 to 3.2; unit quaternions would give 1 ± 1e-6.
        assert!(
            lo < 0.99 || hi > 1.01,
            "{name}: quaternion norms {lo}..{hi} look normalised"
        );
        for i in 0..cloud.len() {
            let u = cloud.unit_rotation(i);
            assert!((u.length() - 1.0).abs() < 1e-5, "{name} vertex {i}");
        }
    }
    let (tile, _) = read_ply(&dir.join("tile_lod1.ply"), &ReadOptions::default()).unwrap();
    let min_log = tile
        .log_scales
        .iter()
        .map(|s| s.min_element())
        .fold(f32::MAX, f32::min);
    // README: log-scales down to -23.
    assert!(min_log <= -22.0, "tile_lod1 min log-scale {min_log}");
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn real_file_rewrites_bit_exactly_in_every_format() {
    let dir = real_dir();
    let (cloud, _) = read_ply(&dir.join("pc_short.ply"), &ReadOptions::default()).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    for format in [
        PlyFormat::BinaryLittleEndian,
        PlyFormat::BinaryBigEndian,
        PlyFormat::Ascii,
    ] {
        let out = tmp.path().join("pc_short.ply");
        write_ply(&out, &cloud, format).unwrap();
        let (back, _) = read_ply(&out, &ReadOptions::default()).unwrap();
        assert_eq!(back.len(), cloud.len());
        let bits = |c: &splatbridge_scene::GaussianCloud| -> Vec<u32> {
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
        };
        assert_eq!(bits(&back), bits(&cloud), "{format:?}");
    }
}

/// The real captures are spread far wider than their Gaussians, so the bounds views are
/// placed around are their robust bounds bit for bit: the rule that frames a lone Gaussian
/// by its extent (`GaussianCloud::view_bounds`) moves no camera of a real scene.
#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn real_scenes_are_framed_by_their_robust_bounds() {
    let dir = real_dir();
    let p = splatbridge_scene::camera::OrbitRig::default().percentile;
    for (name, _, _) in TABLE {
        let (cloud, _) = read_ply(&dir.join(name), &ReadOptions::default()).unwrap();
        let robust = cloud.robust_bounds(p).unwrap();
        assert_eq!(cloud.view_bounds(p), Some(robust), "{name}");
        // By a margin: the half-diagonals are 20–60 times 3σ of the median Gaussian
        // (fourth_st 0.169 against 0.0024, tile_lod1 2.83 against 0.11).
        let half = 0.5 * (robust.1 - robust.0).length();
        let reach = splatbridge_scene::gaussians::VIEW_REACH_SIGMAS * cloud.median_largest_sigma();
        assert!(half > 10.0 * reach, "{name}");
    }
}
