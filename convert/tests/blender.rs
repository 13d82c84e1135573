//! The street fixture's GLB, every profile, imported into Blender through
//! `scripts/blender-check.sh`: one object per mesh node, the cameras, a BLEND unlit material
//! with the colour attribute wired to colour and alpha, one action per moving object over the
//! scene's time range. Skips with a printed reason when Blender is not installed.

use std::path::Path;
use std::process::Command;

use splatbridge_convert::{convert_to_file, ConvertOptions, Profile};

#[test]
fn street_glb_imports_into_blender_as_intended() {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/blender-check.sh");
    let dir = tempfile::tempdir().unwrap();
    let scene = splatbridge_scene::fixtures::street_with(
        &splatbridge_scene::fixtures::StreetParams::new(1, 3000),
    );
    let mut files = Vec::new();
    for profile in [Profile::MeshSplats, Profile::Rings, Profile::Texture] {
        let p = dir.path().join(format!("street-{}.glb", profile.name()));
        convert_to_file(
            &p,
            &scene,
            None,
            &ConvertOptions {
                profile,
                ..Default::default()
            },
            false,
        )
        .unwrap();
        files.push(p);
    }
    let out = Command::new(&script)
        .args(&files)
        .output()
        .expect("run blender-check.sh");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    match out.status.code() {
        Some(3) => println!("skipped: Blender is not available"),
        Some(0) => assert_eq!(
            stdout
                .lines()
                .filter(|l| l.contains("\"problems\": []"))
                .count(),
            files.len()
        ),
        c => panic!("Blender check failed (exit {c:?}):\n{stdout}"),
    }
}
