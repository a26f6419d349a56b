// Scatter accumulation by incidence: each vertex gathers the precomputed forces of its springs
// (negated at the far end) in a fixed order. No atomics; bit-identical from run to run.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> spring_forces: array<vec4<f32>>;
// Per vertex: first entry; length vertex_count + 1.
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
// Spring index, plus B_END when the vertex is the spring's far end.
@group(0) @binding(3) var<storage, read> entries: array<u32>;
@group(0) @binding(4) var<storage, read_write> forces: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    var force = vec3<f32>(0.0);
    for (var k = offsets[v]; k < offsets[v + 1u]; k++) {
        let e = entries[k];
        force += on_entry_end(spring_forces[entry_spring(e)].xyz, e);
    }
    forces[v] = vec4<f32>(force, 0.0);
}
