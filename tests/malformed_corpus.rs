//! The malformed-input corpus: every case of `fixtures/malformed_corpus/cases.tsv` (files made
//! by `fixtures/malformed_corpus/generate.py`, plus the PLY suite of `fixtures/malformed/`) and
//! the cases generated here (FIFOs, devices, large or deep inputs that are not committed) run
//! the CLI under a 4 GiB address-space limit and a 20 s timeout, and must end with exit status
//! 2, a first line `error: FILE: …` or `error: … '--option …': …` holding the expected
//! fragment, no panic, and no file left in the output folder.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The goal's limits: a 4 GiB address space (`ulimit -v` in KiB) and 20 s per run.
const ADDRESS_SPACE_KIB: u64 = 4 << 20;
const TIMEOUT: Duration = Duration::from_secs(20);

struct Outcome {
    code: Option<i32>,
    stderr: String,
    timed_out: bool,
}

fn run(args: &[String]) -> Outcome {
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {ADDRESS_SPACE_KIB} && exec \"$0\" \"$@\""
        ))
        .arg(env!("CARGO_BIN_EXE_splatbridge"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn sh");
    let mut err = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let start = Instant::now();
    let (code, timed_out) = loop {
        if let Some(st) = child.try_wait().expect("wait") {
            break (st.code(), false);
        }
        if start.elapsed() > TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            break (None, true);
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Outcome {
        code,
        stderr: reader.join().unwrap_or_default(),
        timed_out,
    }
}

fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(files_under(&p));
        }
        out.push(p);
    }
    out
}

/// Run one case; the error string describes every way it failed (empty when it passed).
fn check(name: &str, args: &[String], out: &Path, fragment: &str, names: &str) -> String {
    let o = run(args);
    let mut why = Vec::new();
    if o.timed_out {
        why.push(format!("did not finish in {TIMEOUT:?}"));
    }
    if o.code != Some(2) {
        why.push(format!("exit status {:?}, expected 2", o.code));
    }
    let first = o.stderr.lines().next().unwrap_or("");
    if !first.starts_with("error: ") || !first.contains(names) {
        why.push(format!(
            "first line does not start 'error: ' naming '{names}'"
        ));
    }
    if names_file_twice(first) {
        why.push("the message names the file twice".into());
    }
    if !o.stderr.contains(fragment) {
        why.push(format!("message lacks '{fragment}'"));
    }
    if o.stderr.contains("panicked") || o.stderr.contains("RUST_BACKTRACE") {
        why.push("panicked".into());
    }
    if o.stderr.len() > 4096 {
        why.push(format!("message is {} bytes long", o.stderr.len()));
    }
    let left = files_under(out);
    if !left.is_empty() {
        why.push(format!("left {left:?}"));
    }
    if why.is_empty() {
        String::new()
    } else {
        let shown: String = o.stderr.chars().take(600).collect();
        format!("{name}: {}\n  stderr: {shown}", why.join("; "))
    }
}

/// Whether `error: A: B: …` repeats the file: B is A, or A's file name (`meta.json: meta.json:`).
fn names_file_twice(first: &str) -> bool {
    let Some(rest) = first.strip_prefix("error: ") else {
        return false;
    };
    let parts: Vec<&str> = rest.splitn(3, ": ").collect();
    let [a, b, ..] = parts[..] else {
        return false;
    };
    a == b || Path::new(a).file_name().is_some_and(|n| n == b)
}

#[test]
fn a_repeated_file_name_is_seen() {
    assert!(names_file_twice(
        "error: d/meta.json: meta.json: count is missing"
    ));
    assert!(names_file_twice("error: a.ply: a.ply: x"));
    assert!(!names_file_twice(
        "error: a.sog: meta.json: count is missing"
    ));
    assert!(!names_file_twice("error: d/meta.json: count is missing"));
}

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

