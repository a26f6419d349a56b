// Approximate self-collision by binning (hooke_core::selfcollide, the same arithmetic): per
// grid, `cell_keys` moves each vertex by the previous grid's correction, hashes its cell and
// counts the first sort digits, the radix sort orders vertices by key, and `correct` tests each
// vertex against the same-cell vertices next to it in sorted order (at most `window` each
// side) and finds how far it must move. `apply` moves the vertices by the last grid's
// corrections. Runs after `collide`. Blocks and the histogram are digits.wgsl's.

// Mirrors `SelfUniforms` in self_collide.rs.
struct SelfUniforms {
    vertex_count: u32,
    window: u32,
    distance: f32,
    inverse_cell: f32,
    // This grid's shift, in cells, along each axis.
    offset: f32,
    key_bits: u32,
    // 1 when `cell_keys` first applies the previous grid's corrections (every grid but the first).
    apply_previous: u32,
    // Sort blocks (digits.wgsl) over the vertices.
    block_count: u32,
}

@group(0) @binding(0) var<uniform> cu: SelfUniforms;
// This step's new positions, read by `correct` (`moved` is the same buffer, for the kernels that
// write it).
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// (cell key, vertex): in vertex order after `cell_keys`, in key order after the sort.
@group(0) @binding(2) var<storage, read_write> pairs: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read> scales: array<vec4<f32>>;
// The spring adjacency (CSR): neighbours of v are neighbors[offsets[v]..offsets[v + 1]].
@group(0) @binding(5) var<storage, read> offsets: array<u32>;
@group(0) @binding(6) var<storage, read> neighbors: array<u32>;
@group(0) @binding(7) var<storage, read_write> corrections: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> moved: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> deltas: array<vec4<f32>>;

fn cell_of(p: vec3<f32>) -> vec3<i32> {
    return vec3<i32>(floor(p * cu.inverse_cell + vec3<f32>(cu.offset)));
}

fn cell_key(p: vec3<f32>) -> u32 {
    let cell = bitcast<vec3<u32>>(cell_of(p));
    let hash = (cell.x * 73856093u) ^ (cell.y * 19349663u) ^ (cell.z * 83492791u);
    if cu.key_bits >= 32u {
        return hash;
    }
    return hash & ((1u << cu.key_bits) - 1u);
}

// Moves `v` by its correction: position and the step's motion. Returns the new position.
// Most vertices have none: they are left as they are, as on the CPU (which moves only the
// vertices it pushed), and their position and motion are not written back.
fn apply_correction(v: u32) -> vec3<f32> {
    let c = corrections[v];
    let x = moved[v].xyz;
    if all(c.xyz == vec3<f32>(0.0)) {
        return x;
    }
    let corrected = x + c.xyz;
    moved[v] = vec4<f32>(corrected, 1.0);
    deltas[v] = deltas[v] + c;
    return corrected;
}

// Vertex `v`'s key for this grid, after moving it by the previous grid's correction (every
// grid but the first); returns the sort's first digit, which `cell_keys` counts.
fn entry_digit(v: u32) -> u32 {
    var x: vec3<f32>;
    if cu.apply_previous != 0u {
        x = apply_correction(v);
    } else {
        x = moved[v].xyz;
    }
    let key = cell_key(x);
    pairs[v] = vec2<u32>(key, v);
    return key & (DIGITS - 1u);
}

// One sort block of vertices per workgroup, so the block's first-pass digit counts are
// complete when it ends.
@compute @workgroup_size(SORT_GROUP)
fn cell_keys(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    count_block_digits(lane, block_index(group, groups), cu.block_count, cu.vertex_count);
}

fn joined(a: u32, b: u32) -> bool {
    for (var e = offsets[a]; e < offsets[a + 1u]; e++) {
        if neighbors[e] == b {
            return true;
        }
    }
    return false;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn correct(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = flat_index(id, groups);
    let n = cu.vertex_count;
    if j >= n {
        return;
    }
    let slot = pairs[j];
    let p = slot.y;
    let wp = scales[p].x;
    var correction = vec3<f32>(0.0);
    if wp > 0.0 {
        let xp = positions[p].xyz;
        let d2 = cu.distance * cu.distance;
        let key = slot.x;
        let cell = cell_of(xp);
        // The window: the nearest `window` slots of the same cell on each side, below j and
        // then above (as on the CPU), among the slots of the same key; far cells hashed to
        // the same key are passed over.
        var found = 0u;
        for (var m = j; m > 0u && found < cu.window; m--) {
            let other = pairs[m - 1u];
            if other.x != key {
                break;
            }
            let xq = positions[other.y].xyz;
            if all(cell_of(xq) == cell) {
                found++;
                correction += push(p, other.y, xp, xq, wp, d2);
            }
        }
        found = 0u;
        for (var m = j + 1u; m < n && found < cu.window; m++) {
            let other = pairs[m];
            if other.x != key {
                break;
            }
            let xq = positions[other.y].xyz;
            if all(cell_of(xq) == cell) {
                found++;
                correction += push(p, other.y, xp, xq, wp, d2);
            }
        }
    }
    corrections[p] = vec4<f32>(correction, 0.0);
}

// How far `p` (at `xp`, weight `wp`) moves away from `q` (at `xq`): zero unless unjoined and
// too close.
fn push(p: u32, q: u32, xp: vec3<f32>, xq: vec3<f32>, wp: f32, d2: f32) -> vec3<f32> {
    let d = xp - xq;
    let l2 = dot(d, d);
    if l2 >= d2 || joined(p, q) {
        return vec3<f32>(0.0);
    }
    let share = wp / (wp + scales[q].x);
    if l2 == 0.0 {
        // Coincident: part them vertically, the lower index going up.
        let sign = select(-1.0, 1.0, p < q);
        return vec3<f32>(0.0, sign * share * cu.distance, 0.0);
    }
    let l = sqrt(l2);
    return d * (share * (cu.distance - l) / l);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn apply(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v < cu.vertex_count {
        apply_correction(v);
    }
}
