// Approximate self-collision by binning (hooke_core::selfcollide, the same arithmetic): per
// grid, `cell_keys` hashes each vertex's cell, the radix sort orders vertices by key,
// `correct` tests each vertex against its window of sorted neighbours and finds how far it
// must move, and `apply` moves it (position and the step's motion). Runs after `collide`.

// Mirrors `SelfUniforms` in self_collide.rs.
struct SelfUniforms {
    vertex_count: u32,
    window: u32,
    distance: f32,
    inverse_cell: f32,
    // This grid's shift, in cells, along each axis.
    offset: f32,
    key_bits: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> cu: SelfUniforms;
// This step's new positions (read by `cell_keys` and `correct`).
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> keys: array<u32>;
// Vertex ids: in vertex order after `cell_keys`, in key order after the sort.
@group(0) @binding(3) var<storage, read_write> sorted: array<u32>;
@group(0) @binding(4) var<storage, read> scales: array<vec4<f32>>;
// The spring adjacency (CSR): neighbours of v are neighbors[offsets[v]..offsets[v + 1]].
@group(0) @binding(5) var<storage, read> offsets: array<u32>;
@group(0) @binding(6) var<storage, read> neighbors: array<u32>;
@group(0) @binding(7) var<storage, read_write> corrections: array<vec4<f32>>;
// The same buffer as `positions`, written by `apply`.
@group(0) @binding(8) var<storage, read_write> moved: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> deltas: array<vec4<f32>>;

fn cell_key(p: vec3<f32>) -> u32 {
    let cell = bitcast<vec3<u32>>(vec3<i32>(floor(p * cu.inverse_cell + vec3<f32>(cu.offset))));
    let hash = (cell.x * 73856093u) ^ (cell.y * 19349663u) ^ (cell.z * 83492791u);
    if cu.key_bits >= 32u {
        return hash;
    }
    return hash & ((1u << cu.key_bits) - 1u);
}

@compute @workgroup_size(64)
fn cell_keys(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= cu.vertex_count {
        return;
    }
    keys[v] = cell_key(positions[v].xyz);
    sorted[v] = v;
}

fn joined(a: u32, b: u32) -> bool {
    for (var e = offsets[a]; e < offsets[a + 1u]; e++) {
        if neighbors[e] == b {
            return true;
        }
    }
    return false;
}

@compute @workgroup_size(64)
fn correct(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = flat_index(id, groups);
    let n = cu.vertex_count;
    if j >= n {
        return;
    }
    let p = sorted[j];
    let wp = scales[p].x;
    var correction = vec3<f32>(0.0);
    if wp > 0.0 {
        let xp = positions[p].xyz;
        let d2 = cu.distance * cu.distance;
        let low = select(0u, j - cu.window, j >= cu.window);
        let high = min(j + cu.window + 1u, n);
        for (var m = low; m < high; m++) {
            if m == j {
                continue;
            }
            let q = sorted[m];
            let d = xp - positions[q].xyz;
            let l2 = dot(d, d);
            if l2 >= d2 || joined(p, q) {
                continue;
            }
            let share = wp / (wp + scales[q].x);
            if l2 == 0.0 {
                // Coincident: part them vertically, the lower index going up.
                let sign = select(-1.0, 1.0, p < q);
                correction += vec3<f32>(0.0, sign * share * cu.distance, 0.0);
            } else {
                let l = sqrt(l2);
                correction += d * (share * (cu.distance - l) / l);
            }
        }
    }
    corrections[p] = vec4<f32>(correction, 0.0);
}

@compute @workgroup_size(64)
fn apply(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= cu.vertex_count {
        return;
    }
    let c = corrections[v];
    moved[v] = vec4<f32>(moved[v].xyz + c.xyz, 1.0);
    deltas[v] = deltas[v] + c;
}
