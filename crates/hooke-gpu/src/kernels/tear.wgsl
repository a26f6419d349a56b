// Tearing, the rule of `hooke_core::tearing`: one invocation per spring, before the step's
// forces. An edge spring whose ends are farther apart than its limit breaks for good, and a
// bending spring when any edge of its two triangles would: its flag is set (the renderer hides
// triangles with a broken edge) and its stiffness in the force records (gather entries or
// spring records, bound as raw words) becomes 0.0, so no later pass sees a force from it. The
// tests read positions only and each spring's words are written by its own invocation, so the
// result does not depend on the order invocations run in.

struct TearTest {
    a: u32,
    b: u32,
    limit_squared: f32,
    // Word indices of the spring's stiffness in the force records (`second`: gather's other end,
    // or NO_WORD).
    first: u32,
    second: u32,
}

const NO_WORD: u32 = 0xffffffffu;

// x: the first bending spring.
@group(0) @binding(0) var<uniform> tear: vec4<u32>;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> tests: array<TearTest>;
@group(0) @binding(3) var<storage, read_write> broken: array<u32>;
@group(0) @binding(4) var<storage, read_write> records: array<u32>;
// Per bending spring: the edge springs of its two triangles.
@group(0) @binding(5) var<storage, read> hinges: array<array<u32, 5>>;
// How many springs have broken (for a viewer's panel, read back without waiting).
@group(0) @binding(6) var<storage, read_write> torn_count: atomic<u32>;

// Summed in the order `TearTest::breaks` sums on the CPU.
fn edge_breaks(e: u32) -> bool {
    let test = tests[e];
    let d = positions[test.b].xyz - positions[test.a].xyz;
    return d.x * d.x + d.y * d.y + d.z * d.z > test.limit_squared;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = flat_index(id, groups);
    if s >= arrayLength(&tests) || broken[s] != 0u {
        return;
    }
    var breaks: bool;
    if s < tear.x {
        breaks = edge_breaks(s);
    } else {
        let hinge = hinges[s - tear.x];
        breaks = edge_breaks(hinge[0]) || edge_breaks(hinge[1]) || edge_breaks(hinge[2])
            || edge_breaks(hinge[3]) || edge_breaks(hinge[4]);
    }
    if breaks {
        let test = tests[s];
        broken[s] = 1u;
        atomicAdd(&torn_count, 1u);
        records[test.first] = 0u;
        if test.second != NO_WORD {
            records[test.second] = 0u;
        }
    }
}
