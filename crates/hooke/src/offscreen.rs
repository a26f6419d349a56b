//! Simulating and drawing without a window: each frame is one submission of the simulation
//! passes (or, on the CPU, an upload of its positions) and the render pass; only the finished
//! image is read back.

use std::sync::Arc;

use hooke_core::SimError;
use hooke_gpu::render::{Camera, Image, OffscreenTarget, RenderOptions, SceneRenderer};
use hooke_gpu::{GpuContext, GpuError, wgpu};

use crate::{EngineError, Simulation};

#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Simulation(#[from] SimError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// A simulation, a renderer and an offscreen image.
#[derive(Debug)]
pub struct OffscreenRun {
    pub simulation: Simulation,
    context: Arc<GpuContext>,
    renderer: SceneRenderer,
    target: OffscreenTarget,
    readback: wgpu::Buffer,
    pub camera: Camera,
    pub options: RenderOptions,
}

impl OffscreenRun {
    /// Draws `simulation` (on any solver that has a GPU to draw with) at `size` pixels.
    pub fn new(simulation: Simulation, size: [u32; 2]) -> Result<Self, EngineError> {
        let context = match simulation.gpu() {
            Some(context) => Arc::clone(context),
            None => {
                return Err(EngineError::Gpu(GpuError::Validation(
                    "drawing needs a simulation built with a GPU context".into(),
                )));
            }
        };
        let model = simulation.model();
        let mut renderer = SceneRenderer::new(&context, model, OffscreenTarget::FORMAT)?;
        renderer.set_colliders(&context, &model.collision.colliders);
        let target = OffscreenTarget::new(&context, size);
        let readback = target.readback_buffer(&context);
        let options = RenderOptions {
            wind: simulation.control().wind.map(|w| w.velocity.as_vec3()),
            ..Default::default()
        };
        Ok(Self {
            camera: Camera::framing(&renderer.bounds()),
            simulation,
            context,
            renderer,
            target,
            readback,
            options,
        })
    }

    /// Advances `steps` steps, draws, and returns the image.
    pub fn frame(&mut self, steps: u32) -> Result<Image, FrameError> {
        let context = Arc::clone(&self.context);
        let mut encoder = context
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        self.simulation.encode_frame(&mut encoder, steps)?;
        self.renderer
            .set_colliders(&context, &self.simulation.colliders_to_draw());
        // Dynamic balls are where the GPU put them: copied, not read back.
        self.simulation
            .copy_spheres(&mut encoder, self.renderer.sphere_buffer());
        let cloth = self.simulation.cloth_buffers().ok_or_else(|| {
            GpuError::Validation("the reference solver has no positions to draw".into())
        })?;
        self.renderer.encode(
            &context,
            &mut encoder,
            cloth,
            &self.target.view,
            self.target.size,
            &self.camera,
            &self.options,
        );
        self.target.encode_copy(&mut encoder, &self.readback);
        context.queue.submit([encoder.finish()]);
        let rgba = self.target.read_rgba(&context, &self.readback)?;
        if let Some(solver) = self.simulation.gpu_solver_mut() {
            solver.check()?;
        }
        Ok(Image {
            size: self.target.size,
            rgba,
        })
    }

    /// The image size, pixels.
    pub fn size(&self) -> [u32; 2] {
        self.target.size
    }

    pub fn steps_taken(&self) -> u64 {
        self.simulation.steps_taken()
    }
}
