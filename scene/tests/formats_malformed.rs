//! Malformed files for every format of `formats::{splat, spz, compressed_ply}`: each must give
//! an error naming the file, never a panic, a hang or an allocation beyond what the file's
//! size justifies. The same files are committed under `fixtures/formats/malformed/` (see its
//! README); `SPLATBRIDGE_WRITE_MALFORMED=1 cargo test -p splatbridge-scene --test
//! formats_malformed` rewrites them from the definitions here.

mod formats_common;

use std::io::Write;

use flate2::write::GzEncoder;
use flate2::Compression;
use formats_common::{fixtures, random_cloud};
use splatbridge_scene::formats::compressed_ply::encode_compressed_ply;
use splatbridge_scene::formats::load;
use splatbridge_scene::formats::spz::{encode_spz, encode_spz_raw, SpzOptions};
use splatbridge_scene::ply::ReadOptions;

fn gzip(raw: &[u8]) -> Vec<u8> {
    let mut e = GzEncoder::new(Vec::new(), Compression::default());
    e.write_all(raw).unwrap();
    e.finish().unwrap()
}

fn spz_header(version: u32, count: u32, degree: u8, fb: u8, flags: u8) -> Vec<u8> {
    let mut h = Vec::new();
    h.extend_from_slice(&0x5053_474e_u32.to_le_bytes());
    h.extend_from_slice(&version.to_le_bytes());
    h.extend_from_slice(&count.to_le_bytes());
    h.extend_from_slice(&[degree, fb, flags, 0]);
    h
}

/// One `.splat` record: position, linear scale, RGBA, rotation bytes.
fn splat_record(pos: [f32; 3], scale: [f32; 3], rot: [u8; 4]) -> Vec<u8> {
    let mut r = Vec::new();
    for v in pos.iter().chain(scale.iter()) {
        r.extend_from_slice(&v.to_le_bytes());
    }
    r.extend_from_slice(&[200, 100, 50, 255]);
    r.extend_from_slice(&rot);
    r
}

/// A valid compressed PLY of 300 Gaussians (two chunks) with degree-1 SH, split into header
/// text and data.
fn cply() -> (String, Vec<u8>) {
    let bytes = encode_compressed_ply(&random_cloud(3, 300, 1, 1.0)).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    (
        String::from_utf8(bytes[..end].to_vec()).unwrap(),
        bytes[end..].to_vec(),
    )
}

fn cat(h: &str, d: &[u8]) -> Vec<u8> {
    let mut v = h.as_bytes().to_vec();
    v.extend_from_slice(d);
    v
}

