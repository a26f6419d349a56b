//! The few 8-lane float operations the kernels need, portable and with AVX2.
//!
//! Kernels are written once, generic over [`Simd`], and instantiated for each implementation.
//! Every operation is exact IEEE arithmetic per lane (no approximate reciprocals; a fused
//! multiply-add rounds once in both, [`Simd::mul_add`]), so both implementations produce
//! bit-identical results. (A processor without FMA has no AVX2 either: there the portable
//! kernels round a multiply-add's product too, and its states differ from other machines' in
//! the last bits.)

use crate::layout::LANES;

/// One lane-block (8 vertices or springs) of one scalar quantity.
pub type Block = [f32; LANES];

/// A vector quantity as 16 bytes (x, y, z and a zero), so one load fetches all of it.
pub type Point = [f32; 4];

/// Where point `index` is stored. Each group of 8 points (a slice's, or a row of springs')
/// holds lanes `k` and `k + 4` side by side, in the order 0, 4, 1, 5, 2, 6, 3, 7: that is the
/// order in which AVX2's in-lane transposes leave them, so [`Simd::store_points`] stores each
/// register as it comes, without a cross-lane permute (4 of its 12 shuffles, on the one port
/// that takes them).
#[inline(always)]
pub const fn point_slot(index: u32) -> u32 {
    (index & !7) | ((index & 3) << 1) | ((index >> 2) & 1)
}

/// The point whose [`point_slot`] is `slot`.
pub const fn point_at_slot(slot: u32) -> u32 {
    (slot & !7) | ((slot >> 1) & 3) | ((slot & 1) << 2)
}

/// Bytes of a [`Point`]: a slot times this is its byte offset.
pub const POINT_BYTES: u32 = std::mem::size_of::<Point>() as u32;

/// The byte offset of point `entry & mask` (at its [`point_slot`]), what
/// [`Simd::gather_points_at`] reads.
#[inline(always)]
pub const fn point_offset(entry: u32, mask: u32) -> u32 {
    point_slot(entry & mask) * POINT_BYTES
}

