//! The ray-traced Gaussians' pixel footprint against native splatting, and the `trace`
//! command's `--footprint` / `--spp` options: at low resolution, where native's 0.3-pixel
//! low-pass matters, the footprint brings the trace closer to native; bad values exit 2 naming
//! the option.

use std::process::Command;

use glam::DVec3;
use splatbridge_hybrid::native::{render as native, RenderOptions as NativeOptions};
use splatbridge_raytrace::{
    BackendKind, BuildPreset, Footprint, GaussianTracer, RenderOptions, SampleFootprint,
};
use splatbridge_scene::fixtures::large;
use splatbridge_scene::{metrics, Camera};

const BIN: &str = env!("CARGO_BIN_EXE_splatbridge");

fn street() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/street/scene.json").into()
}

/// A synthetic capture (trained-scene scale and opacity distributions, 20k Gaussians) at
/// 48×36 and 96×72: most Gaussians are sub-pixel there, so native's low-pass decides the image.
#[test]
fn footprint_is_closer_to_native_at_low_resolution() {
    let cloud = large(20_000, 5);
    let (lo, hi) = cloud.bounds().unwrap();
    let c = 0.5 * (lo + hi).as_dvec3();
    let r = (hi - lo).as_dvec3().length();
    let tracer =
        GaussianTracer::new(cloud.clone(), BackendKind::Obvhs, BuildPreset::default()).unwrap();
    for (w, h) in [(48u32, 36u32), (96, 72)] {
        let eye = c + DVec3::new(0.45, -0.25, -0.6) * r;
        let cam = Camera::look_at(eye, c, DVec3::NEG_Y, 60.0, w, h).unwrap();
        let (reference, _) = native(&cloud, &cam, &NativeOptions::default()).unwrap();
        let psnr = |footprint, spp, sample_footprint| {
            let o = RenderOptions {
                footprint,
                spp,
                sample_footprint,
                ..RenderOptions::default()
            };
            let (img, _) = tracer.render(&cam, &o).unwrap();
            metrics::psnr(&reference, &img).unwrap()
        };
        let off = psnr(Footprint::Off, 1, SampleFootprint::Subpixel);
        let on = psnr(Footprint::On, 1, SampleFootprint::Subpixel);
        let on4 = psnr(Footprint::On, 4, SampleFootprint::Subpixel);
        eprintln!("{w}×{h}: off {off:.2} dB, on {on:.2} dB, on spp=4 {on4:.2} dB");
        // 1 dB: measured gains are several dB at these sizes (see docs/footprint.md); a
        // footprint that did nothing, or widened by the wrong scale, falls below it.
        assert!(on > off + 1.0, "{w}×{h}: on {on:.2} dB vs off {off:.2} dB");
    }
}

#[test]
fn trace_options_reach_the_tracer_and_bad_values_exit_2() {
    let tmp = tempfile::tempdir().expect("a temporary folder");
    let dir = tmp.path();
    let scene = street();
    let out = dir.join("x.png");
    let o = out.to_str().unwrap();
    let base = [
        "trace",
        scene.as_str(),
        "--mode",
        "gaussian",
        "--camera",
        "scene:0",
        "--width",
        "32",
        "--height",
        "24",
    ];
    for (knob, value) in [
        ("--spp", "0"),
        ("--spp", "1025"),
        ("--spp", "x"),
        ("--footprint", "maybe"),
        ("--sample-footprint", "half"),
    ] {
        let r = Command::new(BIN)
            .args(base)
            .args([knob, value, "-o", o])
            .output()
            .unwrap();
        assert_eq!(r.status.code(), Some(2), "{knob} {value}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains(knob), "{knob} {value}: {err}");
        assert!(!out.exists(), "no output written on a bad value");
    }
    let json = |extra: &[&str]| -> serde_json::Value {
        let r = Command::new(BIN)
            .args(base)
            .args(extra)
            .args(["-o", o, "--json"])
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        serde_json::from_slice(&r.stdout).unwrap()
    };
    let d = json(&[]);
    assert_eq!(
        d["options"]["footprint"], "on",
        "on by default in mode gaussian"
    );
    assert_eq!(d["options"]["spp"], 1);
    assert_eq!(d["options"]["order"], "mean-depth");
    let on = std::fs::read(&out).unwrap();
    let d = json(&["--footprint", "off", "--spp", "4"]);
    assert_eq!(d["options"]["footprint"], "off");
    assert_eq!(d["options"]["order"], "hit");
    assert_eq!(d["options"]["spp"], 4);
    assert_eq!(d["stats"]["rays"], 32 * 24 * 4);
    assert_ne!(std::fs::read(&out).unwrap(), on);
}
