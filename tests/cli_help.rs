//! `splatbridge --help` and the help of every command that reads a scene name every format it
//! reads (the readers of `scene/src/formats`, and for `trace` the meshes of `raytrace`), so
//! a format added to a reader and not to the help, or a help that drifts, fails here.

mod cli_common;

use cli_common::ok;

/// What every scene-reading help must name: PLY (3DGS, its 2DGS variant and compressed), .splat,
/// .spz, .ksplat, SOG in
/// both of its forms, glTF/GLB splats and the manifest.
const SCENE_FORMATS: &[&str] = &[
    "3DGS PLY",
    "compressed PLY",
    ".splat",
    ".spz",
    ".ksplat",
    "2DGS",
    "SOG",
    "meta.json",
    ".sog",
    "glTF",
    "GLB",
    "KHR_gaussian_splatting",
    "manifest",
];

/// The help text of `args … --help`, with clap's line wrapping undone.
fn help(args: &[&str]) -> String {
    let mut a = args.to_vec();
    a.push("--help");
    let text = String::from_utf8_lossy(&ok(&a).stdout).into_owned();
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

fn missing(text: &str, names: &[&str]) -> Vec<String> {
    names
        .iter()
        .filter(|n| !text.contains(*n))
        .map(|n| n.to_string())
        .collect()
}

#[test]
fn every_scene_reading_command_names_every_format() {
    let commands: &[&[&str]] = &[
        &[],
        &["info"],
        &["render"],
        &["convert"],
        &["hybrid"],
        &["compare"],
        &["accuracy"],
        &["bench", "ply"],
        &["bench", "render"],
        &["bench", "convert"],
        &["bench", "hybrid"],
        &["bench", "effects"],
        &["bench", "distill"],
    ];
    for c in commands {
        let text = help(c);
        let gone = missing(&text, SCENE_FORMATS);
        assert!(
            gone.is_empty(),
            "splatbridge {c:?} --help does not name {gone:?}:\n{text}"
        );
    }
}

#[test]
fn trace_names_its_meshes_and_scene_formats() {
    for c in [&["trace"][..], &["bench", "trace"][..]] {
        let text = help(c);
        let mut names = vec!["OBJ"];
        // glTF splats are named too: to say that trace reads a .glb/.gltf as a mesh.
        names.extend_from_slice(SCENE_FORMATS);
        let gone = missing(&text, &names);
        assert!(
            gone.is_empty(),
            "splatbridge {c:?} --help does not name {gone:?}:\n{text}"
        );
    }
    let top = help(&[]);
    assert!(
        top.contains("trace also reads GLB, glTF and OBJ meshes"),
        "{top}"
    );
}

#[test]
fn info_no_longer_says_only_ply_or_manifest() {
    let top = help(&[]);
    assert!(!top.contains("Describe a PLY or a scene manifest"), "{top}");
}
