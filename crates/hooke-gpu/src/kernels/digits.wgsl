// The radix sort's digits and blocks (radix_sort.wgsl), shared with self_collide.wgsl, whose key
// kernel counts the first pass's digits while it computes the keys. A block is the pairs one
// workgroup of SORT_GROUP invocations handles, ROUNDS rounds of SORT_GROUP, so the histogram
// (DIGITS counts per block) has a quarter as many entries as pairs, whatever the digit width.
// SORT_GROUP is set when the pipelines are made (`radix_sort::SortGroup`): 256 on a GPU, where
// a block's pairs then pass a quarter as many barriers and more of each round's memory latency
// is hidden, and 64 on a software renderer, which runs a workgroup's invocations in turn and
// took twice as long with 256.

const DIGITS: u32 = 256u;
// log2(DIGITS): a pass's digit is the key's next BITS_PER_PASS bits.
const BITS_PER_PASS: u32 = 8u;
override SORT_GROUP: u32 = 64u;
override ROUNDS: u32 = BLOCK / SORT_GROUP;
// Equals `radix_sort::BLOCK` in Rust (checked by a test), which sizes the histogram.
const BLOCK: u32 = 1024u;

struct SortUniforms {
    count: u32,
    // The digit of a key is (key >> shift) & (DIGITS - 1).
    shift: u32,
    block_count: u32,
    // Counts per slice of the histogram scanned by one workgroup.
    slice_length: u32,
    // 1 when another pass follows: `scatter` counts its digits into `next_histogram`.
    counts_next: u32,
}

// DIGITS counts per block, digit-major: entry digit * block_count + block. After `scan`, each
// block's first output slot per digit.
@group(0) @binding(10) var<storage, read_write> histogram: array<u32>;

var<workgroup> digit_counts: array<atomic<u32>, DIGITS>;

fn block_index(group: vec3<u32>, groups: vec3<u32>) -> u32 {
    return group.x + group.y * groups.x;
}

// Counts the digits of block `block` of `count` entries into its histogram column: entry `i`'s
// digit is `entry_digit(i)`, a function of the file that includes this one (the radix sort
// reads a key; the self-collision computes it). Every invocation of the workgroup calls it.
fn count_block_digits(lane: u32, block: u32, block_count: u32, count: u32) {
    for (var d = lane; d < DIGITS; d += SORT_GROUP) {
        atomicStore(&digit_counts[d], 0u);
    }
    workgroupBarrier();
    if block < block_count {
        let end = min(block * BLOCK + BLOCK, count);
        for (var i = block * BLOCK + lane; i < end; i += SORT_GROUP) {
            atomicAdd(&digit_counts[entry_digit(i)], 1u);
        }
    }
    workgroupBarrier();
    if block < block_count {
        for (var d = lane; d < DIGITS; d += SORT_GROUP) {
            histogram[d * block_count + block] = atomicLoad(&digit_counts[d]);
        }
    }
}
