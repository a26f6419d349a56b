// Scatter with float atomics (needs SHADER_FLOAT32_ATOMIC), force and accumulation in one
// pass: each spring computes its force (paper eq. 1), adds it to its `a` end and subtracts it
// from its `b` end, as Taichi's atomic scatter does; no per-spring force buffer is written or
// read. The summation order depends on scheduling, so results may differ in the last bits
// from run to run.
//
// Two entry points: `main`, one invocation per spring record; `stencil`, for structured
// meshes whose springs cannot tear (see stencil.rs), one invocation per vertex owning the
// springs whose kind points to a higher index: it computes their forces, subtracts each at
// its far end, and writes their sum at its own end to `own_sums` with a plain store, which
// the integration adds (3 atomic adds a spring instead of 6, and no spring record read).

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> springs: array<Spring>;
@group(0) @binding(2) var<storage, read> positions: array<vec4<f32>>;
// 4 floats per vertex (xyz + unused), zeroed before the pass; read as vec4 by `integrate`.
@group(0) @binding(3) var<storage, read_write> accumulated: array<atomic<f32>>;
// The stencil's: per vertex its mask (in z, see `stencil_mask`), and the kinds.
@group(0) @binding(5) var<storage, read> scales: array<vec4<f32>>;
@group(0) @binding(6) var<uniform> stencil_kinds: Stencil;
// The stencil's: per vertex the sum of the springs it owns (xyz + unused), written every step.
@group(0) @binding(7) var<storage, read_write> own_sums: array<vec4<f32>>;

fn add_at(vertex: u32, force: vec3<f32>) {
    atomicAdd(&accumulated[4u * vertex + 0u], force.x);
    atomicAdd(&accumulated[4u * vertex + 1u], force.y);
    atomicAdd(&accumulated[4u * vertex + 2u], force.z);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = flat_index(id, groups);
    if s >= u.spring_count {
        return;
    }
    let spring = springs[s];
    let force = spring_force(positions[spring.a].xyz, positions[spring.b].xyz, spring.stiffness * u.stiffness_scale, spring.rest_length);
    add_at(spring.a, force);
    add_at(spring.b, -force);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn stencil(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let vertex = flat_index(id, groups);
    if vertex >= u.vertex_count {
        return;
    }
    let x = positions[vertex].xyz;
    let mask = stencil_mask(scales[vertex].z);
    var own = vec3<f32>(0.0);
    for (var k = 0u; k < stencil_kinds.len; k++) {
        let kind = stencil_kinds.kinds[k];
        if (mask & (1u << k)) != 0u && kind.offset > 0 {
            let neighbor = u32(i32(vertex) + kind.offset);
            let force = spring_force(x, positions[neighbor].xyz, kind.stiffness * u.stiffness_scale, kind.rest_length);
            own += force;
            add_at(neighbor, -force);
        }
    }
    own_sums[vertex] = vec4<f32>(own, 0.0);
}
