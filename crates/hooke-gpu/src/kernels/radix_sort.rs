//! A stable LSD radix sort of `(u32 key, u32 value)` pairs on the GPU (`radix_sort.wgsl`), the
//! "GPU sorter" of the paper's self-collision binning. Each pass sorts on 8 key bits with
//! three kernels (count digits per block, scan, scatter); the pairs go back and forth between
//! two buffer pairs, so the result is in the input's pair after an even number of passes and
//! in the other after an odd one. A block is [`BLOCK`] pairs, one workgroup's: the histogram
//! holds a quarter as many counts as pairs, scanned in slices of digits (one workgroup each,
//! [`SLICE_COUNTS`] counts at most unless a digit has more), and then each slice's total.

use crate::GpuError;
use crate::context::GpuContext;
use crate::gpu::{
    WORKGROUP_SIZE, bind_group, compute_pipeline, dispatch_in, read_back, uniform, zeroed,
};
use crate::layout::SortUniforms;

const BITS_PER_PASS: u32 = 8;
const DIGITS: u64 = 256;
/// Pairs per block (`BLOCK` in `digits.wgsl`).
pub const BLOCK: u32 = 1024;
/// Counts one workgroup of the scan takes at most, unless a digit alone has more: 16 per
/// invocation.
const SLICE_COUNTS: u32 = 1024;

/// Digits per slice of the histogram that one scan workgroup takes: as many as fit in
/// [`SLICE_COUNTS`], a power of two from 1 (a slice per digit) to all 256 (one workgroup).
fn slice_digits(block_count: u32) -> u32 {
    let fitting = (SLICE_COUNTS / block_count.max(1)).clamp(1, DIGITS as u32);
    1 << fitting.ilog2()
}

/// Buffers and recorded bind groups to sort `count` pairs on their low `key_bits` bits.
#[derive(Debug)]
pub struct RadixSort {
    /// Input: `keys[0]`, `values[0]`; output: `[passes % 2]`.
    keys: [wgpu::Buffer; 2],
    values: [wgpu::Buffer; 2],
    block_count: u32,
    /// Workgroups of the scan: slices of the histogram's digits.
    slices: u32,
    histogram: wgpu::Buffer,
    /// The kernel that writes the keys also counts the first pass's digits into `histogram`,
    /// so the sort skips that count.
    first_counted: bool,
    count_digits: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    /// Per pass: (count-digits group, scan group, scatter group).
    passes: Vec<[wgpu::BindGroup; 3]>,
    bytes: u64,
}

impl RadixSort {
    /// Sorts on the low `key_bits` bits, rounded up to a multiple of 8 (one pass each).
    /// `first_counted`: the caller's kernel that writes the keys also counts the first pass's
    /// digits into [`RadixSort::histogram`].
    pub fn new(
        context: &GpuContext,
        count: u32,
        key_bits: u32,
        first_counted: bool,
    ) -> Result<Self, GpuError> {
        let pass_count = key_bits.div_ceil(BITS_PER_PASS).max(1);
        let block_count = count.div_ceil(BLOCK).max(1);
        let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let pair_bytes = 4 * u64::from(count);
        let keys = [0, 1].map(|k| zeroed(context, &format!("sort keys {k}"), pair_bytes, usage));
        let values =
            [0, 1].map(|k| zeroed(context, &format!("sort values {k}"), pair_bytes, usage));
        // Each digit's count per block, then each slice's total (written by the scan).
        let histogram_bytes = 4 * DIGITS * (u64::from(block_count) + 1);
        let histogram = zeroed(context, "sort histogram", histogram_bytes, usage);
        let count_digits =
            compute_pipeline(context, "radix count", super::RADIX_SORT, "count_digits")?;
        let scan = compute_pipeline(context, "radix scan", super::RADIX_SORT, "scan")?;
        let scatter = compute_pipeline(context, "radix scatter", super::RADIX_SORT, "scatter")?;
        let digits_per_slice = slice_digits(block_count);
        let passes = (0..pass_count)
            .map(|pass| {
                let uniforms = SortUniforms {
                    count,
                    shift: pass * BITS_PER_PASS,
                    block_count,
                    digits_per_slice,
                };
                let uniforms = uniform(context, &uniforms);
                let (from, to) = ((pass % 2) as usize, 1 - (pass % 2) as usize);
                [
                    bind_group(
                        context,
                        "radix count",
                        &count_digits.get_bind_group_layout(0),
                        &[
                            (0, uniforms.as_entire_binding()),
                            (1, keys[from].as_entire_binding()),
                            (10, histogram.as_entire_binding()),
                        ],
                    ),
                    bind_group(
                        context,
                        "radix scan",
                        &scan.get_bind_group_layout(0),
                        &[
                            (0, uniforms.as_entire_binding()),
                            (10, histogram.as_entire_binding()),
                        ],
                    ),
                    bind_group(
                        context,
                        "radix scatter",
                        &scatter.get_bind_group_layout(0),
                        &[
                            (0, uniforms.as_entire_binding()),
                            (1, keys[from].as_entire_binding()),
                            (2, values[from].as_entire_binding()),
                            (3, keys[to].as_entire_binding()),
                            (4, values[to].as_entire_binding()),
                            (10, histogram.as_entire_binding()),
                        ],
                    ),
                ]
            })
            .collect();
        Ok(Self {
            keys,
            values,
            block_count,
            slices: DIGITS as u32 / digits_per_slice,
            histogram,
            first_counted,
            count_digits,
            scan,
            scatter,
            passes,
            bytes: 4 * pair_bytes + histogram_bytes,
        })
    }

