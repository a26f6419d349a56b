// The paper's own scatter (Section 4.2): every spring end is drawn as a point primitive at its
// vertex's texel of a force render target, carrying the spring's force (negated at the far
// end), and additive blending sums them. Forces are stored in units of `blend_scale` newtons.
// With a float target (rgba32float, rgba16float) the value is signed; with an 8-bit unorm
// target, which clamps to [0, 1], positive and negative parts go to two targets and the host
// sets blend_scale so that a vertex's sum of either part stays below 1.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> springs: array<Spring>;
@group(0) @binding(2) var<storage, read> spring_forces: array<vec4<f32>>;

struct PointOut {
    @builtin(position) position: vec4<f32>,
    @location(0) force: vec4<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> PointOut {
    let spring = springs[index / 2u];
    let far_end = (index & 1u) == 1u;
    let vertex = select(spring.a, spring.b, far_end);
    let force = spring_forces[index / 2u].xyz;
    let texel = vec2<f32>(f32(vertex % u.blend_width), f32(vertex / u.blend_width)) + 0.5;
    let size = vec2<f32>(f32(u.blend_width), f32(u.blend_height));
    // Texel centre to clip space (y down in texture rows, up in clip space).
    let clip = vec2<f32>(texel.x / size.x * 2.0 - 1.0, 1.0 - texel.y / size.y * 2.0);
    var out: PointOut;
    out.position = vec4<f32>(clip, 0.0, 1.0);
    out.force = vec4<f32>(select(force, -force, far_end) / u.blend_scale, 0.0);
    return out;
}

@fragment
fn fs_signed(point: PointOut) -> @location(0) vec4<f32> {
    return point.force;
}

struct SplitOut {
    @location(0) positive: vec4<f32>,
    @location(1) negative: vec4<f32>,
}

@fragment
fn fs_split(point: PointOut) -> SplitOut {
    var out: SplitOut;
    out.positive = max(point.force, vec4<f32>(0.0));
    out.negative = max(-point.force, vec4<f32>(0.0));
    return out;
}
