// Drawing the cloth straight from the simulation's position buffer (vertex pulling: no copy),
// plus the ground, the springs as a wireframe, pin markers and wind arrows.

struct Frame {
    view_projection: mat4x4<f32>,
    // Camera position (xyz).
    eye: vec4<f32>,
    // Centre of the scene (xyz): the ground is centred under it.
    center: vec4<f32>,
    // Direction toward the light (xyz).
    light: vec4<f32>,
    // Ground height, half its size, checker size (m), fog distance (m).
    ground: vec4<f32>,
    // Wind direction (xyz, unit) and arrow length (m); arrow grid origin and spacing.
    wind: vec4<f32>,
    wind_origin: vec4<f32>,
    // x: colour by strain (1) or checker (0); y: strain at full red; z: pin marker size (m);
    // w: 1 if springs can break (triangles with a broken edge are not drawn).
    style: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> triangles: array<vec4<u32>>;
// Per vertex: texture coordinates from the rest shape (xy).
@group(0) @binding(4) var<storage, read> uvs: array<vec2<f32>>;
// Per triangle: rest lengths of edges 01, 12, 20.
@group(0) @binding(5) var<storage, read> rest_edges: array<vec4<f32>>;
// Per spring: its two vertices.
@group(0) @binding(6) var<storage, read> springs: array<vec2<u32>>;
@group(0) @binding(7) var<storage, read> pins: array<u32>;
// Per triangle: the springs of edges 01, 12, 20; per spring: 1 once broken (the solver's flags).
@group(0) @binding(12) var<storage, read> triangle_edges: array<vec4<u32>>;
@group(0) @binding(13) var<storage, read> broken: array<u32>;

fn torn(triangle: u32) -> bool {
    if frame.style.w == 0.0 {
        return false;
    }
    let edges = triangle_edges[triangle];
    return broken[edges.x] != 0u || broken[edges.y] != 0u || broken[edges.z] != 0u;
}

// Outside the depth range: a corner (or a whole primitive) placed here draws nothing.
const CLIPPED = vec4<f32>(0.0, 0.0, 2.0, 1.0);

struct ClothOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) strain: f32,
}

fn fog(color: vec3<f32>, world: vec3<f32>) -> vec3<f32> {
    // Distance fog toward the sky colour: a depth cue without shadows.
    let sky = vec3<f32>(0.80, 0.85, 0.92);
    let amount = clamp(distance(world, frame.eye.xyz) / frame.ground.w, 0.0, 1.0);
    return mix(color, sky, amount * amount * 0.85);
}

@vertex
fn vs_cloth(@builtin(vertex_index) index: u32) -> ClothOut {
    let triangle = triangles[index / 3u];
    let corner = index % 3u;
    let vertex = select(select(triangle.z, triangle.y, corner == 1u), triangle.x, corner == 0u);
    let p0 = positions[triangle.x].xyz;
    let p1 = positions[triangle.y].xyz;
    let p2 = positions[triangle.z].xyz;
    let rest = rest_edges[index / 3u];
    let stretch = max(max(distance(p0, p1) / rest.x, distance(p1, p2) / rest.y), distance(p2, p0) / rest.z);
    var out: ClothOut;
    out.world = positions[vertex].xyz;
    out.clip = frame.view_projection * vec4<f32>(out.world, 1.0);
    out.normal = normals[vertex].xyz;
    out.uv = uvs[vertex];
    out.strain = stretch - 1.0;
    if torn(index / 3u) {
        out.clip = CLIPPED;
    }
    return out;
}

