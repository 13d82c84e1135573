//! The `splatbridge-scene/1` JSON manifest and scene loading (PLY or manifest).
//!
//! ```json
//! {"format": "splatbridge-scene/1",
//!  "time": {"start": 0.0, "end": 4.0, "fps": 10},
//!  "static": "background.ply",
//!  "objects": [{"name": "car_0", "gaussians": "car.ply",
//!               "track": [{"t": 0.0, "translation": [0,0,0], "rotation": [1,0,0,0]}]}],
//!  "cameras": "cameras.json",
//!  "effects": {}}
//! ```
//! Paths are relative to the manifest's directory. Rotations are w, x, y, z like the PLY (any
//! non-zero length; normalised on load). `static`, `objects`, `cameras` and `effects` are
//! optional, as is `frames`: per-frame content (`[{"t": 0.0, "gaussians": "frames/0000.ply"}]`,
//! times strictly increasing, each shown until the next one's time). An object gives either
//! an explicit `track` or a generated `trajectory` rule
//! ([`crate::trajectory::TrajectoryRule`], sampled at the scene's frame rate). Training-free
//! edits: an object with `"remove": true` is left out (its file is not needed), and
//! `"retime": {"offset": s, "scale": k}` replays its motion k times as fast, s seconds later
//! ([`crate::trajectory::Retime`]). Unknown keys are errors at every level, so a misspelt key
//! is reported instead of silently ignored.
//!
//! Every error names the manifest (or the file it refers to) and the field: `objects[1]
//! ('car_1'): track[2].t = 1 is not after track[1].t = 2`.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::camera::{cameras_json_text, load_cameras_json};
use crate::dynamic::{
    quat_from_wxyz, quat_wxyz, DynamicScene, PoseKey, SceneObject, TimeRange, Track,
};
use crate::error::{Result, SceneError};
use crate::ply::{stage_ply, PlyFormat, ReadOptions};
use crate::trajectory::{Retime, TrajectoryRule};
use crate::GaussianCloud;

/// The format string this reader and writer understand.
pub const FORMAT: &str = "splatbridge-scene/1";

/// Effect names a manifest may declare (their parameters: [`crate::effects`]).
pub const KNOWN_EFFECTS: [&str; 4] = ["weather", "motion_blur", "shadows", "lidar"];

/// The manifest as written on disk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: String,
    pub time: TimeJson,
    /// Static Gaussians (a 3DGS PLY), relative to the manifest.
    #[serde(rename = "static", default, skip_serializing_if = "Option::is_none")]
    pub static_gaussians: Option<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub objects: Vec<ObjectJson>,
    /// Per-frame content (what moves without a rigid track), each shown from its time until
    /// the next one's ([`crate::dynamic::FrameContent`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<FrameJson>,
    /// A 3DGS `cameras.json`, relative to the manifest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cameras: Option<String>,
    #[serde(default)]
    pub effects: serde_json::Map<String, Value>,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeJson {
    pub start: f64,
    pub end: f64,
    pub fps: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectJson {
    pub name: String,
    /// The object's Gaussians in its local frame (a 3DGS PLY), relative to the manifest.
    pub gaussians: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub track: Option<Vec<KeyJson>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trajectory: Option<TrajectoryRule>,
    /// Leave the object out of the scene (training-free removal). Its file is neither required
    /// nor read, and it needs no track.
    #[serde(default, skip_serializing_if = "is_false")]
    pub remove: bool,
    /// Replay the object's motion faster/slower and later/earlier ([`Retime`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retime: Option<Retime>,
}

/// One frame of per-frame content: its time and its Gaussians (a 3DGS PLY, world frame).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameJson {
    pub t: f64,
    pub gaussians: String,
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// One pose key. f32 values: JSON numbers beyond f32 range become infinite and are rejected as
/// non-finite.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyJson {
    pub t: f64,
    pub translation: [f32; 3],
    /// w, x, y, z.
    pub rotation: [f32; 4],
}

fn bad(path: &Path, what: impl Into<String>) -> SceneError {
    SceneError::format(path, what)
}