#[test]
fn every_committed_malformed_case_fails_cleanly() {
    let fx = fixtures();
    let table = std::fs::read_to_string(fx.join("malformed_corpus/cases.tsv")).unwrap();
    let mut failures = Vec::new();
    let mut n = 0;
    for line in table
        .lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
    {
        let cols: Vec<&str> = line.split('\t').collect();
        assert_eq!(cols.len(), 4, "bad cases.tsv line: {line}");
        let (name, command, code, fragment) = (cols[0], cols[1], cols[2], cols[3]);
        assert_eq!(code, "2", "{name}: every corpus case expects exit status 2");
        let out = tempfile::tempdir().unwrap();
        let args: Vec<String> = command
            .split_whitespace()
            .map(|a| {
                a.replace("{fx}", fx.to_str().unwrap())
                    .replace("{out}", out.path().to_str().unwrap())
            })
            .collect();
        // The message names the input file, or the option for a command-line value.
        let names = if name.starts_with("cli_") && !name.ends_with("mesh_glb") {
            "'--".to_string()
        } else {
            name.trim_start_matches("ply_").to_string()
        };
        let names = if name.starts_with("cameras_") {
            name.to_string()
        } else {
            names
        };
        let names = if name == "cli_convert_mesh_glb" {
            "mesh.glb".into()
        } else {
            names
        };
        let f = check(name, &args, out.path(), fragment, &names);
        if !f.is_empty() {
            failures.push(f);
        }
        n += 1;
    }
    eprintln!("{n} corpus cases");
    assert!(n >= 100, "the corpus has {n} cases, fewer than 100");
    // At least 8 cases per splat format (the glTF splat prefix also counts its SPZ variant's
    // cases, which have their own 8) and 6 for the PLY layouts beside 3DGS.
    for prefix in [
        "spz_", "splat_", "cply_", "sog_", "khr_", "khr_spz_", "ksplat_", "plyv_",
    ] {
        let k = table.lines().filter(|l| l.starts_with(prefix)).count();
        let least = if prefix == "plyv_" { 6 } else { 8 };
        assert!(k >= least, "{k} cases for {prefix}*, fewer than {least}");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The valid base files the splat-format cases are mutated from load, so each case fails
/// for its own defect and not because the base is broken.
#[test]
fn the_corpus_base_files_load() {
    let dir = fixtures().join("malformed_corpus/files");
    for f in [
        "sog_ok.sog",
        "khr_ok.glb",
        "khr_spz_ok.glb",
        "ksplat_ok.ksplat",
        "ksplat_ok_l1.ksplat",
    ] {
        let o = run(&["info".to_string(), s(&dir.join(f))]);
        assert_eq!(o.code, Some(0), "{f}: {}", o.stderr);
    }
}

fn ok_ply() -> PathBuf {
    fixtures().join("malformed_corpus/files/ok.ply")
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// `trace INPUT --width 8 --height 8 -o PNG`.
fn trace_8x8(input: String, png: String) -> Vec<String> {
    ["trace", &input, "--width", "8", "--height", "8", "-o", &png]
        .map(String::from)
        .to_vec()
}

#[cfg(unix)]
fn mkfifo(p: &Path) {
    let st = Command::new("mkfifo").arg(p).status().expect("mkfifo");
    assert!(st.success());
}

#[cfg(unix)]
#[test]
fn fifos_and_devices_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let fifo_ply = dir.path().join("f.ply");
    mkfifo(&fifo_ply);
    let fifo_json = dir.path().join("cams.json");
    mkfifo(&fifo_json);
    let fifo_bin = dir.path().join("buf.bin");
    mkfifo(&fifo_bin);
    let gltf = dir.path().join("fifo_buffer.gltf");
    std::fs::write(
        &gltf,
        r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":44,"uri":"buf.bin"}]}"#,
    )
    .unwrap();
    let zero_gltf = dir.path().join("zero_buffer.gltf");
    std::fs::write(
        &zero_gltf,
        r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":44,"uri":"file:///dev/zero"}]}"#,
    )
    .unwrap();
    let o = s(out.path());
    let cases: Vec<(&str, Vec<String>, &str, String)> = vec![
        (
            "fifo_ply",
            vec!["info".into(), s(&fifo_ply)],
            "not a regular file",
            "f.ply".into(),
        ),
        (
            "dev_zero",
            vec!["info".into(), "/dev/zero".into()],
            "not a regular file",
            "/dev/zero".into(),
        ),
        (
            "directory",
            vec!["info".into(), s(dir.path())],
            "not a regular file",
            s(dir.path()),
        ),
        (
            "fifo_cameras",
            vec![
                "render".into(),
                s(&ok_ply()),
                "--camera".into(),
                format!("{}:0", s(&fifo_json)),
                "-o".into(),
                format!("{o}/r.png"),
            ],
            "not a regular file",
            "cams.json".into(),
        ),
        (
            "fifo_gltf_buffer",
            trace_8x8(s(&gltf), format!("{o}/t.png")),
            "buffer 0: ",
            "fifo_buffer.gltf".into(),
        ),
        (
            "dev_zero_gltf_buffer",
            trace_8x8(s(&zero_gltf), format!("{o}/t.png")),
            "not a regular file",
            "zero_buffer.gltf".into(),
        ),
    ];
    let mut failures = Vec::new();
    for (name, args, fragment, names) in cases {
        let f = check(name, &args, out.path(), fragment, &names);
        if !f.is_empty() {
            failures.push(f);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// An OBJ whose `mtllib` is a FIFO loads without its materials instead of blocking.
#[cfg(unix)]
#[test]
fn an_obj_with_a_fifo_mtllib_does_not_block() {
    let dir = tempfile::tempdir().unwrap();
    mkfifo(&dir.path().join("m.mtl"));
    let obj = dir.path().join("a.obj");
    std::fs::write(&obj, "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let png = dir.path().join("t.png");
    let o = run(&trace_8x8(s(&obj), s(&png)));
    assert!(
        !o.timed_out && o.code == Some(0),
        "{:?} {}",
        o.code,
        o.stderr
    );
}

#[test]
fn a_huge_format_string_is_not_echoed_whole() {
    let dir = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let p = dir.path().join("long.json");
    // 50 MB, as in the report that found the echo; the message must stay short.
    let long = "x".repeat(50 << 20);
    std::fs::write(&p, format!(r#"{{"format": "{long}"}}"#)).unwrap();
    let f = check(
        "long_format",
        &["info".into(), s(&p)],
        out.path(),
        "bytes) (this reader understands",
        "long.json",
    );
    assert!(f.is_empty(), "{f}");
}

/// A 100 000-deep node chain is refused (depth limit) in linear time, not traced
/// quadratically or by a recursion that overflows the stack.
#[test]
fn a_deep_node_chain_is_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let n = 100_000;
    let mut nodes: Vec<String> = (0..n - 1)
        .map(|i| format!(r#"{{"children":[{}]}}"#, i + 1))
        .collect();
    nodes.push(r#"{"mesh":0}"#.into());
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}}],"bufferViews":[{{"buffer":0,"byteLength":36}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],"nodes":[{}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        nodes.join(",")
    );
    let p = dir.path().join("deep.gltf");
    std::fs::write(&p, json).unwrap();
    let args = trace_8x8(s(&p), format!("{}/t.png", s(out.path())));
    let f = check(
        "deep",
        &args,
        out.path(),
        "hierarchy deeper than 1024 levels",
        "deep.gltf",
    );
    assert!(f.is_empty(), "{f}");
}

/// Coordinates an f32 BVH cannot hold (a position of 1e26, log-scales of 45): mode gaussian
/// culls those Gaussians and traces the rest; mode mesh refuses the converted vertices with an
/// error naming the file. Neither panics, with or without `--drop-invalid`.
#[test]
fn extreme_coordinates_are_culled_or_refused_in_both_trace_modes() {
    let dir = tempfile::tempdir().unwrap();
    let names = [
        "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
        "rot_0", "rot_1", "rot_2", "rot_3",
    ];
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n".to_vec();
    for n in names {
        bytes.extend_from_slice(format!("property float {n}\n").as_bytes());
    }
    bytes.extend_from_slice(b"end_header\n");
    let rows: [[f32; 14]; 3] = [
        [0., 0., 5., 0.5, 0.5, 0.5, 2., -1., -1., -1., 1., 0., 0., 0.],
        [
            1e26, 0., 5., 0.5, 0.5, 0.5, 2., -1., -1., -1., 1., 0., 0., 0.,
        ],
        [0., 0., 5., 0.5, 0.5, 0.5, 2., 45., 45., 45., 1., 0., 0., 0.],
    ];
    for r in rows {
        for v in r {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    let p = dir.path().join("extreme.ply");
    std::fs::write(&p, bytes).unwrap();
    for drop in [false, true] {
        let out = tempfile::tempdir().unwrap();
        let png = out.path().join("t.png");
        let mut args: Vec<String> = vec![
            "trace".into(),
            s(&p),
            "--mode".into(),
            "gaussian".into(),
            "--width".into(),
            "8".into(),
            "--height".into(),
            "8".into(),
            "-o".into(),
            s(&png),
        ];
        if drop {
            args.push("--drop-invalid".into());
        }
        let o = run(&args);
        assert_eq!(o.code, Some(0), "gaussian mode, drop {drop}: {}", o.stderr);
        assert!(png.exists());
        args[3] = "mesh".into();
        let _ = std::fs::remove_file(&png);
        let f = check(
            "extreme_mesh",
            &args,
            out.path(),
            "not finite or beyond",
            "extreme.ply",
        );
        assert!(f.is_empty(), "mesh mode, drop {drop}: {f}");
    }
}

/// Twenty thousand copies of one triangle build in well under the timeout (they once made the
/// PLOC build quadratic).
#[test]
fn thousands_of_identical_triangles_trace_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::from("v -1 -1 0\nv 1 -1 0\nv 0 1 0\n");
    for _ in 0..20_000 {
        obj.push_str("f 1 2 3\n");
    }
    let p = dir.path().join("same.obj");
    std::fs::write(&p, obj).unwrap();
    let png = dir.path().join("t.png");
    let o = run(&trace_8x8(s(&p), s(&png)));
    assert!(
        !o.timed_out && o.code == Some(0),
        "{:?} {}",
        o.code,
        o.stderr
    );
}

/// A stdout that cannot be written is an error (`/dev/full`) or a quiet end (a closed pipe),
/// never a panic.
#[cfg(unix)]
#[test]
fn a_broken_stdout_is_not_a_panic() {
    let bin = env!("CARGO_BIN_EXE_splatbridge");
    let ply = s(&ok_ply());
    let full = Command::new("sh")
        .arg("-c")
        .arg(format!("\"{bin}\" info \"{ply}\" > /dev/full"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&full.stderr);
    assert_eq!(full.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: stdout: "), "{err}");
    let pipe = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "\"{bin}\" info \"{ply}\" | head -c1 >/dev/null; exit ${{PIPESTATUS:-0}}"
        ))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&pipe.stderr);
    assert!(!err.contains("panicked"), "{err}");
}
