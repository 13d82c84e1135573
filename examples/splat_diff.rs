//! Compare two decodings of the same splat file attribute by attribute, within the format's
//! quantisation step. Used by `scripts/formats-compare.sh` to check our decoders against
//! `@playcanvas/splat-transform`'s: both decode one file to a float 3DGS PLY, and this program
//! reports the largest difference per attribute and whether it stays within one step.
//!
//! `cargo run --release --example splat_diff -- FORMAT A B [--flip-yz]`, FORMAT one of `spz`,
//! `compressed-ply`, `sog`, `splat`; A and B in any format the loader reads (usually PLYs).
//! `--flip-yz` turns B half a turn about x first: splat-transform reads and writes SPZ data
//! without nianticlabs/spz's RUB ↔ RDF conversion, which we apply (so `fourth_st.spz` lines up
//! with `fourth_st.ply`); its SPZ decodings differ from ours by exactly that turn.
//! Exit status 0 when every attribute is within its step, 1 otherwise, 2 on a load error.
//!
//! An example rather than a CLI subcommand: it is a test instrument of the comparison script,
//! not something users run, and it needs nothing but the library's loader.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use splatbridge_scene::formats::load_cloud;
use splatbridge_scene::gaussians::sigmoid;
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::sh::SH_C0;
use splatbridge_scene::GaussianCloud;

/// One quantisation step per attribute: positions (as a fraction of the scene's extent, or
/// absolute), log-scales, rotation (per unit-quaternion component), opacity (after the
/// sigmoid), DC colour (display units) and higher SH.
struct Steps {
    pos_rel: f32,
    pos_abs: f32,
    log_scale: f32,
    rot: f32,
    opacity: f32,
    colour: f32,
    sh: f32,
}

fn steps(format: &str) -> Option<Steps> {
    Some(match format {
        // SPZ: 24-bit fixed point with 12 fraction bits (1/4096), log-scales 1/16, rotations
        // 9-bit smallest three (√½/511) or 8-bit x,y,z (1/127.5), opacity and colour 8-bit
        // (colour steps of 1/(0.15·255) in f_dc, ×SH_C0), SH buckets of 16/128.
        "spz" => Steps {
            pos_rel: 0.0,
            pos_abs: 1.0 / 4096.0,
            log_scale: 1.0 / 16.0,
            rot: 1.0 / 127.5,
            opacity: 1.0 / 255.0,
            colour: SH_C0 / (0.15 * 255.0),
            sh: 16.0 / 128.0,
        },
        // Compressed PLY: 10 bits over a chunk's bounds (at most the scene's extent) for
        // positions and log-scales (log-scale range taken as 40, the [−20, 20] clamp),
        // 10-bit rotations over ±√½, 8-bit colour over at most [0, 1], SH bins of 8/256.
        "compressed-ply" => Steps {
            pos_rel: 1.0 / 1023.0,
            pos_abs: 0.0,
            log_scale: 40.0 / 1023.0,
            rot: std::f32::consts::SQRT_2 / 1023.0,
            opacity: 1.0 / 255.0,
            colour: 1.0 / 255.0,
            sh: 8.0 / 256.0,
        },
        // SOG: 16-bit positions on a log scale (relative step 2⁻¹⁶ of the log-range, taken as
        // a fraction of the extent), 8-bit rotations and opacity, 256-entry codebooks for
        // scales/colours (step bounded by the codebook spacing, 1/255 of the range).
        "sog" => Steps {
            pos_rel: 1.0 / 4096.0,
            pos_abs: 0.0,
            log_scale: 40.0 / 255.0,
            rot: std::f32::consts::SQRT_2 / 255.0,
            opacity: 1.0 / 255.0,
            colour: 4.0 / 255.0,
            sh: 16.0 / 255.0,
        },
        // .splat: positions and scales are f32; colour, alpha and rotation 8-bit.
        "splat" => Steps {
            pos_rel: 0.0,
            pos_abs: 1e-6,
            log_scale: 1e-5,
            rot: 1.0 / 128.0,
            opacity: 1.0 / 255.0,
            colour: 1.0 / 255.0,
            sh: 0.0,
        },
        _ => return None,
    })
}