@fragment
fn fs_cloth(in: ClothOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    // Two-sided: each side is lit as seen; the back a little darker so folds read.
    let normal = normalize(select(-in.normal, in.normal, front));
    let view = normalize(frame.eye.xyz - in.world);
    let light = normalize(frame.light.xyz);
    let diffuse = abs(dot(normal, light));
    let half_vector = normalize(light + view);
    let specular = pow(max(dot(normal, half_vector), 0.0), 32.0) * 0.15;
    var base: vec3<f32>;
    if frame.style.x > 0.5 {
        let t = clamp(in.strain / frame.style.y, 0.0, 1.0);
        base = mix(vec3<f32>(0.20, 0.45, 0.85), vec3<f32>(0.90, 0.20, 0.15), t);
    } else {
        let cells = floor(in.uv * 16.0);
        let odd = (i32(cells.x) + i32(cells.y)) % 2 != 0;
        base = select(vec3<f32>(0.93, 0.90, 0.82), vec3<f32>(0.80, 0.35, 0.25), odd);
    }
    let side = select(0.75, 1.0, front);
    let color = base * (0.30 + 0.70 * diffuse) * side + vec3<f32>(specular);
    return vec4<f32>(fog(color, in.world), 1.0);
}

struct GroundOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
}

@vertex
fn vs_ground(@builtin(vertex_index) index: u32) -> GroundOut {
    let corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let c = corners[index] * frame.ground.y;
    var out: GroundOut;
    out.world = vec3<f32>(frame.center.x + c.x, frame.ground.x, frame.center.z + c.y);
    out.clip = frame.view_projection * vec4<f32>(out.world, 1.0);
    return out;
}

@fragment
fn fs_ground(in: GroundOut) -> @location(0) vec4<f32> {
    let cell = in.world.xz / frame.ground.z;
    let odd = (i32(floor(cell.x)) + i32(floor(cell.y))) % 2 != 0;
    let base = select(vec3<f32>(0.62, 0.64, 0.62), vec3<f32>(0.55, 0.57, 0.55), odd);
    return vec4<f32>(fog(base, in.world), 1.0);
}

struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec3<f32>,
}

@vertex
fn vs_springs(@builtin(vertex_index) index: u32) -> LineOut {
    let spring = springs[index / 2u];
    let vertex = select(spring.x, spring.y, (index & 1u) == 1u);
    var out: LineOut;
    out.clip = frame.view_projection * vec4<f32>(positions[vertex].xyz, 1.0);
    // Pulled slightly toward the camera so the lines win the depth test against their faces.
    out.clip.z = out.clip.z - 2e-4 * out.clip.w;
    out.color = vec3<f32>(0.10, 0.12, 0.15);
    if frame.style.w != 0.0 && broken[index / 2u] != 0u {
        out.clip = CLIPPED;
    }
    return out;
}

@vertex
fn vs_pins(@builtin(vertex_index) index: u32, @builtin(instance_index) pin: u32) -> LineOut {
    // A small camera-facing square around each pinned vertex.
    let corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let center = positions[pins[pin]].xyz;
    let forward = normalize(center - frame.eye.xyz);
    let right = normalize(cross(forward, vec3<f32>(0.0, 1.0, 0.0)) + vec3<f32>(1e-6, 0.0, 0.0));
    let up = cross(right, forward);
    let c = corners[index] * frame.style.z;
    var out: LineOut;
    out.clip = frame.view_projection * vec4<f32>(center + right * c.x + up * c.y, 1.0);
    out.clip.z = out.clip.z - 1e-3 * out.clip.w;
    out.color = vec3<f32>(0.85, 0.10, 0.10);
    return out;
}

@vertex
fn vs_wind(@builtin(vertex_index) index: u32, @builtin(instance_index) arrow: u32) -> LineOut {
    // A 4 x 4 grid of arrows (a shaft and two head strokes each) upwind of the cloth.
    let direction = frame.wind.xyz;
    let side = normalize(cross(direction, vec3<f32>(0.0, 1.0, 0.0)) + vec3<f32>(0.0, 0.0, 1e-6));
    let up = normalize(cross(side, direction));
    let cell = vec2<f32>(f32(arrow % 4u), f32(arrow / 4u)) - 1.5;
    let start = frame.wind_origin.xyz + (side * cell.x + up * cell.y) * frame.wind_origin.w;
    return arrow_line(index, start, direction, side, frame.wind.w, vec3<f32>(0.15, 0.35, 0.80));
}