/// Load anything accepted where a scene is expected: any splat file [`crate::formats`]
/// recognises by content (3DGS or compressed PLY, `.splat`, SPZ, SOG, glTF/GLB) or a
/// `splatbridge-scene/1` manifest. Warnings are returned for the caller to print; those from
/// files a manifest refers to start with that file's name. [`crate::formats::load`] also says
/// which format was read.
pub fn load_scene(path: &Path, opts: &ReadOptions) -> Result<(DynamicScene, Vec<String>)> {
    let (scene, info) = crate::formats::load(path, opts)?;
    Ok((scene, info.warnings))
}

/// Parse and validate a manifest's text (no files are touched). `path` names it in errors.
pub fn parse_manifest(path: &Path, text: &str) -> Result<Manifest> {
    let value: Value =
        serde_json::from_str(text).map_err(|e| bad(path, format!("not valid JSON: {e}")))?;
    let obj = value
        .as_object()
        .ok_or_else(|| bad(path, "a scene manifest is a JSON object"))?;
    match obj.get("format") {
        None => {
            return Err(bad(
                path,
                format!(
                    "no \"format\" key (a scene manifest starts with \"format\": \"{FORMAT}\")"
                ),
            ))
        }
        Some(Value::String(f)) if f == FORMAT => {}
        Some(f) => {
            return Err(bad(
                path,
                format!(
                    "unknown format {} (this reader understands \"{FORMAT}\")",
                    crate::input::clip(&f.to_string())
                ),
            ))
        }
    }
    if let Some(Value::Object(effects)) = obj.get("effects") {
        check_effect_names(path, effects)?;
    }
    let m: Manifest = serde_json::from_str(text)
        .map_err(|e| bad(path, crate::input::clip_to(&e.to_string(), 400)))?;
    validate_manifest(path, &m)?;
    Ok(m)
}

fn check_effect_names(path: &Path, effects: &serde_json::Map<String, Value>) -> Result<()> {
    for (name, v) in effects {
        if !KNOWN_EFFECTS.contains(&name.as_str()) {
            return Err(bad(
                path,
                format!(
                    "effects: unknown effect \"{}\" (known: {})",
                    crate::input::clip(name),
                    KNOWN_EFFECTS.join(", ")
                ),
            ));
        }
        if !v.is_object() {
            return Err(bad(
                path,
                format!(
                    "effects.{}: expected an object of parameters, found {}",
                    crate::input::clip(name),
                    crate::input::clip(&v.to_string())
                ),
            ));
        }
    }
    Ok(())
}

/// Largest magnitude of a time (scene time range, key times, retimed key times), in seconds:
/// one day. glTF stores animation times as f32, whose spacing at 86 400 is 1/128 s, still
/// finer than a 100 fps frame; a time of 1e300 would become infinite there.
pub const MAX_TIME_SECONDS: f64 = 86_400.0;

fn check_times(path: &Path, what: &str, times: impl IntoIterator<Item = f64>) -> Result<()> {
    for t in times {
        if !(t.abs() <= MAX_TIME_SECONDS) {
            return Err(bad(
                path,
                format!("{what}: time {t:e} is outside ±{MAX_TIME_SECONDS} s"),
            ));
        }
    }
    Ok(())
}

