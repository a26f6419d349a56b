//! A stable LSD radix sort of `(u32 key, u32 value)` pairs on the GPU (`radix_sort.wgsl`), the
//! "GPU sorter" of the paper's self-collision binning. Each pass sorts on 8 key bits with two
//! kernels (scan the digit counts per block, scatter); the first pass's digits are counted by
//! a third kernel (or by the caller's kernel that writes the keys), and each later pass's by
//! the scatter before it, into the other of two histograms. The pairs (one `vec2<u32>` each)
//! go back and forth between two buffers, so the result is in the input's buffer after an even
//! number of passes and in the other after an odd one. A block is [`BLOCK`] pairs, one
//! workgroup's: a histogram holds a quarter as many counts as pairs, scanned in slices of
//! consecutive counts (one workgroup each, [`SLICE_COUNTS`] counts unless that would make more
//! than [`MAX_SLICES`]), and then each slice's total.

use crate::GpuError;
use crate::context::GpuContext;
use crate::gpu::{
    bind_group, compute_pipeline_with, dispatch_groups_in, read_back, uniform, zeroed,
};
use crate::layout::SortUniforms;

const BITS_PER_PASS: u32 = 8;
const DIGITS: u64 = 256;
/// Pairs per block (`BLOCK` in `digits.wgsl`).
pub const BLOCK: u32 = 1024;
/// Counts one workgroup of the scan takes, unless the histogram is larger than
/// [`MAX_SLICES`] such slices: `SCAN_TILE` in `radix_sort.wgsl`, 16 or 4 per invocation.
const SLICE_COUNTS: u32 = 1024;
/// Slices of the histogram at most: every scatter workgroup scans all their totals in
/// workgroup memory (`MAX_SLICES` in `radix_sort.wgsl`, 4 KiB of the 16 KiB WebGPU grants).
pub const MAX_SLICES: u32 = 1024;

/// Invocations of each sort workgroup, one a block or a slice: `SORT_GROUP` in `digits.wgsl`,
/// a pipeline-overridable constant. On an H100 the self-collision's sort and key passes took
/// 40% less GPU time at 128^2 and 256^2 with wide workgroups, about 10% less at 1024^2 and
/// 2048^2; on lavapipe, which runs a workgroup's invocations in turn, twice as long.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SortGroup {
    /// 64 invocations, 16 rounds a block (the shader's default).
    Narrow,
    /// 256 invocations, 4 rounds a block.
    Wide,
}

impl SortGroup {
    pub const ALL: [SortGroup; 2] = [SortGroup::Narrow, SortGroup::Wide];

    /// Wide on a GPU; narrow on a software renderer, and where the adapter does not say what
    /// it is (a browser's).
    pub fn for_adapter(info: &wgpu::AdapterInfo) -> Self {
        match info.device_type {
            wgpu::DeviceType::DiscreteGpu
            | wgpu::DeviceType::IntegratedGpu
            | wgpu::DeviceType::VirtualGpu => Self::Wide,
            wgpu::DeviceType::Cpu | wgpu::DeviceType::Other => Self::Narrow,
        }
    }

    pub fn invocations(self) -> u32 {
        match self {
            Self::Narrow => 64,
            Self::Wide => 256,
        }
    }

    /// The pipeline constants that make a sort kernel's workgroups this size.
    pub(crate) fn constants(self) -> [(&'static str, f64); 1] {
        [("SORT_GROUP", f64::from(self.invocations()))]
    }
}

/// Counts per slice of the histogram of `block_count` blocks that one scan workgroup takes:
/// [`SLICE_COUNTS`], or more where that would make more than `max_slices` slices (from
/// 4096 blocks, 4 million pairs, with [`MAX_SLICES`]: a 2048^2 grid's vertices take 4096).
fn slice_length(block_count: u32, max_slices: u32) -> u32 {
    (DIGITS as u32 * block_count)
        .div_ceil(max_slices)
        .max(SLICE_COUNTS)
}

/// Buffers and recorded bind groups to sort `count` pairs on their low `key_bits` bits.
#[derive(Debug)]
pub struct RadixSort {
    /// (key, value) pairs. Input: `pairs[0]`; output: `pairs[passes % 2]`.
    pairs: [wgpu::Buffer; 2],
    block_count: u32,
    /// Workgroups of the scan: slices of the histogram.
    slices: u32,
    /// Pass `p` scans `histograms[p % 2]`; its scatter counts pass `p + 1`'s digits into the
    /// other.
    histograms: [wgpu::Buffer; 2],
    /// The kernel that writes the keys also counts the first pass's digits into
    /// `histograms[0]`, so the sort skips that count.
    first_counted: bool,
    count_digits: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    /// The first pass's count-digits group.
    first_count: wgpu::BindGroup,
    /// Per pass: (scan group, scatter group).
    passes: Vec<[wgpu::BindGroup; 2]>,
    bytes: u64,
}

impl RadixSort {
    /// Sorts on the low `key_bits` bits, rounded up to a multiple of 8 (one pass each), in
    /// workgroups of `group`. `first_counted`: the caller's kernel that writes the keys also
    /// counts the first pass's digits into [`RadixSort::histogram`], in workgroups of `group`.
    pub fn new(
        context: &GpuContext,
        count: u32,
        key_bits: u32,
        first_counted: bool,
        group: SortGroup,
    ) -> Result<Self, GpuError> {
        Self::with_max_slices(context, count, key_bits, first_counted, group, MAX_SLICES)
    }

