#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    splatbridge_fuzz::run("spacetime_ply", data);
});