fn validate_manifest(path: &Path, m: &Manifest) -> Result<()> {
    let time = TimeRange {
        start: m.time.start,
        end: m.time.end,
        fps: m.time.fps,
    };
    time.validate().map_err(|e| bad(path, e))?;
    check_times(path, "time", [time.start, time.end])?;
    check_effect_names(path, &m.effects)?;
    crate::effects::Effects::from_json(&m.effects).map_err(|e| bad(path, e))?;
    check_times(path, "frames", m.frames.iter().map(|f| f.t))?;
    for (k, f) in m.frames.iter().enumerate() {
        if f.gaussians.trim().is_empty() {
            return Err(bad(path, format!("frames[{k}].gaussians is empty")));
        }
        if k > 0 && f.t <= m.frames[k - 1].t {
            return Err(bad(
                path,
                format!(
                    "frames[{k}].t = {} is not after frames[{}].t = {} (times must increase strictly)",
                    f.t,
                    k - 1,
                    m.frames[k - 1].t
                ),
            ));
        }
    }
    for (k, o) in m.objects.iter().enumerate() {
        let at = format!("objects[{k}] ('{}')", crate::input::clip(&o.name));
        if o.name.trim().is_empty() {
            return Err(bad(path, format!("objects[{k}].name is empty")));
        }
        if let Some(j) = m.objects[..k].iter().position(|p| p.name == o.name) {
            return Err(bad(
                path,
                format!("{at}: name already used by objects[{j}]"),
            ));
        }
        if o.gaussians.trim().is_empty() {
            return Err(bad(path, format!("{at}.gaussians is empty")));
        }
        if let Some(r) = &o.retime {
            r.check().map_err(|e| bad(path, format!("{at}: {e}")))?;
        }
        if o.remove {
            if o.retime.is_some() {
                return Err(bad(
                    path,
                    format!("{at}: \"remove\": true and \"retime\" contradict each other"),
                ));
            }
            if o.track.is_some() && o.trajectory.is_some() {
                return Err(bad(
                    path,
                    format!("{at}: give either \"track\" or \"trajectory\", not both"),
                ));
            }
            continue;
        }
        let track = match (&o.track, &o.trajectory) {
            (Some(_), Some(_)) => {
                return Err(bad(
                    path,
                    format!("{at}: give either \"track\" or \"trajectory\", not both"),
                ))
            }
            (None, None) => {
                return Err(bad(
                    path,
                    format!("{at}: no \"track\" (or \"trajectory\") given"),
                ))
            }
            (Some(keys), None) => {
                let tr = track_from_json(keys);
                tr.validate().map_err(|e| bad(path, format!("{at}: {e}")))?;
                tr
            }
            (None, Some(rule)) => rule
                .track(time.start, time.end, time.fps)
                .and_then(|tr| {
                    tr.validate()
                        .map_err(crate::trajectory::TrajectoryError)
                        .map(|_| tr)
                })
                .map_err(|e| bad(path, format!("{at}: {e}")))?,
        };
        check_times(path, &format!("{at}.track"), track.keys.iter().map(|k| k.t))?;
        if let Some(r) = &o.retime {
            let re = r
                .apply(&track, time.start)
                .map_err(|e| bad(path, format!("{at}: {e}")))?;
            check_times(path, &format!("{at}.retime"), re.keys.iter().map(|k| k.t))?;
        }
    }
    Ok(())
}

fn track_from_json(keys: &[KeyJson]) -> Track {
    // Rotations are kept raw here so validation can see a zero quaternion; normalised after.
    Track::new(
        keys.iter()
            .map(|k| PoseKey {
                t: k.t,
                pose: crate::dynamic::Pose {
                    translation: k.translation.into(),
                    rotation: quat_from_wxyz(k.rotation),
                },
            })
            .collect(),
    )
}

