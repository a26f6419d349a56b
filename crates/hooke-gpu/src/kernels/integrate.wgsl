// The integration pass of the scatter methods: each vertex advances under the forces their
// accumulation summed (the integration itself is `verlet.wgsl`).

// Per vertex: the net spring force.
@group(0) @binding(5) var<storage, read> forces: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    integrate_vertex(v, positions[v].xyz, forces[v].xyz);
}

// atomic-f32 over a stencil: the far ends' atomic sums, plus each vertex's own springs' sum,
// which its accumulation stored rather than added.
@group(0) @binding(8) var<storage, read> own_sums: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn with_own_sums(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    integrate_vertex(v, positions[v].xyz, forces[v].xyz + own_sums[v].xyz);
}
