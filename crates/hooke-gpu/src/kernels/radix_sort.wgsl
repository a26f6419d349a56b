// One pass of a stable LSD radix sort of (key, value) pairs on 4-bit digits, in three kernels:
// `histogram` counts each block's digits, `scan` turns the counts (digit-major, then block)
// into each block's first output slot per digit, and `scatter` moves every pair to its slot,
// ranked within its block by its position so equal digits keep their order. A block is one
// workgroup of WORKGROUP_SIZE pairs. hooke_gpu::radix_sort runs the passes, 4 key bits each.

struct SortUniforms {
    count: u32,
    // The digit of a key is (key >> shift) & 15.
    shift: u32,
    block_count: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> su: SortUniforms;
@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> values_in: array<u32>;
@group(0) @binding(3) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(4) var<storage, read_write> values_out: array<u32>;
// 16 counts per block, digit-major: entry digit * block_count + block.
@group(0) @binding(5) var<storage, read_write> histogram: array<u32>;

const DIGITS: u32 = 16u;
// Bit masks of the block's members per digit: WORKGROUP_SIZE / 32 words each.
const WORDS: u32 = 2u;

var<workgroup> digit_counts: array<atomic<u32>, 16>;
var<workgroup> members: array<atomic<u32>, 32>;
var<workgroup> partial_sums: array<u32, WORKGROUP_SIZE>;

fn block_index(group: vec3<u32>, groups: vec3<u32>) -> u32 {
    return group.x + group.y * groups.x;
}

fn digit_of(key: u32) -> u32 {
    return (key >> su.shift) & (DIGITS - 1u);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn count_digits(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    if lane < DIGITS {
        atomicStore(&digit_counts[lane], 0u);
    }
    workgroupBarrier();
    let block = block_index(group, groups);
    let i = block * WORKGROUP_SIZE + lane;
    if block < su.block_count && i < su.count {
        atomicAdd(&digit_counts[digit_of(keys_in[i])], 1u);
    }
    workgroupBarrier();
    if lane < DIGITS && block < su.block_count {
        histogram[lane * su.block_count + block] = atomicLoad(&digit_counts[lane]);
    }
}

// One workgroup: each invocation sums a contiguous run of the histogram, the 64 run totals
// are scanned in shared memory, then each run is rewritten as exclusive prefix sums.
@compute @workgroup_size(WORKGROUP_SIZE)
fn scan(@builtin(local_invocation_index) lane: u32) {
    let length = DIGITS * su.block_count;
    let run = (length + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    let start = min(lane * run, length);
    let end = min(start + run, length);
    var total = 0u;
    for (var i = start; i < end; i++) {
        total += histogram[i];
    }
    partial_sums[lane] = total;
    workgroupBarrier();
    for (var offset = 1u; offset < WORKGROUP_SIZE; offset <<= 1u) {
        var earlier = 0u;
        if lane >= offset {
            earlier = partial_sums[lane - offset];
        }
        workgroupBarrier();
        partial_sums[lane] += earlier;
        workgroupBarrier();
    }
    var running = partial_sums[lane] - total;
    for (var i = start; i < end; i++) {
        let c = histogram[i];
        histogram[i] = running;
        running += c;
    }
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn scatter(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    if lane < DIGITS * WORDS {
        atomicStore(&members[lane], 0u);
    }
    workgroupBarrier();
    let block = block_index(group, groups);
    let i = block * WORKGROUP_SIZE + lane;
    let valid = block < su.block_count && i < su.count;
    var key = 0u;
    var digit = 0u;
    let word = lane / 32u;
    let bit = lane % 32u;
    if valid {
        key = keys_in[i];
        digit = digit_of(key);
        atomicOr(&members[digit * WORDS + word], 1u << bit);
    }
    workgroupBarrier();
    if valid {
        // Rank: members of the same digit earlier in the block.
        var rank = countOneBits(atomicLoad(&members[digit * WORDS + word]) & ((1u << bit) - 1u));
        for (var w = 0u; w < word; w++) {
            rank += countOneBits(atomicLoad(&members[digit * WORDS + w]));
        }
        let slot = histogram[digit * su.block_count + block] + rank;
        keys_out[slot] = key;
        values_out[slot] = values_in[i];
    }
}
