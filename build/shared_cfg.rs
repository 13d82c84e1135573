// Build-time facts for the tests, shared by every crate's `build.rs` through `include!`, so a
// test whose data or tool is missing is reported as *ignored, with the reason*
// (`#[cfg_attr(not(real_data), ignore = "…")]`) instead of passing after an early return.
// libtest has no run-time "ignored" outcome, hence a build-time check:
//
// - `cfg(real_data)`: the shared real scenes exist (`shared/data/real` next to the workspace).
// - `cfg(gltf_tools)`: the glTF validator wrapper exists (`shared/tools/gltf-validate.sh`).
// - `cfg(blender_render)`: `blender` and `xvfb-run` are on PATH, so `scripts/blender-render.sh`
//   can render with both engines (EEVEE needs the virtual display).
//
// When a folder is present it is watched, so removing it re-runs the script; a folder that
// appears later is picked up on the next change to the script (or `cargo clean -p CRATE`).

/// Emit `cfg(real_data)` and `cfg(gltf_tools)` for a crate whose workspace root is
/// `workspace` relative to its manifest folder (`.` for the root crate, `..` for a member);
/// `shared/` sits beside the workspace.
fn emit_shared_cfgs(workspace: &str) {
    println!("cargo::rustc-check-cfg=cfg(real_data)");
    println!("cargo::rustc-check-cfg=cfg(gltf_tools)");
    println!("cargo::rustc-check-cfg=cfg(blender_render)");
    println!("cargo::rerun-if-changed=build.rs");
    let workspace = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(workspace);
    println!(
        "cargo::rerun-if-changed={}",
        workspace.join("build/shared_cfg.rs").display()
    );
    let root = workspace.join("..");
    let real = root.join("shared/data/real");
    if real.is_dir() {
        println!("cargo::rustc-cfg=real_data");
        println!("cargo::rerun-if-changed={}", real.display());
    }
    let tools = root.join("shared/tools/gltf-validate.sh");
    if tools.is_file() {
        println!("cargo::rustc-cfg=gltf_tools");
        println!("cargo::rerun-if-changed={}", tools.display());
    }
    println!("cargo::rerun-if-env-changed=PATH");
    if on_path("blender") && on_path("xvfb-run") {
        println!("cargo::rustc-cfg=blender_render");
    }
}

/// Whether an executable file `name` is in one of PATH's folders.
#[allow(dead_code)]
fn on_path(name: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|paths| {
        std::env::split_paths(&paths).any(|dir| {
            let p = dir.join(name);
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                std::fs::metadata(&p)
                    .is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
            }
            #[cfg(not(unix))]
            {
                p.is_file()
            }
        })
    })
}
