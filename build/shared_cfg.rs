// Build-time facts for the tests, shared by every crate's `build.rs` through `include!`, so a
// test whose data or tool is missing is reported as *ignored, with the reason*
// (`#[cfg_attr(not(real_data), ignore = "…")]`) instead of passing after an early return.
// libtest has no run-time "ignored" outcome, hence a build-time check:
//
// - `cfg(real_data)`: the shared real scenes exist (`shared/data/real` next to the workspace).
// - `cfg(gltf_tools)`: the glTF validator wrapper exists (`shared/tools/gltf-validate.sh`).
// - `cfg(web_clients)`: the browser viewer check can run: Debian's `chromium` and the npm
//   packages of `scripts/package.json` in `$SPLATBRIDGE_WEB_DIR` (default
//   `~/.cache/splatbridge-web`), as `scripts/setup.sh` installs them.
//
// When a folder is present it is watched, so removing it re-runs the script; a folder that
// appears later is picked up on the next change to the script (or `cargo clean -p CRATE`).

/// Emit `cfg(real_data)` and `cfg(gltf_tools)` for a crate whose workspace root is
/// `workspace` relative to its manifest folder (`.` for the root crate, `..` for a member);
/// `shared/` sits beside the workspace.
fn emit_shared_cfgs(workspace: &str) {
    println!("cargo::rustc-check-cfg=cfg(real_data)");
    println!("cargo::rustc-check-cfg=cfg(gltf_tools)");
    println!("cargo::rustc-check-cfg=cfg(web_clients)");
    println!("cargo::rerun-if-env-changed=SPLATBRIDGE_WEB_DIR");
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
    let web = std::env::var_os("SPLATBRIDGE_WEB_DIR")
        .map(std::path::PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| std::path::Path::new(&h).join(".cache/splatbridge-web")));
    if let Some(web) = web {
        let modules = web.join("node_modules");
        let chromium = std::path::Path::new("/usr/bin/chromium");
        let packages = ["three", "@babylonjs/core", "@babylonjs/loaders", "puppeteer-core"];
        if chromium.is_file() && packages.iter().all(|p| modules.join(p).join("package.json").is_file()) {
            println!("cargo::rustc-cfg=web_clients");
            println!("cargo::rerun-if-changed={}", web.join("package.json").display());
        }
    }
    let tools = root.join("shared/tools/gltf-validate.sh");
    if tools.is_file() {
        println!("cargo::rustc-cfg=gltf_tools");
        println!("cargo::rerun-if-changed={}", tools.display());
    }
}
