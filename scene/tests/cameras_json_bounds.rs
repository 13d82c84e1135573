//! `cameras.json` values that parse as numbers but are not a camera (1e308 anywhere, NaN
//! from overflowing rotations, absurd focal lengths) are refused with the file and the
//! field named, instead of rendering nothing.

use splatbridge_scene::camera::load_cameras_json;

const GOOD: &str = r#"[{"id": 0, "img_name": "cam", "width": 64, "height": 48,
  "position": [0.0, -1.0, -5.0],
  "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
  "fx": 60.0, "fy": 60.0}]"#;

fn load(text: &str) -> Result<usize, String> {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("cameras.json");
    std::fs::write(&p, text).unwrap();
    load_cameras_json(&p)
        .map(|c| c.len())
        .map_err(|e| e.to_string())
}

#[test]
fn the_good_file_loads() {
    assert_eq!(load(GOOD), Ok(1));
}

#[test]
fn every_field_at_1e308_is_refused_by_name() {
    let cases = [
        ("\"width\": 64", "\"width\": 1e308", "width 1e308"),
        ("\"height\": 48", "\"height\": 1e308", "height 1e308"),
        ("[0.0, -1.0, -5.0]", "[1e308, -1.0, -5.0]", "position[0]"),
        ("[0.0, -1.0, -5.0]", "[0.0, -1.0, -1e13]", "position[2]"),
        ("[0.0, 1.0, 0.0]", "[0.0, 1e308, 0.0]", "rotation[1][1]"),
        ("\"fx\": 60.0", "\"fx\": 1e308", "fx is 1e308"),
        ("\"fy\": 60.0", "\"fy\": 1e308", "fy is 1e308"),
        ("\"fx\": 60.0", "\"fx\": 1e-300", "fx is"),
        ("\"fy\": 60.0", "\"fy\": -60.0", "fy is -60"),
        ("\"width\": 64", "\"width\": 64.5", "width 64.5"),
    ];
    for (from, to, want) in cases {
        let text = GOOD.replacen(from, to, 1);
        assert_ne!(text, GOOD, "{from} not found");
        let err = load(&text).expect_err(to);
        assert!(err.contains("cameras.json"), "{to}: {err}");
        assert!(err.contains(want), "{to}: {err}");
    }
}

#[test]
fn a_matrix_of_small_entries_that_is_no_rotation_is_refused() {
    // Every entry passes the per-entry bound; the orthonormality check catches the matrix.
    let text = GOOD.replacen(
        r#"[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]"#,
        r#"[[1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 1.0]]"#,
        1,
    );
    let err = load(&text).unwrap_err();
    assert!(err.contains("not orthonormal"), "{err}");
}
