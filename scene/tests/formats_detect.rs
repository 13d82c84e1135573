//! Format detection of the files users bring, and messages that name the file once:
//! a SOG `meta.json` written by splat-transform 0.16 or later (it carries a glTF-style
//! `"asset"` key) is a SOG, a glTF with neither splats nor a mesh is an error (never an empty
//! scene), and an unbundled `meta.json`'s errors do not repeat its name.

use std::path::{Path, PathBuf};

use splatbridge_scene::formats::{detect, load, SplatFormat};
use splatbridge_scene::ply::ReadOptions;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures")
}

/// A copy of the unbundled SOG fixture with `meta.json` edited by `edit`.
fn unbundled_with(edit: impl FnOnce(&mut serde_json::Value)) -> (tempfile::TempDir, PathBuf) {
    let src = fixtures().join("formats/sog/v2_unbundled");
    let tmp = tempfile::tempdir().unwrap();
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), tmp.path().join(e.file_name())).unwrap();
    }
    let p = tmp.path().join("meta.json");
    let mut meta: serde_json::Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
    edit(&mut meta);
    std::fs::write(&p, serde_json::to_vec(&meta).unwrap()).unwrap();
    (tmp, p)
}

#[test]
fn sog_meta_with_an_asset_key_is_a_sog() {
    // The committed fixture is splat-transform 3.7.0's output, whose meta.json has
    // `"asset": {"generator": …}` second, before `count` and `means`.
    let p = fixtures().join("formats/sog/v2_unbundled/meta.json");
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains("\"asset\""), "the fixture lost its asset key");
    assert_eq!(
        detect(&p).unwrap(),
        SplatFormat::Sog {
            version: Some(2),
            bundled: false
        }
    );
    let (scene, info) = load(&p, &ReadOptions::default()).unwrap();
    assert_eq!(info.format.name(), "sog");
    assert_eq!(scene.gaussian_count(), 300);
}

#[test]
fn sog_meta_keys_in_any_order_are_a_sog() {
    // `asset` first, as 0.16 wrote it, and `means` after a long codebook-like key.
    let (_tmp, p) = unbundled_with(|m| {
        let mut o = serde_json::Map::new();
        o.insert(
            "asset".into(),
            serde_json::json!({"generator": "splat-transform v0.16.0"}),
        );
        for (k, v) in m.as_object().unwrap() {
            o.insert(k.clone(), v.clone());
        }
        *m = serde_json::Value::Object(o);
    });
    assert!(matches!(detect(&p).unwrap(), SplatFormat::Sog { .. }));
    assert_eq!(
        load(&p, &ReadOptions::default())
            .unwrap()
            .0
            .gaussian_count(),
        300
    );
}

#[test]
fn an_unbundled_meta_json_is_named_once() {
    let (_tmp, p) = unbundled_with(|m| {
        m.as_object_mut().unwrap().remove("count");
    });
    let err = load(&p, &ReadOptions::default()).unwrap_err().to_string();
    let shown = p.display().to_string();
    assert!(err.starts_with(&format!("{shown}: ")), "{err}");
    assert!(!err.contains("meta.json: meta.json"), "{err}");
    assert!(err.ends_with("count is missing or not an integer"), "{err}");
}

#[test]
fn a_bundled_meta_json_is_named_after_its_zip() {
    // Inside a zip the entry's name is information: `x.sog: meta.json: …`.
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("x.sog");
    let mut z = zip::ZipWriter::new(std::fs::File::create(&p).unwrap());
    z.start_file("meta.json", zip::write::SimpleFileOptions::default())
        .unwrap();
    std::io::Write::write_all(&mut z, br#"{"version": 2, "means": {"files": []}}"#).unwrap();
    z.finish().unwrap();
    let err = load(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(
        err.starts_with(&format!("{}: meta.json: count", p.display())),
        "{err}"
    );
}

#[test]
fn a_gltf_without_splats_or_meshes_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    for (name, text, expect) in [
        (
            "empty.gltf",
            r#"{"asset": {"version": "2.0"}}"#,
            "holds neither Gaussians",
        ),
        (
            "scene.gltf",
            r#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{}]}"#,
            "holds neither Gaussians",
        ),
    ] {
        let p = tmp.path().join(name);
        std::fs::write(&p, text).unwrap();
        assert!(matches!(detect(&p).unwrap(), SplatFormat::Gltf { .. }));
        let err = load(&p, &ReadOptions::default()).unwrap_err().to_string();
        assert!(err.contains(expect), "{name}: {err}");
        let err = splatbridge_scene::formats::load_cloud(&p, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains(expect), "{name}: {err}");
    }
}

#[test]
fn a_mesh_gltf_is_not_read_as_an_empty_scene() {
    let p = fixtures().join("malformed_corpus/files/mesh.glb");
    let err = load(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(err.contains("holds no Gaussians"), "{err}");
    assert!(err.contains("1 mesh primitives"), "{err}");
}
