//! glTF `KHR_gaussian_splatting` reading, plain and SPZ-compressed, against reference-made
//! files and on malformed input.
//!
//! Fixtures (`fixtures/formats/khr/`): `st_source.glb` and `st_source.spz` (SPZ v3) are
//! splat-transform 3.7.0's encodings of `fixtures/formats/sog/source.ply` (300 Gaussians, SH
//! degree 3 from `fourth_st.ply`). splat-transform writes no SPZ-compressed glTF, so the
//! compressed files are built here around its SPZ stream.

use std::path::{Path, PathBuf};

use serde_json::json;
use splatbridge_scene::formats::gltf_khr::read_gltf_splats;
use splatbridge_scene::formats::spz::read_spz;
use splatbridge_scene::ply::{read_ply, ReadOptions};
use splatbridge_scene::GaussianCloud;

fn fx(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/formats")
        .join(name)
}

fn source() -> GaussianCloud {
    read_ply(&fx("sog/source.ply"), &ReadOptions::default())
        .unwrap()
        .0
}

/// Compare two clouds attribute by attribute; `tol` bounds means and SH (absolute), log-
/// scales are compared through the activated scale (relative `tol`), opacity activated
/// (absolute `tol`), orientation through the covariance (relative to its largest entry,
/// 10·`tol`: it multiplies three rounded factors and squares the scales).
fn assert_close(a: &GaussianCloud, b: &GaussianCloud, tol: f32, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: count");
    assert_eq!(a.sh_degree, b.sh_degree, "{what}: degree");
    for i in 0..a.len() {
        let e = (a.means[i] - b.means[i]).abs().max_element();
        assert!(e <= tol, "{what}: mean {i} off by {e}");
        let e = ((a.scale(i) - b.scale(i)) / b.scale(i)).abs().max_element();
        assert!(e <= tol, "{what}: scale {i} off by {e}");
        let e = (a.opacity(i) - b.opacity(i)).abs();
        assert!(e <= tol, "{what}: opacity {i} off by {e}");
        // Orientation through the covariance: an axis flip S may be carried as S·R or as
        // S·R·Sᵀ (both give S·Σ·Sᵀ for a diagonal scale), so quaternions need not agree.
        let (ca, cb) = (a.covariance(i), b.covariance(i));
        let big = cb.to_cols_array().iter().fold(0f32, |m, x| m.max(x.abs()));
        let e = (ca - cb)
            .to_cols_array()
            .iter()
            .fold(0f32, |m, x| m.max(x.abs()))
            / big;
        assert!(
            e <= 10.0 * tol,
            "{what}: covariance {i} off by {e} relative"
        );
        for (j, (x, y)) in a.sh_of(i).iter().zip(b.sh_of(i)).enumerate() {
            let e = (*x - *y).abs().max_element();
            assert!(e <= tol, "{what}: SH {i}.{j} off by {e}");
        }
    }
}

/// splat-transform's GLB holds the PLY turned into glTF's frame (a half turn about z, SH
/// rotated); reading turns it back exactly (sign flips). Float32 attributes, so the
/// differences are splat-transform's own rounding when it rotated the data (~1e-7 relative)
/// and scale through exp then ln, opacity through the sigmoid; 2e-6 covers those with a
/// margin (values here are ≤ ~5 in magnitude).
#[test]
fn reference_glb_reads_back_to_the_source_ply() {
    let s = read_gltf_splats(&fx("khr/st_source.glb")).unwrap();
    assert!(s.objects.is_empty());
    assert_close(&s.static_gaussians, &source(), 2e-6, "st_source.glb");
}

/// A GLB whose one primitive is the SPZ variant over `spz` (the stream's count `n`), with
/// accessors for the decoded attributes (no buffer views), as the extension specifies.
fn spz_glb(spz: &[u8], n: u64, edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let mut bin = spz.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let acc = |ty: &str| json!({"componentType": 5126, "count": n, "type": ty});
    let mut attrs = serde_json::Map::new();
    attrs.insert("POSITION".into(), json!(0));
    attrs.insert("KHR_gaussian_splatting:ROTATION".into(), json!(1));
    attrs.insert("KHR_gaussian_splatting:SCALE".into(), json!(2));
    attrs.insert("KHR_gaussian_splatting:OPACITY".into(), json!(3));
    let mut v = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_gaussian_splatting", "KHR_gaussian_splatting_compression_spz_2"],
        "extensionsRequired": ["KHR_gaussian_splatting", "KHR_gaussian_splatting_compression_spz_2"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attrs, "mode": 0, "extensions": {
            "KHR_gaussian_splatting": {"kernel": "ellipse", "extensions": {
                "KHR_gaussian_splatting_compression_spz_2": {"bufferView": 0}}}}}]}],
        "accessors": [acc("VEC3"), acc("VEC4"), acc("VEC3"), acc("SCALAR")],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": spz.len()}],
    });
    edit(&mut v);
    glb(&v, &bin)
}

fn glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    j.resize(j.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin);
    out
}

