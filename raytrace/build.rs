//! With the `embree` feature: tell the linker where `libembree4.so` is (the folder that
//! `scripts/get-embree.sh` fills, or `SPLATBRIDGE_EMBREE_DIR`) and embed an rpath to it, so
//! this crate's test binaries run without `LD_LIBRARY_PATH`. Without the feature: nothing.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-env-changed=SPLATBRIDGE_EMBREE_DIR");
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var_os("CARGO_FEATURE_EMBREE").is_none() {
        return;
    }
    let dir = match std::env::var_os("SPLATBRIDGE_EMBREE_DIR") {
        Some(d) => PathBuf::from(d),
        None => {
            let manifest = PathBuf::from(
                std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"),
            );
            manifest
                .join("..")
                .join(".tools")
                .join("embree")
                .join("lib")
        }
    };
    let dir = dir.canonicalize().unwrap_or(dir);
    if !dir.join("libembree4.so").exists() {
        println!(
            "cargo:warning=libembree4.so not found in {} (run scripts/get-embree.sh or set SPLATBRIDGE_EMBREE_DIR)",
            dir.display()
        );
    }
    println!("cargo:rustc-link-search=native={}", dir.display());
    // The rpath reaches this package's own test binaries (`rustc-link-arg` does not propagate
    // to dependents): the root CLI built with `--features embree` needs LD_LIBRARY_PATH,
    // which scripts/get-embree.sh prints.
    println!("cargo:rustc-link-arg=-Wl,-rpath,{}", dir.display());
}
