// Scatter in fixed point with integer atomics (works everywhere, WebGPU too), force and
// accumulation in one pass: each spring computes its force (paper eq. 1), and a force f becomes
// round(f * fixed_scale) in an i32 added to its `a` end and subtracted from its `b` end. The
// host picks fixed_scale so that no single contribution exceeds 2^31 / (max valence + 1): a
// vertex's sum then cannot wrap. A larger contribution is clamped and raises the overflow
// flag, which the solver reports. Integer addition is associative, so the result is
// bit-identical from run to run. The sums stay integers in the per-vertex force buffer;
// `integrate_fixed.wgsl` turns them back into newtons.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> springs: array<Spring>;
@group(0) @binding(2) var<storage, read> positions: array<vec4<f32>>;
// The per-vertex force buffer as 4 integers per vertex, zeroed before the pass.
@group(0) @binding(3) var<storage, read_write> accumulated: array<atomic<i32>>;
@group(0) @binding(4) var<storage, read_write> status: Status;

fn to_fixed(force: vec3<f32>) -> vec3<i32> {
    let scaled = force * u.fixed_scale;
    if any(abs(scaled) > vec3<f32>(u.fixed_limit)) || !is_finite3(scaled) {
        atomicOr(&status.fixed_overflow, 1u);
    }
    // NaN fails both comparisons of clamp and is sent to 0 by select; the flag is already set.
    let clamped = clamp(scaled, vec3<f32>(-u.fixed_limit), vec3<f32>(u.fixed_limit));
    return vec3<i32>(round(select(vec3<f32>(0.0), clamped, clamped == clamped)));
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = flat_index(id, groups);
    if s >= u.spring_count {
        return;
    }
    let spring = springs[s];
    let q = to_fixed(spring_force(positions[spring.a].xyz, positions[spring.b].xyz, spring.stiffness * u.stiffness_scale, spring.rest_length));
    atomicAdd(&accumulated[4u * spring.a + 0u], q.x);
    atomicAdd(&accumulated[4u * spring.a + 1u], q.y);
    atomicAdd(&accumulated[4u * spring.a + 2u], q.z);
    atomicSub(&accumulated[4u * spring.b + 0u], q.x);
    atomicSub(&accumulated[4u * spring.b + 1u], q.y);
    atomicSub(&accumulated[4u * spring.b + 2u], q.z);
}
