//! Write a scene as `KHR_gaussian_splatting` GLB with SPZ compression
//! (`KHR_gaussian_splatting_compression_spz_2`), for `scripts/formats-compare.sh` to time the
//! encoder against splat-transform's SPZ writer on the same PLY.
//!
//! `cargo run --release --example khr_encode -- IN OUT.glb [none|spz]`; IN in any format the
//! loader reads. Exit status 0 on success, 2 on an error.

use std::path::PathBuf;
use std::process::ExitCode;

use splatbridge_convert::splats_gltf::{write_file_with, KhrCompression};
use splatbridge_convert::ConvertOptions;
use splatbridge_scene::formats::load;
use splatbridge_scene::ply::ReadOptions;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (input, output, mode) = match args.as_slice() {
        [i, o] => (i, o, "spz"),
        [i, o, m] => (i, o, m.as_str()),
        _ => {
            eprintln!("usage: khr_encode IN OUT.glb [none|spz]");
            return ExitCode::from(2);
        }
    };
    let compression = match mode {
        "spz" => KhrCompression::Spz,
        "none" => KhrCompression::None,
        _ => {
            eprintln!("error: compression must be none or spz");
            return ExitCode::from(2);
        }
    };
    let scene = match load(&PathBuf::from(input), &ReadOptions::default()) {
        Ok((s, _)) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    match write_file_with(
        &PathBuf::from(output),
        &scene,
        &ConvertOptions::default(),
        compression,
    ) {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
