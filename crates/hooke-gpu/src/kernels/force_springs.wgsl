// Scatter (ECA, paper Section 4.2), first pass: every spring's force on its `a` end, computed
// once (the paper's "force texture").

@group(0) @binding(0) var<uniform> u: StepUniforms;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> springs: array<Spring>;
@group(0) @binding(3) var<storage, read_write> spring_forces: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = flat_index(id, groups);
    if s >= u.spring_count {
        return;
    }
    let spring = springs[s];
    let force = spring_force(positions[spring.a].xyz, positions[spring.b].xyz, spring.stiffness * u.stiffness_scale, spring.rest_length);
    spring_forces[s] = vec4<f32>(force, 0.0);
}
