#![no_main]
//! Fuzz target: hooke's scene reader (see `hooke_fuzz::scene`).
libfuzzer_sys::fuzz_target!(|data: &[u8]| hooke_fuzz::scene(data));
