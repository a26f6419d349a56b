//! The compute kernels of a step, one `<name>.rs` beside each `<name>.wgsl`. Each `.rs` owns
//! its pipelines and bind groups and records its passes with a typed `encode`; the buffers
//! they bind belong to [`crate::GpuModel`] and [`crate::GpuState`] (or, for per-step scratch, to
//! the kernel itself). Each source is `workgroup.wgsl` and `common.wgsl` followed by the
//! kernel's own file.

pub mod accumulate_atomic;
pub mod accumulate_blend;
pub mod accumulate_incidence;
pub mod balls;
pub mod collide;
pub mod external;
pub mod force_springs;
pub mod gather_integrate;
pub mod handles;
pub mod integrate;
pub mod radix_sort;
pub mod self_collide;
pub mod tear;

#[cfg(test)]
mod testing;

/// The buffers every scatter accumulation binds.
#[derive(Debug)]
pub struct ScatterBuffers<'a> {
    /// Whose step uniforms the accumulations bind ([`crate::GpuModel::uniforms_binding`]).
    pub model: &'a crate::GpuModel,
    pub springs: &'a wgpu::Buffer,
    /// The per-vertex sums the accumulation writes.
    pub forces: &'a wgpu::Buffer,
    pub status: &'a wgpu::Buffer,
    pub vertex_count: u32,
    pub spring_count: u32,
}

impl<'a> ScatterBuffers<'a> {
    /// The buffers of `model` (a scatter model: it has spring records), summing into `forces`.
    pub fn new(
        model: &'a crate::GpuModel,
        forces: &'a wgpu::Buffer,
        state: &'a crate::state::GpuState,
    ) -> Result<Self, crate::GpuError> {
        Ok(Self {
            model,
            springs: model.springs().ok_or_else(|| {
                crate::GpuError::Validation("scatter without spring records".into())
            })?,
            forces,
            status: &state.status,
            vertex_count: model.uniforms.vertex_count,
            spring_count: model.uniforms.spring_count,
        })
    }
}

/// A kernel's full source with the shared prelude (and `verlet.wgsl` for the kernels that
/// integrate, `paths.wgsl` for collider kernels, `digits.wgsl` for the radix sort and the
/// self-collision keys that count its first digits).
macro_rules! kernel_source {
    ($file:literal) => {
        concat!(
            include_str!("workgroup.wgsl"),
            "\n",
            include_str!("common.wgsl"),
            "\n",
            include_str!($file)
        )
    };
    (with verlet $file:literal) => {
        concat!(
            include_str!("workgroup.wgsl"),
            "\n",
            include_str!("common.wgsl"),
            "\n",
            include_str!("verlet.wgsl"),
            "\n",
            include_str!($file)
        )
    };
    (with digits $file:literal) => {
        concat!(
            include_str!("workgroup.wgsl"),
            "\n",
            include_str!("common.wgsl"),
            "\n",
            include_str!("digits.wgsl"),
            "\n",
            include_str!($file)
        )
    };
    (with paths $file:literal) => {
        concat!(
            include_str!("workgroup.wgsl"),
            "\n",
            include_str!("common.wgsl"),
            "\n",
            include_str!("paths.wgsl"),
            "\n",
            include_str!($file)
        )
    };
}

pub const GATHER_INTEGRATE: &str = kernel_source!(with verlet "gather_integrate.wgsl");
pub const FORCE_SPRINGS: &str = kernel_source!("force_springs.wgsl");
pub const ACCUMULATE_ATOMIC_F32: &str = kernel_source!("accumulate_atomic_f32.wgsl");
pub const ACCUMULATE_FIXED: &str = kernel_source!("accumulate_fixed.wgsl");
pub const ACCUMULATE_INCIDENCE: &str = kernel_source!("accumulate_incidence.wgsl");
pub const ACCUMULATE_BLEND: &str = kernel_source!("accumulate_blend.wgsl");
pub const RESOLVE_BLEND: &str = kernel_source!("resolve_blend.wgsl");
pub const INTEGRATE: &str = kernel_source!(with verlet "integrate.wgsl");
pub const INTEGRATE_INCIDENCE: &str = kernel_source!(with verlet "integrate_incidence.wgsl");
pub const INTEGRATE_FIXED: &str = kernel_source!(with verlet "integrate_fixed.wgsl");
pub const EXTERNAL: &str = kernel_source!("external.wgsl");
pub const TEAR: &str = kernel_source!("tear.wgsl");
pub const COLLIDE: &str = kernel_source!(with paths "collide.wgsl");
pub const BALLS: &str = kernel_source!(with paths "balls.wgsl");
pub const HANDLES: &str = kernel_source!(with paths "handles.wgsl");
pub const RADIX_SORT: &str = kernel_source!(with digits "radix_sort.wgsl");
pub const SELF_COLLIDE: &str = kernel_source!(with digits "self_collide.wgsl");

