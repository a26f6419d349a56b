// Gather (PCA, paper Section 4.1), fused with integration: each vertex sums the forces of its
// springs from a CSR adjacency stored in the paper's valence-sorted order, so the invocations
// of a workgroup loop the same number of times, and advances at once (`verlet.wgsl`). The
// net force never leaves the invocation: one pass per step, no per-vertex force buffer.
//
// Three entry points: `main` reads each spring's stiffness from its entry; `uniform_stiffness`,
// for models whose springs all have one stiffness and cannot tear (nothing rewrites their
// entries), takes it from the uniforms and reads 8 of each entry's 12 bytes; `stencil`, for
// structured meshes that cannot tear (a grid: see stencil.rs), reads one mask per vertex (from
// the integration scales it loads anyway) and takes each spring's neighbour offset, rest length
// and stiffness from a small uniform table.
// The same floats go into the same arithmetic in the same order, so all give the same bits.

struct GatherEntry {
    neighbor: u32,
    rest_length: f32,
    stiffness: f32,
}

// Per processing slot: (vertex, its first entry); one more row whose .y ends the last one.
// (Vertex and offset share a buffer: with the integration's six, a stage may bind no more
// than WebGPU's default of eight storage buffers.)
@group(0) @binding(5) var<storage, read> rows: array<vec2<u32>>;
@group(0) @binding(8) var<storage, read> entries: array<GatherEntry>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    gather_and_integrate(flat_index(id, groups), false);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn uniform_stiffness(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    gather_and_integrate(flat_index(id, groups), true);
}

// `uniform` is a constant at each call, so the compiler drops the other case and its load.
fn gather_and_integrate(slot: u32, uniform: bool) {
    if slot >= u.vertex_count {
        return;
    }
    let row = rows[slot];
    let vertex = row.x;
    let x = positions[vertex].xyz;
    var force = vec3<f32>(0.0);
    for (var k = row.y; k < rows[slot + 1u].y; k++) {
        var stiffness = u.uniform_stiffness;
        if !uniform {
            stiffness = entries[k].stiffness;
        }
        let neighbor = positions[entries[k].neighbor].xyz;
        force += spring_force(x, neighbor, stiffness * u.stiffness_scale, entries[k].rest_length);
    }
    integrate_vertex(vertex, x, force);
}

@group(0) @binding(9) var<uniform> stencil_kinds: Stencil;

@compute @workgroup_size(WORKGROUP_SIZE)
fn stencil(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let vertex = flat_index(id, groups);
    if vertex >= u.vertex_count {
        return;
    }
    let x = positions[vertex].xyz;
    var force = vec3<f32>(0.0);
    let mask = stencil_mask(scales[vertex].z);
    // Lowest kind first: the order the vertex's CSR row lists its springs in.
    for (var k = 0u; k < stencil_kinds.len; k++) {
        if (mask & (1u << k)) != 0u {
            let kind = stencil_kinds.kinds[k];
            let neighbor = positions[u32(i32(vertex) + kind.offset)].xyz;
            force += spring_force(x, neighbor, kind.stiffness * u.stiffness_scale, kind.rest_length);
        }
    }
    integrate_vertex(vertex, x, force);
}