/// 8-lane float operations. A value of the implementing type is proof the CPU can run them.
pub trait Simd: Copy {
    type V: Copy;
    fn splat(self, value: f32) -> Self::V;
    fn load(self, block: &Block) -> Self::V;
    fn store(self, value: Self::V, block: &mut Block);
    /// `values[index[lane] & mask]` per lane. A pointer, not a slice: the caller may let other
    /// threads write other floats of the same buffer meanwhile (see `crate::view`).
    ///
    /// # Safety
    /// Every masked index must be below the number of readable floats at `values`, and no
    /// thread may write the floats read during the call.
    unsafe fn gather(self, values: *const f32, index: &[u32; LANES], mask: u32) -> Self::V;
    /// Point `index[lane] & mask` (stored at its [`point_slot`]) per lane, as its x, y and z
    /// (the fourth word is ignored).
    ///
    /// # Safety
    /// As for [`Simd::gather`], in points.
    #[inline(always)]
    unsafe fn gather_points(
        self,
        points: *const Point,
        index: &[u32; LANES],
        mask: u32,
    ) -> [Self::V; 3] {
        let offsets = index.map(|entry| point_offset(entry, mask));
        // SAFETY: the caller guarantees every masked index is a point in bounds, and a slot
        // is in the same group of 8 as its index.
        unsafe { self.gather_points_at(points, &offsets, u32::MAX) }
    }
    /// The points at byte offsets `offsets[lane] & mask` from `points`, as x, y and z: slots
    /// already times 16 (see [`point_slot`]), which saves the arithmetic a lane.
    ///
    /// # Safety
    /// Every masked offset must be a multiple of 16 below the readable bytes at `points`, and
    /// no thread may write the points read during the call.
    #[inline(always)]
    unsafe fn gather_points_at(
        self,
        points: *const Point,
        offsets: &[u32; LANES],
        mask: u32,
    ) -> [Self::V; 3] {
        // SAFETY: the caller's guarantee.
        self.transpose_point_pairs(unsafe { self.point_pairs_at(points, offsets, mask) })
    }
    /// The points at byte offsets `offsets[lane] & mask` from `points`, as they lie, two to a
    /// value: value `k` holds lanes `k` and `k + 4` (x, y, z and w of each), the pairs
    /// [`point_slot`] stores side by side. Adding such values adds points.
    ///
    /// # Safety
    /// As for [`Simd::gather_points_at`].
    unsafe fn point_pairs_at(
        self,
        points: *const Point,
        offsets: &[u32; LANES],
        mask: u32,
    ) -> [Self::V; 4];
    /// The 8 points of a group stored in [`point_slot`] order from byte offset `offset` of
    /// `points`, two to a value as [`Simd::point_pairs_at`] gives them: four plain loads.
    ///
    /// # Safety
    /// The 128 bytes from `offset` must be in bounds and not written.
    unsafe fn point_pairs_run(self, points: *const Point, offset: u32) -> [Self::V; 4];
    /// x, y and z of the 8 points held two to a value (see [`Simd::point_pairs_at`]).
    fn transpose_point_pairs(self, pairs: [Self::V; 4]) -> [Self::V; 3];
    /// Per value of [`Simd::point_pairs_at`], -1 in the words of each point whose lane's
    /// `sign` word has its top bit set, else +1.
    fn pair_signs(self, sign: &[u32; LANES]) -> [Self::V; 4];
    /// `sum + value * sign` for `sign` of +1 or -1: the product is exact, so this is exactly
    /// `sum` plus `value` with its sign flipped there, rounded once (one fused multiply-add
    /// with AVX2).
    fn add_signed(self, sum: Self::V, value: Self::V, sign: Self::V) -> Self::V;
    /// Each point's fourth word in all four of its words, for two points loaded as a pair
    /// ([`Simd::point_pairs_at`]): a stretch's `k` beside its `d`.
    fn fourths(self, pairs: Self::V) -> Self::V;
    /// Stores lane `k` of `x`, `y` and `z` as point `k` of `out` (at its [`point_slot`]), its
    /// fourth word a copy of z (which nothing reads).
    fn store_points(self, value: [Self::V; 3], out: &mut [Point; LANES]);
    /// Stores 8 springs' stretches: lane `k`'s `d` as point `k`'s x, y and z, and its `k` as
    /// the point's fourth word (read back with [`Simd::fourths`]).
    fn store_stretches(self, d: [Self::V; 3], k: Self::V, out: &mut [Point; LANES]);
    /// Lane `k` of x, y and z from point `k` of `points` (at its [`point_slot`]): what
    /// [`Simd::store_points`] stored.
    fn load_points(self, points: &[Point; LANES]) -> [Self::V; 3];
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    fn div(self, a: Self::V, b: Self::V) -> Self::V;
    fn sqrt(self, a: Self::V) -> Self::V;
    /// `a * b + c`, rounded once where the processor has a fused multiply-add (always with
    /// AVX2), else the product and the sum each.
    fn mul_add(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `c - a * b`, rounded as [`Simd::mul_add`] rounds.
    fn neg_mul_add(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// Flips the sign of lanes whose `sign` word has its top bit set.
    fn flip_sign(self, a: Self::V, sign: &[u32; LANES]) -> Self::V;
    /// `if test > 0 { then } else { otherwise }` per lane.
    fn select_positive(self, test: Self::V, then: Self::V, otherwise: Self::V) -> Self::V;
}

/// Plain loops over arrays; any CPU. With `FUSED`, [`Simd::mul_add`] rounds once (for a
/// processor with FMA, whose kernels are compiled with it), else the product and the sum each.
#[derive(Clone, Copy, Debug)]
pub struct Portable<const FUSED: bool>;

fn map2(a: Block, b: Block, f: impl Fn(f32, f32) -> f32) -> Block {
    std::array::from_fn(|lane| f(a[lane], b[lane]))
}

/// Whether this processor has a fused multiply-add, so that the portable kernels can round
/// [`Simd::mul_add`] once, as AVX2 does, and stay fast (compiled with FMA; without it,
/// `f32::mul_add` is a library call per lane and the portable gather 6x slower).
#[cfg(target_arch = "x86_64")]
pub fn has_fma() -> bool {
    std::arch::is_x86_feature_detected!("fma")
}

/// Whether the portable kernels fuse multiply-adds on this architecture without asking the
/// processor: every ARM64 has a fused multiply-add.
#[cfg(not(target_arch = "x86_64"))]
pub const FUSED_ALWAYS: bool = cfg!(target_arch = "aarch64");

impl<const FUSED: bool> Simd for Portable<FUSED> {
    type V = Block;
    #[inline(always)]
    fn splat(self, value: f32) -> Block {
        [value; LANES]
    }
    #[inline(always)]
    fn load(self, block: &Block) -> Block {
        *block
    }
    #[inline(always)]
    fn store(self, value: Block, block: &mut Block) {
        *block = value;
    }
    #[inline(always)]
    unsafe fn gather(self, values: *const f32, index: &[u32; LANES], mask: u32) -> Block {
        // SAFETY: the caller guarantees every masked index is in bounds and not written.
        std::array::from_fn(|lane| unsafe { *values.add((index[lane] & mask) as usize) })
    }
    #[inline(always)]
    unsafe fn point_pairs_at(
        self,
        points: *const Point,
        offsets: &[u32; LANES],
        mask: u32,
    ) -> [Block; 4] {
        // SAFETY: the caller guarantees every masked offset is a point in bounds and not
        // written.
        let at =
            |lane: usize| unsafe { *points.add(((offsets[lane] & mask) / POINT_BYTES) as usize) };
        std::array::from_fn(|k| {
            let (low, high) = (at(k), at(k + 4));
            std::array::from_fn(|word| if word < 4 { low[word] } else { high[word - 4] })
        })
    }
    #[inline(always)]
    unsafe fn point_pairs_run(self, points: *const Point, offset: u32) -> [Block; 4] {
        // SAFETY: the caller's guarantee; 4 blocks are the 8 points' 128 bytes.
        unsafe {
            *points
                .cast::<u8>()
                .add(offset as usize)
                .cast::<[Block; 4]>()
        }
    }
    #[inline(always)]
    fn transpose_point_pairs(self, pairs: [Block; 4]) -> [Block; 3] {
        std::array::from_fn(|axis| {
            std::array::from_fn(|lane| pairs[lane % 4][4 * (lane / 4) + axis])
        })
    }
    #[inline(always)]
    fn pair_signs(self, sign: &[u32; LANES]) -> [Block; 4] {
        let of = |lane: usize| if sign[lane] >> 31 == 1 { -1.0 } else { 1.0 };
        std::array::from_fn(|k| std::array::from_fn(|word| of(k + 4 * (word / 4))))
    }
    #[inline(always)]
    fn add_signed(self, sum: Block, value: Block, sign: Block) -> Block {
        std::array::from_fn(|lane| sum[lane] + value[lane] * sign[lane])
    }
    #[inline(always)]
    fn fourths(self, pairs: Block) -> Block {
        std::array::from_fn(|word| pairs[4 * (word / 4) + 3])
    }
    #[inline(always)]
    fn store_points(self, [x, y, z]: [Block; 3], out: &mut [Point; LANES]) {
        self.store_stretches([x, y, z], z, out);
    }
    #[inline(always)]
    fn store_stretches(self, [x, y, z]: [Block; 3], k: Block, out: &mut [Point; LANES]) {
        for lane in 0..LANES {
            out[point_slot(lane as u32) as usize] = [x[lane], y[lane], z[lane], k[lane]];
        }
    }
    #[inline(always)]
    fn load_points(self, points: &[Point; LANES]) -> [Block; 3] {
        std::array::from_fn(|axis| {
            std::array::from_fn(|lane| points[point_slot(lane as u32) as usize][axis])
        })
    }
    #[inline(always)]
    fn add(self, a: Block, b: Block) -> Block {
        map2(a, b, |x, y| x + y)
    }
    #[inline(always)]
    fn sub(self, a: Block, b: Block) -> Block {
        map2(a, b, |x, y| x - y)
    }
    #[inline(always)]
    fn mul(self, a: Block, b: Block) -> Block {
        map2(a, b, |x, y| x * y)
    }
    #[inline(always)]
    fn div(self, a: Block, b: Block) -> Block {
        map2(a, b, |x, y| x / y)
    }
    #[inline(always)]
    fn sqrt(self, a: Block) -> Block {
        a.map(f32::sqrt)
    }
    #[inline(always)]
    fn mul_add(self, a: Block, b: Block, c: Block) -> Block {
        if FUSED {
            std::array::from_fn(|lane| a[lane].mul_add(b[lane], c[lane]))
        } else {
            std::array::from_fn(|lane| a[lane] * b[lane] + c[lane])
        }
    }
    #[inline(always)]
    fn neg_mul_add(self, a: Block, b: Block, c: Block) -> Block {
        self.mul_add(a.map(|a| -a), b, c)
    }
    #[inline(always)]
    fn flip_sign(self, a: Block, sign: &[u32; LANES]) -> Block {
        std::array::from_fn(|lane| f32::from_bits(a[lane].to_bits() ^ (sign[lane] & 0x8000_0000)))
    }
    #[inline(always)]
    fn select_positive(self, test: Block, then: Block, otherwise: Block) -> Block {
        std::array::from_fn(|lane| {
            if test[lane] > 0.0 {
                then[lane]
            } else {
                otherwise[lane]
            }
        })
    }
}

#[cfg(target_arch = "x86_64")]
pub use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;
    use std::sync::OnceLock;

    use super::{Block, LANES, Point, Simd};

    /// AVX2 intrinsics (and BMI1's `bextr`). Only [`Avx2::detect`] makes one, after checking
    /// the CPU.
    #[derive(Clone, Copy, Debug)]
    pub struct Avx2 {
        /// Gathers load their 8 lanes one by one instead of with `vgatherdps`.
        load_by_lane: bool,
    }

    impl Avx2 {
        /// AVX2 (with BMI1, which every AVX2 processor has) if the CPU has it. On AMD
        /// processors gathers load lane by lane: their `vgatherdps` is microcode, with which
        /// the irregular bench mesh's gather step took 0.88-0.91 ms on this project's AMD
        /// EPYC VM against 0.36-0.60 ms lane by lane. Other processors use the instruction
        /// (not measured against loads here).
        pub fn detect() -> Option<Self> {
            static LOAD_BY_LANE: OnceLock<bool> = OnceLock::new();
            let found = std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("bmi1")
                && std::arch::is_x86_feature_detected!("fma");
            found.then(|| Self {
                load_by_lane: *LOAD_BY_LANE.get_or_init(is_amd),
            })
        }

        /// How gathers load, for [`crate::kernels::InstructionSet::resolved_name`].
        pub fn gathers_by_lane(self) -> bool {
            self.load_by_lane
        }

        /// Either way of gathering, for tests on any CPU with AVX2.
        #[cfg(test)]
        pub fn with_gathers_by_lane(self, load_by_lane: bool) -> Self {
            Self { load_by_lane }
        }
    }

    /// Whether the CPU's vendor string is AMD's.
    fn is_amd() -> bool {
        // SAFETY: CPUID leaf 0 (vendor string) exists on every x86-64 processor. (Newer
        // toolchains declare `__cpuid` safe.)
        #[allow(unused_unsafe)]
        let leaf = unsafe { __cpuid(0) };
        let vendor = [leaf.ebx, leaf.edx, leaf.ecx].map(u32::to_le_bytes);
        vendor.as_flattened() == b"AuthenticAMD"
    }

    /// x, y and z of 8 points loaded two to a register (lanes k and k + 4, one 16-byte load
    /// each): a 4x4 transpose in each 128-bit half. With the loads, 8 loads and 11 shuffles
    /// where three gathers by lane take 24 loads and 21 inserts.
    ///
    /// # Safety
    /// AVX2 must be enabled.
    #[inline(always)]
    unsafe fn transpose_pairs([a0, a1, a2, a3]: [__m256; 4]) -> [__m256; 3] {
        // SAFETY: the caller's guarantee.
        unsafe {
            // Lanes (0, 4), (1, 5), (2, 6), (3, 7): each half transposes on its own.
            let xy01 = _mm256_unpacklo_ps(a0, a1);
            let zw01 = _mm256_unpackhi_ps(a0, a1);
            let xy23 = _mm256_unpacklo_ps(a2, a3);
            let zw23 = _mm256_unpackhi_ps(a2, a3);
            [
                _mm256_shuffle_ps::<0x44>(xy01, xy23),
                _mm256_shuffle_ps::<0xEE>(xy01, xy23),
                _mm256_shuffle_ps::<0x44>(zw01, zw23),
            ]
        }
    }

    // SAFETY (every `unsafe` block below): an `Avx2` value exists only if the CPU has AVX2, and
    // the kernels using these methods are compiled with AVX2 enabled (see `kernels::dispatch`),
    // so the intrinsics are supported and inline. Loads and stores go through references to
    // 8-float blocks, which are exactly 32 readable/writable bytes, or to 8 points, 128 bytes.
    impl Simd for Avx2 {
        type V = __m256;
        #[inline(always)]
        fn splat(self, value: f32) -> __m256 {
            unsafe { _mm256_set1_ps(value) }
        }
        #[inline(always)]
        fn load(self, block: &Block) -> __m256 {
            unsafe { _mm256_loadu_ps(block.as_ptr()) }
        }
        #[inline(always)]
        fn store(self, value: __m256, block: &mut Block) {
            unsafe { _mm256_storeu_ps(block.as_mut_ptr(), value) }
        }
        #[inline(always)]
        unsafe fn gather(self, values: *const f32, index: &[u32; LANES], mask: u32) -> __m256 {
            // SAFETY: the caller guarantees every masked index is in bounds; masked indices are
            // below 2^31, so they are valid i32 offsets.
            unsafe {
                if self.load_by_lane {
                    let at = |lane: usize| *values.add((index[lane] & mask) as usize);
                    return _mm256_setr_ps(at(0), at(1), at(2), at(3), at(4), at(5), at(6), at(7));
                }
                let index = _mm256_and_si256(
                    _mm256_loadu_si256(index.as_ptr().cast()),
                    _mm256_set1_epi32(mask as i32),
                );
                _mm256_i32gather_ps::<4>(values, index)
            }
        }
        #[inline(always)]
        unsafe fn point_pairs_at(
            self,
            points: *const Point,
            offsets: &[u32; LANES],
            mask: u32,
        ) -> [__m256; 4] {
            let bytes = points.cast::<u8>();
            // Two offsets per 8-byte load, half the loads: an irregular mesh's scatter step
            // took 0.27 instead of 0.29 ms (its gather, no change). x86-64 is little-endian,
            // so lane 2k is the low half of pair k.
            // SAFETY: 8 u32 are 4 u64 in size, and any bits are a valid u64.
            let pairs: [u64; 4] = unsafe { std::mem::transmute(*offsets) };
            // A mask of low bits (the incidence rows' flag cleared) takes one BMI1 `bextr` a
            // lane instead of a move or shift and an `and`: 8 of some 45 instructions a row.
            let low_bits = mask.wrapping_add(1).is_power_of_two();
            let at = |lane: usize| {
                let pair = pairs[lane / 2];
                let start = 32 * (lane % 2) as u32;
                let offset = if mask == u32::MAX {
                    (pair >> start) as u32
                } else if low_bits {
                    // SAFETY: `Avx2::detect` found BMI1 too.
                    unsafe { _bextr_u64(pair, start, mask.count_ones()) as u32 }
                } else {
                    (pair >> start) as u32 & mask
                };
                // SAFETY: the caller guarantees every masked offset is a point in bounds.
                unsafe { bytes.add(offset as usize).cast::<Point>() }
            };
            // SAFETY: every pointer `at` gives is a point in bounds (above).
            unsafe {
                let pair = |low: usize, high: usize| {
                    _mm256_insertf128_ps::<1>(
                        _mm256_castps128_ps256(_mm_loadu_ps(at(low).cast())),
                        _mm_loadu_ps(at(high).cast()),
                    )
                };
                [pair(0, 4), pair(1, 5), pair(2, 6), pair(3, 7)]
            }
        }
        #[inline(always)]
        unsafe fn point_pairs_run(self, points: *const Point, offset: u32) -> [__m256; 4] {
            // SAFETY: the caller guarantees the 128 bytes are in bounds.
            unsafe {
                let base = points.cast::<u8>().add(offset as usize).cast::<f32>();
                [
                    _mm256_loadu_ps(base),
                    _mm256_loadu_ps(base.add(8)),
                    _mm256_loadu_ps(base.add(16)),
                    _mm256_loadu_ps(base.add(24)),
                ]
            }
        }
        #[inline(always)]
        fn transpose_point_pairs(self, pairs: [__m256; 4]) -> [__m256; 3] {
            unsafe { transpose_pairs(pairs) }
        }
        #[inline(always)]
        fn pair_signs(self, sign: &[u32; LANES]) -> [__m256; 4] {
            unsafe {
                // +1 or -1 per lane: the sign bit kept, ored into 1.0's bits.
                let ones = _mm256_or_si256(
                    _mm256_and_si256(
                        _mm256_loadu_si256(sign.as_ptr().cast()),
                        _mm256_set1_epi32(i32::MIN),
                    ),
                    _mm256_set1_epi32(1.0f32.to_bits() as i32),
                );
                // Lane k in the low half and lane k + 4 in the high one, as the pairs hold
                // their points.
                [
                    _mm256_castsi256_ps(_mm256_shuffle_epi32::<0x00>(ones)),
                    _mm256_castsi256_ps(_mm256_shuffle_epi32::<0x55>(ones)),
                    _mm256_castsi256_ps(_mm256_shuffle_epi32::<0xAA>(ones)),
                    _mm256_castsi256_ps(_mm256_shuffle_epi32::<0xFF>(ones)),
                ]
            }
        }
        #[inline(always)]
        fn add_signed(self, sum: __m256, value: __m256, sign: __m256) -> __m256 {
            unsafe { _mm256_fmadd_ps(value, sign, sum) }
        }
        #[inline(always)]
        fn fourths(self, pairs: __m256) -> __m256 {
            unsafe { _mm256_permute_ps::<0xFF>(pairs) }
        }
        #[inline(always)]
        fn store_points(self, [x, y, z]: [__m256; 3], out: &mut [Point; LANES]) {
            unsafe {
                // The transpose of `gather_points`: points (k, k + 4) in each register, which
                // `point_slot` stores side by side: one 32-byte store each.
                // z goes in twice, as z and w: two shuffles fewer than pairing it with zeros.
                let xy01 = _mm256_unpacklo_ps(x, y);
                let xy23 = _mm256_unpackhi_ps(x, y);
                let p04 = _mm256_shuffle_ps::<0x04>(xy01, z);
                let p15 = _mm256_shuffle_ps::<0x5E>(xy01, z);
                let p26 = _mm256_shuffle_ps::<0xA4>(xy23, z);
                let p37 = _mm256_shuffle_ps::<0xFE>(xy23, z);
                let base = out.as_mut_ptr().cast::<f32>();
                _mm256_storeu_ps(base, p04);
                _mm256_storeu_ps(base.add(8), p15);
                _mm256_storeu_ps(base.add(16), p26);
                _mm256_storeu_ps(base.add(24), p37);
            }
        }
        #[inline(always)]
        fn store_stretches(self, [x, y, z]: [__m256; 3], k: __m256, out: &mut [Point; LANES]) {
            unsafe {
                // As `store_points`, with k as the fourth word.
                let xy01 = _mm256_unpacklo_ps(x, y);
                let xy23 = _mm256_unpackhi_ps(x, y);
                let zk01 = _mm256_unpacklo_ps(z, k);
                let zk23 = _mm256_unpackhi_ps(z, k);
                let base = out.as_mut_ptr().cast::<f32>();
                _mm256_storeu_ps(base, _mm256_shuffle_ps::<0x44>(xy01, zk01));
                _mm256_storeu_ps(base.add(8), _mm256_shuffle_ps::<0xEE>(xy01, zk01));
                _mm256_storeu_ps(base.add(16), _mm256_shuffle_ps::<0x44>(xy23, zk23));
                _mm256_storeu_ps(base.add(24), _mm256_shuffle_ps::<0xEE>(xy23, zk23));
            }
        }
        #[inline(always)]
        fn load_points(self, points: &[Point; LANES]) -> [__m256; 3] {
            unsafe {
                // Stored side by side as points (k, k + 4): the pairs `transpose_pairs` takes.
                let base = points.as_ptr().cast::<f32>();
                transpose_pairs([
                    _mm256_loadu_ps(base),
                    _mm256_loadu_ps(base.add(8)),
                    _mm256_loadu_ps(base.add(16)),
                    _mm256_loadu_ps(base.add(24)),
                ])
            }
        }
        #[inline(always)]
        fn add(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_add_ps(a, b) }
        }
        #[inline(always)]
        fn sub(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_sub_ps(a, b) }
        }
        #[inline(always)]
        fn mul(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_mul_ps(a, b) }
        }
        #[inline(always)]
        fn div(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_div_ps(a, b) }
        }
        #[inline(always)]
        fn sqrt(self, a: __m256) -> __m256 {
            unsafe { _mm256_sqrt_ps(a) }
        }
        #[inline(always)]
        fn mul_add(self, a: __m256, b: __m256, c: __m256) -> __m256 {
            unsafe { _mm256_fmadd_ps(a, b, c) }
        }
        #[inline(always)]
        fn neg_mul_add(self, a: __m256, b: __m256, c: __m256) -> __m256 {
            unsafe { _mm256_fnmadd_ps(a, b, c) }
        }
        #[inline(always)]
        fn flip_sign(self, a: __m256, sign: &[u32; LANES]) -> __m256 {
            unsafe {
                let bits = _mm256_and_si256(
                    _mm256_loadu_si256(sign.as_ptr().cast()),
                    _mm256_set1_epi32(i32::MIN),
                );
                _mm256_xor_ps(a, _mm256_castsi256_ps(bits))
            }
        }
        #[inline(always)]
        fn select_positive(self, test: __m256, then: __m256, otherwise: __m256) -> __m256 {
            unsafe {
                let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(test, _mm256_setzero_ps());
                _mm256_blendv_ps(otherwise, then, positive)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_matches_portable_bit_for_bit() {
        let Some(detected) = Avx2::detect() else {
            return;
        };
        for by_lane in [false, true] {
            check_avx2(detected.with_gathers_by_lane(by_lane));
        }
    }

    /// Lane 0: `a * a` of `a = 1 + 2^-12` is `1 + 2^-11 + 2^-24`, a rounding tie; adding
    /// `-(1 + 2^-11)` leaves `2^-24` fused, 0 rounded twice.
    const ADDENDS: Block = [-1.000_488_3, 0.5, -1.0, 0.0, 3.0, -0.0, 1e-10, -7.0];

    #[test]
    fn a_multiply_add_rounds_once_only_when_fused() {
        let a: Block = [1.000_244_1, -2.0, 3.25, 1e-30, 7.0, -0.0, 1e20, 0.1];
        assert_eq!(
            a[0] * a[0],
            1.000_488_3,
            "the product rounds to the addend's negative"
        );
        let fused = Portable::<true>.mul_add(a, a, ADDENDS);
        let twice = Portable::<false>.mul_add(a, a, ADDENDS);
        assert_eq!((fused[0], twice[0]), (2f32.powi(-24), 0.0));
        for lane in 0..LANES {
            let (a, c) = (a[lane], ADDENDS[lane]);
            assert_eq!(fused[lane].to_bits(), a.mul_add(a, c).to_bits());
            assert_eq!(twice[lane].to_bits(), (a * a + c).to_bits());
        }
        let negated = Portable::<true>.neg_mul_add(a, a.map(|a| -a), ADDENDS);
        assert_eq!(negated.map(f32::to_bits), fused.map(f32::to_bits));
    }

    #[cfg(target_arch = "x86_64")]
    fn check_avx2(avx2: Avx2) {
        // The portable loops as the kernels run them on this processor, which has FMA.
        let loops = Portable::<true>;
        let a: Block = [1.5, -2.0, 3.25, 1e-30, 7.0, -0.0, 1e20, 0.1];
        let b: Block = [0.3, 0.7, -1.1, 2.0, 1e-20, 5.0, 3.0, 0.2];
        let check = |p: Block, v: std::arch::x86_64::__m256| {
            let mut out = [0.0; LANES];
            avx2.store(v, &mut out);
            assert_eq!(p.map(f32::to_bits), out.map(f32::to_bits));
        };
        let (pa, pb) = (loops.load(&a), loops.load(&b));
        let (va, vb) = (avx2.load(&a), avx2.load(&b));
        check(loops.div(pa, pb), avx2.div(va, vb));
        check(loops.sqrt(loops.mul(pa, pa)), avx2.sqrt(avx2.mul(va, va)));
        let (pc, vc) = (loops.load(&ADDENDS), avx2.load(&ADDENDS));
        check(loops.mul_add(pa, pb, pc), avx2.mul_add(va, vb, vc));
        check(loops.neg_mul_add(pa, pb, pc), avx2.neg_mul_add(va, vb, vc));
        let sign = [0, 0x8000_0000, 0, 0x8000_0005, 0, 0, 0x8000_0000, 1];
        check(loops.flip_sign(pa, &sign), avx2.flip_sign(va, &sign));
        check(
            loops.select_positive(pa, pb, pa),
            avx2.select_positive(va, vb, va),
        );
        let points: Vec<Point> = (0..40)
            .map(|i| [i as f32, -(i as f32), 0.25 * i as f32, 9.0])
            .collect();
        let index = [3, 39, 0, 7 | 0x8000_0000, 12, 12, 1, 30];
        // SAFETY: every masked index is below 40.
        let (portable, vector) = unsafe {
            (
                loops.gather_points(points.as_ptr(), &index, !0x8000_0000),
                avx2.gather_points(points.as_ptr(), &index, !0x8000_0000),
            )
        };
        for (p, v) in portable.into_iter().zip(vector) {
            check(p, v);
        }
        // Byte offsets with the flag in either half of a pair: cleared by `bextr` (a mask of
        // low bits), by a shift and an `and` (another mask), or not at all.
        let mut offsets =
            index.map(|i| (point_slot(i & !0x8000_0000) * POINT_BYTES) | (i & 0x8000_0000));
        offsets[0] |= 0x8000_0000;
        for mask in [!0x8000_0000, !0x8000_0001] {
            // SAFETY: every masked offset is a point below 40.
            let (portable, vector) = unsafe {
                (
                    loops.gather_points_at(points.as_ptr(), &offsets, mask),
                    avx2.gather_points_at(points.as_ptr(), &offsets, mask),
                )
            };
            for (p, v) in portable.into_iter().zip(vector) {
                check(p, v);
            }
        }
        // Points added as loaded, two to a value, with the flags' signs, then transposed: as
        // the portable code, and as adding the gathered axes with their signs flipped.
        let signed_sum = |simd: Avx2| {
            let zero = [simd.splat(0.0); 4];
            // SAFETY: every masked offset is a point below 40.
            let f = unsafe { simd.point_pairs_at(points.as_ptr(), &offsets, !0x8000_0000) };
            let signs = simd.pair_signs(&offsets);
            let once: [_; 4] = std::array::from_fn(|k| simd.add_signed(zero[k], f[k], signs[k]));
            let twice: [_; 4] = std::array::from_fn(|k| simd.add_signed(once[k], f[k], signs[k]));
            simd.transpose_point_pairs(twice)
        };
        let portable = {
            // SAFETY: as above.
            let f = unsafe { loops.point_pairs_at(points.as_ptr(), &offsets, !0x8000_0000) };
            let signs = loops.pair_signs(&offsets);
            let zero = [0.0; LANES];
            let once: [Block; 4] = std::array::from_fn(|k| loops.add_signed(zero, f[k], signs[k]));
            let twice: [Block; 4] =
                std::array::from_fn(|k| loops.add_signed(once[k], f[k], signs[k]));
            loops.transpose_point_pairs(twice)
        };
        for (p, v) in portable.iter().zip(signed_sum(avx2)) {
            check(*p, v);
        }
        // SAFETY: as above.
        let axes = unsafe { loops.gather_points_at(points.as_ptr(), &offsets, !0x8000_0000) };
        for (p, axis) in portable.iter().zip(axes) {
            let flipped = loops.flip_sign(axis, &offsets);
            let by_flips = loops.add(loops.add([0.0; LANES], flipped), flipped);
            assert_eq!(p.map(f32::to_bits), by_flips.map(f32::to_bits));
        }
        // Rounding sums: fused or not, `sum + value * (+-1)` rounds once, as `sum +- value`.
        let (sum, value): (Block, Block) = (
            [1.0, 1e8, -3.5, 0.1, 1e-30, -0.0, 7.25, 16777216.0],
            [1e-8, 3.0, 1.0e7, 0.2, -1e-30, 0.0, -7.25, 1.0],
        );
        let sign: Block = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0];
        check(
            loops.add_signed(sum, value, sign),
            avx2.add_signed(avx2.load(&sum), avx2.load(&value), avx2.load(&sign)),
        );
        let plain = offsets.map(|o| o & !0x8000_0000);
        // SAFETY: every offset is a point below 40.
        let (portable, vector) = unsafe {
            (
                loops.gather_points_at(points.as_ptr(), &plain, u32::MAX),
                avx2.gather_points_at(points.as_ptr(), &plain, u32::MAX),
            )
        };
        for (p, v) in portable.into_iter().zip(vector) {
            check(p, v);
        }
        let (mut from_portable, mut from_vector) = ([[0.0; 4]; LANES], [[1.0; 4]; LANES]);
        loops.store_points(portable, &mut from_portable);
        avx2.store_points(vector, &mut from_vector);
        assert_eq!(from_portable, from_vector);
        // Point `k` is read from and stored at its slot, z again as its fourth word: stored
        // points hold what was gathered.
        for lane in 0..LANES {
            let source = points[point_slot(index[lane] & !0x8000_0000) as usize];
            let point = from_portable[point_slot(lane as u32) as usize];
            assert_eq!(point, [source[0], source[1], source[2], source[2]]);
        }
        // And load back as they were gathered.
        let loaded = loops.load_points(&from_portable);
        for ((p, v), l) in portable
            .iter()
            .zip(avx2.load_points(&from_vector))
            .zip(loaded)
        {
            check(*p, v);
            assert_eq!(p.map(f32::to_bits), l.map(f32::to_bits));
        }
        for index in 0..64 {
            assert_eq!(point_at_slot(point_slot(index)), index);
            assert_eq!(point_slot(index) / 8, index / 8);
        }
        let values: Vec<f32> = (0..40).map(|i| i as f32 * 0.5).collect();
        let index = [3, 39, 0, 7 | 0x8000_0000, 12, 12, 1, 30];
        // SAFETY: every masked index is below 40.
        unsafe {
            check(
                loops.gather(values.as_ptr(), &index, !0x8000_0000),
                avx2.gather(values.as_ptr(), &index, !0x8000_0000),
            )
        };
    }
}
