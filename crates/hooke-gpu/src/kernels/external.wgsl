// Point forces, drags, wind (models documented in hooke_core::control) and bending springs'
// dampers (hooke_core::diagnostics::damper_force_on_a), into a per-vertex extra-force buffer
// that `integrate` adds. Wind is computed per triangle, then gathered per vertex over its
// triangles in a fixed order (deterministic); dampers are summed per vertex in a fixed order.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> deltas: array<vec4<f32>>;
// Two entries per vertex: (constant point force xyz N, drag stiffness N/m), (drag target xyz m, 0).
@group(0) @binding(3) var<storage, read> point_and_drag: array<vec4<f32>>;
// Wind velocity (xyz, m/s) and coefficient (w, N s/m^3).
@group(0) @binding(4) var<uniform> wind: vec4<f32>;
@group(0) @binding(5) var<storage, read> triangles: array<vec4<u32>>;
@group(0) @binding(6) var<storage, read_write> triangle_forces: array<vec4<f32>>;
// vertex_count + 1 offsets of each vertex's triangle list, then the lists (triangle indices).
@group(0) @binding(7) var<storage, read> vertex_triangles: array<u32>;
@group(0) @binding(8) var<storage, read_write> extra_forces: array<vec4<f32>>;
// The damping of every damper (f32 bits, N s/m), vertex_count + 1 offsets of each vertex's
// dampers, then per damper (the vertex at its other end, its spring).
@group(0) @binding(9) var<storage, read> dampers: array<u32>;
// Per spring: 1 once torn (a torn spring damps no more); zeros when nothing tears.
@group(0) @binding(10) var<storage, read> broken: array<u32>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn wind_triangles(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let t = flat_index(id, groups);
    if t >= u.triangle_count {
        return;
    }
    let tri = triangles[t];
    let p0 = positions[tri.x].xyz;
    let p1 = positions[tri.y].xyz;
    let p2 = positions[tri.z].xyz;
    let cross_product = cross(p1 - p0, p2 - p0);
    let twice_area = length(cross_product);
    var force = vec3<f32>(0.0);
    if twice_area > 0.0 {
        let normal = cross_product / twice_area;
        let velocity = (deltas[tri.x].xyz + deltas[tri.y].xyz + deltas[tri.z].xyz) * u.inverse_dt / 3.0;
        let relative = wind.xyz - velocity;
        force = wind.w * 0.5 * twice_area * dot(relative, normal) * normal / 3.0;
    }
    triangle_forces[t] = vec4<f32>(force, 0.0);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn vertices(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    let point = point_and_drag[2u * v];
    let drag_target = point_and_drag[2u * v + 1u].xyz;
    var force = point.xyz + point.w * (drag_target - positions[v].xyz);
    // triangle_count is 0 when there is no wind.
    if u.triangle_count > 0u {
        let lists = u.vertex_count + 1u;
        for (var k = vertex_triangles[v]; k < vertex_triangles[v + 1u]; k++) {
            force += triangle_forces[vertex_triangles[lists + k]].xyz;
        }
    }
    let damping = bitcast<f32>(dampers[0]);
    let first = u.vertex_count + 2u;
    let x = positions[v].xyz;
    let d = deltas[v].xyz;
    for (var k = dampers[v + 1u]; k < dampers[v + 2u]; k++) {
        let other = dampers[first + 2u * k];
        if broken[dampers[first + 2u * k + 1u]] != 0u {
            continue;
        }
        let offset = x - positions[other].xyz;
        let length = length(offset);
        if length > 0.0 {
            let direction = offset / length;
            let rate = (d - deltas[other].xyz) * u.inverse_dt;
            force -= damping * dot(rate, direction) * direction;
        }
    }
    extra_forces[v] = vec4<f32>(force, 0.0);
}
