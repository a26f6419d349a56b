// Fixed-point accumulation, second pass: integer sums back to newtons.

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> accumulated: array<vec4<i32>>;
@group(0) @binding(2) var<storage, read_write> forces: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    forces[v] = vec4<f32>(vec3<f32>(accumulated[v].xyz) / u.fixed_scale, 0.0);
}