fn load(p: &Path) -> Result<GaussianCloud, String> {
    load_cloud(p, &ReadOptions::default())
        .map(|(c, _)| c)
        .map_err(|e| e.to_string())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flip = args.iter().any(|a| a == "--flip-yz");
    let args: Vec<&String> = args.iter().filter(|a| *a != "--flip-yz").collect();
    let [format, a, b] = args.as_slice() else {
        eprintln!("usage: splat_diff FORMAT A B [--flip-yz]");
        return ExitCode::from(2);
    };
    let Some(st) = steps(format.as_str()) else {
        eprintln!("error: FORMAT must be spz, compressed-ply, sog or splat");
        return ExitCode::from(2);
    };
    let (ca, mut cb) = match (
        load(&PathBuf::from(a.as_str())),
        load(&PathBuf::from(b.as_str())),
    ) {
        (Ok(x), Ok(y)) => (x, y),
        (Err(e), _) | (_, Err(e)) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if flip {
        splatbridge_scene::formats::spz::flip_yz(&mut cb);
    }
    if ca.len() != cb.len() {
        eprintln!("counts differ: {} vs {}", ca.len(), cb.len());
        return ExitCode::from(1);
    }
    let extent = ca
        .bounds()
        .map(|(lo, hi)| (hi - lo).max_element())
        .unwrap_or(0.0);
    let (ka, kb) = (ca.coeffs(), cb.coeffs());
    let k = ka.min(kb);
    // Largest difference per attribute; a non-finite difference (±inf against a finite
    // value) counts as infinite, except opacities, compared after the sigmoid.
    let mut m = [0.0f32; 6];
    let up = |slot: &mut f32, d: f32| {
        let d = if d.is_nan() { f32::INFINITY } else { d };
        *slot = slot.max(d);
    };
    for i in 0..ca.len() {
        up(&mut m[0], (ca.means[i] - cb.means[i]).abs().max_element());
        up(
            &mut m[1],
            (ca.log_scales[i] - cb.log_scales[i]).abs().max_element(),
        );
        let (qa, mut qb) = (ca.unit_rotation(i), cb.unit_rotation(i));
        if qa.dot(qb) < 0.0 {
            qb = -qb;
        }
        up(
            &mut m[2],
            (glam::Vec4::from(qa) - glam::Vec4::from(qb))
                .abs()
                .max_element(),
        );
        up(
            &mut m[3],
            (sigmoid(ca.opacity_logits[i]) - sigmoid(cb.opacity_logits[i])).abs(),
        );
        up(
            &mut m[4],
            (ca.sh[i * ka] - cb.sh[i * kb]).abs().max_element() * SH_C0,
        );
        for c in 1..k {
            up(
                &mut m[5],
                (ca.sh[i * ka + c] - cb.sh[i * kb + c]).abs().max_element(),
            );
        }
    }
    let limits = [
        st.pos_abs.max(st.pos_rel * extent),
        st.log_scale,
        st.rot,
        st.opacity,
        st.colour,
        st.sh,
    ];
    let names = [
        "position",
        "log-scale",
        "rotation",
        "opacity",
        "colour",
        "SH rest",
    ];
    println!(
        "{format}: {} Gaussians, SH degrees {} / {}",
        ca.len(),
        ca.sh_degree,
        cb.sh_degree
    );
    let mut ok = true;
    for j in 0..6 {
        if j == 5 && k <= 1 {
            continue;
        }
        let within = m[j] <= limits[j];
        ok &= within;
        println!(
            "  {:<10} max |Δ| {:<12.4e} step {:<12.4e} {}",
            names[j],
            m[j],
            limits[j],
            if within { "ok" } else { "EXCEEDS" }
        );
    }
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}
