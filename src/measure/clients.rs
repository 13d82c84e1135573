//! Viewer clients in the comparison: what a person sees when they open an export in three.js,
//! Babylon.js, three.js's own Gaussian splats, Spark, Blender EEVEE or Cycles, measured against
//! native splatting.
//!
//! Every client runs as a process through `scripts/client-render.sh CLIENT FILE OUT.png
//! --camera N --size WxH [--cameras CAMS.glb]` (the contract shared with the Blender scripts):
//! it renders the N-th glTF camera (of FILE, or of CAMS.glb for a file without cameras, `.spz`)
//! on black without tone mapping and writes a display-referred sRGB PNG. Exit status 3 means
//! the client is not installed; its reason is recorded and the client reported as skipped,
//! never as a failure of the comparison.
//!
//! The files are exported once per comparison with the comparison's cameras embedded
//! (`ConvertOptions` and `scene.cameras`), so every client opens on exactly the views native
//! splatting rendered: the mesh GLB in the arrangement for viewers
//! ([`ConvertOptions::for_viewers`]); for the splat renderers the `--splats` GLB
//! (`KHR_gaussian_splatting`) and an `.spz` (default version, RUB axes) of the same Gaussians,
//! whose cameras are the GLB's.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::Context;
use splatbridge_convert::ConvertOptions;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::spz;
use splatbridge_scene::{Camera, Frame};

/// A viewer that `client-render.sh` drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Client {
    Three,
    Babylon,
    /// three.js's `GaussianSplat` (`WebGPURenderer`) at its default sRGB output.
    ThreeSplats,
    /// The same with a linear output colour space: the fix for its loaders' colour handling.
    ThreeSplatsLinear,
    /// Spark 2.2 at its defaults.
    Spark,
    /// Spark with native 3DGS numerics (low-pass, σ cut, α threshold, depth sort).
    SparkNative,
    Eevee,
    Cycles,
}

/// Every client, in the order `--clients` lists them in messages.
const ALL: [Client; 8] = [
    Client::Three,
    Client::Babylon,
    Client::ThreeSplats,
    Client::ThreeSplatsLinear,
    Client::Spark,
    Client::SparkNative,
    Client::Eevee,
    Client::Cycles,
];

impl Client {
    pub fn name(self) -> &'static str {
        match self {
            Client::Three => "three",
            Client::Babylon => "babylon",
            Client::ThreeSplats => "three-splats",
            Client::ThreeSplatsLinear => "three-splats-linear",
            Client::Spark => "spark",
            Client::SparkNative => "spark-native",
            Client::Eevee => "eevee",
            Client::Cycles => "cycles",
        }
    }

    /// Parse `three,babylon,…`.
    pub fn parse_list(s: &str) -> Result<Vec<Client>, String> {
        s.split(',')
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(|t| {
                ALL.into_iter().find(|c| c.name() == t).ok_or_else(|| {
                    let names: Vec<_> = ALL.iter().map(|c| c.name()).collect();
                    format!("unknown client '{t}' (expected {})", names.join(", "))
                })
            })
            .collect()
    }

    /// The exports this client is measured on (`mesh`, `splats` or `spz`: [`FileKind`]).
    fn files(self) -> &'static [FileKind] {
        match self {
            Client::Babylon => &[FileKind::Splats, FileKind::Mesh],
            Client::ThreeSplats | Client::ThreeSplatsLinear => &[FileKind::Splats, FileKind::Spz],
            Client::Spark | Client::SparkNative => &[FileKind::Spz],
            Client::Three | Client::Eevee | Client::Cycles => &[FileKind::Mesh],
        }
    }
}

/// An export the clients open.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// The mesh GLB arranged for viewers.
    Mesh,
    /// The `--splats` GLB (`KHR_gaussian_splatting`), with the cameras.
    Splats,
    /// An `.spz` of the Gaussians; its cameras are the `Splats` GLB's.
    Spz,
}

