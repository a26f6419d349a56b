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
