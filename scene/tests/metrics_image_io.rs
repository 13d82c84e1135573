//! Image output and input: PNG quantisation and round trip, OpenEXR channels read back with
//! the `exr` crate, atomic writes, clear errors.

use splatbridge_scene::image_io::{load_png, save_frame, save_rgb8_png, to_u8, write_atomic};
use splatbridge_scene::Frame;

fn test_frame() -> Frame {
    let mut f = Frame::new(5, 3);
    for i in 0..f.pixels() {
        for c in 0..3 {
            // Includes out-of-range and NaN values to exercise the clamping.
            f.rgb[3 * i + c] = match (i + c) % 6 {
                0 => -0.2,
                1 => 1.7,
                2 => f32::NAN,
                _ => (i * 3 + c) as f32 / 47.0,
            };
        }
        f.alpha[i] = i as f32 / 14.0;
        f.depth[i] = 0.25 * i as f32 + 1e-3;
    }
    f
}

#[test]
fn png_round_trip_gives_the_quantised_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.PNG");
    let f = test_frame();
    save_frame(&path, &f).unwrap();
    let back = load_png(&path).unwrap();
    assert_eq!((back.width, back.height), (5, 3));
    for (i, (&orig, &got)) in f.rgb.iter().zip(&back.rgb).enumerate() {
        // 8-bit PNG decoded to float is exactly level/255.
        assert_eq!(got, to_u8(orig) as f32 / 255.0, "value {i}");
    }
    assert!(back.alpha.iter().all(|&a| a == 1.0), "RGB PNG has no alpha");
    assert!(back.depth.iter().all(|&d| d == 0.0));
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "temporary file left behind: {names:?}");
}

#[test]
fn exr_holds_rgba_and_depth_as_f32() {
    use exr::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.exr");
    let f = test_frame();
    save_frame(&path, &f).unwrap();
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(&path)
        .unwrap();
    let layer = &image.layer_data;
    assert_eq!((layer.size.0, layer.size.1), (5, 3));
    let channel = |name: &str| -> Vec<f32> {
        let ch = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.eq(name))
            .unwrap_or_else(|| panic!("no {name}"));
        ch.sample_data.values_as_f32().collect()
    };
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, ["A", "B", "G", "R", "Z"]);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let want: Vec<f32> = (0..f.pixels()).map(|i| f.rgb[3 * i + c]).collect();
        assert_eq!(
            bits(&channel(name)),
            bits(&want),
            "{name} is stored losslessly, NaN included"
        );
    }
    assert_eq!(channel("A"), f.alpha);
    assert_eq!(channel("Z"), f.depth);
}

#[test]
fn bad_outputs_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let e = save_frame(&dir.path().join("x.jpg"), &test_frame())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("x.jpg") && e.contains("unsupported image extension 'jpg'"),
        "{e}"
    );
    let mut broken = test_frame();
    broken.depth.pop();
    let e = save_frame(&dir.path().join("y.png"), &broken)
        .unwrap_err()
        .to_string();
    assert!(e.contains("y.png") && e.contains("14 depth values"), "{e}");
    let e = save_rgb8_png(&dir.path().join("z.png"), 2, 2, &[0; 11])
        .unwrap_err()
        .to_string();
    assert!(e.contains("z.png") && e.contains("11 bytes"), "{e}");
    let e = save_frame(&dir.path().join("missing/dir/f.png"), &test_frame())
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing/dir/f.png"), "{e}");
    std::fs::write(dir.path().join("not.png"), b"hello").unwrap();
    let e = load_png(&dir.path().join("not.png"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not.png") && e.contains("not a readable PNG"),
        "{e}"
    );
    // Only the input written above remains: failed writes left nothing.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn rgb8_png_round_trips_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("heat.png");
    let data: Vec<u8> = (0..3 * 4 * 2).map(|i| (i * 11) as u8).collect();
    save_rgb8_png(&path, 4, 2, &data).unwrap();
    let back = load_png(&path).unwrap();
    let got: Vec<u8> = back
        .rgb
        .iter()
        .map(|&v| (v * 255.0).round() as u8)
        .collect();
    assert_eq!(got, data);
}

#[test]
fn atomic_write_replaces_the_whole_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.txt");
    write_atomic(&path, b"a long first version").unwrap();
    write_atomic(&path, b"short").unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"short");
}
