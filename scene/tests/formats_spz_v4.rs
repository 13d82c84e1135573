//! SPZ version 4 writing: our files decode to exactly what version 3 decodes to (the same
//! quantisation, another container), their header and table of contents are laid out as
//! splat-transform 3.7.0's (`fixtures/formats/cut300.spz`), and splat-transform's own reader
//! decodes our file as we do (`cut300.v4.spz.st.ply`, see `fixtures/formats/README.md`).

mod formats_common;

use formats_common::{assert_same_decode, fixtures, max_err};
use splatbridge_scene::formats::spz::{decode_spz, encode_spz, flip_yz, SpzAxes, SpzOptions};
use splatbridge_scene::formats::{detect, load_cloud, SplatFormat};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::GaussianCloud;
use std::path::Path;

fn read(name: &str) -> GaussianCloud {
    load_cloud(&fixtures().join(name), &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .0
}

fn opts(version: u32) -> SpzOptions {
    SpzOptions {
        version,
        ..SpzOptions::default()
    }
}

#[test]
fn version_4_decodes_exactly_as_version_3() {
    let src = read("cut300.ply");
    let p = Path::new("mem.spz");
    for degree in 0..=3u8 {
        let mut c = src.clone();
        if degree < 3 {
            let k = splatbridge_scene::gaussians::sh_coeffs(degree);
            let old = c.coeffs();
            c.sh = c.sh.chunks(old).flat_map(|g| g[..k].to_vec()).collect();
            c.sh_degree = degree;
        }
        let v3 = decode_spz(&encode_spz(&c, &opts(3)).unwrap(), p).unwrap();
        let bytes = encode_spz(&c, &opts(4)).unwrap();
        assert_eq!(&bytes[4..8], &4u32.to_le_bytes());
        let v4 = decode_spz(&bytes, p).unwrap();
        assert_eq!(v4, v3, "degree {degree}");
        // Degree 0 has no SH plane: five streams.
        assert_eq!(bytes[15], if degree == 0 { 5 } else { 6 });
    }
}

#[test]
fn an_empty_cloud_round_trips() {
    let c = GaussianCloud::new(0);
    let bytes = encode_spz(&c, &opts(4)).unwrap();
    let back = decode_spz(&bytes, Path::new("e.spz")).unwrap();
    assert!(back.is_empty());
}

#[test]
fn header_and_table_are_laid_out_as_splat_transform_writes_them() {
    let theirs = std::fs::read(fixtures().join("cut300.spz")).unwrap();
    // splat-transform writes the PLY's values unconverted: so do we here, for equal bytes.
    let c = read("cut300.ply");
    let ours = encode_spz(
        &c,
        &SpzOptions {
            version: 4,
            axes: SpzAxes::AsStored,
            ..SpzOptions::default()
        },
    )
    .unwrap();
    // Magic, version, count, SH degree, fraction bits, flags, streams, table offset, reserved.
    assert_eq!(&ours[..32], &theirs[..32]);
    // The table: compressed sizes differ (another zstd build and level), uncompressed agree.
    let streams = ours[15] as usize;
    for k in 0..streams {
        let u =
            |b: &[u8]| u64::from_le_bytes(b[32 + 16 * k + 8..32 + 16 * k + 16].try_into().unwrap());
        assert_eq!(u(&ours), u(&theirs), "stream {k}");
    }
}

#[test]
fn splat_transform_reads_our_version_4_as_we_do() {
    let path = fixtures().join("cut300.v4.spz");
    assert_eq!(detect(&path).unwrap(), SplatFormat::Spz { version: 4 });
    let ours = read("cut300.v4.spz");
    // The fixture is what the writer writes today (so a change of the writer shows here).
    let fresh = encode_spz(&read("cut300.ply"), &opts(4)).unwrap();
    assert_eq!(decode_spz(&fresh, &path).unwrap(), ours);
    let mut reference = read("cut300.v4.spz.st.ply");
    flip_yz(&mut reference);
    let e = max_err(&ours, &reference);
    println!("cut300.v4.spz, ours vs splat-transform's reader: {e:?}");
    assert_same_decode(&e);
}
