// Dynamic balls (hooke_core::collide::advance_balls, the same rule): `advance` runs one
// workgroup per collider, sums the cloth's reaction on it in a fixed order (deterministic),
// and moves a dynamic ball by gravity, its applied force and that reaction; `contacts`, one
// invocation, then lets each ball in turn meet the planes and other spheres. Runs after
// `collide`. Collider entries as in collide.wgsl.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read_write> colliders: array<Collider>;
@group(0) @binding(2) var<storage, read> reactions: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> status: Status;

var<workgroup> partial: array<vec3<f32>, WORKGROUP_SIZE>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn advance(
    @builtin(local_invocation_index) lane: u32,
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let c = group.x + group.y * groups.x;
    var sum = vec3<f32>(0.0);
    if c < u.collider_count {
        for (var v = lane; v < u.vertex_count; v += WORKGROUP_SIZE) {
            sum += reactions[v * u.collider_count + c].xyz;
        }
    }
    partial[lane] = sum;
    workgroupBarrier();
    for (var half = WORKGROUP_SIZE / 2u; half > 0u; half >>= 1u) {
        if lane < half {
            partial[lane] += partial[lane + half];
        }
        workgroupBarrier();
    }
    if lane != 0u || c >= u.collider_count {
        return;
    }
    let inverse_mass = colliders[c].motion.w;
    if inverse_mass <= 0.0 {
        return;
    }
    let dt = 1.0 / u.inverse_dt;
    let gravity = u.gravity_step.xyz * u.inverse_dt * u.inverse_dt;
    let force = colliders[c].script.xyz - partial[0];
    let velocity = colliders[c].motion.xyz + (force * inverse_mass + gravity) * dt;
    let position = colliders[c].place.xyz + velocity * dt;
    colliders[c].motion = vec4<f32>(velocity, inverse_mass);
    colliders[c].place = vec4<f32>(position, colliders[c].place.w);
    if !is_finite3(position) || !is_finite3(velocity) {
        // Reported like a vertex, marked as a ball (a bad vertex of the same step wins).
        let step = status.steps_done[u.parity] + 1u;
        let previous = atomicMin(&status.first_bad_step, step);
        if previous >= step {
            atomicMin(&status.first_bad_vertex, BALL_MARK | c);
        }
    }
}

// The status buffer, for the step clocks that place scripted colliders.
@group(0) @binding(3) var<storage, read> status_words: array<u32, 5>;

// Collider `c` at time `t` (a dynamic ball where it is): place (xyz, radius or -1) and velocity.
fn place(c: u32, t: f32) -> Placement {
    let motion = colliders[c].motion;
    if motion.w > 0.0 {
        return Placement(colliders[c].place.xyz, motion.xyz);
    }
    return scripted_placement(c, colliders[c].place.xyz, motion.xyz, colliders[c].script, t);
}

@compute @workgroup_size(1)
fn contacts() {
    let t = f32(status_words[STEPS_DONE_WORD + u.parity] + 1u) / u.inverse_dt;
    for (var k = 0u; k < u.collider_count; k++) {
        let inverse_mass = colliders[k].motion.w;
        if inverse_mass <= 0.0 {
            continue;
        }
        let restitution = colliders[k].script.w;
        for (var o = 0u; o < u.collider_count; o++) {
            if o == k {
                continue;
            }
            let ball = colliders[k].place;
            let placed = place(o, t);
            let other = vec4<f32>(placed.position, colliders[o].place.w);
            var normal: vec3<f32>;
            var depth: f32;
            if other.w < 0.0 {
                normal = colliders[o].surface.xyz;
                depth = ball.w - dot(ball.xyz - other.xyz, normal);
            } else {
                let offset = ball.xyz - round_center(o, other.xyz, ball.xyz);
                let distance = length(offset);
                normal = select(vec3<f32>(0.0, 1.0, 0.0), offset / distance, distance > 0.0);
                depth = ball.w + other.w - distance;
            }
            if depth <= 0.0 {
                continue;
            }
            let other_inverse_mass = colliders[o].motion.w;
            // The ball's share of push and impulse: all of it against a scripted obstacle.
            var share = 1.0;
            if other_inverse_mass > 0.0 {
                share = inverse_mass / (inverse_mass + other_inverse_mass);
            }
            let relative = colliders[k].motion.xyz - placed.velocity;
            let approach = dot(relative, normal);
            var bounce = 0.0;
            if approach < 0.0 {
                bounce = -(1.0 + restitution) * approach;
            }
            // Slip of the contact point; stopping it takes 2/7 of it from the centre's
            // velocity, the rest from the spin, within mu times the normal speed change.
            let spin = colliders[k].surface;
            let arm = -normal * ball.w;
            let contact = relative + cross(spin.xyz, arm);
            let slip = contact - normal * dot(contact, normal);
            let wanted = slip * (2.0 / 7.0);
            let limit = colliders[o].surface.w * bounce;
            var friction = wanted;
            if length(wanted) > limit {
                friction = wanted * (limit / length(wanted));
            }
            let change = normal * bounce - friction;
            colliders[k].motion = vec4<f32>(colliders[k].motion.xyz + change * share, inverse_mass);
            let spun = spin.xyz + cross(arm, -friction) * (share * 2.5 / (ball.w * ball.w));
            colliders[k].surface = vec4<f32>(spun, spin.w);
            colliders[k].place = vec4<f32>(ball.xyz + normal * (depth * share), ball.w);
            if other_inverse_mass > 0.0 {
                let rest = 1.0 - share;
                colliders[o].motion = vec4<f32>(colliders[o].motion.xyz - change * rest, other_inverse_mass);
                colliders[o].place = vec4<f32>(other.xyz - normal * (depth * rest), other.w);
            }
        }
    }
}
