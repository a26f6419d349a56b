// Scatter with float atomics (needs SHADER_FLOAT32_ATOMIC), force and accumulation in one
// pass: each spring computes its force (paper eq. 1), adds it to its `a` end and subtracts it
// from its `b` end, as Taichi's atomic scatter does; no per-spring force buffer is written or
// read. The summation order depends on scheduling, so results may differ in the last bits
// from run to run.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> springs: array<Spring>;
@group(0) @binding(2) var<storage, read> positions: array<vec4<f32>>;
// 4 floats per vertex (xyz + unused), zeroed before the pass; read as vec4 by `integrate`.
@group(0) @binding(3) var<storage, read_write> accumulated: array<atomic<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = flat_index(id, groups);
    if s >= u.spring_count {
        return;
    }
    let spring = springs[s];
    let force = spring_force(positions[spring.a].xyz, positions[spring.b].xyz, spring.stiffness * u.stiffness_scale, spring.rest_length);
    atomicAdd(&accumulated[4u * spring.a + 0u], force.x);
    atomicAdd(&accumulated[4u * spring.a + 1u], force.y);
    atomicAdd(&accumulated[4u * spring.a + 2u], force.z);
    atomicAdd(&accumulated[4u * spring.b + 0u], -force.x);
    atomicAdd(&accumulated[4u * spring.b + 1u], -force.y);
    atomicAdd(&accumulated[4u * spring.b + 2u], -force.z);
}
