// One pass of a stable LSD radix sort of (key, value) pairs on 8-bit digits, in three kernels:
// `count_digits` counts each block's digits, `scan` turns the counts (digit-major, then block)
// into prefix sums within slices of digits, with each slice's total after them, and `scatter`
// adds the totals of the slices below and moves every pair to its slot,
// ranked within its block by its position so equal digits keep their order. Blocks and the
// histogram are digits.wgsl's. hooke_gpu::radix_sort runs the passes, 8 key bits each.

@group(0) @binding(0) var<uniform> su: SortUniforms;
@group(0) @binding(1) var<storage, read> keys_in: array<u32>;
@group(0) @binding(2) var<storage, read> values_in: array<u32>;
@group(0) @binding(3) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(4) var<storage, read_write> values_out: array<u32>;

// Bit masks of one round's members per digit: WORKGROUP_SIZE / 32 words each.
const WORDS: u32 = 2u;

var<workgroup> members: array<atomic<u32>, 512>;
// The next output slot of each digit in this block, advanced round by round.
var<workgroup> next_slot: array<u32, DIGITS>;
// The first slot of each slice of the histogram's digits.
var<workgroup> slice_base: array<u32, DIGITS>;
var<workgroup> partial_sums: array<u32, WORKGROUP_SIZE>;

fn digit_of(key: u32) -> u32 {
    return (key >> su.shift) & (DIGITS - 1u);
}

fn entry_digit(i: u32) -> u32 {
    return digit_of(keys_in[i]);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn count_digits(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    count_block_digits(lane, block_index(group, groups), su.block_count, su.count);
}

// One workgroup per slice of `digits_per_slice` digits (consecutive in the digit-major
// histogram): each invocation sums a contiguous run of the slice's counts, the run totals are
// scanned in shared memory, then each run is rewritten as exclusive prefix sums within the
// slice, and the slice's total goes after the histogram for `scatter`. Slices keep each
// invocation's run short on large meshes (one workgroup for the whole histogram took most of
// the self-collision's time on a real GPU) and the workgroups few on small ones (each pays
// for its barriers where a software renderer runs invocations in turn).
@compute @workgroup_size(WORKGROUP_SIZE)
fn scan(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let slice = block_index(group, groups);
    // Uniform across the workgroup, so the barriers below are reached by every invocation.
    if slice * su.digits_per_slice >= DIGITS {
        return;
    }
    let length = su.digits_per_slice * su.block_count;
    let base = slice * length;
    let run = lane_run(lane, length);
    var total = 0u;
    for (var i = run.x; i < run.y; i++) {
        total += histogram[base + i];
    }
    var running = exclusive_scan(lane, total);
    for (var i = run.x; i < run.y; i++) {
        let c = histogram[base + i];
        histogram[base + i] = running;
        running += c;
    }
    if lane == WORKGROUP_SIZE - 1u {
        histogram[DIGITS * su.block_count + slice] = running;
    }
}

// The run [x, y) of `length` items that invocation `lane` takes: contiguous, in lane order.
fn lane_run(lane: u32, length: u32) -> vec2<u32> {
    let run = (length + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    let start = min(lane * run, length);
    return vec2<u32>(start, min(start + run, length));
}

// The sum of `value` over the invocations before `lane` (every invocation calls it).
fn exclusive_scan(lane: u32, value: u32) -> u32 {
    partial_sums[lane] = value;
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
    let inclusive = partial_sums[lane];
    // Callers may reuse partial_sums right after.
    workgroupBarrier();
    return inclusive - value;
}

// The block's pairs go out in ROUNDS rounds of WORKGROUP_SIZE, in order: a pair's slot is its
// digit's next slot in the block plus the members of its digit before it in its round.
@compute @workgroup_size(WORKGROUP_SIZE)
fn scatter(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let block = block_index(group, groups);
    // Uniform across the workgroup, so the barriers below are reached by every invocation.
    if block >= su.block_count {
        return;
    }
    // Each digit's first slot is its count's prefix within its slice (from `scan`) plus the
    // totals of the slices before (after the histogram): each invocation takes a run of them.
    let slices = DIGITS / su.digits_per_slice;
    let totals = DIGITS * su.block_count;
    let run = lane_run(lane, slices);
    var sum = 0u;
    for (var s = run.x; s < run.y; s++) {
        sum += histogram[totals + s];
    }
    var below = exclusive_scan(lane, sum);
    for (var s = run.x; s < run.y; s++) {
        slice_base[s] = below;
        below += histogram[totals + s];
    }
    workgroupBarrier();
    for (var d = lane; d < DIGITS; d += WORKGROUP_SIZE) {
        next_slot[d] = slice_base[d / su.digits_per_slice] + histogram[d * su.block_count + block];
    }
    for (var w = lane; w < DIGITS * WORDS; w += WORKGROUP_SIZE) {
        atomicStore(&members[w], 0u);
    }
    let word = lane / 32u;
    let bit = lane % 32u;
    for (var round = 0u; round < ROUNDS; round++) {
        workgroupBarrier();
        let i = block * BLOCK + round * WORKGROUP_SIZE + lane;
        let valid = i < su.count;
        var key = 0u;
        var digit = 0u;
        if valid {
            key = keys_in[i];
            digit = digit_of(key);
            atomicOr(&members[digit * WORDS + word], 1u << bit);
        }
        workgroupBarrier();
        var last = false;
        var rank = 0u;
        if valid {
            let mine = atomicLoad(&members[digit * WORDS + word]);
            rank = countOneBits(mine & ((1u << bit) - 1u));
            var later = mine >> bit >> 1u;
            for (var w = 0u; w < word; w++) {
                rank += countOneBits(atomicLoad(&members[digit * WORDS + w]));
            }
            for (var w = word + 1u; w < WORDS; w++) {
                later |= atomicLoad(&members[digit * WORDS + w]);
            }
            last = later == 0u;
            let slot = next_slot[digit] + rank;
            keys_out[slot] = key;
            values_out[slot] = values_in[i];
        }
        workgroupBarrier();
        if valid {
            // Every member reads its digit's words above; now they are cleared for the next
            // round, and the digit's last member of the round advances its next slot.
            atomicStore(&members[digit * WORDS + word], 0u);
            if last {
                next_slot[digit] += rank + 1u;
            }
        }
    }
}
