#![no_main]
//! Fuzz target: hooke's obj reader (see `hooke_fuzz::obj`).
libfuzzer_sys::fuzz_target!(|data: &[u8]| hooke_fuzz::obj(data));
