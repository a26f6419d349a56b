// Scatter's incidence accumulation and integration in one pass, where the incidence table is
// stored in rows of `ROW_ENTRIES` entries per vertex (a grid's: see `IncidenceLayout`): each
// vertex sums its springs' forces from the per-spring buffer in a fixed order (the far end's
// negated), then advances (`verlet.wgsl`). The loop has a constant count, which a CPU driver
// unrolls and runs alike in every lane: on lavapipe at 512^2 the accumulation by offsets took
// 5.3-5.5 ms, this loop 4.1-4.5 as a pass of its own, and the fused pass saves the forces'
// write and read and a dispatch besides. A padding entry names the zero force kept past the
// springs' with B_END, so it adds -0.0: every sum keeps its bits, as if the row ended there.

// Per spring: its force on its `a` end; one zero force past the last.
@group(0) @binding(8) var<storage, read> spring_forces: array<vec4<f32>>;
// Per vertex, `ROW_ENTRIES` of: spring index, plus B_END when the vertex is the far end.
@group(0) @binding(9) var<storage, read> entries: array<u32>;

// Entries per vertex (the largest valence).
override ROW_ENTRIES: u32 = 8u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(id, groups);
    if v >= u.vertex_count {
        return;
    }
    var force = vec3<f32>(0.0);
    for (var i = 0u; i < ROW_ENTRIES; i++) {
        let e = entries[v * ROW_ENTRIES + i];
        force += on_entry_end(spring_forces[entry_spring(e)].xyz, e);
    }
    integrate_vertex(v, positions[v].xyz, force);
}
