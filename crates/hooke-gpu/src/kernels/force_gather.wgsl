// Gather (PCA, paper Section 4.1): each vertex sums the forces of its springs from a CSR
// adjacency stored in the paper's valence-sorted order, so the invocations of a workgroup
// loop the same number of times. Writes the net spring force per vertex.

struct GatherEntry {
    neighbor: u32,
    rest_length: f32,
    stiffness: f32,
}

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// Processing slot -> vertex (vertices sorted by decreasing valence).
@group(0) @binding(2) var<storage, read> order: array<u32>;
// Per slot: first entry; length vertex_count + 1.
@group(0) @binding(3) var<storage, read> offsets: array<u32>;
@group(0) @binding(4) var<storage, read> entries: array<GatherEntry>;
@group(0) @binding(5) var<storage, read_write> forces: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let slot = flat_index(id, groups);
    if slot >= u.vertex_count {
        return;
    }
    let vertex = order[slot];
    let x = positions[vertex].xyz;
    var force = vec3<f32>(0.0);
    for (var k = offsets[slot]; k < offsets[slot + 1u]; k++) {
        let e = entries[k];
        force += spring_force(x, positions[e.neighbor].xyz, e.stiffness * u.stiffness_scale, e.rest_length);
    }
    forces[vertex] = vec4<f32>(force, 0.0);
}
