//! What a live front end draws and how the pointer moves it: the renderer, the GPU picker, the
//! camera, the drawing options and the [`Pointer`], recorded into a frame the same way by the
//! viewer's window and the browser page.

use hooke_gpu::render::{Camera, Picker, RenderOptions, SceneRenderer};
use hooke_gpu::{GpuContext, GpuError, wgpu};

use crate::live::LiveSimulation;
use crate::pointer::Pointer;

#[derive(Debug)]
pub struct LiveView {
    pub renderer: SceneRenderer,
    pub picker: Picker,
    pub camera: Camera,
    pub options: RenderOptions,
    pub pointer: Pointer,
    /// The [`LiveSimulation::pins_changed`] count the pin markers show.
    pins_drawn: u64,
}

impl LiveView {
    /// A view of `simulation` drawn into targets of `format` and `size` pixels, the camera
    /// framing the scene.
    pub fn new(
        context: &GpuContext,
        simulation: &LiveSimulation,
        format: wgpu::TextureFormat,
        size: [u32; 2],
    ) -> Result<Self, GpuError> {
        let model = simulation.model();
        let mut renderer = SceneRenderer::new(context, model, format)?;
        renderer.set_colliders(context, &model.collision.colliders);
        let picker = Picker::new(context, model.vertex_count() as u32)?;
        Ok(Self {
            camera: Camera::framing(&renderer.bounds()),
            options: RenderOptions::default(),
            pointer: Pointer::new(size),
            renderer,
            picker,
            pins_drawn: simulation.pins_changed(),
        })
    }

    /// Before a frame: takes a pick answer that has arrived (the pointer grabs or orbits).
    pub fn take_pick(&mut self, context: &GpuContext, simulation: &mut LiveSimulation) {
        if let Some(answer) = self.picker.poll(context) {
            self.pointer.picked(answer, &mut self.camera, simulation);
        }
    }

    /// After the frame's steps: records the pick a press asked for, then the scene drawn from
    /// the solver's positions into `target`. Returns whether a pick was recorded (then call
    /// [`LiveView::submitted`] once the encoder is submitted).
    pub fn encode(
        &mut self,
        context: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        simulation: &LiveSimulation,
        target: &wgpu::TextureView,
    ) -> Result<bool, GpuError> {
        let cloth = simulation.cloth().ok_or_else(|| {
            GpuError::Validation("the solver has no position buffer to draw".into())
        })?;
        let mut picking = false;
        if let Some(at) = self.pointer.pick_request() {
            picking = self
                .picker
                .encode(context, encoder, cloth.positions, &self.camera, at);
            if picking {
                self.pointer.pick_recorded();
            }
        }
        if simulation.pins_changed() != self.pins_drawn {
            self.renderer.set_pins(context, &simulation.model().pinned);
            self.pins_drawn = simulation.pins_changed();
        }
        self.options.wind = simulation.wind().map(|w| w.velocity.as_vec3());
        self.renderer
            .set_colliders(context, &simulation.colliders_to_draw());
        simulation.copy_spheres(encoder, self.renderer.sphere_buffer());
        self.renderer.encode(
            context,
            encoder,
            cloth,
            target,
            self.pointer.size,
            &self.camera,
            &self.options,
        );
        Ok(picking)
    }

    /// The encoder [`LiveView::encode`] recorded into was submitted.
    pub fn submitted(&self, picking: bool) {
        if picking {
            self.picker.submitted();
        }
    }
}
