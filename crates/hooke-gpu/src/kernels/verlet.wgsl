// Verlet with damping (paper eq. 3-4) in delta form, the same arithmetic as the CPU solver:
// with d = x - x_prev, a = dt^2 / m and v = 1 - c dt / m (both 0 for pinned vertices),
// d' = v d + a F + g dt^2 and x' = x + d'. Storing d instead of x_prev keeps float32
// increments at their own precision. Records the first non-finite position in `status`, and
// counts the step there.
// Prepended to every kernel that integrates: `integrate.wgsl` (after a scatter method's
// accumulation) and `gather_integrate.wgsl` (which sums the springs in the same invocation).

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> next_positions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> deltas: array<vec4<f32>>;
// Per vertex: (dt^2 / m, 1 - c dt / m, 0, 0).
@group(0) @binding(4) var<storage, read> scales: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> extra_forces: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> status: Status;

// Advances vertex `v`, now at `x`, under its net spring force.
fn integrate_vertex(v: u32, x: vec3<f32>, spring_force: vec3<f32>) {
    let scale = scales[v];
    var force = spring_force;
    if u.has_extra != 0u {
        force += extra_forces[v].xyz;
    }
    let moved = deltas[v].xyz * scale.y + force * scale.x + u.gravity_step.xyz;
    // Select rather than scale by zero: a pinned vertex must stay put even if a force is inf.
    let free = scale.x > 0.0;
    let delta = select(vec3<f32>(0.0), moved, free);
    let next = select(x, x + delta, free);
    deltas[v] = vec4<f32>(delta, 0.0);
    next_positions[v] = vec4<f32>(next, 1.0);
    if v == 0u {
        // Every step integrates vertex 0 once: it advances the clock the next step reads.
        status.steps_done[1u - u.parity] = status.steps_done[u.parity] + 1u;
    }
    if !is_finite3(next) {
        let step = status.steps_done[u.parity] + 1u;
        // Steps run one after another, so only invocations of the first bad step see
        // `previous >= step` and compete for the lowest vertex.
        let previous = atomicMin(&status.first_bad_step, step);
        if previous >= step {
            atomicMin(&status.first_bad_vertex, v);
        }
    }
}