/// Load a `splatbridge-scene/1` manifest: validate it, check every referenced file exists (all
/// missing ones are named together), then read the PLYs and cameras.
pub fn load_manifest(path: &Path, opts: &ReadOptions) -> Result<(DynamicScene, Vec<String>)> {
    let text = crate::input::read_text_bounded(path, crate::input::Cap::Text)?;
    let m = parse_manifest(path, &text)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let resolve = |p: &str| dir.join(p);

    let mut refs: Vec<(String, &str)> = Vec::new();
    if let Some(s) = &m.static_gaussians {
        refs.push(("static".into(), s));
    }
    for (k, o) in m.objects.iter().enumerate().filter(|(_, o)| !o.remove) {
        refs.push((
            format!("objects[{k}] ('{}').gaussians", o.name),
            &o.gaussians,
        ));
    }
    for (k, f) in m.frames.iter().enumerate() {
        refs.push((format!("frames[{k}].gaussians"), &f.gaussians));
    }
    if let Some(c) = &m.cameras {
        refs.push(("cameras".into(), c));
    }
    let missing: Vec<String> = refs
        .iter()
        .filter(|(_, p)| !resolve(p).is_file())
        .map(|(field, p)| format!("{field} \"{p}\" ({})", resolve(p).display()))
        .collect();
    if !missing.is_empty() {
        return Err(bad(path, format!("missing files: {}", missing.join("; "))));
    }

    let mut warnings = Vec::new();
    let mut read = |field: &str, rel: &str| -> Result<GaussianCloud> {
        let (cloud, info) = crate::formats::load_cloud(&resolve(rel), opts)
            .map_err(|e| bad(path, format!("{field}: {e}")))?;
        warnings.extend(info.warnings.into_iter().map(|w| format!("{rel}: {w}")));
        Ok(cloud)
    };
    let static_gaussians = match &m.static_gaussians {
        Some(s) => read("static", s)?,
        None => GaussianCloud::new(0),
    };
    let time = TimeRange {
        start: m.time.start,
        end: m.time.end,
        fps: m.time.fps,
    };
    let mut objects = Vec::with_capacity(m.objects.len());
    for (k, o) in m.objects.iter().enumerate().filter(|(_, o)| !o.remove) {
        let field = format!("objects[{k}] ('{}').gaussians", o.name);
        let gaussians = read(&field, &o.gaussians)?;
        let mut track = match (&o.track, &o.trajectory) {
            (Some(keys), _) => track_from_json(keys),
            (None, Some(rule)) => rule
                .track(time.start, time.end, time.fps)
                .map_err(|e| bad(path, format!("objects[{k}] ('{}'): {e}", o.name)))?,
            (None, None) => unreachable!("validated: every object has a track or a trajectory"),
        };
        for key in &mut track.keys {
            key.pose.rotation = crate::dynamic::normalize_or_identity(key.pose.rotation);
        }
        if let Some(r) = &o.retime {
            track = r
                .apply(&track, time.start)
                .map_err(|e| bad(path, format!("objects[{k}] ('{}'): {e}", o.name)))?;
        }
        objects.push(SceneObject {
            name: o.name.clone(),
            gaussians,
            track,
        });
    }
    let mut frames = Vec::with_capacity(m.frames.len());
    for (k, f) in m.frames.iter().enumerate() {
        frames.push(crate::dynamic::FrameContent {
            t: f.t,
            gaussians: read(&format!("frames[{k}].gaussians"), &f.gaussians)?,
        });
    }
    let cameras = match &m.cameras {
        Some(c) => {
            load_cameras_json(&resolve(c)).map_err(|e| bad(path, format!("cameras: {e}")))?
        }
        None => Vec::new(),
    };
    let scene = DynamicScene {
        time,
        static_gaussians,
        objects,
        frames,
        cameras,
        effects: m.effects,
        four_d: None,
    };
    scene.validate().map_err(|e| bad(path, e.to_string()))?;
    Ok((scene, warnings))
}

/// What [`save_manifest`] wrote.
#[derive(Clone, Debug)]
pub struct SavedScene {
    /// The manifest, `DIR/scene.json`.
    pub manifest: PathBuf,
    /// Every file written, the manifest last.
    pub files: Vec<PathBuf>,
}

/// A file name for an object: its name with anything but ASCII letters, digits, `-` and `_`
/// replaced by `_`.
fn file_stem_for(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "object".into()
    } else {
        s
    }
}