/// Every kernel by name, for validation.
#[cfg(test)]
pub const ALL: &[(&str, &str)] = &[
    ("gather_integrate", GATHER_INTEGRATE),
    ("force_springs", FORCE_SPRINGS),
    ("accumulate_atomic_f32", ACCUMULATE_ATOMIC_F32),
    ("accumulate_fixed", ACCUMULATE_FIXED),
    ("accumulate_incidence", ACCUMULATE_INCIDENCE),
    ("accumulate_blend", ACCUMULATE_BLEND),
    ("resolve_blend", RESOLVE_BLEND),
    ("integrate", INTEGRATE),
    ("integrate_incidence", INTEGRATE_INCIDENCE),
    ("integrate_fixed", INTEGRATE_FIXED),
    ("external", EXTERNAL),
    ("tear", TEAR),
    ("collide", COLLIDE),
    ("balls", BALLS),
    ("handles", HANDLES),
    ("radix_sort", RADIX_SORT),
    ("self_collide", SELF_COLLIDE),
];

#[cfg(test)]
mod tests {
    use naga::valid::{Capabilities, ValidationFlags, Validator};

    #[test]
    fn every_wgsl_kernel_parses_and_validates() {
        for (name, source) in super::ALL {
            let module = naga::front::wgsl::parse_str(source)
                .unwrap_or_else(|e| panic!("{name}.wgsl: {}", e.emit_to_string(source)));
            // Only the float-atomic kernel needs a capability beyond WebGPU's baseline.
            let capabilities = if *name == "accumulate_atomic_f32" {
                Capabilities::SHADER_FLOAT32_ATOMIC
            } else {
                Capabilities::empty()
            };
            Validator::new(ValidationFlags::all(), capabilities)
                .validate(&module)
                .unwrap_or_else(|e| panic!("{name}.wgsl: {}", e.emit_to_string(source)));
        }
    }

    #[test]
    fn every_kernel_binds_no_more_storage_buffers_than_webgpu_allows_by_default() {
        // WebGPU's default `maxStorageBuffersPerShaderStage`: the page asks for no more.
        const LIMIT: usize = 8;
        for (name, source) in super::ALL {
            let module = naga::front::wgsl::parse_str(source).expect("parses");
            let info = Validator::new(ValidationFlags::all(), Capabilities::all())
                .validate(&module)
                .expect("validates");
            for (index, entry) in module.entry_points.iter().enumerate() {
                let uses = info.get_entry_point(index);
                let storage = module
                    .global_variables
                    .iter()
                    .filter(|(handle, g)| {
                        matches!(g.space, naga::AddressSpace::Storage { .. })
                            && !uses[*handle].is_empty()
                    })
                    .count();
                assert!(
                    storage <= LIMIT,
                    "{name}.wgsl {}: {storage} storage buffers",
                    entry.name
                );
            }
        }
    }

    /// The sort's kernels, dispatched a workgroup per block or slice (`dispatch_groups_in`),
    /// whose workgroup size is the pipeline constant `SORT_GROUP` (`radix_sort::SortGroup`).
    const SORT_KERNELS: [(&str, &str); 4] = [
        ("radix_sort", "count_digits"),
        ("radix_sort", "scan"),
        ("radix_sort", "scatter"),
        ("self_collide", "cell_keys"),
    ];

    #[test]
    fn wgsl_workgroup_size_is_the_one_dispatches_are_sized_for() {
        for (name, source) in super::ALL {
            let module = naga::front::wgsl::parse_str(source).expect("parses");
            let compute = module
                .entry_points
                .iter()
                .filter(|e| e.stage == naga::ShaderStage::Compute);
            for entry in compute {
                let size = entry.workgroup_size;
                if SORT_KERNELS.contains(&(name, entry.name.as_str())) {
                    let overrides = entry.workgroup_size_overrides.expect("an override");
                    assert!(
                        overrides[0].is_some() && overrides[1..] == [None, None],
                        "{name}.wgsl {}: workgroup size {overrides:?}",
                        entry.name
                    );
                    continue;
                }
                assert!(
                    size == [crate::gpu::WORKGROUP_SIZE, 1, 1] || size == [1, 1, 1],
                    "{name}.wgsl {}: workgroup size {size:?}",
                    entry.name
                );
            }
        }
    }
}
