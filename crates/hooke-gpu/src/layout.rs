//! Host mirrors of the WGSL structs in `kernels/common.wgsl` (checked against naga's layout).

use bytemuck::{Pod, Zeroable};

/// Per-step constants of every kernel (`StepUniforms` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct StepUniforms {
    /// `g dt^2` (m) in xyz.
    pub gravity_step: [f32; 4],
    pub vertex_count: u32,
    pub spring_count: u32,
    /// 1 when the extra-force buffer holds this step's point forces, drags and wind.
    pub has_extra: u32,
    /// Fixed-point accumulation: integer units per newton.
    pub fixed_scale: f32,
    /// Blend accumulation: texels per row and rows of the force render target.
    pub blend_width: u32,
    pub blend_height: u32,
    /// Blend accumulation: newtons per stored unit.
    pub blend_scale: f32,
    pub inverse_dt: f32,
    /// Triangles the wind acts on (0 without wind).
    pub triangle_count: u32,
    /// Fixed-point accumulation: largest allowed |contribution| in integer units.
    pub fixed_limit: f32,
    /// Colliders in the collider buffer.
    pub collider_count: u32,
    /// Distance the cloth keeps from collider surfaces, m.
    pub collision_thickness: f32,
    /// Dynamic balls among the colliders (0: no reactions are recorded).
    pub dynamic_count: u32,
    /// The material's stiffness scale: every spring's stiffness is its record's times this.
    pub stiffness_scale: f32,
    /// Every spring's stiffness when all are alike (read by the gather kernel's entry point
    /// for that case; 0 otherwise).
    pub uniform_stiffness: f32,
    /// Which of the status's two step clocks is this step's: the solver's current position
    /// buffer (0 or 1). The uniform buffer holds one copy per value (see
    /// [`crate::model::GpuModel::uniforms_binding`]).
    pub parity: u32,
}

/// One collider (`Collider` in WGSL): a sphere, plane or capsule, scripted or a dynamic ball.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCollider {
    /// Centre (sphere), point (plane) or start (capsule) xyz, m; radius w, or -1 for a plane.
    pub place: [f32; 4],
    /// A ball's spin (rad/s), a plane's normal or a capsule's axis (end - start) xyz; friction w.
    pub surface: [f32; 4],
    /// Velocity xyz, m/s; inverse mass w (1/kg), > 0 only for a dynamic ball.
    pub motion: [f32; 4],
    /// A dynamic ball: applied force xyz (N) and restitution w. A scripted collider: 1 if a
    /// capsule, 0, 1 if its path repeats, its keyframe count.
    pub script: [f32; 4],
}

/// One kind of spring of a stencil (`StencilEntry` in `common.wgsl`, see
/// [`crate::stencil`]): the offset from a vertex's index to its neighbour's, the rest length
/// and the stiffness.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuStencilEntry {
    pub offset: i32,
    pub rest_length: f32,
    pub stiffness: f32,
    pub pad: u32,
}

/// Places for kinds in [`GpuStencil`] (at most [`crate::stencil::MAX_KINDS`] are used).
pub const STENCIL_KINDS: usize = 24;

/// A stencil's kinds (`Stencil` in `common.wgsl`): the first `len` are used.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GpuStencil {
    pub kinds: [GpuStencilEntry; STENCIL_KINDS],
    pub len: u32,
    pub pad: [u32; 3],
}

/// A spring (`Spring` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSpring {
    pub a: u32,
    pub b: u32,
    pub rest_length: f32,
    pub stiffness: f32,
}

/// One entry of the gather adjacency (`GatherEntry` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GatherEntry {
    pub neighbor: u32,
    pub rest_length: f32,
    pub stiffness: f32,
}

/// One spring's tear test (`TearTest` in `tear.wgsl`): the ends and squared length at which it
/// breaks, and the words of its stiffness in the force records (`second`: `u32::MAX` if none).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTearTest {
    pub a: u32,
    pub b: u32,
    pub limit_squared: f32,
    pub first: u32,
    pub second: u32,
}

/// What the kernels report back (`Status` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuStatus {
    /// First step (1-based, counted from the solver's start) with a non-finite position.
    pub first_bad_step: u32,
    /// Lowest vertex that was non-finite at that step.
    pub first_bad_vertex: u32,
    /// Non-zero once a fixed-point contribution was clamped.
    pub fixed_overflow: u32,
    /// Steps completed since the solver started, in two clocks: a step reads the one its
    /// uniforms' `parity` names, and its integration sets the other to one more. No dispatch
    /// reads the clock it writes, so the count needs no pass of its own between steps.
    pub steps_done: [u32; 2],
}

impl GpuStatus {
    pub const NO_FAILURE: u32 = u32::MAX;
    /// Set in `first_bad_vertex` when the bad one is a dynamic ball (`BALL_MARK` in WGSL).
    pub const BALL_MARK: u32 = 0x8000_0000;

