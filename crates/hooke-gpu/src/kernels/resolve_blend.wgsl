// Blend accumulation, second pass: the force render target(s) back to newtons per vertex.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var positive: texture_2d<f32>;
// Negative parts (8-bit unorm targets only; bound to a cleared texture otherwise).
@group(0) @binding(2) var negative: texture_2d<f32>;
@group(0) @binding(3) var<storage, read_write> forces: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    let texel = vec2<u32>(v % u.blend_width, v / u.blend_width);
    let sum = textureLoad(positive, texel, 0).xyz - textureLoad(negative, texel, 0).xyz;
    forces[v] = vec4<f32>(sum * u.blend_scale, 0.0);
}
