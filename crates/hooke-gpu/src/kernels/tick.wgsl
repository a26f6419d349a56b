// Advances the step counter that `integrate` uses to name a failing step.

@group(0) @binding(0) var<storage, read_write> status: Status;

@compute @workgroup_size(1)
fn main() {
    status.step_counter += 1u;
}
