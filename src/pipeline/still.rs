//! A scene file rendered by native splatting or the hybrid (`render`, `hybrid`): the scene
//! loaded with its declared effects, the camera resolved once (orbit rigs frame the first
//! composite, without particles, so every frame shares it), then one frame written, or every
//! frame of the scene's time range as one atomic sequence (`render --frames`).

use std::path::Path;

use anyhow::{bail, Context};
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::{EffectCounters, Effects};
use splatbridge_scene::effects_run::effects_of;
use splatbridge_scene::image_io::save_frame;
use splatbridge_scene::Camera;

use super::sequence::{render_sequence, SequenceFrame, SequenceRequest, SequenceRun};
use super::source::load_scene_kind;
use super::{render_frame, FrameRequest, RenderedFrame, Renderer};
use crate::batch::shard::Shard;
use splatbridge_scene::ply::GaussianKind;

/// Refuse an output image that is neither `.png` nor `.exr` (any case).
pub fn check_image_output(out: &Path) -> anyhow::Result<()> {
    let ext = out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if ext != "png" && ext != "exr" {
        bail!("{}: output must end in .png or .exr", out.display());
    }
    Ok(())
}

/// A loaded scene with its effects, camera and frame times.
pub struct Still {
    /// The input's name in errors and reports.
    pub name: String,
    pub scene: DynamicScene,
    pub effects: Effects,
    pub camera: Camera,
    /// `time` (default: the scene's start), or every frame time with `frames`.
    pub times: Vec<f64>,
    /// What the file's Gaussians are (2DGS surfels are drawn by the 2DGS renderer unless
    /// asked otherwise); 3D Gaussians for manifests.
    pub kind: GaussianKind,
}

impl Still {
    /// Load `path` (warnings to `warn`) and resolve `camera` on the composite at the first
    /// time.
    pub fn load(
        path: &Path,
        drop_invalid: bool,
        warn: &dyn Fn(&str),
        camera: &dyn Fn() -> anyhow::Result<CameraRequest>,
        time: Option<f64>,
        frames: bool,
    ) -> anyhow::Result<Still> {
        let name = path.display().to_string();
        let (scene, kind) = load_scene_kind(path, drop_invalid, warn)?;
        let effects = effects_of(&scene).with_context(|| name.clone())?;
        let times = if frames {
            scene.frame_times()
        } else {
            vec![time.unwrap_or(scene.time.start)]
        };
        let resolve = || -> anyhow::Result<Camera> {
            // A generated camera (orbit, view) is framed on the scene at its start, so stills
            // of one scene at several times share one camera and show the motion.
            let cloud = scene.composite_view(scene.time.start);
            let src = CameraSource {
                cloud: &cloud,
                own: &scene.cameras,
            };
            Ok(camera()?.resolve(src)?)
        };
        let camera = resolve().with_context(|| name.clone())?;
        Ok(Still {
            name,
            scene,
            effects,
            camera,
            times,
            kind,
        })
    }

    /// Render the frame at the first time through `r` and write it to `out` (checked by the
    /// caller with [`check_image_output`] before loading).
    pub fn render_one(&self, r: &mut Renderer, out: &Path) -> anyhow::Result<RenderedFrame> {
        let req = FrameRequest {
            scene: Some(&self.scene),
            effects: &self.effects,
            camera: &self.camera,
            time: self.times[0],
            content: EffectCounters::default(),
            lidar: None,
        };
        let rendered = render_frame(r, &req).with_context(|| self.name.clone())?;
        save_frame(out, &rendered.frame)?;
        Ok(rendered)
    }

    /// Render every frame of the scene's time range through `r` as one atomic set named after
    /// `out` (`command` and `canonical` name the run for a shard's partial report).
    pub fn render_frames(
        &self,
        r: &mut Renderer,
        out: &Path,
        command: &str,
        shard: Option<Shard>,
        canonical: String,
        on_frame: &mut dyn FnMut(&SequenceFrame) -> anyhow::Result<()>,
    ) -> anyhow::Result<SequenceRun> {
        let req = SequenceRequest {
            command,
            scene: &self.scene,
            effects: &self.effects,
            camera: &self.camera,
            out,
            content: EffectCounters::default(),
            lidar: None,
            shard,
            canonical,
        };
        render_sequence(r, &req, &mut |_, _| Ok(None), on_frame).with_context(|| self.name.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_must_be_png_or_exr() {
        assert!(check_image_output(Path::new("a/b.PNG")).is_ok());
        assert!(check_image_output(Path::new("b.exr")).is_ok());
        assert!(check_image_output(Path::new("b.jpg")).is_err());
        assert!(check_image_output(Path::new("b")).is_err());
    }
}
