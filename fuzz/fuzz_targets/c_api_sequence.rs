//! cargo-fuzz target `c_api_sequence` (see `fuzz/targets/mod.rs` and `docs/RELIABILITY.md`).
#![no_main]

#[path = "../targets/mod.rs"]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| targets::c_api_sequence(data));
