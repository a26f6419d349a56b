//! Simulating and drawing without a window: each frame is one submission of the simulation
//! passes and the render pass; only the finished image is read back.

use std::sync::Arc;

use hooke_core::{Model, SimError, SimParams, Solver};

use super::{Camera, Image, OffscreenTarget, RenderOptions, SceneRenderer};
use crate::context::{GpuContext, GpuError};
use crate::solver::{GpuMethod, GpuSolver};

#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Simulation(#[from] SimError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// A solver, a renderer and an offscreen image.
#[derive(Debug)]
pub struct OffscreenRun {
    pub solver: GpuSolver,
    renderer: SceneRenderer,
    target: OffscreenTarget,
    readback: wgpu::Buffer,
    pub camera: Camera,
    pub options: RenderOptions,
    params: SimParams,
}

impl OffscreenRun {
    pub fn new(
        context: Arc<GpuContext>,
        model: &Model,
        params: &SimParams,
        method: GpuMethod,
        size: [u32; 2],
    ) -> Result<Self, GpuError> {
        let mut renderer = SceneRenderer::new(&context, model, OffscreenTarget::FORMAT)?;
        renderer.set_colliders(&context, &params.colliders);
        let target = OffscreenTarget::new(&context, size);
        let readback = target.readback_buffer(&context);
        let options = RenderOptions {
            wind: params.wind.map(|w| w.velocity.as_vec3()),
            ..Default::default()
        };
        Ok(Self {
            camera: Camera::framing(&renderer.bounds()),
            solver: GpuSolver::new(context, model, params, method)?,
            renderer,
            target,
            readback,
            options,
            params: params.clone(),
        })
    }

    /// Advances `steps` steps, draws, and returns the image.
    pub fn frame(&mut self, steps: u32) -> Result<Image, FrameError> {
        let context = Arc::clone(self.solver.context());
        let mut encoder = context
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        self.solver.encode_steps(&mut encoder, steps);
        let t = self.solver.steps_taken() as f64 * self.params.dt;
        let colliders = hooke_core::collide::placed(&self.params.colliders, t);
        self.renderer.set_colliders(&context, &colliders);
        // Dynamic balls are where the GPU put them: copied, not read back.
        self.solver
            .copy_spheres(&mut encoder, self.renderer.sphere_buffer());
        self.renderer.encode(
            &context,
            &mut encoder,
            self.solver.current_positions(),
            &self.target.view,
            self.target.size,
            &self.camera,
            &self.options,
        );
        self.target.encode_copy(&mut encoder, &self.readback);
        context.queue.submit([encoder.finish()]);
        let rgba = self.target.read_rgba(&context, &self.readback)?;
        self.solver.check()?;
        Ok(Image {
            size: self.target.size,
            rgba,
        })
    }

    pub fn steps_taken(&self) -> u64 {
        self.solver.steps_taken()
    }
}
