//! The frame an OBJ export was written in.
//!
//! glTF keeps the converter's axis convention in one root node (`splatbridge_root`, a rotation
//! taking the capture's up axis onto glTF's +Y), so a tracer can undo it
//! (`TriScene::to_capture_frame`). OBJ has no nodes: the converter bakes that rotation into
//! the vertices and records its options in a header comment (`# {"generator": "splatbridge
//! …", "options": {"up": "-y", …}, …}`). Reading the header back lets the loader give an OBJ
//! the same shape as a GLB: vertices un-rotated into the capture frame under a
//! `splatbridge_root` node carrying the written rotation, so the file's own frame (what a
//! viewer shows) and the capture frame (where cameras and native renders live) are one node
//! apart, as in glTF.

use glam::DQuat;

/// How far into an OBJ the header comment may reach (the converter writes two short lines and
/// the metadata line, whose size grows with the number of meshes).
pub const HEADER_SCAN: usize = 1 << 20;

/// The root rotation of a splatbridge OBJ: the rotation that was baked into its vertices,
/// read from the metadata comment at the top of the file. `None` for a file without one
/// (another writer's OBJ, or an up axis this reader does not know): it is taken as written.
pub fn written_root(bytes: &[u8]) -> Option<DQuat> {
    let head = &bytes[..bytes.len().min(HEADER_SCAN)];
    for line in head.split(|&b| b == b'\n') {
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        let Some(comment) = line.strip_prefix(b"#") else {
            if line.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            // The header is the comment block before the first statement.
            return None;
        };
        let text = comment.trim_ascii_start();
        if !text.starts_with(b"{") {
            continue;
        }
        let Ok(meta) = serde_json::from_slice::<serde_json::Value>(text) else {
            continue;
        };
        let ours = meta["generator"]
            .as_str()
            .is_some_and(|g| g.starts_with("splatbridge"));
        if !ours {
            continue;
        }
        return meta["options"]["up"].as_str().and_then(up_rotation);
    }
    None
}

/// The converter's root rotation for an input up axis (`UpAxis::root_rotation` in the convert
/// crate, which this crate does not depend on; a test in the workspace's root crate checks the
/// two agree).
pub fn up_rotation(up: &str) -> Option<DQuat> {
    match up {
        "y" => Some(DQuat::IDENTITY),
        "z" => Some(DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2)),
        "-y" => Some(DQuat::from_xyzw(1.0, 0.0, 0.0, 0.0)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_up_axis_from_a_splatbridge_header() {
        let obj = b"# splatbridge mesh export at t = 0 s.\n# {\"generator\": \"splatbridge 0.1.0\", \"options\": {\"up\": \"z\"}}\nmtllib a.mtl\nv 0 0 0\n";
        let q = written_root(obj).unwrap();
        assert!(q.abs_diff_eq(DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2), 0.0));
        let neg_y = b"#{\"generator\":\"splatbridge 9\",\"options\":{\"up\":\"-y\"}}\r\nv 1 2 3\n";
        assert_eq!(
            written_root(neg_y),
            Some(DQuat::from_xyzw(1.0, 0.0, 0.0, 0.0))
        );
    }

    #[test]
    fn a_splatbridge_obj_loads_in_the_written_frame_under_its_root() {
        // Written with up -y: the capture's (1, 2, 3) was baked to (1, −2, −3).
        let obj = "# splatbridge mesh export\n# {\"generator\": \"splatbridge 0.1.0\", \"options\": {\"up\": \"-y\"}}\n\
                   v 1 -2 -3\nv 2 -2 -3\nv 1 -1 -3\nf 1 2 3\n";
        let mut s =
            crate::scene_load::load_obj_bytes(obj.as_bytes(), std::path::Path::new("a.obj"))
                .unwrap();
        let written = glam::DVec3::new(1.0, -2.0, -3.0);
        // As a viewer shows it: the file's own coordinates.
        assert!(s.sample_points(0.0, 1)[0].abs_diff_eq(written, 1e-12));
        assert!(s.to_capture_frame());
        let capture = glam::DVec3::new(1.0, 2.0, 3.0);
        assert!(s.sample_points(0.0, 1)[0].abs_diff_eq(capture, 1e-12));
    }

    #[test]
    fn other_files_are_taken_as_written() {
        // Another generator, metadata after the first statement, an unknown axis, bad JSON.
        for obj in [
            &b"# {\"generator\": \"blender\", \"options\": {\"up\": \"-y\"}}\nv 0 0 0\n"[..],
            b"v 0 0 0\n# {\"generator\": \"splatbridge\", \"options\": {\"up\": \"-y\"}}\n",
            b"# {\"generator\": \"splatbridge\", \"options\": {\"up\": \"x\"}}\n",
            b"# {\"generator\": \"splatbridge\", \"options\": {\"up\": \n",
            b"",
        ] {
            assert_eq!(written_root(obj), None, "{}", String::from_utf8_lossy(obj));
        }
    }
}
