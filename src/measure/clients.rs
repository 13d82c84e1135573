//! Viewer clients in the comparison: what a person sees when they open an export in three.js,
//! Babylon.js, Blender EEVEE or Cycles, measured against native splatting.
//!
//! Every client runs as a process through `scripts/client-render.sh CLIENT FILE OUT.png
//! --camera N --size WxH` (the contract shared with the Blender scripts): it renders the
//! file's N-th glTF camera on black without tone mapping and writes a display-referred sRGB
//! PNG. Exit status 3 means the client is not installed; its reason is recorded and the
//! client reported as skipped, never as a failure of the comparison.
//!
//! The files are exported once per comparison with the comparison's cameras embedded
//! (`ConvertOptions` and `scene.cameras`), so every client opens on exactly the views native
//! splatting rendered: the mesh GLB in the arrangement for viewers
//! ([`ConvertOptions::for_viewers`]) and, for Babylon.js, the `--splats` GLB as well.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::Context;
use splatbridge_convert::ConvertOptions;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::{Camera, Frame};

/// A viewer that `client-render.sh` drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Client {
    Three,
    Babylon,
    Eevee,
    Cycles,
}

impl Client {
    pub fn name(self) -> &'static str {
        match self {
            Client::Three => "three",
            Client::Babylon => "babylon",
            Client::Eevee => "eevee",
            Client::Cycles => "cycles",
        }
    }

    /// Parse `three,babylon,…`.
    pub fn parse_list(s: &str) -> Result<Vec<Client>, String> {
        s.split(',')
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(|t| match t {
                "three" => Ok(Client::Three),
                "babylon" => Ok(Client::Babylon),
                "eevee" => Ok(Client::Eevee),
                "cycles" => Ok(Client::Cycles),
                _ => Err(format!(
                    "unknown client '{t}' (expected three, babylon, eevee, cycles)"
                )),
            })
            .collect()
    }

    /// The exports this client is measured on: (file kind, `--splats`).
    fn files(self) -> &'static [(&'static str, bool)] {
        match self {
            Client::Babylon => &[("splats", true), ("mesh", false)],
            _ => &[("mesh", false)],
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

/// Render `file` in `client` through camera `index` at `width`×`height` into `out`.
pub fn render(
    script: &Path,
    client: Client,
    file: &Path,
    out: &Path,
    index: usize,
    width: u32,
    height: u32,
) -> anyhow::Result<Outcome> {
    let res = Command::new(script)
        .arg(client.name())
        .arg(file)
        .arg(out)
        .args(["--camera", &index.to_string()])
        .args(["--size", &format!("{width}x{height}")])
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
    /// (kind, path, bytes): `mesh` and, when asked, `splats`.
    pub files: Vec<(&'static str, PathBuf, u64)>,
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
    let mut files = Vec::new();
    for &(kind, splats) in clients.iter().flat_map(|c| c.files()) {
        if files.iter().any(|(k, _, _)| *k == kind) {
            continue;
        }
        let path = dir.join(format!("client_{kind}.glb"));
        let report = if splats {
            splatbridge_convert::splats_gltf::write_file_with(
                &path,
                &with_cams,
                &ConvertOptions::default(),
                splatbridge_convert::splats_gltf::KhrCompression::None,
            )?
        } else {
            let opts = ConvertOptions {
                coplanar_offset: true,
                ..ConvertOptions::default()
            }
            .for_viewers();
            splatbridge_convert::convert_to_file(&path, &with_cams, None, &opts, false)?
        };
        files.push((kind, path, report.bytes));
    }
    Ok(ClientFiles { files })
}

/// One client measurement: a frame, or the reason the client was skipped.
pub struct ClientResult {
    pub client: Client,
    pub kind: &'static str,
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
        for &(kind, _) in c.files() {
            let Some((_, path, bytes)) = files.files.iter().find(|(k, _, _)| *k == kind) else {
                continue;
            };
            progress(&format!("{} {kind} camera {index}", c.name()));
            let png = dir.join(format!("client_{}_{kind}_c{index}.raw.png", c.name()));
            let t0 = Instant::now();
            let outcome = render(script, c, path, &png, index, cam.width, cam.height)?;
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