    /// [`RadixSort::new`] with the histogram in at most `max_slices` slices (tests take fewer
    /// than [`MAX_SLICES`] to make slices of several tiles on few pairs).
    fn with_max_slices(
        context: &GpuContext,
        count: u32,
        key_bits: u32,
        first_counted: bool,
        group: SortGroup,
        max_slices: u32,
    ) -> Result<Self, GpuError> {
        let pass_count = key_bits.div_ceil(BITS_PER_PASS).max(1);
        let block_count = count.div_ceil(BLOCK).max(1);
        let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let pair_bytes = 8 * u64::from(count);
        let pairs = [0, 1].map(|k| zeroed(context, &format!("sort pairs {k}"), pair_bytes, usage));
        let slice_length = slice_length(block_count, max_slices.min(MAX_SLICES));
        let slices = (DIGITS as u32 * block_count).div_ceil(slice_length);
        // Each digit's count per block, then each slice's total (written by the scan).
        let histogram_bytes = 4 * (DIGITS * u64::from(block_count) + u64::from(slices));
        let histograms = [0, 1].map(|k| {
            zeroed(
                context,
                &format!("sort histogram {k}"),
                histogram_bytes,
                usage,
            )
        });
        let pipeline = |label, entry| {
            compute_pipeline_with(context, label, super::RADIX_SORT, entry, &group.constants())
        };
        let count_digits = pipeline("radix count", "count_digits")?;
        let scan = pipeline("radix scan", "scan")?;
        let scatter = pipeline("radix scatter", "scatter")?;
        let uniforms: Vec<wgpu::Buffer> = (0..pass_count)
            .map(|pass| {
                uniform(
                    context,
                    &SortUniforms {
                        count,
                        shift: pass * BITS_PER_PASS,
                        block_count,
                        slice_length,
                        counts_next: u32::from(pass + 1 < pass_count),
                    },
                )
            })
            .collect();
        let first_count = bind_group(
            context,
            "radix count",
            &count_digits.get_bind_group_layout(0),
            &[
                (0, uniforms[0].as_entire_binding()),
                (1, pairs[0].as_entire_binding()),
                (10, histograms[0].as_entire_binding()),
            ],
        );
        let passes = uniforms
            .iter()
            .enumerate()
            .map(|(pass, uniforms)| {
                let (from, to) = (pass % 2, 1 - pass % 2);
                let (histogram, next) = (&histograms[from], &histograms[to]);
                [
                    bind_group(
                        context,
                        "radix scan",
                        &scan.get_bind_group_layout(0),
                        &[
                            (0, uniforms.as_entire_binding()),
                            (10, histogram.as_entire_binding()),
                            (11, next.as_entire_binding()),
                        ],
                    ),
                    bind_group(
                        context,
                        "radix scatter",
                        &scatter.get_bind_group_layout(0),
                        &[
                            (0, uniforms.as_entire_binding()),
                            (1, pairs[from].as_entire_binding()),
                            (3, pairs[to].as_entire_binding()),
                            (10, histogram.as_entire_binding()),
                            (11, next.as_entire_binding()),
                        ],
                    ),
                ]
            })
            .collect();
        Ok(Self {
            pairs,
            block_count,
            slices,
            histograms,
            first_counted,
            count_digits,
            scan,
            scatter,
            first_count,
            passes,
            bytes: 2 * pair_bytes + 2 * histogram_bytes,
        })
    }

    /// Where the (key, value) pairs to sort go, a `vec2<u32>` each.
    pub fn pairs(&self) -> &wgpu::Buffer {
        &self.pairs[0]
    }

    /// Where the pairs are in key order afterwards.
    pub fn sorted_pairs(&self) -> &wgpu::Buffer {
        &self.pairs[self.passes.len() % 2]
    }

    /// The first pass's digit counts per block (`histogram` in `digits.wgsl`, binding 10), for
    /// a kernel that writes the keys and counts those digits itself.
    pub fn histogram(&self) -> &wgpu::Buffer {
        &self.histograms[0]
    }

    /// Blocks of [`BLOCK`] pairs.
    pub fn block_count(&self) -> u32 {
        self.block_count
    }

    /// GPU memory held, bytes.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Dispatches the sort records: scan and scatter per digit, and the first count unless
    /// the caller's kernel counts it.
    pub fn dispatches(&self) -> u32 {
        2 * self.passes.len() as u32 + u32::from(!self.first_counted)
    }

    /// Records the sort into an open compute pass.
    pub fn encode(&self, pass: &mut wgpu::ComputePass<'_>) {
        // One workgroup per block, or per slice of the histogram.
        if !self.first_counted {
            dispatch_groups_in(
                pass,
                &self.count_digits,
                &self.first_count,
                self.block_count,
            );
        }
        for [scan_group, scatter_group] in &self.passes {
            dispatch_groups_in(pass, &self.scan, scan_group, self.slices);
            dispatch_groups_in(pass, &self.scatter, scatter_group, self.block_count);
        }
    }

