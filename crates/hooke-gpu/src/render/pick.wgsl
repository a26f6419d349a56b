// Picking: the vertex nearest the cursor on screen (front-most among equals), found on the GPU
// from the current positions, so the viewer never reads the cloth back to pick.

struct Pick {
    view_projection: mat4x4<f32>,
    // Cursor in normalised device coordinates (xy) and the pick radius in NDC units (zw).
    cursor: vec4<f32>,
    vertex_count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

struct PickResult {
    // Best key: distance to the cursor (high 12 bits) then depth (low 20 bits).
    key: atomic<u32>,
    vertex: atomic<u32>,
    _pad0: u32,
    _pad1: u32,
    // Position of the picked vertex (xyz), w = 1 when a vertex was picked.
    position: vec4<f32>,
}

@group(0) @binding(0) var<uniform> pick: Pick;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> result: PickResult;

fn key_of(v: u32) -> u32 {
    let clip = pick.view_projection * vec4<f32>(positions[v].xyz, 1.0);
    if clip.w <= 0.0 {
        return 0xffffffffu;
    }
    let ndc = clip.xyz / clip.w;
    let distance = length((ndc.xy - pick.cursor.xy) / pick.cursor.zw);
    if distance >= 1.0 || ndc.z < 0.0 || ndc.z > 1.0 {
        return 0xffffffffu;
    }
    return (u32(distance * 4095.0) << 20u) | u32(ndc.z * 1048575.0);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn closest(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v < pick.vertex_count {
        atomicMin(&result.key, key_of(v));
    }
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn which(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v < pick.vertex_count {
        let key = key_of(v);
        if key != 0xffffffffu && key == atomicLoad(&result.key) {
            atomicMin(&result.vertex, v);
        }
    }
}

@compute @workgroup_size(1)
fn fetch() {
    let v = atomicLoad(&result.vertex);
    if v < pick.vertex_count {
        result.position = vec4<f32>(positions[v].xyz, 1.0);
    }
}
