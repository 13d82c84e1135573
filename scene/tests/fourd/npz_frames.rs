//! The per-frame `params.npz` reader (`fourd::npz_frames`, what `fourd::load` gives) against
//! the whole-file reader it replaced (`fourd::npz::read_params_npz`, the reference): every value
//! of every frame equal, stored and deflated, read in order, backwards and at random; and the
//! failures only the per-frame reader can meet.

use super::{npy_with, write_npz_members};
use splatbridge_scene::fourd::npz::read_params_npz;
use splatbridge_scene::fourd::npz_frames::NpzFrames;
use splatbridge_scene::fourd::{self, FourDForm};

/// T timesteps of N Gaussians with values that differ everywhere (so a slice taken at the
/// wrong offset cannot match), colours per timestep or constant, scales isotropic or not.
fn arrays(
    t: usize,
    n: usize,
    colors_per_frame: bool,
    iso: bool,
) -> Vec<(&'static str, Vec<usize>, Vec<f32>)> {
    let v = |k: usize, salt: f32| ((k as f32 * 0.37 + salt).sin() * 3.0).round() / 8.0 + salt;
    let means: Vec<f32> = (0..t * n * 3).map(|k| v(k, 0.1)).collect();
    let rots: Vec<f32> = (0..t * n * 4).map(|k| v(k, 0.7) + 0.01).collect();
    let cols: Vec<f32> = (0..if colors_per_frame { t * n * 3 } else { n * 3 })
        .map(|k| (k % 11) as f32 / 10.0)
        .collect();
    let color_shape = if colors_per_frame {
        vec![t, n, 3]
    } else {
        vec![n, 3]
    };
    let (scale_shape, scales) = if iso {
        (vec![n, 1], (0..n).map(|k| -(k as f32) / 10.0).collect())
    } else {
        (vec![n, 3], (0..n * 3).map(|k| -(k as f32) / 30.0).collect())
    };
    vec![
        ("means3D", vec![t, n, 3], means),
        ("seg_colors", vec![n, 3], vec![0.0; n * 3]),
        ("rgb_colors", color_shape, cols),
        ("unnorm_rotations", vec![t, n, 4], rots),
        ("log_scales", scale_shape, scales),
        (
            "logit_opacities",
            vec![n, 1],
            (0..n).map(|k| k as f32 - 3.0).collect(),
        ),
    ]
}

/// Every value of `got` equal to the whole-file reader's frame `f` (bit for bit: both decode
/// the same bytes with the same conversions).
fn same(got: &splatbridge_scene::GaussianCloud, want: &splatbridge_scene::GaussianCloud, f: usize) {
    assert_eq!(got.len(), want.len(), "frame {f}");
    assert_eq!(got.sh_degree, want.sh_degree, "frame {f}");
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let flat3 = |v: &[glam::Vec3]| v.iter().flat_map(|x| x.to_array()).collect::<Vec<_>>();
    let flatq = |v: &[glam::Quat]| v.iter().flat_map(|x| x.to_array()).collect::<Vec<_>>();
    assert_eq!(
        bits(&flat3(&got.means)),
        bits(&flat3(&want.means)),
        "means, frame {f}"
    );
    assert_eq!(
        bits(&flatq(&got.rotations)),
        bits(&flatq(&want.rotations)),
        "rotations, frame {f}"
    );
    assert_eq!(
        bits(&flat3(&got.sh)),
        bits(&flat3(&want.sh)),
        "colours, frame {f}"
    );
    assert_eq!(
        bits(&flat3(&got.log_scales)),
        bits(&flat3(&want.log_scales)),
        "scales, frame {f}"
    );
    assert_eq!(
        bits(&got.opacity_logits),
        bits(&want.opacity_logits),
        "opacities, frame {f}"
    );
}

#[test]
fn per_frame_reads_equal_the_whole_file_reader_stored_and_deflated() {
    let (t, n) = (7, 53);
    for deflate in [false, true] {
        for (per_frame, iso, descr) in [
            (true, false, "<f4"),
            (false, true, "<f4"),
            (true, true, ">f8"),
            (true, false, "<f2"),
        ] {
            let what =
                format!("deflate {deflate}, colours per frame {per_frame}, iso {iso}, {descr}");
            let dir = tempfile::tempdir().unwrap();
            let p = dir.path().join("params.npz");
            let members: Vec<(String, Vec<u8>)> = arrays(t, n, per_frame, iso)
                .into_iter()
                .map(|(name, shape, data)| (format!("{name}.npy"), npy_with(&shape, &data, descr)))
                .collect();
            write_npz_members(&p, &members, deflate);
            let whole = read_params_npz(&p).unwrap();
            let frames = NpzFrames::open(&p).unwrap();
            assert_eq!((frames.frames, frames.count), (t, n), "{what}");
            assert_eq!(frames.deflated(), deflate, "{what}");
            // In order, the same frame twice, backwards (restarts a deflated member), at
            // random, and past the end (clamped, as the whole reader clamps).
            let order = [0, 1, 2, 2, 3, 4, 5, 6, 6, 5, 3, 0, 4, 1, 6, 2, 9];
            for &f in &order {
                same(&frames.frame(f).unwrap(), &whole.frame(f), f);
            }
            // Through the model every command samples.
            let model = fourd::load(&p, FourDForm::Npz, 10.0).unwrap();
            for f in 0..t {
                same(&model.sample(f as f64 / 10.0).unwrap(), &whole.frame(f), f);
            }
        }
    }
}

