// Build-time facts for the tests, shared by every crate's `build.rs` through `include!`, so a
// test whose data or tool is missing is reported as *ignored, with the reason*
// (`#[cfg_attr(not(real_data), ignore = "…")]`) instead of passing after an early return.
// libtest has no run-time "ignored" outcome, hence a build-time check:
//
// - `cfg(real_data)`: the shared real scenes exist (`shared/data/real` next to the workspace).
// - `cfg(gltf_tools)`: the glTF validator can run: its wrapper exists
//   (`shared/tools/gltf-validate.sh`) and `node` and `npm` are on PATH
//   (what `scripts/validate-exports.sh` needs).
// - `cfg(blender)`: `blender` is on PATH (what `scripts/blender-check.sh` needs).
// - `cfg(blender_render)`: `blender` and `xvfb-run` are on PATH, so `scripts/blender-render.sh`
//   can render with both engines (EEVEE needs the virtual display).
// - `cfg(web_clients)`: the browser viewer check can run: Debian's `chromium` and the npm
//   packages of `scripts/package.json` in `$SPLATBRIDGE_WEB_DIR` (default
//   `~/.cache/splatbridge-web`), as `scripts/setup.sh` installs them.
//
// A test behind one of these fails, not skips, when the tool is there but cannot do its job.
//
// When a folder is present it is watched, so removing it re-runs the script; a folder that
// appears later is picked up on the next change to the script (or `cargo clean -p CRATE`).

/// Whether an executable named `name` is in one of PATH's folders.
fn on_path(name: &str) -> bool {
    let executable = |p: &std::path::Path| {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        }
        #[cfg(not(unix))]
        {
            p.is_file()
        }
    };
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| executable(&d.join(name))))
}

/// Emit `cfg(real_data)`, `cfg(gltf_tools)`, `cfg(blender)`, `cfg(blender_render)` and
/// `cfg(web_clients)` for a crate whose workspace root is `workspace` relative to its manifest
/// folder (`.` for the root crate, `..` for a member); `shared/` sits beside the workspace.
fn emit_shared_cfgs(workspace: &str) {
    println!("cargo::rustc-check-cfg=cfg(real_data)");
    println!("cargo::rustc-check-cfg=cfg(gltf_tools)");
    println!("cargo::rustc-check-cfg=cfg(blender)");
    println!("cargo::rustc-check-cfg=cfg(blender_render)");
    // Tools found on PATH are looked up again when PATH changes.
    println!("cargo::rerun-if-env-changed=PATH");
    println!("cargo::rustc-check-cfg=cfg(web_clients)");
    println!("cargo::rerun-if-env-changed=SPLATBRIDGE_WEB_DIR");
    println!("cargo::rerun-if-changed=build.rs");
    // Read when the script runs, not baked in when it is compiled: a build script compiled in
    // one checkout and reused from a copied target folder must look beside its own checkout.
    let manifest = std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default();
    let workspace = std::path::Path::new(&manifest).join(workspace);
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
    let web = std::env::var_os("SPLATBRIDGE_WEB_DIR")
        .map(std::path::PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME").map(|h| std::path::Path::new(&h).join(".cache/splatbridge-web"))
        });
    if let Some(web) = web {
        let modules = web.join("node_modules");
        let chromium = std::path::Path::new("/usr/bin/chromium");
        let packages = [
            "three",
            "@babylonjs/core",
            "@babylonjs/loaders",
            "puppeteer-core",
            "cesium",
            "3d-tiles-renderer",
            "@sparkjsdev/spark",
        ];
        let installed = |p: &&str| modules.join(p).join("package.json").is_file();
        if chromium.is_file() && packages.iter().all(installed) {
            println!("cargo::rustc-cfg=web_clients");
            println!("cargo::rerun-if-changed={}", web.join("package.json").display());
        }
    }
    let tools = root.join("shared/tools/gltf-validate.sh");
    if tools.is_file() {
        println!("cargo::rerun-if-changed={}", tools.display());
        if on_path("node") && on_path("npm") {
            println!("cargo::rustc-cfg=gltf_tools");
        }
    }
    if on_path("blender") {
        println!("cargo::rustc-cfg=blender");
    }
    if on_path("blender") && on_path("xvfb-run") {
        println!("cargo::rustc-cfg=blender_render");
    }
}
