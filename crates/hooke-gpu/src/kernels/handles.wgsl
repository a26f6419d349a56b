// Handles (hooke_core::handles, the same rule): each handle vertex is put at its initial
// position plus its handle's displacement at the end of this step, along the handle's own
// keyframes or as the collider it follows has moved. Runs after collide and balls.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> next_positions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> deltas: array<vec4<f32>>;
struct HandleVertex {
    // Its initial position xyz.
    rest: vec4<f32>,
    // The vertex, its handle.
    ids: vec4<u32>,
}

@group(0) @binding(4) var<storage, read> handle_vertices: array<HandleVertex>;
// The colliders as collide.wgsl and balls.wgsl keep them (a placeholder when there are none).
@group(0) @binding(5) var<storage, read> colliders: array<Collider>;
// The status buffer, read only here for its step clocks (`STEPS_DONE_WORD`).
@group(0) @binding(6) var<storage, read> status_words: array<u32, 5>;
// Two entries per handle: (the collider it follows, or -1 for its own path; 0; 1 if the path
// repeats; the path's keyframe count), then that collider's anchor at time 0 xyz.
@group(0) @binding(8) var<storage, read> handles: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = flat_index(id, groups);
    if k >= arrayLength(&handle_vertices) {
        return;
    }
    let v = handle_vertices[k].ids.x;
    let h = handle_vertices[k].ids.y;
    let rest = handle_vertices[k].rest;
    let motion = handles[2u * h];
    let dt = 1.0 / u.inverse_dt;
    let t = f32(status_words[STEPS_DONE_WORD + u.parity] + 1u) * dt;
    var displacement: vec3<f32>;
    if motion.x < 0.0 {
        // The handle's keyframes follow the colliders' in the keyframe buffer.
        let slot = u.collider_count + h;
        let script = vec4<f32>(0.0, 0.0, motion.z, motion.w);
        displacement = scripted_placement(slot, vec3<f32>(0.0), vec3<f32>(0.0), script, t).position;
    } else {
        let c = u32(motion.x);
        var anchor = colliders[c].place.xyz;
        if colliders[c].motion.w <= 0.0 {
            anchor = scripted_placement(c, anchor, colliders[c].motion.xyz, colliders[c].script, t).position;
        }
        displacement = anchor - handles[2u * h + 1u].xyz;
    }
    let p = rest.xyz + displacement;
    next_positions[v] = vec4<f32>(p, 1.0);
    deltas[v] = vec4<f32>(p - positions[v].xyz, 0.0);
}