#[test]
fn a_bad_value_is_found_in_its_frame_with_the_whole_readers_message() {
    let (t, n) = (4, 5);
    for deflate in [false, true] {
        for (member, at, frame) in [
            ("means3D", 2 * n * 3 + 4, 2),
            ("unnorm_rotations", 3 * n * 4 + 1, 3),
        ] {
            let mut a = arrays(t, n, true, false);
            let k = a.iter().position(|x| x.0 == member).unwrap();
            a[k].2[at] = f32::NAN;
            let dir = tempfile::tempdir().unwrap();
            let p = dir.path().join("params.npz");
            let members: Vec<(String, Vec<u8>)> = a
                .into_iter()
                .map(|(name, shape, data)| (format!("{name}.npy"), npy_with(&shape, &data, "<f4")))
                .collect();
            write_npz_members(&p, &members, deflate);
            let want = read_params_npz(&p).unwrap_err().to_string();
            // Opening reads no frame; the frames before the bad one read fine.
            let frames = NpzFrames::open(&p).unwrap();
            for f in 0..frame {
                frames.frame(f).unwrap();
            }
            let got = frames.frame(frame).unwrap_err().to_string();
            assert_eq!(got, want, "deflate {deflate}");
            assert!(
                got.contains(&format!("{member}: value {at} is NaN")),
                "{got}"
            );
        }
        // A zero quaternion: the same message, naming the Gaussian and the timestep.
        let mut a = arrays(t, n, true, false);
        let k = a.iter().position(|x| x.0 == "unnorm_rotations").unwrap();
        for c in 0..4 {
            a[k].2[(2 * n + 3) * 4 + c] = 0.0;
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("params.npz");
        let members: Vec<(String, Vec<u8>)> = a
            .into_iter()
            .map(|(name, shape, data)| (format!("{name}.npy"), npy_with(&shape, &data, "<f4")))
            .collect();
        write_npz_members(&p, &members, deflate);
        let want = read_params_npz(&p).unwrap_err().to_string();
        let got = NpzFrames::open(&p)
            .unwrap()
            .frame(2)
            .unwrap_err()
            .to_string();
        assert_eq!(got, want);
        assert!(got.contains("quaternion 3 of timestep 2 is zero"), "{got}");
    }
}

#[test]
fn a_deflated_member_shorter_than_its_zip_header_says_fails_at_its_frame() {
    // A zip whose means3D entry declares the full size but whose deflate stream holds only the
    // first two timesteps: its local and central headers are patched to the full size (and its
    // CRC left as written), which the zip crate cannot see without inflating it.
    let (t, n) = (4, 6);
    let a = arrays(t, n, true, false);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("params.npz");
    let full = npy_with(&a[0].1, &a[0].2, "<f4");
    let header_len = full.len() - t * n * 3 * 4;
    let short = full[..header_len + 2 * n * 3 * 4].to_vec();
    let mut members: Vec<(String, Vec<u8>)> = a
        .iter()
        .map(|(name, shape, data)| (format!("{name}.npy"), npy_with(shape, data, "<f4")))
        .collect();
    members[0].1 = short.clone();
    write_npz_members(&p, &members, true);
    let mut bytes = std::fs::read(&p).unwrap();
    let (from, to) = (short.len() as u32, full.len() as u32);
    let mut patched = 0;
    // Local header: uncompressed size at +22; central header: at +24.
    for (sig, at) in [(b"PK\x03\x04", 22), (b"PK\x01\x02", 24)] {
        let mut i = 0;
        while let Some(k) = bytes[i..].windows(4).position(|w| w == sig) {
            let o = i + k + at;
            if bytes[o..o + 4] == from.to_le_bytes() {
                bytes[o..o + 4].copy_from_slice(&to.to_le_bytes());
                patched += 1;
            }
            i += k + 4;
        }
    }
    assert_eq!(patched, 2, "both headers of means3D patched");
    std::fs::write(&p, &bytes).unwrap();
    let frames = NpzFrames::open(&p).unwrap();
    frames.frame(0).unwrap();
    frames.frame(1).unwrap();
    let e = frames.frame(2).unwrap_err().to_string();
    assert!(e.contains("means3D: entry ends in timestep 2"), "{e}");
    // The whole-file reader refuses the same file (its entry is short of the header's size).
    assert!(read_params_npz(&p).is_err());
}
