// The integration pass of scatter's atomic-fixed accumulation: the integer sums that
// `accumulate_fixed.wgsl` left in the per-vertex force buffer go back to newtons as each
// vertex advances (`verlet.wgsl`), so they need no pass of their own.

// Per vertex: the net spring force as integer units of 1 / fixed_scale newtons.
@group(0) @binding(5) var<storage, read> sums: array<vec4<i32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    integrate_vertex(v, positions[v].xyz, vec3<f32>(sums[v].xyz) / u.fixed_scale);
}

// Over a stencil: plus each vertex's own springs' integer sum, which its accumulation stored
// rather than added (integer sums: the same bits either way).
@group(0) @binding(8) var<storage, read> own_sums: array<vec4<i32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn with_own_sums(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    integrate_vertex(v, positions[v].xyz, vec3<f32>(sums[v].xyz + own_sums[v].xyz) / u.fixed_scale);
}
