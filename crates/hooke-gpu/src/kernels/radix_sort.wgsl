// One pass of a stable LSD radix sort of (key, value) pairs on 8-bit digits (a pair is one
// vec2<u32>, so moving it is one 8-byte write, not two 4-byte ones): `count_digits`
// counts each block's digits (only for a first pass whose keys nobody counted as they were
// written), `scan` turns the counts (digit-major, then block) into prefix sums within slices of
// `slice_length` counts, with each slice's total after them, and `scatter` adds the totals of
// the slices below and moves every pair to its slot, ranked within its block by its position
// so equal digits keep their order. Where another pass follows, `scatter` also counts that
// pass's digits in the blocks the pairs land in, into the other of two histograms (which this
// pass's `scan` cleared), so later passes need no counting kernel: two dispatches a pass
// instead of three. Blocks and
// the histogram are digits.wgsl's. hooke_gpu::radix_sort runs the passes, 8 key bits each.

@group(0) @binding(0) var<uniform> su: SortUniforms;
// (key, value)
@group(0) @binding(1) var<storage, read> pairs_in: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> pairs_out: array<vec2<u32>>;
// The next pass's digit counts (its `histogram`), when `su.counts_next` is 1: cleared by `scan`,
// added to by `scatter`. Integer additions, so the counts do not depend on their order.
@group(0) @binding(11) var<storage, read_write> next_histogram: array<atomic<u32>>;

// Bit masks of one round's members per digit: SORT_GROUP / 32 words each.
override WORDS: u32 = SORT_GROUP / 32u;
override MEMBER_WORDS: u32 = DIGITS * WORDS;

var<workgroup> members: array<atomic<u32>, MEMBER_WORDS>;
// The next output slot of each digit in this block, advanced round by round.
var<workgroup> next_slot: array<u32, DIGITS>;
// Slices of the histogram at most (`radix_sort::MAX_SLICES`): `scatter` scans all their totals.
const MAX_SLICES: u32 = 1024u;
// The first slot of each slice of the histogram.
var<workgroup> slice_base: array<u32, MAX_SLICES>;
var<workgroup> partial_sums: array<u32, SORT_GROUP>;
// `scan`'s tile of counts: loaded and stored by consecutive invocations (coalesced), summed
// in runs per invocation from here.
const SCAN_TILE: u32 = 1024u;
var<workgroup> tile_counts: array<u32, SCAN_TILE>;
var<workgroup> tile_total: u32;

fn digit_of(key: u32) -> u32 {
    return (key >> su.shift) & (DIGITS - 1u);
}

fn entry_digit(i: u32) -> u32 {
    return digit_of(pairs_in[i].x);
}

@compute @workgroup_size(SORT_GROUP)
fn count_digits(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    count_block_digits(lane, block_index(group, groups), su.block_count, su.count);
}

// One workgroup per slice of `slice_length` consecutive counts of the digit-major histogram
// (a tile, SCAN_TILE, unless the histogram is so large that MAX_SLICES slices would not cover
// it), tile by tile: the tile is loaded into workgroup memory, each invocation sums a
// contiguous run of it, the run totals are scanned, each run is rewritten as exclusive prefix
// sums within the slice, and the tile is stored back; the slice's total goes after the
// histogram for `scatter`. Slices of a tile give a large sort many workgroups, each with one
// short pass over its counts, and a small one few (each pays for its barriers where a software
// renderer runs invocations in turn). Earlier a slice was one digit's counts at least: on an
// H100 its 256 workgroups, each reading 4096 counts in runs 64 counts apart between
// neighbouring invocations, took a fifth to a third of a 2048^2 self-collision step.
@compute @workgroup_size(SORT_GROUP)
fn scan(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let slice = block_index(group, groups);
    let counts = DIGITS * su.block_count;
    let base = slice * su.slice_length;
    // Uniform across the workgroup, so the barriers below are reached by every invocation.
    if base >= counts {
        return;
    }
    let length = min(su.slice_length, counts - base);
    if su.counts_next != 0u {
        // The same entries of the next pass's histogram: the slices cover it all. The last
        // reader of that histogram was the previous pass's `scatter`, which has finished.
        for (var i = lane; i < length; i += SORT_GROUP) {
            atomicStore(&next_histogram[base + i], 0u);
        }
    }
    var carry = 0u;
    for (var first = 0u; first < length; first += SCAN_TILE) {
        let size = min(SCAN_TILE, length - first);
        for (var i = lane; i < size; i += SORT_GROUP) {
            tile_counts[i] = histogram[base + first + i];
        }
        workgroupBarrier();
        let run = lane_run(lane, size);
        var total = 0u;
        for (var i = run.x; i < run.y; i++) {
            total += tile_counts[i];
        }
        var running = carry + exclusive_scan(lane, total);
        for (var i = run.x; i < run.y; i++) {
            let c = tile_counts[i];
            tile_counts[i] = running;
            running += c;
        }
        if lane == SORT_GROUP - 1u {
            tile_total = running;
        }
        workgroupBarrier();
        for (var i = lane; i < size; i += SORT_GROUP) {
            histogram[base + first + i] = tile_counts[i];
        }
        carry = tile_total;
        // Every invocation has read the tile and its total before the next tile replaces them.
        workgroupBarrier();
    }
    if lane == 0u {
        histogram[counts + slice] = carry;
    }
}

// The run [x, y) of `length` items that invocation `lane` takes: contiguous, in lane order.
fn lane_run(lane: u32, length: u32) -> vec2<u32> {
    let run = (length + SORT_GROUP - 1u) / SORT_GROUP;
    let start = min(lane * run, length);
    return vec2<u32>(start, min(start + run, length));
}

// The sum of `value` over the invocations before `lane` (every invocation calls it).
fn exclusive_scan(lane: u32, value: u32) -> u32 {
    partial_sums[lane] = value;
    workgroupBarrier();
    for (var offset = 1u; offset < SORT_GROUP; offset <<= 1u) {
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

// The block's pairs go out in ROUNDS rounds of SORT_GROUP, in order: a pair's slot is its
// digit's next slot in the block plus the members of its digit before it in its round.
@compute @workgroup_size(SORT_GROUP)
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
    let totals = DIGITS * su.block_count;
    let slices = (totals + su.slice_length - 1u) / su.slice_length;
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
    for (var d = lane; d < DIGITS; d += SORT_GROUP) {
        let entry = d * su.block_count + block;
        next_slot[d] = slice_base[entry / su.slice_length] + histogram[entry];
    }
    for (var w = lane; w < DIGITS * WORDS; w += SORT_GROUP) {
        atomicStore(&members[w], 0u);
    }
    let word = lane / 32u;
    let bit = lane % 32u;
    for (var round = 0u; round < ROUNDS; round++) {
        workgroupBarrier();
        let i = block * BLOCK + round * SORT_GROUP + lane;
        let valid = i < su.count;
        var pair = vec2<u32>(0u);
        var digit = 0u;
        if valid {
            pair = pairs_in[i];
            digit = digit_of(pair.x);
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
            pairs_out[slot] = pair;
            if su.counts_next != 0u {
                let next_digit = (pair.x >> (su.shift + BITS_PER_PASS)) & (DIGITS - 1u);
                atomicAdd(&next_histogram[next_digit * su.block_count + slot / BLOCK], 1u);
            }
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
