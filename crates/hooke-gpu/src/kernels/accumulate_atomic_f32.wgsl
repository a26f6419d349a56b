// Scatter accumulation with float atomics (needs SHADER_FLOAT32_ATOMIC): each spring adds its
// force to its `a` end and subtracts it from its `b` end. Fast, but the summation order
// depends on scheduling, so results may differ in the last bits from run to run.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> springs: array<Spring>;
@group(0) @binding(2) var<storage, read> spring_forces: array<vec4<f32>>;
// 4 floats per vertex (xyz + unused), zeroed before the pass; read as vec4 by `integrate`.
@group(0) @binding(3) var<storage, read_write> accumulated: array<atomic<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = flat_index(id, groups);
    if s >= u.spring_count {
        return;
    }
    let spring = springs[s];
    let force = spring_forces[s].xyz;
    atomicAdd(&accumulated[4u * spring.a + 0u], force.x);
    atomicAdd(&accumulated[4u * spring.a + 1u], force.y);
    atomicAdd(&accumulated[4u * spring.a + 2u], force.z);
    atomicAdd(&accumulated[4u * spring.b + 0u], -force.x);
    atomicAdd(&accumulated[4u * spring.b + 1u], -force.y);
    atomicAdd(&accumulated[4u * spring.b + 2u], -force.z);
}
