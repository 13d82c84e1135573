//! Make a 2DGS-layout scene from a 3DGS capture: every Gaussian flattened to the disc of its two
//! largest axes (`scene::ply::flatten_to_surfels`) and written as a 2DGS PLY (`scale_0 scale_1`
//! only, 2DGS's `save_ply` layout), for measuring the 2DGS paths on real data.
//!
//! Usage: `cargo run --release --example flatten_2dgs -- IN OUT.ply` (IN: any splat format).

use std::path::PathBuf;

use splatbridge_scene::formats::load_cloud;
use splatbridge_scene::ply::{flatten_to_surfels, write_ply_2dgs, ReadOptions};

fn main() -> anyhow::Result<()> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [input, output] = args.as_slice() else {
        anyhow::bail!("usage: flatten_2dgs IN OUT.ply");
    };
    let (cloud, _) = load_cloud(input, &ReadOptions::default())?;
    let surfels = flatten_to_surfels(&cloud);
    write_ply_2dgs(output, &surfels)?;
    println!(
        "{}: {} Gaussians flattened to 2DGS surfels (SH degree {})",
        output.display(),
        surfels.len(),
        surfels.sh_degree
    );
    Ok(())
}
