//! The streamed GLB read-back (`raytrace::gltf_stream`, what `load_path` does for a GLB file:
//! one accessor's bytes at a time) against the whole-file reader (`load_glb_bytes`), the
//! reference: the same triangle scene, value for value, for real exports of the street
//! fixture — every profile (interleaved vertex attributes, one index view), the texture
//! profile's embedded image, surfels (a second material), and the moving objects' animation
//! channels. Compared through `Debug`, which prints every float exactly (shortest round trip).

use std::path::Path;

use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_raytrace::scene_load::{load_glb_bytes, load_path};
use splatbridge_scene::fixtures::{street_with, StreetParams};

#[test]
fn streamed_glb_read_back_equals_the_whole_file_reader() {
    let scene = street_with(&StreetParams::new(2, 2500));
    let tmp = tempfile::tempdir().unwrap();
    let mut cases = Vec::new();
    for profile in [Profile::MeshSplats, Profile::Rings, Profile::Texture] {
        cases.push((
            format!("{profile:?}"),
            ConvertOptions {
                profile,
                ..ConvertOptions::default()
            },
        ));
    }
    cases.push((
        "surfels".into(),
        ConvertOptions {
            surfels: Some(Default::default()),
            ..ConvertOptions::default()
        },
    ));
    for (name, opts) in cases {
        let (bytes, _) = splatbridge_convert::glb_bytes(&scene, None, &opts).unwrap();
        let path = tmp.path().join(format!("{name}.glb"));
        std::fs::write(&path, &bytes).unwrap();
        let (_, buffers, _) = splatbridge_raytrace::gltf_stream::import_path(&path).unwrap();
        assert!(buffers.is_streamed(), "{name}: the GLB was read whole");
        let whole = load_glb_bytes(&bytes, Path::new("x.glb")).unwrap();
        let streamed = load_path(&path).unwrap();
        assert!(whole.triangle_count() > 1000, "{name}: nothing exported");
        assert!(
            !whole.channels.is_empty(),
            "{name}: no animation to compare"
        );
        if name == "Texture" {
            assert!(!whole.textures.is_empty(), "{name}: no image to compare");
        }
        // Debug prints every field, floats exactly.
        assert!(
            format!("{whole:?}") == format!("{streamed:?}"),
            "{name}: the streamed read-back differs from the whole-file reader"
        );
    }
}

/// A `.gltf` with its buffer in an external `.bin` (the form of a mesh over GLB's 4 GiB) is
/// streamed from the `.bin` the same way: the same scene, value for value, as the GLB export
/// of the same options read whole; a `.bin` cut short is refused with the file named.
#[test]
fn streamed_gltf_with_external_buffer_equals_the_glb_read_whole() {
    let scene = street_with(&StreetParams::new(2, 2500));
    let tmp = tempfile::tempdir().unwrap();
    for profile in [Profile::MeshSplats, Profile::Texture] {
        let opts = ConvertOptions {
            profile,
            ..ConvertOptions::default()
        };
        let (bytes, _) = splatbridge_convert::glb_bytes(&scene, None, &opts).unwrap();
        let whole = load_glb_bytes(&bytes, Path::new("x.glb")).unwrap();
        let path = tmp.path().join(format!("{profile:?}.gltf"));
        splatbridge_convert::convert_to_file(&path, &scene, None, &opts, false).unwrap();
        let bins: Vec<_> = std::fs::read_dir(tmp.path())
            .unwrap()
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "bin"))
            .collect();
        assert!(!bins.is_empty(), "no external buffer written");
        let (_, buffers, _) = splatbridge_raytrace::gltf_stream::import_path(&path).unwrap();
        assert!(
            buffers.is_streamed(),
            "{profile:?}: the .gltf was read whole"
        );
        let streamed = load_path(&path).unwrap();
        assert!(
            whole.triangle_count() > 1000,
            "{profile:?}: nothing exported"
        );
        assert!(
            format!("{whole:?}") == format!("{streamed:?}"),
            "{profile:?}: the streamed .gltf read-back differs from the GLB read whole"
        );
    }
    // The external buffer shorter than the buffer's byteLength.
    let path = tmp.path().join("MeshSplats.gltf");
    let bin = std::fs::read_dir(tmp.path())
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| {
            p.to_string_lossy().contains("MeshSplats") && p.extension().is_some_and(|x| x == "bin")
        })
        .unwrap();
    let data = std::fs::read(&bin).unwrap();
    std::fs::write(&bin, &data[..data.len() - 4096]).unwrap();
    let e = load_path(&path).unwrap_err().to_string();
    assert!(e.contains("MeshSplats.gltf"), "{e}");
}

/// A truncated or corrupted export still fails with the file named, streamed or not.
#[test]
fn damaged_glb_files_are_refused_by_the_streamed_reader() {
    let scene = street_with(&StreetParams::new(2, 800));
    let (bytes, _) =
        splatbridge_convert::glb_bytes(&scene, None, &ConvertOptions::default()).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let cut = tmp.path().join("cut.glb");
    std::fs::write(&cut, &bytes[..bytes.len() - 1000]).unwrap();
    let e = load_path(&cut).unwrap_err().to_string();
    assert!(e.contains("cut.glb"), "{e}");
    // The BIN chunk shorter than the buffer it holds (header lengths patched to agree).
    let mut short = bytes.clone();
    let json_len = u32::from_le_bytes(short[12..16].try_into().unwrap()) as usize;
    let bin_at = 20 + json_len;
    let bin_len = u32::from_le_bytes(short[bin_at..bin_at + 4].try_into().unwrap()) - 4096;
    short[bin_at..bin_at + 4].copy_from_slice(&bin_len.to_le_bytes());
    short.truncate(bin_at + 8 + bin_len as usize);
    let total = short.len() as u32;
    short[8..12].copy_from_slice(&total.to_le_bytes());
    let p = tmp.path().join("short.glb");
    std::fs::write(&p, &short).unwrap();
    let e = load_path(&p).unwrap_err().to_string();
    assert!(e.contains("short.glb"), "{e}");
}
