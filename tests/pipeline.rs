//! The frame pipeline (`splatbridge::pipeline`) against the stage crates called directly, the
//! slow obvious way: with nothing declared, `render_frame` is the plain render of the
//! composite bit for bit (native, hybrid, Gaussian tracer); with motion blur it is the
//! weighted average of one plain render per shutter sample; shadows and LiDAR run only where
//! declared and only in the tracers, and the counters say so.
//!
//! Scenes are the street fixture at 1,200 Gaussians and 48×32 images, so the file runs in
//! seconds.

use splatbridge::pipeline::{
    render_frame, FrameRequest, FrameStats, LidarRequest, Renderer, SurfelSplit,
};
use splatbridge_hybrid::ges::{render_cloud, GesOptions, SplitMode};
use splatbridge_hybrid::native::{self, RenderOptions as NativeOptions};
use splatbridge_raytrace::{
    BackendKind, BuildPreset, GaussianTracer, RenderOptions as TraceOptions,
};
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource, CameraSpec};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::Effects;
use splatbridge_scene::effects_run::{blend_frames, effects_of, time_samples};
use splatbridge_scene::fixtures::{street_effect, street_with, StreetParams};
use splatbridge_scene::surfels::SplitParams;
use splatbridge_scene::{Camera, Frame};

const T: f64 = 1.0;

fn street(effects: &[&str]) -> DynamicScene {
    let mut s = street_with(&StreetParams::new(3, 1200));
    s.effects.clear();
    for e in effects {
        let (name, value) = street_effect(e, 1).unwrap();
        s.effects.insert(name.into(), value);
    }
    s
}

fn camera(scene: &DynamicScene) -> Camera {
    let mut req = CameraRequest::new(CameraSpec::Scene(0));
    req.width = Some(48);
    req.height = Some(32);
    let cloud = scene.composite(T);
    req.resolve(CameraSource {
        cloud: &cloud,
        own: &scene.cameras,
    })
    .unwrap()
}

fn frame(r: &mut Renderer, scene: &DynamicScene, effects: &Effects, cam: &Camera) -> Frame {
    let req = FrameRequest {
        scene: Some(scene),
        effects,
        camera: cam,
        time: T,
        content: Default::default(),
        lidar: None,
    };
    render_frame(r, &req).unwrap().frame
}

