//! cargo-fuzz target `rig_retarget` (see `fuzz/targets/mod.rs` and `docs/RELIABILITY.md`).
#![no_main]

#[path = "../targets/mod.rs"]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::rig_retarget(data));