impl FileKind {
    pub fn name(self) -> &'static str {
        match self {
            FileKind::Mesh => "mesh",
            FileKind::Splats => "splats",
            FileKind::Spz => "spz",
        }
    }

    /// The file's format (its extension).
    pub fn format(self) -> &'static str {
        match self {
            FileKind::Spz => "spz",
            _ => "glb",
        }
    }
}

/// The dispatcher script shipped in the repository.
pub fn default_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/client-render.sh")
}

/// What one client run gave.
pub enum Outcome {
    Image(Frame),
    /// Exit status 3: the client is not installed (its message).
    Unavailable(String),
}

/// Render `file` in `client` through camera `index` (of `cameras` when given: a glTF holding
/// the cameras of a file that has none) at `width`×`height` into `out`.
#[allow(clippy::too_many_arguments)]
pub fn render(
    script: &Path,
    client: Client,
    file: &Path,
    cameras: Option<&Path>,
    out: &Path,
    index: usize,
    width: u32,
    height: u32,
) -> anyhow::Result<Outcome> {
    let mut cmd = Command::new(script);
    cmd.arg(client.name())
        .arg(file)
        .arg(out)
        .args(["--camera", &index.to_string()])
        .args(["--size", &format!("{width}x{height}")]);
    if let Some(c) = cameras {
        cmd.arg("--cameras").arg(c);
    }
    let res = cmd
        .output()
        .with_context(|| format!("{}: cannot run", script.display()))?;
    let msg = String::from_utf8_lossy(&res.stderr).trim().to_string();
    match res.status.code() {
        Some(0) => {
            let frame = splatbridge_scene::image_io::load_png(out)
                .with_context(|| format!("{} wrote an unreadable image", client.name()))?;
            if (frame.width, frame.height) != (width, height) {
                anyhow::bail!(
                    "{}: {}×{} image, asked for {width}×{height}",
                    client.name(),
                    frame.width,
                    frame.height
                );
            }
            Ok(Outcome::Image(frame))
        }
        Some(3) => Ok(Outcome::Unavailable(msg)),
        _ => anyhow::bail!("{} failed on {}: {msg}", client.name(), file.display()),
    }
}

/// The files every client needs, exported once with `cams` embedded.
pub struct ClientFiles {
    /// (kind, path, bytes) of each export the clients asked for (`splats` too when `spz` is
    /// asked: it holds the cameras).
    pub files: Vec<(FileKind, PathBuf, u64)>,
}

impl ClientFiles {
    fn get(&self, kind: FileKind) -> Option<&(FileKind, PathBuf, u64)> {
        self.files.iter().find(|(k, _, _)| *k == kind)
    }
}

/// Export the viewer GLBs for `clients` into `dir` with `cams` as the files' cameras.
pub fn export(
    scene: &DynamicScene,
    cams: &[Camera],
    clients: &[Client],
    dir: &Path,
) -> anyhow::Result<ClientFiles> {
    let mut with_cams = scene.clone();
    with_cams.cameras = cams.to_vec();
    let mut kinds: Vec<FileKind> = Vec::new();
    for &kind in clients.iter().flat_map(|c| c.files()) {
        // The `.spz` has no cameras: the splats GLB carries them (written first).
        let need: &[FileKind] = if kind == FileKind::Spz {
            &[FileKind::Splats, FileKind::Spz]
        } else {
            std::slice::from_ref(&kind)
        };
        for &k in need {
            if !kinds.contains(&k) {
                kinds.push(k);
            }
        }
    }
    let mut files = Vec::new();
    for kind in kinds {
        let path = dir.join(format!("client_{}.{}", kind.name(), kind.format()));
        let bytes = match kind {
            FileKind::Splats => {
                splatbridge_convert::splats_gltf::write_file_with(
                    &path,
                    &with_cams,
                    &ConvertOptions::default(),
                    splatbridge_convert::splats_gltf::KhrCompression::None,
                )?
                .bytes
            }
            FileKind::Mesh => {
                let opts = ConvertOptions {
                    coplanar_offset: true,
                    ..ConvertOptions::default()
                }
                .for_viewers();
                splatbridge_convert::convert_to_file(&path, &with_cams, None, &opts, false)?.bytes
            }
            FileKind::Spz => {
                // The Gaussians at the scene's start, as the splats GLB's first frame.
                let cloud = scene.composite(scene.time.start);
                spz::write_spz(&path, &cloud, &spz::SpzOptions::default())?;
                std::fs::metadata(&path)
                    .with_context(|| format!("{}: cannot read back", path.display()))?
                    .len()
            }
        };
        files.push((kind, path, bytes));
    }
    Ok(ClientFiles { files })
}