    pub fn fresh(steps_done: u32) -> Self {
        Self {
            first_bad_step: Self::NO_FAILURE,
            first_bad_vertex: Self::NO_FAILURE,
            fixed_overflow: 0,
            steps_done: [steps_done; 2],
        }
    }
}

/// One radix-sort pass's constants (`SortUniforms` in `radix_sort.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct SortUniforms {
    pub count: u32,
    /// The pass sorts on bits `shift..shift + 8` of the key.
    pub shift: u32,
    pub block_count: u32,
    /// Counts per slice of the histogram that one workgroup of the scan takes (see
    /// `radix_sort::slice_length`).
    pub slice_length: u32,
    /// 1 when another pass follows, whose digits this pass's scatter counts.
    pub counts_next: u32,
}

/// One self-collision grid's constants (`SelfUniforms` in `self_collide.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SelfUniforms {
    pub vertex_count: u32,
    pub window: u32,
    pub distance: f32,
    pub inverse_cell: f32,
    /// The grid's shift along each axis, in cells.
    pub offset: f32,
    pub key_bits: u32,
    /// 1 when the key kernel first applies the previous grid's corrections.
    pub apply_previous: u32,
    /// The sort's blocks over the vertices.
    pub block_count: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (size, member offsets) of a struct as naga lays it out for WGSL.
    fn wgsl_layout(name: &str) -> (u32, Vec<u32>) {
        layout_in(crate::kernels::GATHER_INTEGRATE, name)
    }

    fn layout_in(source: &str, name: &str) -> (u32, Vec<u32>) {
        let module = naga::front::wgsl::parse_str(source).expect("parses");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("layout");
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("struct {name} in WGSL"));
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is a struct");
        };
        assert_eq!(layouter[handle].size, *span);
        (*span, members.iter().map(|m| m.offset).collect())
    }

    #[test]
    fn host_mirrors_match_wgsl_sizes_and_offsets() {
        use std::mem::{offset_of, size_of};
        let (size, offsets) = wgsl_layout("StepUniforms");
        assert_eq!(size as usize, size_of::<StepUniforms>());
        let host = [
            offset_of!(StepUniforms, gravity_step),
            offset_of!(StepUniforms, vertex_count),
            offset_of!(StepUniforms, spring_count),
            offset_of!(StepUniforms, has_extra),
            offset_of!(StepUniforms, fixed_scale),
            offset_of!(StepUniforms, blend_width),
            offset_of!(StepUniforms, blend_height),
            offset_of!(StepUniforms, blend_scale),
            offset_of!(StepUniforms, inverse_dt),
            offset_of!(StepUniforms, triangle_count),
            offset_of!(StepUniforms, fixed_limit),
            offset_of!(StepUniforms, collider_count),
            offset_of!(StepUniforms, collision_thickness),
            offset_of!(StepUniforms, dynamic_count),
            offset_of!(StepUniforms, stiffness_scale),
            offset_of!(StepUniforms, uniform_stiffness),
        ];
        assert_eq!(&offsets[..host.len()], host.map(|o| o as u32).as_slice());

        let (size, offsets) = wgsl_layout("Collider");
        assert_eq!(size as usize, size_of::<GpuCollider>());
        let host = [
            offset_of!(GpuCollider, place),
            offset_of!(GpuCollider, surface),
            offset_of!(GpuCollider, motion),
            offset_of!(GpuCollider, script),
        ];
        assert_eq!(offsets, host.map(|o| o as u32));

        let (size, offsets) = wgsl_layout("Spring");
        assert_eq!(size as usize, size_of::<GpuSpring>());
        assert_eq!(offsets, [0, 4, 8, 12]);
        let (size, offsets) = wgsl_layout("StencilEntry");
        assert_eq!(size as usize, size_of::<GpuStencilEntry>());
        assert_eq!(offsets, [0, 4, 8, 12]);
        let (size, offsets) = wgsl_layout("Stencil");
        assert_eq!(size as usize, size_of::<GpuStencil>());
        assert_eq!(offsets[..2], [0, offset_of!(GpuStencil, len) as u32]);
        let (size, _) = wgsl_layout("GatherEntry");
        assert_eq!(size as usize, size_of::<GatherEntry>());
        let (size, offsets) = layout_in(crate::kernels::TEAR, "TearTest");
        assert_eq!(size as usize, size_of::<GpuTearTest>());
        assert_eq!(offsets, [0, 4, 8, 12, 16]);
        let (size, _) = wgsl_layout("Status");
        assert_eq!(size as usize, size_of::<GpuStatus>());
        let (size, offsets) = layout_in(crate::kernels::RADIX_SORT, "SortUniforms");
        assert_eq!(size as usize, size_of::<SortUniforms>());
        assert_eq!(offsets, [0, 4, 8, 12, 16]);
        let (size, offsets) = layout_in(crate::kernels::SELF_COLLIDE, "SelfUniforms");
        assert_eq!(size as usize, size_of::<SelfUniforms>());
        assert_eq!(offsets, [0, 4, 8, 12, 16, 20, 24, 28]);
    }
}
