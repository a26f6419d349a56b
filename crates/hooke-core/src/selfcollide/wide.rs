//! Self-collision's inner loops compiled for AVX2 where the processor has it.
//!
//! The crate is built for baseline x86-64: SSE2, 4 lanes, and no 32-bit integer multiply,
//! which the cell hash needs three of per point. A loop run through [`wide`] is compiled a
//! second time with AVX2 (8 lanes, `vpmulld`), and that copy runs when the processor has it.
//! The results are the same bits: AVX2 brings no fused multiply-add, and Rust never fuses a
//! multiply and an add by itself, so every float operation rounds as before.

/// Runs `run`, compiled with AVX2 where the processor has it. Whatever `run` calls is
/// compiled so only where it is inlined into it: the loops go in the closure, or in
/// functions marked `#[inline(always)]`.
#[inline(always)]
pub(super) fn wide<R>(run: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        #[target_feature(enable = "avx2")]
        fn with_avx2<R>(run: impl FnOnce() -> R) -> R {
            run()
        }
        // SAFETY: the processor has AVX2 (checked above).
        #[allow(unsafe_code)]
        return unsafe { with_avx2(run) };
    }
    run()
}