/// One client measurement: a frame, or the reason the client was skipped.
pub struct ClientResult {
    pub client: Client,
    pub kind: FileKind,
    pub bytes: u64,
    pub ms: f64,
    pub outcome: Outcome,
}

/// Render camera `index` (of the exported files) in every client.
pub fn render_all(
    script: &Path,
    clients: &[Client],
    files: &ClientFiles,
    dir: &Path,
    index: usize,
    cam: &Camera,
    progress: &dyn Fn(&str),
) -> anyhow::Result<Vec<ClientResult>> {
    let mut out = Vec::new();
    for &c in clients {
        for &kind in c.files() {
            let Some((_, path, bytes)) = files.get(kind) else {
                continue;
            };
            let cameras = match kind {
                FileKind::Spz => files.get(FileKind::Splats).map(|(_, p, _)| p.as_path()),
                _ => None,
            };
            let kn = kind.name();
            progress(&format!("{} {kn} camera {index}", c.name()));
            let png = dir.join(format!("client_{}_{kn}_c{index}.raw.png", c.name()));
            let t0 = Instant::now();
            let outcome = render(script, c, path, cameras, &png, index, cam.width, cam.height)?;
            out.push(ClientResult {
                client: c,
                kind,
                bytes: *bytes,
                ms: t0.elapsed().as_secs_f64() * 1e3,
                outcome,
            });
            let _ = std::fs::remove_file(&png);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_client_parses_by_its_name() {
        let names: Vec<_> = ALL.iter().map(|c| c.name()).collect();
        assert_eq!(Client::parse_list(&names.join(",")).unwrap(), ALL.to_vec());
        let err = Client::parse_list("three,sparks").unwrap_err();
        assert!(
            err.contains("'sparks'") && err.contains("spark-native"),
            "{err}"
        );
    }

    /// An `.spz` has no cameras: asking for it exports the splats GLB (the cameras) too, and
    /// the `.spz` holds the same Gaussians.
    #[test]
    fn spz_exports_bring_the_cameras_glb() {
        let street = splatbridge_scene::fixtures::street(3);
        let cams = street.cameras[..2].to_vec();
        let scene = DynamicScene::from_static(street.composite(0.0));
        let dir = tempfile::tempdir().unwrap();
        let files = export(&scene, &cams, &[Client::Spark], dir.path()).unwrap();
        let kinds: Vec<_> = files.files.iter().map(|(k, _, _)| *k).collect();
        assert_eq!(kinds, [FileKind::Splats, FileKind::Spz]);
        for (kind, path, bytes) in &files.files {
            assert_eq!(std::fs::metadata(path).unwrap().len(), *bytes, "{kind:?}");
            assert_eq!(
                path.extension().unwrap().to_str().unwrap(),
                kind.format(),
                "{kind:?}"
            );
        }
        let (back, _) = spz::read_spz(&files.files[1].1).unwrap();
        assert_eq!(back.len(), scene.static_gaussians.len());
        // Babylon.js and three.js share the splats GLB: it is written once.
        let files = export(
            &scene,
            &cams,
            &[Client::Babylon, Client::ThreeSplats, Client::SparkNative],
            dir.path(),
        )
        .unwrap();
        let kinds: Vec<_> = files.files.iter().map(|(k, _, _)| *k).collect();
        assert_eq!(kinds, [FileKind::Splats, FileKind::Mesh, FileKind::Spz]);
    }
}