/// The SPZ variant over splat-transform's stream reads as the `.spz` file itself does: the
/// extension's LUF rule (x, z negated from SPZ's RUB) followed by glTF → PLY (a half turn
/// about z) is SPZ's own RUB → RDF (y, z negated). This ties the x·z sign table and the SH
/// rotation to the `.spz` reader's y·z table. Rounding as above (2e-6).
#[test]
fn spz_variant_reads_like_the_spz_file() {
    let spz = std::fs::read(fx("khr/st_source.spz")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("spz.glb");
    std::fs::write(&p, spz_glb(&spz, 300, |_| {})).unwrap();
    let s = read_gltf_splats(&p).unwrap();
    let (direct, _) = read_spz(&fx("khr/st_source.spz")).unwrap();
    assert_close(&s.static_gaussians, &direct, 2e-6, "spz.glb");
}

struct Case {
    name: &'static str,
    bytes: Vec<u8>,
    expect: &'static str,
}

fn cases() -> Vec<Case> {
    let good = std::fs::read(fx("khr/st_source.glb")).unwrap();
    let spz = std::fs::read(fx("khr/st_source.spz")).unwrap();
    // The reference GLB's JSON and BIN, to edit.
    let jlen = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let gjson: serde_json::Value = serde_json::from_slice(&good[20..20 + jlen]).unwrap();
    let gbin = good[20 + jlen + 8..].to_vec();
    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = gjson.clone();
        f(&mut v);
        glb(&v, &gbin)
    };
    vec![
        Case {
            name: "truncated.glb",
            bytes: good[..good.len() / 2].to_vec(),
            expect: "is not the file's",
        },
        // Truncated with the header's length made to agree: the chunk itself runs past the end.
        Case {
            name: "truncated_chunk.glb",
            bytes: {
                let mut b = good[..good.len() / 2].to_vec();
                let n = b.len() as u32;
                b[8..12].copy_from_slice(&n.to_le_bytes());
                b
            },
            expect: "runs past the end",
        },
        Case {
            name: "bad_magic.glb",
            bytes: {
                let mut b = good.clone();
                b[..4].copy_from_slice(b"glTX");
                b
            },
            expect: "glTF JSON",
        },
        Case {
            name: "glb_version_1.glb",
            bytes: {
                let mut b = good.clone();
                b[4] = 1;
                b
            },
            expect: "version 1",
        },
        Case {
            name: "accessor_count_lies.glb",
            bytes: edit(&|v| v["accessors"][0]["count"] = json!(4_000_000_000u64)),
            expect: "do not fit",
        },
        Case {
            name: "attribute_counts_differ.glb",
            bytes: edit(&|v| v["accessors"][2]["count"] = json!(10)),
            expect: "different counts",
        },
        Case {
            name: "stride_too_short.glb",
            bytes: edit(&|v| v["bufferViews"][0]["byteStride"] = json!(4)),
            expect: "byteStride",
        },
        Case {
            name: "node_cycle.glb",
            bytes: edit(&|v| {
                v["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
            }),
            expect: "reached twice",
        },
        Case {
            name: "missing_node.glb",
            bytes: edit(&|v| v["scenes"][0]["nodes"] = json!([7])),
            expect: "node 7 does not exist",
        },
        Case {
            name: "spz_view_out_of_range.glb",
            bytes: spz_glb(&spz, 300, |v| {
                v["bufferViews"][0]["byteOffset"] = json!(16);
            }),
            expect: "lies outside buffer",
        },
        Case {
            name: "spz_missing_view.glb",
            bytes: spz_glb(&spz, 300, |v| {
                v["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]
                    ["extensions"]["KHR_gaussian_splatting_compression_spz_2"]["bufferView"] =
                    json!(5);
            }),
            expect: "bufferView 5 does not exist",
        },
        Case {
            name: "spz_count_lies.glb",
            bytes: spz_glb(&spz, 301, |_| {}),
            expect: "SPZ stream holds 300",
        },
        Case {
            name: "spz_not_spz.glb",
            bytes: spz_glb(
                &[0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3, 4],
                300,
                |_| {},
            ),
            expect: "spz_not_spz.glb",
        },
    ]
}

#[test]
fn malformed_gltf_files_fail_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = cases();
    assert!(cases.len() >= 8);
    for c in cases {
        let p = tmp.path().join(c.name);
        std::fs::write(&p, &c.bytes).unwrap();
        let r = std::panic::catch_unwind(|| read_gltf_splats(&p));
        let err = match r {
            Ok(Err(e)) => e.to_string(),
            Ok(Ok(s)) => panic!("{}: read {} Gaussians", c.name, s.gaussian_count()),
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

#[cfg(unix)]
#[test]
fn a_fifo_is_refused_without_blocking() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("x.glb");
    // mkfifo is POSIX (coreutils): on a unix host its absence is a broken machine, not a skip.
    let ok = std::process::Command::new("mkfifo").arg(&p).status();
    assert!(matches!(ok, Ok(s) if s.success()), "mkfifo failed");
    let err = read_gltf_splats(&p).unwrap_err().to_string();
    assert!(err.contains("regular file"), "{err}");
}
