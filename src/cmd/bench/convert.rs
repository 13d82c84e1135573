//! `splatbridge bench convert`: Gaussians to GLB, median wall time over repeats.
//!
//! Default input: the `large` fixture with 1 M Gaussians; default profile `meshsplats`
//! (8-segment fans). Each run does the whole conversion (classification, bounds pass,
//! streamed vertex and index generation) into a byte-counting sink, and with `--to-file` into
//! a real file (atomic write included). `--splats` times the KHR_gaussian_splatting writer.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use splatbridge_convert::{ChunkedMesh, ConvertOptions, Profile};
use splatbridge_scene::dynamic::DynamicScene;

use crate::cmd::common;

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene to convert: ", scene_formats!(), "; default: the `large` fixture."))]
    pub scene: Option<PathBuf>,
    /// Gaussians of the generated `large` fixture.
    #[arg(long, default_value_t = 1_000_000)]
    pub count: usize,
    /// Meshing profile: meshsplats, rings or texture.
    #[arg(long, default_value = "meshsplats")]
    pub profile: String,
    /// Segments per fan.
    #[arg(long, default_value_t = 8, value_parser = crate::cmd::ranges::segments)]
    pub segments: usize,
    /// Timed repeats (the median is reported).
    #[arg(long, alias = "repeats", default_value_t = 5)]
    pub repeat: usize,
    /// Also time writing to this file.
    #[arg(long)]
    pub to_file: Option<PathBuf>,
    /// Time the KHR_gaussian_splatting writer instead of meshing.
    #[arg(long)]
    pub splats: bool,
}

/// Counts bytes, stores nothing.
struct Sink(u64);

impl Write for Sink {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0 += b.len() as u64;
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let t = Instant::now();
    let scene = match &args.scene {
        Some(p) => common::load(p, true)?,
        None => DynamicScene::from_static(splatbridge_scene::fixtures::large(args.count, 1)),
    };
    let n = scene.static_gaussians.len()
        + scene
            .objects
            .iter()
            .map(|o| o.gaussians.len())
            .sum::<usize>();
    eprintln!(
        "input: {n} Gaussians (prepared in {:.2} s), {} threads",
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    let profile = match args.profile.as_str() {
        "meshsplats" => Profile::MeshSplats,
        "rings" => Profile::Rings,
        "texture" => Profile::Texture,
        p => anyhow::bail!("unknown profile '{p}' (meshsplats, rings, texture)"),
    };
    let opts = ConvertOptions {
        profile,
        segments: Some(args.segments),
        ..Default::default()
    };
    let repeat = args.repeat.max(1);
    if !args.splats {
        // Phase breakdown of one run (static cloud only).
        let shape = splatbridge_convert::shape_for(&opts);
        let t = Instant::now();
        let m =
            splatbridge_convert::Mesher::new(&scene.static_gaussians, &shape, &opts, "static", 0);
        let t_classify = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let b = m.bounds();
        let t_bounds = t.elapsed().as_secs_f64();
        let layout = splatbridge_convert::gltf_writer::VertexLayout {
            ids: true,
            uv: profile == Profile::Texture,
            normals: true,
        };
        let t = Instant::now();
        let mut nb = 0usize;
        m.map_chunks_with::<_, Vec<u8>, ()>(
            |n| splatbridge_convert::gltf_writer::Interleaved::new(n, layout),
            |s| s.bytes,
            |v| {
                nb += v.len();
                Ok(())
            },
        )
        .ok();
        let t_vertices = t.elapsed().as_secs_f64();
        let t = Instant::now();
        m.map_index_chunks::<usize, ()>(0, |i| i.len(), |_| Ok(()))
            .ok();
        let t_indices = t.elapsed().as_secs_f64();
        eprintln!(
            "phases: classify {t_classify:.3} s, bounds {t_bounds:.3} s, vertices {t_vertices:.3} s ({:.0} MB), indices {t_indices:.3} s; bounds {:?}",
            nb as f64 / 1e6,
            b
        );
    }
    let mut times = Vec::new();
    let mut report = None;
    for _ in 0..repeat {
        let mut sink = Sink(0);
        let t = Instant::now();
        let r = if args.splats {
            splatbridge_convert::splats_gltf::write_glb(&mut sink, &scene, &opts)?
        } else {
            splatbridge_convert::write_glb(&mut sink, &scene, None, &opts)?
        };
        times.push(t.elapsed().as_secs_f64());
        anyhow::ensure!(
            sink.0 == r.bytes,
            "sink saw {} bytes, report says {}",
            sink.0,
            r.bytes
        );
        report = Some(r);
    }
    let r = report.expect("at least one run");
    let m = median(times.clone());
    let what = if args.splats {
        "splats GLB".to_string()
    } else {
        format!("GLB {} n={}", r.profile, r.segments)
    };
    println!(
        "convert {what}: {n} Gaussians → {} triangles, {:.1} MB; median {:.3} s over {repeat} (min {:.3}, max {:.3}); {:.1} M Gaussians/s, {:.0} MB/s",
        r.triangles,
        r.bytes as f64 / 1e6,
        m,
        times.iter().cloned().fold(f64::INFINITY, f64::min),
        times.iter().cloned().fold(0.0, f64::max),
        n as f64 / m / 1e6,
        r.bytes as f64 / m / 1e6
    );
    if let Some(path) = &args.to_file {
        let mut ft = Vec::new();
        for _ in 0..repeat {
            let t = Instant::now();
            if args.splats {
                splatbridge_convert::splats_gltf::write_file(path, &scene, &opts)?;
            } else {
                splatbridge_convert::convert_to_file(path, &scene, None, &opts, false)?;
            }
            ft.push(t.elapsed().as_secs_f64());
        }
        println!(
            "  to file {}: median {:.3} s over {repeat}",
            path.display(),
            median(ft)
        );
    }
    Ok(())
}
