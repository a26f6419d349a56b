// The compute workgroup size and the flat invocation index, prepended to every compute shader.
// WORKGROUP_SIZE equals `gpu::WORKGROUP_SIZE` in Rust (checked by a test), which sizes dispatches.

const WORKGROUP_SIZE: u32 = 64u;

// Flattened invocation index of a 1D problem dispatched as a 2D grid of workgroups
// (a single dimension is limited to 65535 workgroups).
fn flat_index(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.x + id.y * groups.x * WORKGROUP_SIZE;
}
