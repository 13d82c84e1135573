//! Multi-file exports commit as a set: a failure on one file of a `.gltf` + `.bin` pair or of
//! an OBJ `--frames` sequence leaves the previous files untouched and no temporary behind.

mod common;

use std::path::Path;

use splatbridge_convert::{convert_to_file, ConvertOptions};
use splatbridge_scene::dynamic::DynamicScene;

/// Names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_gltf_whose_json_cannot_be_written_leaves_the_old_bin() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = dir.path().join("s.gltf");
    let bin = dir.path().join("s.bin");
    let opts = ConvertOptions::default();
    let first = DynamicScene::from_static(common::cloud(50, 0, 1));
    convert_to_file(&gltf, &first, None, &opts, false).unwrap();
    let old_bin = std::fs::read(&bin).unwrap();
    // The .gltf path becomes a folder: the .bin of a second, different export is written
    // first and must not replace the old one when the .gltf fails.
    std::fs::remove_file(&gltf).unwrap();
    std::fs::create_dir(&gltf).unwrap();
    let second = DynamicScene::from_static(common::cloud(80, 0, 2));
    let err = convert_to_file(&gltf, &second, None, &opts, false).unwrap_err();
    assert!(err.to_string().contains("s.gltf"), "{err}");
    assert_eq!(std::fs::read(&bin).unwrap(), old_bin);
    assert_eq!(names(dir.path()), ["s.bin", "s.gltf"]);
}

#[test]
fn an_obj_frame_sequence_that_fails_midway_leaves_the_old_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("f.obj");
    let opts = ConvertOptions::default();
    let scene = common::street(40);
    convert_to_file(&obj, &scene, None, &opts, true).unwrap();
    let before = names(dir.path());
    assert!(before.len() > 3, "{before:?}");
    let first = dir.path().join("f_0000.obj");
    let old_first = std::fs::read(&first).unwrap();
    let mtl = std::fs::read(dir.path().join("f.mtl")).unwrap();
    // A frame in the middle cannot be written: a different scene's export must change none of
    // the old frames.
    let third = dir.path().join("f_0002.obj");
    std::fs::remove_file(&third).unwrap();
    std::fs::create_dir(&third).unwrap();
    let other = common::street(60);
    assert!(convert_to_file(&obj, &other, None, &opts, true).is_err());
    assert_eq!(std::fs::read(&first).unwrap(), old_first);
    assert_eq!(std::fs::read(dir.path().join("f.mtl")).unwrap(), mtl);
    assert_eq!(names(dir.path()), before);
}