    /// Sorts `keys` with their indices as values and reads both back: `(sorted keys, order)`.
    /// For tests and studies; the solver sorts in place without reading back.
    pub fn sort_indices(
        context: &GpuContext,
        keys: &[u32],
        key_bits: u32,
    ) -> Result<(Vec<u32>, Vec<u32>), GpuError> {
        let group = SortGroup::for_adapter(&context.info);
        Self::new(context, keys.len() as u32, key_bits, false, group)?.sort(context, keys)
    }

    /// Sorts `keys` (as many as the sorter was made for) with their indices as values, and
    /// reads both back.
    fn sort(&self, context: &GpuContext, keys: &[u32]) -> Result<(Vec<u32>, Vec<u32>), GpuError> {
        let pairs: Vec<[u32; 2]> = keys.iter().zip(0..).map(|(&k, i)| [k, i]).collect();
        context
            .queue
            .write_buffer(self.pairs(), 0, bytemuck::cast_slice(&pairs));
        let mut encoder = context
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("radix sort"),
            });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("radix sort"),
                timestamp_writes: None,
            });
            self.encode(&mut pass);
        }
        context.queue.submit([encoder.finish()]);
        let bytes = 8 * keys.len() as u64;
        let out = read_back(context, &[(self.sorted_pairs(), bytes)])?;
        context.take_error()?;
        let sorted: Vec<[u32; 2]> = bytemuck::pod_collect_to_vec(&out[0]);
        Ok(sorted.into_iter().map(|[k, i]| (k, i)).unzip())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wgsl_digits_and_block_are_the_ones_the_histogram_is_sized_for() {
        let module = naga::front::wgsl::parse_str(super::super::RADIX_SORT).expect("parses");
        let constant = |name: &str| {
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("no {name}"));
            match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::U32(value)) => value,
                ref other => panic!("{name} = {other:?}"),
            }
        };
        assert_eq!(u64::from(constant("DIGITS")), DIGITS);
        assert_eq!(DIGITS, 1 << BITS_PER_PASS);
        assert_eq!(constant("BLOCK"), BLOCK);
        // The overrides: a workgroup size from the one SORT_GROUP, which the others follow.
        let sizes: Vec<&str> = module
            .overrides
            .iter()
            .filter_map(|(_, o)| o.name.as_deref())
            .collect();
        assert_eq!(sizes, ["SORT_GROUP", "ROUNDS", "WORDS", "MEMBER_WORDS"]);
        for group in SortGroup::ALL {
            let invocations = group.invocations();
            assert_eq!(BLOCK % invocations, 0, "{group:?}");
            assert_eq!(invocations % 32, 0, "{group:?}: whole words of members");
        }
        assert_eq!(constant("MAX_SLICES"), MAX_SLICES);
        assert_eq!(constant("SCAN_TILE"), SLICE_COUNTS);
    }

    #[test]
    fn slices_take_a_tile_of_counts_unless_there_would_be_too_many() {
        for blocks in [1, 4, 5, 64, 100, 1024, 4096] {
            assert_eq!(
                slice_length(blocks, MAX_SLICES),
                SLICE_COUNTS,
                "{blocks} blocks"
            );
        }
        for blocks in [4097, 16_384, 100_000, 4_194_304] {
            let length = slice_length(blocks, MAX_SLICES);
            assert!(length > SLICE_COUNTS, "{blocks} blocks");
            let slices = (DIGITS as u32 * blocks).div_ceil(length);
            assert!(slices <= MAX_SLICES, "{blocks} blocks: {slices} slices");
        }
    }

    /// Slices of several tiles, which only sorts of over 4 million pairs make with
    /// [`MAX_SLICES`]: the same order as a stable sort on the CPU.
    #[test]
    fn slices_of_several_tiles_sort_as_one_tile_does() {
        let Some(context) = crate::kernels::testing::context() else {
            return;
        };
        let count = 300_000_u32;
        // Few distinct keys, so equal keys must keep their order.
        let keys: Vec<u32> = (0..count)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) & 0xf0f0f)
            .collect();
        for (group, max_slices) in SortGroup::ALL
            .into_iter()
            .flat_map(|g| [(g, 3), (g, 16), (g, MAX_SLICES)])
        {
            let sorter = RadixSort::with_max_slices(&context, count, 24, false, group, max_slices)
                .expect("sort");
            assert!(max_slices == MAX_SLICES || sorter.slices <= max_slices);
            let (sorted_keys, order) = sorter.sort(&context, &keys).expect("sorted");
            let mut expected: Vec<u32> = (0..count).collect();
            expected.sort_by_key(|&i| keys[i as usize]);
            assert!(order == expected, "{group:?}, {max_slices} slices at most");
            let expected_keys: Vec<u32> = expected.iter().map(|&i| keys[i as usize]).collect();
            assert!(
                sorted_keys == expected_keys,
                "{group:?}, {max_slices} slices at most"
            );
        }
    }
}