    /// Where the keys to sort go.
    pub fn keys(&self) -> &wgpu::Buffer {
        &self.keys[0]
    }

    /// Where the values go.
    pub fn values(&self) -> &wgpu::Buffer {
        &self.values[0]
    }

    /// Where the sorted keys are afterwards.
    pub fn sorted_keys(&self) -> &wgpu::Buffer {
        &self.keys[self.passes.len() % 2]
    }

    /// Where the values are in key order afterwards.
    pub fn sorted_values(&self) -> &wgpu::Buffer {
        &self.values[self.passes.len() % 2]
    }

    /// The digit counts per block (`histogram` in `digits.wgsl`, binding 10), for a kernel
    /// that writes the keys and counts the first pass's digits itself.
    pub fn histogram(&self) -> &wgpu::Buffer {
        &self.histogram
    }

    /// Blocks of [`BLOCK`] pairs.
    pub fn block_count(&self) -> u32 {
        self.block_count
    }

    /// GPU memory held, bytes.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Dispatches the sort records: count, scan and scatter per digit, less the first count
    /// when the caller's kernel counts it.
    pub fn dispatches(&self) -> u32 {
        3 * self.passes.len() as u32 - u32::from(self.first_counted)
    }

    /// Records the sort into an open compute pass.
    pub fn encode(&self, pass: &mut wgpu::ComputePass<'_>) {
        // One workgroup per block.
        let block_invocations = self.block_count * WORKGROUP_SIZE;
        for (index, [count_group, scan_group, scatter_group]) in self.passes.iter().enumerate() {
            if index > 0 || !self.first_counted {
                dispatch_in(pass, &self.count_digits, count_group, block_invocations);
            }
            dispatch_in(pass, &self.scan, scan_group, self.slices * WORKGROUP_SIZE);
            dispatch_in(pass, &self.scatter, scatter_group, block_invocations);
        }
    }

    /// Sorts `keys` with their indices as values and reads both back: `(sorted keys, order)`.
    /// For tests and studies; the solver sorts in place without reading back.
    pub fn sort_indices(
        context: &GpuContext,
        keys: &[u32],
        key_bits: u32,
    ) -> Result<(Vec<u32>, Vec<u32>), GpuError> {
        let sorter = Self::new(context, keys.len() as u32, key_bits, false)?;
        let indices: Vec<u32> = (0..keys.len() as u32).collect();
        context
            .queue
            .write_buffer(sorter.keys(), 0, bytemuck::cast_slice(keys));
        context
            .queue
            .write_buffer(sorter.values(), 0, bytemuck::cast_slice(&indices));
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
            sorter.encode(&mut pass);
        }
        context.queue.submit([encoder.finish()]);
        let bytes = 4 * keys.len() as u64;
        let out = read_back(
            context,
            &[
                (sorter.sorted_keys(), bytes),
                (sorter.sorted_values(), bytes),
            ],
        )?;
        context.take_error()?;
        Ok((
            bytemuck::pod_collect_to_vec(&out[0]),
            bytemuck::pod_collect_to_vec(&out[1]),
        ))
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
        assert_eq!(constant("ROUNDS") * WORKGROUP_SIZE, BLOCK);
    }

    #[test]
    fn slices_take_up_to_a_thousand_counts_and_divide_the_digits() {
        // (blocks, digits per slice): one workgroup for a small sort, one per digit for a
        // large one, powers of two between.
        for (blocks, digits) in [(1, 256), (4, 256), (5, 128), (16, 64), (64, 16), (100, 8)] {
            assert_eq!(slice_digits(blocks), digits, "{blocks} blocks");
        }
        for blocks in [1024, 1025, 4096, 100_000] {
            assert_eq!(slice_digits(blocks), 1, "{blocks} blocks");
        }
        for blocks in 1..3000 {
            let digits = slice_digits(blocks);
            assert_eq!(DIGITS as u32 % digits, 0);
            assert!(digits == 1 || digits * blocks <= SLICE_COUNTS);
        }
    }
}
