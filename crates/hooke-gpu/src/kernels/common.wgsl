// Shared by every hooke kernel (prepended to each file when it is compiled).

// Mirrors `StepUniforms` in layout.rs.
struct StepUniforms {
    // g dt^2 (m), xyz.
    gravity_step: vec4<f32>,
    vertex_count: u32,
    spring_count: u32,
    // 1 when the extra-force buffer (point forces, drags, wind) holds this step's forces.
    has_extra: u32,
    // Fixed-point accumulation: integer units per newton.
    fixed_scale: f32,
    // Blend accumulation: texels per row of the force render target, and its row count.
    blend_width: u32,
    blend_height: u32,
    // Blend accumulation: newtons per stored unit.
    blend_scale: f32,
    inverse_dt: f32,
    triangle_count: u32,
    // Fixed-point accumulation: largest allowed |contribution| in integer units.
    fixed_limit: f32,
    // Colliders in the collider buffer, and the distance the cloth keeps from them (m).
    collider_count: u32,
    collision_thickness: f32,
    // Dynamic balls among the colliders (0: no reactions are recorded).
    dynamic_count: u32,
    // Every spring's stiffness is its record's times this (the material's stiffness scale).
    stiffness_scale: f32,
    // Every spring's stiffness, when all are alike and none can tear (see gather_integrate).
    uniform_stiffness: f32,
    // Which of the status's two step clocks is this step's (the current position buffer).
    parity: u32,
}

// Word of `Status` where `steps_done` starts, for kernels that read it as plain words.
const STEPS_DONE_WORD: u32 = 3u;

// Mirrors `GpuStatus` in layout.rs: written by the kernels, read back by the solver.
struct Status {
    // First step (1-based) that produced a non-finite position; 0xffffffff if none.
    first_bad_step: atomic<u32>,
    // Lowest vertex that was non-finite at that step.
    first_bad_vertex: atomic<u32>,
    // Non-zero once a fixed-point contribution was clamped.
    fixed_overflow: atomic<u32>,
    // Steps completed since the solver started, in two clocks: a step reads
    // `steps_done[u.parity]` and its integration sets the other one (see `verlet.wgsl`).
    steps_done: array<u32, 2>,
}

// Mirrors `GpuCollider` in layout.rs: one sphere, plane or capsule collider.
struct Collider {
    // Centre (sphere), point (plane) or start (capsule) xyz; radius w, or -1 for a plane.
    place: vec4<f32>,
    // A ball's spin, a plane's normal or a capsule's axis (end - start) xyz; friction w.
    surface: vec4<f32>,
    // Velocity xyz (m/s); inverse mass w, > 0 only for a dynamic ball.
    motion: vec4<f32>,
    // A dynamic ball: applied force xyz (N), restitution w. A scripted collider: 1 if a
    // capsule, 0, 1 if its path repeats, its keyframe count.
    script: vec4<f32>,
}

// Mirrors `GpuSpring` in layout.rs.
struct Spring {
    a: u32,
    b: u32,
    rest_length: f32,
    stiffness: f32,
}

// Status: a first bad "vertex" with this bit set is the dynamic ball of that collider.
const BALL_MARK: u32 = 0x80000000u;
// Incidence entries: spring index plus this bit when the vertex is the spring's far end.
const B_END: u32 = 0x80000000u;

// The spring of incidence entry `entry` (its index, without B_END).
fn entry_spring(entry: u32) -> u32 {
    return entry & ~B_END;
}

// `force`, a spring's force on its near end, on the end that incidence entry `entry` names.
fn on_entry_end(force: vec3<f32>, entry: u32) -> vec3<f32> {
    return select(force, -force, (entry & B_END) != 0u);
}

// Force of a spring on its near end (paper eq. 1, sign of eq. 4): D (1 - l0 / |d|) d.
fn spring_force(near: vec3<f32>, far: vec3<f32>, stiffness: f32, rest_length: f32) -> vec3<f32> {
    let d = far - near;
    // Clamped so coincident ends give zero force rather than 0/0.
    let length = sqrt(max(dot(d, d), 1.17549435e-38));
    return stiffness * (1.0 - rest_length / length) * d;
}

fn is_finite3(v: vec3<f32>) -> bool {
    // WGSL has no isnan/isinf: an all-ones exponent means inf or NaN.
    let exponent = bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u);
    return all(exponent != vec3<u32>(0x7f800000u));
}

// One kind of spring of a structured mesh (mirrors `GpuStencilEntry` in layout.rs).
struct StencilEntry {
    offset: i32,
    rest_length: f32,
    stiffness: f32,
    pad: u32,
}

// Mirrors `GpuStencil` in layout.rs: the first `len` kinds are used.
struct Stencil {
    kinds: array<StencilEntry, 24>,
    len: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// A vertex's stencil mask, bit k set if it has a spring of kind k: the mantissa of the float
// that carries it in its integration scales' z (stencil.rs).
fn stencil_mask(carrier: f32) -> u32 {
    return bitcast<u32>(carrier) & 0x7fffffu;
}
