// Scripted collider motion, shared by collide.wgsl and balls.wgsl (prepended to both):
// hooke_core::collide::Collider::at for colliders without dynamics.

// Keyframes (t, x, y, z) of scripted paths, MAX_KEYFRAMES slots per collider.
@group(0) @binding(12) var<storage, read> keyframes: array<vec4<f32>>;

const MAX_KEYFRAMES: u32 = 8u;

// The point the cloth or a ball at `p` meets on collider `c` placed at `place` (a sphere's or
// capsule's; see collide.wgsl for the entries): a capsule's axis point closest to `p`.
fn round_center(c: u32, place: vec3<f32>, p: vec3<f32>) -> vec3<f32> {
    // Capsules are never dynamic, and mark entry 3's x.
    if colliders[c].motion.w > 0.0 || colliders[c].script.x < 0.5 {
        return place;
    }
    let axis = colliders[c].surface.xyz;
    let length2 = dot(axis, axis);
    if length2 == 0.0 {
        return place;
    }
    return place + axis * clamp(dot(p - place, axis) / length2, 0.0, 1.0);
}

struct Placement {
    position: vec3<f32>,
    velocity: vec3<f32>,
}

// Where scripted collider `c` is at time `t` and how fast it moves: along its keyframes when
// it has two or more (`script` = collider entry 3: z > 0.5 repeats, w counts keyframes), else
// on the straight path from `anchor` at `velocity`.
fn scripted_placement(c: u32, anchor: vec3<f32>, velocity: vec3<f32>, script: vec4<f32>, t: f32) -> Placement {
    let count = u32(script.w);
    if count < 2u {
        return Placement(anchor + velocity * t, velocity);
    }
    let base = c * MAX_KEYFRAMES;
    let first = keyframes[base];
    let last = keyframes[base + count - 1u];
    var s = t;
    if script.z > 0.5 {
        let span = last.x - first.x;
        s = first.x + (t - first.x) - floor((t - first.x) / span) * span;
    }
    if s <= first.x {
        return Placement(first.yzw, vec3<f32>(0.0));
    }
    for (var k = 0u; k + 1u < count; k++) {
        let a = keyframes[base + k];
        let b = keyframes[base + k + 1u];
        if s < b.x {
            let v = (b.yzw - a.yzw) / (b.x - a.x);
            return Placement(a.yzw + v * (s - a.x), v);
        }
    }
    return Placement(last.yzw, vec3<f32>(0.0));
}
