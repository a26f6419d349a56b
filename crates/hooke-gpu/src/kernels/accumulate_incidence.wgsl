// Scatter accumulation by incidence: each vertex gathers the precomputed forces of its springs
// (negated at the far end) in a fixed order. No atomics; bit-identical from run to run.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> spring_forces: array<vec4<f32>>;
// Per vertex: first entry; length vertex_count + 1 (`main` only).
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
// Spring index, plus B_END when the vertex is the spring's far end.
@group(0) @binding(3) var<storage, read> entries: array<u32>;
@group(0) @binding(4) var<storage, read_write> forces: array<vec4<f32>>;

// Entries per vertex in `rows`, whose rows are padded to this many.
override ROW_ENTRIES: u32 = 8u;

fn add_entry(force: vec3<f32>, e: u32) -> vec3<f32> {
    let f = spring_forces[e & ~B_END].xyz;
    return force + select(f, -f, (e & B_END) != 0u);
}

// A vertex's entries from `offsets[v]` to `offsets[v + 1]`.
@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    var force = vec3<f32>(0.0);
    for (var k = offsets[v]; k < offsets[v + 1u]; k++) {
        force = add_entry(force, entries[k]);
    }
    forces[v] = vec4<f32>(force, 0.0);
}

// A vertex's `ROW_ENTRIES` entries from `v * ROW_ENTRIES`: a loop of a constant count, which
// a CPU driver unrolls and runs alike in every lane (lavapipe took 5.3-5.5 ms for the loop above
// at 512^2 and 4.1-4.5 for this one). A padding entry names the zero force past the springs' with
// B_END, so it adds -0.0: the sum keeps its bits, as if the row ended there.
@compute @workgroup_size(WORKGROUP_SIZE)
fn rows(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    var force = vec3<f32>(0.0);
    for (var i = 0u; i < ROW_ENTRIES; i++) {
        force = add_entry(force, entries[v * ROW_ENTRIES + i]);
    }
    forces[v] = vec4<f32>(force, 0.0);
}