/// The manifest describing `scene` with the given file names (no files written).
pub fn manifest_for(
    scene: &DynamicScene,
    static_file: Option<&str>,
    object_files: &[String],
    frame_files: &[String],
    cameras_file: Option<&str>,
) -> Manifest {
    Manifest {
        format: FORMAT.into(),
        time: TimeJson {
            start: scene.time.start,
            end: scene.time.end,
            fps: scene.time.fps,
        },
        static_gaussians: static_file.map(str::to_string),
        objects: scene
            .objects
            .iter()
            .zip(object_files)
            .map(|(o, f)| ObjectJson {
                name: o.name.clone(),
                gaussians: f.clone(),
                track: Some(
                    o.track
                        .keys
                        .iter()
                        .map(|k| KeyJson {
                            t: k.t,
                            translation: k.pose.translation.to_array(),
                            rotation: quat_wxyz(k.pose.rotation),
                        })
                        .collect(),
                ),
                trajectory: None,
                remove: false,
                retime: None,
            })
            .collect(),
        frames: scene
            .frames
            .iter()
            .zip(frame_files)
            .map(|(f, name)| FrameJson {
                t: f.t,
                gaussians: name.clone(),
            })
            .collect(),
        cameras: cameras_file.map(str::to_string),
        effects: scene.effects.clone(),
    }
}

/// Write `scene` into `dir` (created if needed): `static.ply` (when there are static
/// Gaussians), one `NAME.ply` per object (binary little-endian), `frames/NNNN.ply` per frame
/// of per-frame content, `cameras.json` (when the
/// scene has cameras) and the manifest `scene.json`, each atomically. Tracks are written as
/// explicit keys. The scene (effects included) is validated first; nothing is written when it
/// is invalid.
pub fn save_manifest(dir: &Path, scene: &DynamicScene) -> Result<SavedScene> {
    scene.validate()?;
    // The same effect checks as loading, so a written scene always loads back.
    let target = dir.join("scene.json");
    check_effect_names(&target, &scene.effects)?;
    crate::effects::Effects::from_json(&scene.effects).map_err(|e| bad(&target, e))?;
    std::fs::create_dir_all(dir).map_err(|e| SceneError::io(dir, e))?;
    // The manifest and every file it names appear together or not at all.
    let mut set = crate::output::OutputSet::new();
    let mut files = Vec::new();
    let static_file = if scene.static_gaussians.is_empty() {
        None
    } else {
        let p = dir.join("static.ply");
        stage_ply(
            &mut set,
            &p,
            &scene.static_gaussians,
            PlyFormat::BinaryLittleEndian,
        )?;
        files.push(p);
        Some("static.ply")
    };
    let mut used: Vec<String> = vec!["static".into(), "scene".into(), "cameras".into()];
    let mut object_files = Vec::new();
    for o in &scene.objects {
        let base = file_stem_for(&o.name);
        let mut stem = base.clone();
        let mut n = 1;
        while used.contains(&stem) {
            stem = format!("{base}_{n}");
            n += 1;
        }
        used.push(stem.clone());
        let name = format!("{stem}.ply");
        let p = dir.join(&name);
        stage_ply(&mut set, &p, &o.gaussians, PlyFormat::BinaryLittleEndian)?;
        files.push(p);
        object_files.push(name);
    }
    let mut frame_files = Vec::new();
    for (k, f) in scene.frames.iter().enumerate() {
        let name = format!("frames/{k:04}.ply");
        let p = dir.join(&name);
        if k == 0 {
            std::fs::create_dir_all(dir.join("frames"))
                .map_err(|e| SceneError::io(dir.join("frames"), e))?;
        }
        stage_ply(&mut set, &p, &f.gaussians, PlyFormat::BinaryLittleEndian)?;
        files.push(p);
        frame_files.push(name);
    }
    let cameras_file = if scene.cameras.is_empty() {
        None
    } else {
        let p = dir.join("cameras.json");
        set.write(&p, cameras_json_text(&scene.cameras)?.as_bytes())?;
        files.push(p);
        Some("cameras.json")
    };
    let m = manifest_for(
        scene,
        static_file,
        &object_files,
        &frame_files,
        cameras_file,
    );
    let manifest = dir.join("scene.json");
    let mut text =
        serde_json::to_string_pretty(&m).map_err(|e| SceneError::Invalid(e.to_string()))?;
    text.push('\n');
    set.write(&manifest, text.as_bytes())?;
    set.commit()?;
    files.push(manifest.clone());
    Ok(SavedScene { manifest, files })
}