/// (file name, content, what the error must mention).
fn cases() -> Vec<(String, Vec<u8>, &'static str)> {
    let mut v: Vec<(String, Vec<u8>, &'static str)> = Vec::new();
    let mut add =
        |name: &str, bytes: Vec<u8>, want: &'static str| v.push((name.to_string(), bytes, want));

    // --- SPZ ---
    let good = encode_spz(&random_cloud(1, 200, 1, 1.0), &SpzOptions::default()).unwrap();
    let raw = encode_spz_raw(&random_cloud(1, 200, 1, 1.0), &SpzOptions::default()).unwrap();
    add(
        "spz_truncated_gzip.spz",
        good[..good.len() / 2].to_vec(),
        "SPZ",
    );
    let mut bad_magic = raw.clone();
    bad_magic[0] = b'X';
    add("spz_bad_magic.spz", gzip(&bad_magic), "not SPZ");
    let mut v7 = raw.clone();
    v7[4] = 7;
    add("spz_bad_version.spz", gzip(&v7), "version 7");
    let mut v4 = raw.clone();
    v4[4] = 4;
    add("spz_v4_in_gzip.spz", gzip(&v4), "version 4");
    let mut more = raw.clone();
    more[8..12].copy_from_slice(&1000u32.to_le_bytes());
    add("spz_count_too_large.spz", gzip(&more), "truncated");
    let mut fewer = raw.clone();
    fewer[8..12].copy_from_slice(&100u32.to_le_bytes());
    add("spz_count_too_small.spz", gzip(&fewer), "more data");
    // Declared size far beyond what a 40-byte stream can inflate to.
    add(
        "spz_bomb_declared.spz",
        gzip(&spz_header(3, u32::MAX, 3, 12, 0)),
        "can hold at most",
    );
    // Real bomb: 10 Gaussians declared, 64 MiB of zeros actually inside (~65 KB on disk).
    let mut bomb = spz_header(3, 10, 0, 12, 0);
    bomb.resize(64 << 20, 0);
    add("spz_bomb_real.spz", gzip(&bomb), "more data");
    let mut deg = raw.clone();
    deg[12] = 5;
    add("spz_sh_degree_5.spz", gzip(&deg), "SH degree 5");
    let mut fb = raw.clone();
    fb[13] = 30;
    add("spz_fraction_bits_30.spz", gzip(&fb), "fractional bits");
    let mut crc = good.clone();
    let n = crc.len();
    crc[n - 8] ^= 0xff;
    add("spz_bad_crc.spz", crc, "SPZ");
    add("spz_header_only_truncated.spz", gzip(&raw[..10]), "header");
    // Version 4 (zstd streams), from splat-transform's committed fixture.
    let v4 = std::fs::read(fixtures().join("cut300.spz")).unwrap();
    add(
        "spz_v4_truncated.spz",
        v4[..v4.len() - 50].to_vec(),
        "truncated",
    );
    let mut v4_streams = v4.clone();
    v4_streams[15] = 5;
    add("spz_v4_stream_count.spz", v4_streams, "streams");
    let mut v4_bomb = v4[..32].to_vec();
    v4_bomb[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    add(
        "spz_v4_bomb_declared.spz",
        v4_bomb,
        "more than a 32-byte file",
    );
    let mut v4_size = v4.clone();
    // The first table entry's uncompressed size (bytes 40..48): 300·9 = 2700 → 2701.
    v4_size[40..48].copy_from_slice(&2701u64.to_le_bytes());
    add("spz_v4_stream_size.spz", v4_size, "need 2700");
    // The positions stream replaced by a zstd frame that asks for a 2 GiB window: refused
    // before the decoder allocates it (`v4_with_first_stream`'s control test loads the
    // same frame with a small window).
    add(
        "spz_v4_window_bomb.spz",
        v4_with_first_stream(&v4, &raw_zstd_frame(21, &[7u8; 2700])),
        "stream 0 does not decompress",
    );
    let mut not_zstd = raw_zstd_frame(2, &[7u8; 2700]);
    not_zstd[0] ^= 0xff;
    add(
        "spz_v4_not_zstd.spz",
        v4_with_first_stream(&v4, &not_zstd),
        "stream 0 is not zstd",
    );

    // --- .splat ---
    let ok = splat_record([0.1, 0.2, 0.3], [0.01, 0.02, 0.03], [255, 128, 128, 128]);
    add("splat_empty.splat", Vec::new(), "empty");
    let mut trunc = ok.repeat(3);
    trunc.truncate(80);
    add("splat_truncated_record.splat", trunc, "whole number");
    let mut nan = ok.clone();
    nan.extend(splat_record(
        [f32::NAN, 0.0, 0.0],
        [0.01; 3],
        [255, 128, 128, 128],
    ));
    add("splat_nan_position.splat", nan, "vertex 1");
    let mut inf = ok.clone();
    inf.extend(splat_record(
        [0.0; 3],
        [f32::INFINITY, 0.01, 0.01],
        [255, 128, 128, 128],
    ));
    add("splat_inf_scale.splat", inf, "vertex 1");
    add(
        "splat_negative_scale.splat",
        splat_record([0.0; 3], [-0.5, 0.01, 0.01], [255, 128, 128, 128]),
        "vertex 0",
    );
    add(
        "splat_zero_scale.splat",
        splat_record([0.0; 3], [0.0, 0.01, 0.01], [255, 128, 128, 128]),
        "vertex 0",
    );
    add(
        "splat_zero_quaternion.splat",
        splat_record([0.0; 3], [0.01; 3], [128, 128, 128, 128]),
        "zero quaternion",
    );
    add(
        "splat_text.splat",
        b"this is not a splat file at all!".repeat(2)[..63].to_vec(),
        "whole number",
    );

    // --- compressed PLY ---
    let (h, d) = cply();
    add(
        "cply_truncated.compressed.ply",
        cat(&h, &d[..d.len() - 100]),
        "truncated",
    );
    add(
        "cply_count_huge.compressed.ply",
        cat(
            &h.replace("element vertex 300", "element vertex 1099511627776"),
            &d,
        ),
        "element 'vertex'",
    );
    add(
        "cply_too_few_chunks.compressed.ply",
        cat(&h.replace("element chunk 2", "element chunk 1"), &d),
        "chunks",
    );
    let mut nan_d = d.clone();
    nan_d[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
    add(
        "cply_nan_bounds.compressed.ply",
        cat(&h, &nan_d),
        "min_x is NaN",
    );
    let mut inf_d = d.clone();
    // max_scale_x is the tenth float of chunk 1 (chunks are 18 floats).
    inf_d[(18 + 9) * 4..(18 + 10) * 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    add(
        "cply_inf_scale_bounds.compressed.ply",
        cat(&h, &inf_d),
        "chunk 1: max_scale_x",
    );
    add(
        "cply_float_packed.compressed.ply",
        cat(
            &h.replace(
                "property uint packed_position",
                "property float packed_position",
            ),
            &d,
        ),
        "packed_position is f32",
    );
    add(
        "cply_missing_color.compressed.ply",
        cat(
            &h.replace("property uint packed_color", "property uint packed_colour"),
            &d,
        ),
        "packed_color",
    );
    add(
        "cply_sh_count.compressed.ply",
        cat(&h.replace("element sh 300", "element sh 299"), &d),
        "'sh' has 299 rows",
    );
    add(
        "cply_ascii.compressed.ply",
        cat(&h.replace("binary_little_endian", "ascii"), &d),
        "binary_little_endian",
    );
    add(
        "cply_no_end_header.compressed.ply",
        h.replace("end_header\n", "").into_bytes(),
        "end_header",
    );
    add(
        "cply_sh_10_props.compressed.ply",
        cat(
            &h.replace(
                "property uchar f_rest_8\n",
                "property uchar f_rest_8\nproperty uchar f_rest_9\n",
            ),
            &d,
        ),
        "element 'sh'",
    );
    v
}

/// A zstd frame (RFC 8878 §3.1.1) holding `data` as one raw block, with no content size, so
/// its Window_Descriptor decides the window: 2^(10 + `exponent`) bytes.
fn raw_zstd_frame(exponent: u8, data: &[u8]) -> Vec<u8> {
    let mut f = vec![0x28, 0xb5, 0x2f, 0xfd, 0x00, exponent << 3];
    // Block header: last block, raw, its size (little-endian, 3 bytes).
    let h = 1 | ((data.len() as u32) << 3);
    f.extend_from_slice(&h.to_le_bytes()[..3]);
    f.extend_from_slice(data);
    f
}

/// `v4` (an SPZ version-4 file) with its first stream replaced and the table of contents
/// updated to the new stream's compressed size.
fn v4_with_first_stream(v4: &[u8], first: &[u8]) -> Vec<u8> {
    let u64_at = |o: usize| u64::from_le_bytes(v4[o..o + 8].try_into().unwrap()) as usize;
    let toc = u32::from_le_bytes(v4[16..20].try_into().unwrap()) as usize;
    let toc_end = toc + 16 * v4[15] as usize;
    let old = u64_at(toc);
    let mut out = v4[..toc_end].to_vec();
    out[toc..toc + 8].copy_from_slice(&(first.len() as u64).to_le_bytes());
    out.extend_from_slice(first);
    out.extend_from_slice(&v4[toc_end + old..]);
    out
}

/// The control for the window and magic cases: the same hand-made frame with a 4 KiB window
/// loads, so those files fail for the reason they name, not for a malformed frame.
#[test]
fn a_hand_made_zstd_stream_with_a_small_window_loads() {
    let v4 = std::fs::read(fixtures().join("cut300.spz")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small_window.spz");
    std::fs::write(
        &path,
        v4_with_first_stream(&v4, &raw_zstd_frame(2, &[7u8; 2700])),
    )
    .unwrap();
    let (scene, _) = load(&path, &ReadOptions::default()).unwrap();
    assert_eq!(scene.static_gaussians.len(), 300);
}

#[test]
fn every_malformed_file_is_a_clean_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let write_fixtures = std::env::var_os("SPLATBRIDGE_WRITE_MALFORMED").is_some();
    let fixture_dir = fixtures().join("malformed");
    let mut per_format = [0usize; 3];
    for (name, bytes, want) in cases() {
        let path = dir.path().join(&name);
        std::fs::write(&path, &bytes).unwrap();
        if write_fixtures {
            std::fs::write(fixture_dir.join(&name), &bytes).unwrap();
        }
        let err = match load(&path, &ReadOptions::default()) {
            Ok(_) => panic!("{name}: loaded"),
            Err(e) => e.to_string(),
        };
        assert!(
            err.contains(&name),
            "{name}: error does not name the file: {err}"
        );
        assert!(err.contains(want), "{name}: expected '{want}' in: {err}");
        per_format[["spz_", "splat_", "cply_"]
            .iter()
            .position(|p| name.starts_with(p))
            .unwrap()] += 1;
    }
    assert!(per_format.iter().all(|&n| n >= 8), "{per_format:?}");
}

/// The committed copies fail the same way, and the README describes each.
#[test]
fn committed_malformed_fixtures_fail_and_are_documented() {
    let dir = fixtures().join("malformed");
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name == "README.md" {
            continue;
        }
        assert!(
            readme.contains(&format!("`{name}`")),
            "{name} is not in the README"
        );
        let err = load(&path, &ReadOptions::default())
            .err()
            .unwrap_or_else(|| panic!("{name} loaded"));
        assert!(err.to_string().contains(&name), "{name}: {err}");
        seen += 1;
    }
    assert_eq!(
        seen,
        cases().len(),
        "fixtures and definitions differ; regenerate them"
    );
}

#[cfg(unix)]
#[test]
fn fifo_and_directory_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("folder.splat");
    std::fs::create_dir(&d).unwrap();
    let err = load(&d, &ReadOptions::default()).unwrap_err().to_string();
    assert!(
        err.contains("folder.splat") && err.contains("not a regular file"),
        "{err}"
    );
    let fifo = dir.path().join("pipe.spz");
    // mkfifo is POSIX (coreutils): on a unix host its absence is a broken machine, not a skip.
    let status = std::process::Command::new("mkfifo").arg(&fifo).status();
    assert!(status.is_ok_and(|s| s.success()), "mkfifo failed");
    // Opening a FIFO for reading would block until a writer appears; the loader must not.
    let err = load(&fifo, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("pipe.spz") && err.contains("not a regular file"),
        "{err}"
    );
}
