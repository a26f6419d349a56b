// Collisions with spheres and planes (hooke_core::collide, the same rule): a vertex that ended
// inside a collider grown by the thickness moves out along the normal, and the collider's
// friction removes that share of the step's tangential motion. Runs after `integrate`.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> next_positions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> deltas: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> scales: array<vec4<f32>>;
// Four entries per collider: (centre, point or capsule start xyz, radius; < 0 for a plane),
// (a plane's normal, a ball's spin or a capsule's axis end - start xyz, friction), (velocity xyz, inverse mass; > 0 for a dynamic ball), (applied force xyz,
// restitution; for a scripted collider: 1 if a capsule, 0, repeat, keyframes). A scripted collider's first
// entry is its place at time 0; a dynamic ball's is where it is now (balls.wgsl moves it).
@group(0) @binding(5) var<storage, read> colliders: array<Collider>;
// The status buffer, read only here for its step clocks (`STEPS_DONE_WORD`).
@group(0) @binding(6) var<storage, read> status_words: array<u32, 5>;
// With dynamic balls: per vertex and collider, m c / dt^2 for the move c the collider made
// (N), which balls.wgsl sums into the ball's reaction.
@group(0) @binding(7) var<storage, read_write> reactions: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count || scales[v].x <= 0.0 {
        return;
    }
    let x = positions[v].xyz;
    var p = next_positions[v].xyz;
    let dt = 1.0 / u.inverse_dt;
    // Colliders are placed where their script puts them at the end of this step.
    let t = f32(status_words[STEPS_DONE_WORD + u.parity] + 1u) * dt;
    for (var c = 0u; c < u.collider_count; c++) {
        let motion = colliders[c].motion;
        var velocity = motion.xyz;
        var shape = colliders[c].place;
        if motion.w <= 0.0 {
            let placed = scripted_placement(c, shape.xyz, velocity, colliders[c].script, t);
            shape = vec4<f32>(placed.position, shape.w);
            velocity = placed.velocity;
        }
        let surface = colliders[c].surface;
        var normal = surface.xyz;
        var depth: f32;
        if shape.w >= 0.0 {
            let offset = p - round_center(c, shape.xyz, p);
            let distance = length(offset);
            normal = select(vec3<f32>(0.0, 1.0, 0.0), offset / distance, distance > 0.0);
            depth = shape.w + u.collision_thickness - distance;
        } else {
            depth = u.collision_thickness - dot(p - shape.xyz, normal);
        }
        let before = p;
        if depth > 0.0 {
            p += normal * depth;
            let step = p - x - velocity * dt;
            p -= (step - normal * dot(step, normal)) * surface.w;
        }
        if u.dynamic_count > 0u {
            // scales.x is dt^2 / m.
            reactions[v * u.collider_count + c] = vec4<f32>((p - before) / scales[v].x, 0.0);
        }
    }
    next_positions[v] = vec4<f32>(p, 1.0);
    deltas[v] = vec4<f32>(p - x, 0.0);
}