// Corner `index` (0..6) of an arrow drawn as a line list: a shaft of `length` along the unit
// `direction` from `start`, and two head strokes spread along `side`.
fn arrow_line(index: u32, start: vec3<f32>, direction: vec3<f32>, side: vec3<f32>, length: f32, color: vec3<f32>) -> LineOut {
    let tip = start + direction * length;
    let head = length * 0.3;
    let points = array<vec3<f32>, 6>(
        start, tip,
        tip, tip - direction * head + side * head * 0.5,
        tip, tip - direction * head - side * head * 0.5,
    );
    var out: LineOut;
    out.clip = frame.view_projection * vec4<f32>(points[index], 1.0);
    out.color = color;
    return out;
}

@fragment
fn fs_flat(in: LineOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.color, 1.0);
}

// Collider spheres: a unit sphere mesh (position = normal) instanced per sphere.
// Per sphere: centre (xyz) and radius (w).
@group(0) @binding(8) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> sphere_mesh: array<vec4<f32>>;

struct SphereOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

@vertex
fn vs_sphere(@builtin(vertex_index) index: u32, @builtin(instance_index) sphere: u32) -> SphereOut {
    let unit = sphere_mesh[index].xyz;
    let s = spheres[sphere];
    var out: SphereOut;
    // Drawn a hair inside the true radius so cloth resting at the thickness is never hidden.
    out.world = s.xyz + unit * s.w * 0.995;
    out.normal = unit;
    out.clip = frame.view_projection * vec4<f32>(out.world, 1.0);
    return out;
}

@fragment
fn fs_sphere(in: SphereOut) -> @location(0) vec4<f32> {
    let light = normalize(frame.light.xyz);
    let diffuse = max(dot(normalize(in.normal), light), 0.0);
    let color = vec3<f32>(0.35, 0.55, 0.40) * (0.35 + 0.65 * diffuse);
    return vec4<f32>(fog(color, in.world), 1.0);
}

// Capsules: per capsule (start xyz, radius) and (end xyz, 0). The unit sphere's upper half
// is drawn around the end, its lower half around the start; the triangles across the equator
// stretch into the cylinder between.
@group(0) @binding(11) var<storage, read> capsules: array<vec4<f32>>;

@vertex
fn vs_capsule(@builtin(vertex_index) index: u32, @builtin(instance_index) capsule: u32) -> SphereOut {
    let unit = sphere_mesh[index].xyz;
    let start = capsules[2u * capsule];
    let end = capsules[2u * capsule + 1u].xyz;
    let axis = end - start.xyz;
    let span = length(axis);
    let up = select(vec3<f32>(0.0, 1.0, 0.0), axis / span, span > 0.0);
    let helper = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 0.0, 1.0), abs(up.x) > 0.9);
    let side = normalize(cross(up, helper));
    let front = cross(side, up);
    let normal = side * unit.x + up * unit.y + front * unit.z;
    let base = select(start.xyz, end, unit.y > -1e-3);
    var out: SphereOut;
    out.world = base + normal * start.w * 0.995;
    out.normal = normal;
    out.clip = frame.view_projection * vec4<f32>(out.world, 1.0);
    return out;
}

// Forces applied to dynamic balls (the paper's Fig. 4 arrows): per sphere, the force's
// direction (xyz) and the arrow's length (w, 0 for none), drawn from the ball's surface.
@group(0) @binding(10) var<storage, read> sphere_forces: array<vec4<f32>>;

@vertex
fn vs_ball_force(@builtin(vertex_index) index: u32, @builtin(instance_index) sphere: u32) -> LineOut {
    let s = spheres[sphere];
    let force = sphere_forces[sphere];
    let direction = force.xyz;
    let side = normalize(cross(direction, vec3<f32>(0.0, 1.0, 0.0)) + vec3<f32>(1e-6, 0.0, 1e-6));
    let start = s.xyz + direction * s.w * 1.05;
    return arrow_line(index, start, direction, side, force.w, vec3<f32>(0.85, 0.35, 0.10));
}
