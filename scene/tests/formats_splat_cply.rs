//! `.splat` and compressed PLY: round trips through our writers stay within each format's
//! quantisation, content detection ignores the extension, and the real `plant.splat` decodes
//! to the `plant.ply` made from it.

mod formats_common;

use std::path::Path;

use formats_common::{max_err, random_cloud, real_file};
use splatbridge_scene::formats::compressed_ply::{decode_compressed_ply, encode_compressed_ply};
use splatbridge_scene::formats::splat::{decode_splat, encode_splat};
use splatbridge_scene::formats::{detect, load, write_cloud, CloudFormat, SplatFormat};
use splatbridge_scene::ply::{read_ply, ReadOptions};

#[test]
fn splat_round_trip_within_quantisation() {
    let cloud = random_cloud(21, 3000, 2, 3.0);
    let back = decode_splat(&encode_splat(&cloud).unwrap(), Path::new("t.splat")).unwrap();
    assert_eq!(back.sh_degree, 0, ".splat keeps only the DC term");
    let e = max_err(&cloud, &back);
    // Positions are f32 as stored.
    assert_eq!(e.pos, 0.0, "{e:?}");
    // Scales are stored linear: ln(exp(x)) in f32 is within a few ulps of x (|x| ≤ 7).
    assert!(e.log_scale <= 2e-6, "{e:?}");
    // Display colour and alpha in 8 bits: ≤ 0.5/255 (colours here stay inside [0, 1]).
    assert!(e.colour <= 0.5 / 255.0 + 1e-6, "{e:?}");
    assert!(e.opacity <= 0.5 / 255.0 + 1e-6, "{e:?}");
    // Each component q·128 + 128 rounded: ≤ 0.5/128 each, plus the clamp of +1 to 255/128
    // (0.0078): |Δq| ≤ 0.0117, an angle ≤ 2|Δq| = 0.0234 rad.
    assert!(e.rot_angle <= 0.0234, "{e:?}");
}

#[test]
fn compressed_ply_round_trip_within_quantisation() {
    let cloud = random_cloud(22, 1000, 3, 1.0);
    let bytes = encode_compressed_ply(&cloud).unwrap();
    let back = decode_compressed_ply(&bytes, Path::new("t.compressed.ply")).unwrap();
    assert_eq!(back.sh_degree, 3);
    let e = max_err(&cloud, &back);
    // 10 bits (y; x and z have 11) across a chunk's extent, here at most 2 units:
    // ≤ 2·0.5/1023 = 9.8e-4.
    assert!(e.pos <= 9.8e-4, "{e:?}");
    // Log-scales span at most 6 ([−7, −1]) per chunk: ≤ 6·0.5/1023 = 2.93e-3.
    assert!(e.log_scale <= 2.94e-3, "{e:?}");
    // 10-bit smallest three over ±1/√2: δ = 6.9e-4 per stored component, the largest moves by
    // ≤ 3δ: angle ≤ 2·√12·δ = 4.8e-3 rad.
    assert!(e.rot_angle <= 4.8e-3, "{e:?}");
    // Colour 8 bits across the chunk's colour range (≤ 3·SH_C0 = 0.846): ≤ 1.66e-3.
    assert!(e.colour <= 1.66e-3, "{e:?}");
    assert!(e.opacity <= 0.5 / 255.0 + 1e-6, "{e:?}");
    // Higher SH: 256 bins over [−4, 4], decoded at bin centres: ≤ 4/256 = 0.0157.
    assert!(e.sh_rest <= 4.0 / 256.0 + 1e-6, "{e:?}");
}

#[test]
fn formats_are_detected_by_content_not_extension() {
    let dir = tempfile::tempdir().unwrap();
    let cloud = random_cloud(23, 100, 1, 1.0);
    let cases = [
        (CloudFormat::Splat, SplatFormat::Splat),
        (CloudFormat::CompressedPly, SplatFormat::CompressedPly),
        (CloudFormat::Ply, SplatFormat::Ply),
    ];
    for (i, (write_as, expect)) in cases.into_iter().enumerate() {
        // Every file named .bin: only the content can tell.
        let path = dir.path().join(format!("scene{i}.bin"));
        write_cloud(&path, &cloud, write_as).unwrap();
        assert_eq!(detect(&path).unwrap(), expect, "{write_as:?}");
        let (scene, info) = load(&path, &ReadOptions::default()).unwrap();
        assert_eq!(info.format, expect);
        assert_eq!(scene.static_gaussians.len(), 100);
    }
    // Unknown content is an error naming the file.
    let junk = dir.path().join("junk.bin");
    std::fs::write(&junk, b"\x00\x01\x02 not a splat").unwrap();
    let err = detect(&junk).unwrap_err().to_string();
    assert!(
        err.contains("junk.bin") && err.contains("not a splat file"),
        "{err}"
    );
}

/// plant.ply was decoded from plant.splat; ours must give the same Gaussians.
#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn real_plant_splat_matches_its_decoded_ply() {
    let (splat, ply) = (real_file("plant.splat"), real_file("plant.ply"));
    assert_eq!(detect(&splat).unwrap(), SplatFormat::Splat);
    let (scene, _) = load(&splat, &ReadOptions::default()).unwrap();
    let ours = scene.static_gaussians;
    let (reference, _) = read_ply(&ply, &ReadOptions::default()).unwrap();
    let e = max_err(&ours, &reference);
    println!("plant.splat vs plant.ply: {e:?}");
    assert_eq!(e.pos, 0.0, "{e:?}");
    // Same formulas in f32; only the last bits may differ.
    assert!(e.log_scale <= 1e-5, "{e:?}");
    assert!(e.colour <= 1e-5, "{e:?}");
    assert!(e.opacity <= 1e-5, "{e:?}");
    // The decoder that made plant.ply maps rotation bytes with /127.5 − 1 where we (like the
    // antimatter15 viewer, whose writer stores q·128 + 128) use (b − 128)/128: the two differ
    // by less than one quantisation step, whose bound is 0.0234 rad (see the round trip above).
    assert!(e.rot_angle <= 0.0234, "{e:?}");
}
