#![no_main]
//! Fuzz target: hooke's ply reader (see `hooke_fuzz::ply`).
libfuzzer_sys::fuzz_target!(|data: &[u8]| hooke_fuzz::ply(data));
