//! `tear.wgsl`: springs break when stretched past their limit (the rule of
//! `hooke_core::tearing`), one invocation per spring before the step's forces. The broken flags
//! (one `u32` per spring) are state: read back for a snapshot, written on restore, and bound by
//! the renderer, which hides triangles with a broken edge without a read-back.

use hooke_core::tearing::{TearRule, Tearing};
use wgpu::util::DeviceExt;

use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, read_back, storage, zeroed};
use crate::layout::GpuTearTest;
use crate::model::GpuModel;
use crate::state::GpuState;

/// The per-spring broken flags (`u32`, 1 once broken) of a model of `spring_count` springs.
pub fn broken_flags(context: &GpuContext, spring_count: usize) -> wgpu::Buffer {
    let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
    zeroed(context, "broken springs", 4 * spring_count as u64, copy)
}

#[derive(Debug)]
pub struct Tear {
    pub kernel: Kernel,
    /// Per spring: 1 once broken.
    pub broken: wgpu::Buffer,
    /// How many are (a `u32`, then padding).
    pub count: wgpu::Buffer,
    spring_count: usize,
    bytes: u64,
}

impl Tear {
    /// The tear pass of `model` under `tearing`, setting the per-spring flags in `broken`
    /// ([`broken_flags`]).
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        tearing: &Tearing,
        broken: &wgpu::Buffer,
    ) -> Result<Self, GpuError> {
        let cpu = &model.model;
        let words = model.stiffness_words();
        let rule = TearRule::new(cpu, tearing);
        let tests: Vec<GpuTearTest> = rule
            .tests()
            .iter()
            .zip(&words)
            .map(|(test, [first, second])| GpuTearTest {
                a: test.ends[0],
                b: test.ends[1],
                limit_squared: test.limit_squared,
                first: *first,
                second: *second,
            })
            .collect();
        let spring_count = cpu.spring_count();
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let broken = broken.clone();
        let count = zeroed(context, "broken spring count", 16, copy);
        let none = wgpu::BufferUsages::empty();
        let tests = storage(context, "tear tests", &tests, none);
        // At least one entry: a binding holds one element of its array.
        let mut hinges = rule.hinges().to_vec();
        hinges.resize(hinges.len().max(1), [0; 5]);
        let hinges = storage(context, "bending hinges", &hinges, none);
        let first_bending = [rule.first_bending() as u32, 0, 0, 0];
        let uniform = context
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("tear uniforms"),
                contents: bytemuck::cast_slice(&first_bending),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let records = model.force_records().ok_or_else(|| {
            GpuError::Validation("tearing needs the springs' records, not a stencil".into())
        })?;
        let kernel = Kernel::new(
            context,
            "tear",
            super::TEAR,
            "main",
            spring_count as u32,
            |current| {
                vec![
                    (0, uniform.as_entire_binding()),
                    (1, state.positions[current].as_entire_binding()),
                    (2, tests.as_entire_binding()),
                    (3, broken.as_entire_binding()),
                    (4, records.as_entire_binding()),
                    (5, hinges.as_entire_binding()),
                    (6, count.as_entire_binding()),
                ]
            },
        )?;
        let bytes = broken.size() + tests.size() + hinges.size() + count.size();
        Ok(Self {
            kernel,
            broken,
            count,
            spring_count,
            bytes,
        })
    }

    /// The broken springs, in order (a blocking read-back).
    pub fn read(&self, context: &GpuContext) -> Result<Vec<u32>, GpuError> {
        let bytes = read_back(context, &[(&self.broken, 4 * self.spring_count as u64)])?;
        let flags: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes[0]);
        Ok((0..flags.len() as u32)
            .filter(|&s| flags[s as usize] != 0)
            .collect())
    }

    /// Sets the flags to `broken` and the count to match (the force records are the model's
    /// to rewrite).
    pub fn write(&self, context: &GpuContext, broken: &[bool]) {
        let flags: Vec<u32> = broken.iter().map(|b| u32::from(*b)).collect();
        let count = flags.iter().sum::<u32>();
        let queue = &context.queue;
        queue.write_buffer(&self.broken, 0, bytemuck::cast_slice(&flags));
        queue.write_buffer(&self.count, 0, bytemuck::cast_slice(&[count, 0, 0, 0]));
    }

    /// Bytes held: the flags, the tests and the hinges.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}
