//! `splatbridge accuracy`: sweep the named knobs one at a time around the defaults and measure
//! error against the reference (native splatting, reference settings) and time
//! (`splatbridge::accuracy`). Writes `accuracy.json`, `accuracy.md` and plots of PSNR against
//! time and against triangles, with the Pareto front and the MeshSplats default marked.

use std::path::PathBuf;

use anyhow::Context;
use splatbridge::accuracy::{
    commit_outputs, measure_setting, read_records, reference_frames, settings, Sweep,
};
use splatbridge::report::Record;
use splatbridge_scene::{Camera, GaussianCloud};

use super::common;
use super::compare::resolve_cameras;

#[derive(clap::Args)]
pub struct Args {
    /// A 3DGS PLY or a splatbridge-scene/1 manifest (measured at --time).
    pub scene: PathBuf,
    /// Cameras, comma-separated (as `compare --cameras`).
    #[arg(long, default_value = "orbit:3")]
    pub cameras: String,
    #[arg(long, default_value_t = 0.0, value_parser = super::ranges::time, allow_hyphen_values = true)]
    pub time: f64,
    #[arg(long, default_value_t = 320)]
    pub width: u32,
    #[arg(long, default_value_t = 240)]
    pub height: u32,
    /// Knob families to sweep (default: all): profile, segments, extent, k, native-extent,
    /// hybrid, sh-degree, format (each splat file format's quantisation: the cloud written by
    /// our writer, read back and rendered natively), footprint (ray-traced Gaussians with the
    /// pixel footprint off/on), footprint-spp (the same at 4 samples per pixel), footprint-causes (native's hit
    /// order and SH direction on top, and the projected mode), mesh-spp (the default profile's
    /// mesh traced at 1 and 4 samples per pixel).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    #[arg(long)]
    pub drop_invalid: bool,
    /// Re-draw the plots and table from OUT/accuracy.json without measuring again.
    #[arg(long)]
    pub replot: bool,
    #[arg(short, long, alias = "output")]
    pub out: PathBuf,
}

fn print_records(records: &[Record]) {
    for r in records {
        println!(
            "{:14} {:28} PSNR {:7.2} dB  {:9.1} ms  {:>10} triangles",
            r.knob, r.value, r.psnr, r.milliseconds, r.triangles
        );
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.replot {
        let records = read_records(&args.out)?;
        let what = format!("`{}` (re-plotted from accuracy.json)", args.scene.display());
        commit_outputs(&args.out, &what, &records)?;
        print_records(&records);
        println!("wrote {}", args.out.join("accuracy.md").display());
        return Ok(());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the output folder", args.out.display()))?;
    let scene = common::load(&args.scene, args.drop_invalid)?;
    let cloud: GaussianCloud = scene.composite(args.time);
    let cams: Vec<Camera> =
        resolve_cameras(&args.cameras, &cloud, &scene, args.width, args.height)?;
    let refs = reference_frames(&cloud, &cams)?;
    let sweep = Sweep {
        cloud: &cloud,
        cameras: &cams,
        references: &refs,
        time: args.time,
        work_dir: &args.out,
        drop_invalid: args.drop_invalid,
    };
    let settings = settings(&args.only);
    let pb = common::progress(settings.len() as u64, "accuracy");
    let mut records = Vec::new();
    for (family, value, setting, _baseline) in settings {
        pb.set_message(format!("{family} {value}"));
        records.push(measure_setting(
            &sweep,
            records.len(),
            family,
            &value,
            &setting,
        )?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let what = format!(
        "`{}`: {} cameras at {}×{}, time {}",
        args.scene.display(),
        cams.len(),
        args.width,
        args.height,
        args.time
    );
    commit_outputs(&args.out, &what, &records)?;
    print_records(&records);
    println!("wrote {}", args.out.join("accuracy.md").display());
    Ok(())
}
