//! Build-time facts for the tests, so a test whose data or tool is missing is reported as
//! *ignored, with the reason* (`#[cfg_attr(not(real_data), ignore = "…")]`) instead of passing
//! after an early return. libtest has no run-time "ignored" outcome, hence a build-time check:
//!
//! - `cfg(real_data)`: the shared real scenes exist (`shared/data/real` next to the workspace).
//! - `cfg(gltf_tools)`, `cfg(blender)`: the glTF validator or Blender can run (see
//!   `build/shared_cfg.rs`).
//! - `cfg(host_avx2)`, `cfg(host_sse41)`: the CPU has the instructions a SIMD test compares.
//!
//! When a folder is present it is watched, so removing it re-runs this script; a folder that
//! appears later is picked up on the next change to this file (or `cargo clean -p CRATE`).

include!("../build/shared_cfg.rs");

fn main() {
    emit_shared_cfgs("..");
    println!("cargo::rustc-check-cfg=cfg(host_avx2)");
    println!("cargo::rustc-check-cfg=cfg(host_sse41)");
    // The SIMD tests compare each kernel with the portable code on the machine that runs them;
    // tests run where they are built, so the build host's CPU decides (only when not
    // cross-compiling).
    #[cfg(target_arch = "x86_64")]
    if std::env::var("HOST").ok() == std::env::var("TARGET").ok() {
        if std::arch::is_x86_feature_detected!("avx2") {
            println!("cargo::rustc-cfg=host_avx2");
        }
        if std::arch::is_x86_feature_detected!("sse4.1") {
            println!("cargo::rustc-cfg=host_sse41");
        }
    }
}
