// Per-vertex normals for drawing, recomputed every frame on the GPU from the current
// positions: the area-weighted sum of the normals of the vertex's triangles (those not torn).

@group(0) @binding(0) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> triangles: array<vec4<u32>>;
// vertex_count + 1 offsets of each vertex's triangle list, then the lists.
@group(0) @binding(2) var<storage, read> vertex_triangles: array<u32>;
@group(0) @binding(3) var<storage, read_write> normals: array<vec4<f32>>;
// x: vertex count; y: 1 if springs can break.
@group(0) @binding(4) var<uniform> counts: vec4<u32>;
// Per triangle: the springs of its edges; per spring: 1 once broken.
@group(0) @binding(5) var<storage, read> triangle_edges: array<vec4<u32>>;
@group(0) @binding(6) var<storage, read> broken: array<u32>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    let vertex_count = counts.x;
    if v >= vertex_count {
        return;
    }
    var sum = vec3<f32>(0.0);
    for (var k = vertex_triangles[v]; k < vertex_triangles[v + 1u]; k++) {
        let triangle = vertex_triangles[vertex_count + 1u + k];
        if counts.y != 0u {
            let edges = triangle_edges[triangle];
            if broken[edges.x] != 0u || broken[edges.y] != 0u || broken[edges.z] != 0u {
                continue;
            }
        }
        let t = triangles[triangle];
        let p0 = positions[t.x].xyz;
        // Twice the area times the unit normal: larger triangles weigh more.
        sum += cross(positions[t.y].xyz - p0, positions[t.z].xyz - p0);
    }
    let length = length(sum);
    normals[v] = vec4<f32>(select(vec3<f32>(0.0, 1.0, 0.0), sum / length, length > 0.0), 0.0);
}
