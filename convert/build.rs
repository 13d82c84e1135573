//! Build-time facts for the tests: see `build/shared_cfg.rs` at the workspace root.

include!("../build/shared_cfg.rs");

fn main() {
    emit_shared_cfgs("..");
}
