//! `gather_integrate.wgsl`: the point-centric (PCA) step in one pass. One invocation per
//! vertex, in valence-sorted order, sums the forces of its springs (paper eq. 1) from its CSR
//! row and integrates at once (`verlet.wgsl`, shared with the scatter methods' `integrate`).

use super::integrate::verlet_bindings;
use crate::context::{GpuContext, GpuError};
use crate::gpu::Kernel;
use crate::model::{GpuModel, GpuTopology, uniform_stiffness};
use crate::state::GpuState;

/// Where the kernel finds each spring: the three entry points of `gather_integrate.wgsl`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GatherVariant {
    /// Each spring's CSR entry: neighbour, rest length and stiffness.
    Entries,
    /// The CSR entry's neighbour and rest length, one stiffness for all from the uniforms.
    UniformStiffness,
    /// A mask per vertex over a structured mesh's few kinds of spring (`crate::stencil`).
    Stencil,
}

impl GatherVariant {
    /// For the solver's description.
    pub fn name(self) -> &'static str {
        match self {
            Self::Entries => "CSR entries",
            Self::UniformStiffness => "CSR entries, one stiffness",
            Self::Stencil => "stencil",
        }
    }
}

#[derive(Debug)]
pub struct GatherIntegrate {
    pub kernel: Kernel,
    pub variant: GatherVariant,
}

impl GatherIntegrate {
    /// Unless the model's records may change ([`GpuModel::records_change`]), the kernel reads
    /// less than each spring's CSR entry where the model allows: a structured mesh (a grid) as a `Stencil`, a mask per vertex; else,
    /// when every spring has one stiffness, 8 of each entry's 12 bytes. Springs that can tear
    /// need the entries' stiffness, which tearing zeroes. The same floats are summed in the same
    /// order every way, so all give the same bits.
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        extra_forces: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let (variant, kinds) = match &model.topology {
            GpuTopology::Stencil(stencil) => (GatherVariant::Stencil, Some(&stencil.kinds)),
            GpuTopology::Gather { .. }
                if !model.records_change && uniform_stiffness(&model.model).is_some() =>
            {
                (GatherVariant::UniformStiffness, None)
            }
            GpuTopology::Gather { .. } => (GatherVariant::Entries, None),
            _ => {
                return Err(GpuError::Validation(
                    "the gather step needs the gather adjacency (or, for springs that cannot \
                     tear, a stencil)"
                        .into(),
                ));
            }
        };
        let kernel = Kernel::new(
            context,
            "gather and integrate",
            super::GATHER_INTEGRATE,
            match variant {
                GatherVariant::Entries => "main",
                GatherVariant::UniformStiffness => "uniform_stiffness",
                GatherVariant::Stencil => "stencil",
            },
            model.uniforms.vertex_count,
            |current| {
                let mut resources = verlet_bindings(model, state, extra_forces, current);
                // A stencil's masks travel in the integration scales.
                if let Some(kinds) = kinds {
                    resources.push((9, kinds.as_entire_binding()));
                }
                if let GpuTopology::Gather { rows, entries } = &model.topology {
                    resources.push((5, rows.as_entire_binding()));
                    resources.push((8, entries.as_entire_binding()));
                }
                resources
            },
        )?;
        Ok(Self { kernel, variant })
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use hooke_core::scene::MeshSection;

    use super::*;
    use crate::gpu::zeroed;
    use crate::kernels::testing::{
        assert_next_positions, context, damped_on_gpu, damped_on_gpu_from, expected_verlet_step,
        read_vec3s, reference_spring_forces, run, stretched,
    };
    use crate::layout::{GatherEntry, GpuStencil};
    use crate::methods::GpuMethod;
    use crate::model::vec4s;

    /// float32 positions of order 1 m after summing up to 10 springs and a handful of
    /// operations: a few ulps. (A spring left out moves its ends by millimetres here.)
    const TOLERANCE_M: f64 = 1e-6;

    #[test]
    fn one_pass_sums_each_vertex_springs_and_takes_the_reference_verlet_step() {
        let Some(context) = context() else { return };
        let grid = stretched(MeshSection::unit_grid(13, 11), 143);
        let mut setups = [damped_on_gpu(&context), damped_on_gpu_from(&context, grid)];
        // (setup, records may change, the kernel expected). The grid's model starts as a
        // stencil; `let_records_change` before its second run gives it the CSR rows.
        let runs = [
            (0, false, GatherVariant::UniformStiffness),
            (0, true, GatherVariant::Entries),
            (1, false, GatherVariant::Stencil),
            (1, true, GatherVariant::Entries),
        ];
        let mut results = Vec::new();
        for (setup, records_change, variant) in runs {
            let (scene, seen, model, gpu_state) = &mut setups[setup];
            let (scene, seen, gpu_state) = (&*scene, &*seen, &*gpu_state);
            if records_change {
                model.let_records_change(&context).expect("CSR rows");
            }
            let n = scene.model.vertex_count();
            let extra = zeroed(&context, "extra", vec4s(n), wgpu::BufferUsages::empty());
            let springs = reference_spring_forces(&scene.model, &seen.positions);
            let expected = expected_verlet_step(scene, seen, &springs, &vec![DVec3::ZERO; n]);
            // Each run updates the deltas in place: start each from the same state.
            gpu_state.write(&context, seen);
            let gather = GatherIntegrate::new(&context, model, gpu_state, &extra).expect("kernel");
            assert_eq!(gather.variant, variant);
            run(&context, |e| {
                gather.kernel.encode(e, gpu_state.current, None)
            });
            assert_next_positions(&context, gpu_state, &expected, TOLERANCE_M);
            let next = &gpu_state.positions[1 - gpu_state.current];
            results.push(read_vec3s(&context, next, n));
        }
        // (Not assert_eq: a failure would print every position.)
        assert!(
            results[0] == results[1],
            "both ways of reading CSR entries give the same bits"
        );
        assert!(
            results[2] == results[3],
            "the stencil gives the CSR entries' bits"
        );
    }

    #[test]
    fn a_stencil_allocates_no_csr_rows_until_tears_need_them() {
        let Some(context) = context() else { return };
        let grid = stretched(MeshSection::unit_grid(13, 11), 143);
        let (scene, _, mut model, _) = damped_on_gpu_from(&context, grid);
        assert!(matches!(model.topology, GpuTopology::Stencil(_)));
        assert_eq!(model.topology_bytes, size_of::<GpuStencil>() as u64);
        assert!(model.force_records().is_none());
        model.let_records_change(&context).expect("CSR rows");
        let entries = 2 * scene.model.spring_count() * size_of::<GatherEntry>();
        let rows = (scene.model.vertex_count() + 1) * size_of::<[u32; 2]>();
        assert_eq!(model.topology_bytes, (entries + rows) as u64);
        assert!(model.force_records().is_some());
    }

    #[test]
    fn springs_of_different_stiffness_read_each_entry() {
        let Some(context) = context() else { return };
        let (mut scene, _, _, gpu_state) = damped_on_gpu(&context);
        scene.model.stiffnesses[0] *= 2.0;
        let model = GpuModel::new(&context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        let extra = zeroed(&context, "extra", vec4s(1), wgpu::BufferUsages::empty());
        let gather = GatherIntegrate::new(&context, &model, &gpu_state, &extra).expect("kernel");
        assert_eq!(gather.variant, GatherVariant::Entries);
    }
}
