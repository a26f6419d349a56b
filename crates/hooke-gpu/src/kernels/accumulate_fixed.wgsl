// Scatter in fixed point with integer atomics (works everywhere, WebGPU too), force and
// accumulation in one pass: each spring computes its force (paper eq. 1), and a force f becomes
// round(f * fixed_scale) in an i32 added to its `a` end and subtracted from its `b` end. The
// host picks fixed_scale so that no single contribution exceeds 2^31 / (max valence + 1): a
// vertex's sum then cannot wrap. A larger contribution is clamped and raises the overflow
// flag, which the solver reports. Integer addition is associative, so the result is
// bit-identical from run to run. The sums stay integers in the per-vertex force buffer;
// `integrate_fixed.wgsl` turns them back into newtons.
//
// Two entry points, as in `accumulate_atomic_f32.wgsl`: `main` per spring record, `stencil`
// per vertex of a structured mesh, which stores its own springs' integers' sum in `own_sums`
// for the integration to add (the same integers reach every vertex, so the same bits as
// `main`).

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> springs: array<Spring>;
@group(0) @binding(2) var<storage, read> positions: array<vec4<f32>>;
// The per-vertex force buffer as 4 integers per vertex, zeroed before the pass.
@group(0) @binding(3) var<storage, read_write> accumulated: array<atomic<i32>>;
@group(0) @binding(4) var<storage, read_write> status: Status;
// The stencil's: per vertex its mask (in z, see `stencil_mask`), and the kinds.
@group(0) @binding(5) var<storage, read> scales: array<vec4<f32>>;
@group(0) @binding(6) var<uniform> stencil_kinds: Stencil;
// The stencil's: per vertex the integer sum of the springs it owns, written every step.
@group(0) @binding(7) var<storage, read_write> own_sums: array<vec4<i32>>;

fn to_fixed(force: vec3<f32>) -> vec3<i32> {
    let scaled = force * u.fixed_scale;
    if any(abs(scaled) > vec3<f32>(u.fixed_limit)) || !is_finite3(scaled) {
        atomicOr(&status.fixed_overflow, 1u);
    }
    // NaN fails both comparisons of clamp and is sent to 0 by select; the flag is already set.
    let clamped = clamp(scaled, vec3<f32>(-u.fixed_limit), vec3<f32>(u.fixed_limit));
    return vec3<i32>(round(select(vec3<f32>(0.0), clamped, clamped == clamped)));
}

fn add_at(vertex: u32, q: vec3<i32>) {
    atomicAdd(&accumulated[4u * vertex + 0u], q.x);
    atomicAdd(&accumulated[4u * vertex + 1u], q.y);
    atomicAdd(&accumulated[4u * vertex + 2u], q.z);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = flat_index(id, groups);
    if s >= u.spring_count {
        return;
    }
    let spring = springs[s];
    let q = to_fixed(spring_force(positions[spring.a].xyz, positions[spring.b].xyz, spring.stiffness * u.stiffness_scale, spring.rest_length));
    add_at(spring.a, q);
    add_at(spring.b, -q);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn stencil(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let vertex = flat_index(id, groups);
    if vertex >= u.vertex_count {
        return;
    }
    let x = positions[vertex].xyz;
    let mask = stencil_mask(scales[vertex].z);
    var own = vec3<i32>(0);
    for (var k = 0u; k < stencil_kinds.len; k++) {
        let kind = stencil_kinds.kinds[k];
        if (mask & (1u << k)) != 0u && kind.offset > 0 {
            let neighbor = u32(i32(vertex) + kind.offset);
            let q = to_fixed(spring_force(x, positions[neighbor].xyz, kind.stiffness * u.stiffness_scale, kind.rest_length));
            own += q;
            add_at(neighbor, -q);
        }
    }
    own_sums[vertex] = vec4<i32>(own, 0);
}