fn same_bits(a: &Frame, b: &Frame) -> bool {
    let bits = |f: &Frame| {
        f.rgb
            .iter()
            .chain(&f.alpha)
            .chain(&f.depth)
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    (a.width, a.height) == (b.width, b.height) && bits(a) == bits(b)
}

#[test]
fn without_effects_every_renderer_draws_the_plain_composite() {
    let scene = street(&[]);
    let effects = effects_of(&scene).unwrap();
    let cam = camera(&scene);
    let cloud = scene.composite(T);

    let mut r = Renderer::native(NativeOptions::default()).unwrap();
    let want = native::render(&cloud, &cam, &NativeOptions::default())
        .unwrap()
        .0;
    assert!(same_bits(&frame(&mut r, &scene, &effects, &cam), &want));

    let split = SurfelSplit {
        params: SplitParams::default(),
        ges_ply: false,
        detect_ges: false,
    };
    let mut r = Renderer::hybrid(GesOptions::default(), split).unwrap();
    let want = render_cloud(
        &cloud,
        SplitMode::Thresholds(SplitParams::default()),
        &cam,
        &GesOptions::default(),
    )
    .unwrap()
    .0;
    assert!(same_bits(&frame(&mut r, &scene, &effects, &cam), &want));

    let tracer =
        GaussianTracer::for_scene(&scene, T, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let want = tracer.render(&cam, &TraceOptions::default()).unwrap().0;
    let mut r = Renderer::Gaussian {
        tracer,
        options: TraceOptions::default(),
    };
    assert!(same_bits(&frame(&mut r, &scene, &effects, &cam), &want));
}

#[test]
fn motion_blur_is_the_average_of_plain_renders_at_the_shutter_samples() {
    let scene = street(&["motion_blur"]);
    let effects = effects_of(&scene).unwrap();
    let cam = camera(&scene);
    let samples = time_samples(&scene, T).unwrap();
    assert!(samples.len() > 1, "the street's cars move, so blur samples");
    let weights: Vec<f32> = samples.iter().map(|s| s.1).collect();

    let opts = NativeOptions::default();
    let plain: Vec<Frame> = samples
        .iter()
        .map(|&(t, _)| native::render(&scene.composite(t), &cam, &opts).unwrap().0)
        .collect();
    let want = blend_frames(&plain, &weights).unwrap();
    let mut r = Renderer::native(opts).unwrap();
    let req = FrameRequest {
        scene: Some(&scene),
        effects: &effects,
        camera: &cam,
        time: T,
        content: Default::default(),
        lidar: None,
    };
    let got = render_frame(&mut r, &req).unwrap();
    assert_eq!(got.time_samples, samples.len());
    assert!(same_bits(&got.frame, &want));

    let mut tracer =
        GaussianTracer::for_scene(&scene, T, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let plain: Vec<Frame> = samples
        .iter()
        .map(|&(t, _)| {
            tracer.set_time(t);
            tracer.render(&cam, &TraceOptions::default()).unwrap().0
        })
        .collect();
    let want = blend_frames(&plain, &weights).unwrap();
    let mut r = Renderer::Gaussian {
        tracer,
        options: TraceOptions::default(),
    };
    let got = render_frame(&mut r, &req).unwrap();
    assert!(same_bits(&got.frame, &want));
    assert_eq!(got.counters.extra_time_samples, samples.len() as u64 - 1);
}

#[test]
fn shadows_and_lidar_run_in_the_tracers_only_and_are_counted() {
    let scene = street(&["shadows", "lidar"]);
    let effects = effects_of(&scene).unwrap();
    let cam = camera(&scene);
    let dir = tempfile::tempdir().unwrap();
    let tracer =
        GaussianTracer::for_scene(&scene, T, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let plain = tracer.render(&cam, &TraceOptions::default()).unwrap().0;
    let mut r = Renderer::Gaussian {
        tracer,
        options: TraceOptions::default(),
    };
    let req = FrameRequest {
        scene: Some(&scene),
        effects: &effects,
        camera: &cam,
        time: T,
        content: Default::default(),
        lidar: Some(LidarRequest {
            dir: dir.path().to_path_buf(),
            all_frames: false,
            backend: BackendKind::Obvhs,
            preset: BuildPreset::Medium,
            shard: None,
        }),
    };
    let got = render_frame(&mut r, &req).unwrap();
    let c = &got.counters;
    assert!(c.shadow_rays > 0 && c.lidar_rays > 0, "{c:?}");
    assert_eq!(c.simulated, ["shadows", "lidar"]);
    assert!(c.not_simulated.is_empty());
    // Shadows darken some pixel of the street and never brighten one.
    assert!(got.frame.rgb.iter().zip(&plain.rgb).all(|(s, p)| s <= p));
    assert!(got.frame.rgb.iter().zip(&plain.rgb).any(|(s, p)| s < p));
    let run = got.lidar.expect("a LiDAR run");
    assert_eq!(run.files.len(), 1);
    assert!(run.files[0].exists());
    let FrameStats::Trace(st) = &got.stats else {
        panic!("tracer stats expected");
    };
    assert_eq!(st.rays, u64::from(cam.width) * u64::from(cam.height));

    // Native splatting draws the frame without them and says so.
    let mut r = Renderer::native(NativeOptions::default()).unwrap();
    let req = FrameRequest { lidar: None, ..req };
    let got = render_frame(&mut r, &req).unwrap();
    assert_eq!(got.counters.shadow_rays + got.counters.lidar_rays, 0);
    assert_eq!(got.counters.not_simulated, ["shadows", "lidar"]);
    let want = native::render(&scene.composite(T), &cam, &NativeOptions::default())
        .unwrap()
        .0;
    assert!(same_bits(&got.frame, &want));
}
