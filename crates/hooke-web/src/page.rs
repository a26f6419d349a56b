//! [`Page`]: one simulation on one canvas, exported to JavaScript.
//!
//! A frame is one encoder, as in the viewer: the steps, a pick when a press asked for one, the
//! renderer's passes reading the solver's current position buffer, then present. Nothing waits
//! for the GPU: picks and the solver's status come back by mapping that the browser completes
//! between frames. The one read-back a caller can await is [`Page::positions`].

use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;

use glam::{DVec3, Vec2, Vec3};
use hooke::live::{Choice, LiveSimulation};
use hooke::live_view::LiveView;
use hooke::pointer::PushDirection;
use hooke_gpu::{GpuContext, GpuMethod, wgpu};
use wasm_bindgen::prelude::*;

use crate::scenes;

/// Panics reach the browser's console with their message instead of "unreachable".
#[wasm_bindgen(start)]
pub fn start() {
    console_error_panic_hook::set_once();
}

/// The scenes the page offers, as JSON: `[{"name": ..., "description": ...}]`.
#[wasm_bindgen(js_name = scenes)]
pub fn offered_scenes() -> Result<String, JsError> {
    let list = scenes::SCENES
        .iter()
        .map(|s| {
            Ok(serde_json::json!({
                "name": s.name(),
                "description": s.description()?,
            }))
        })
        .collect::<Result<Vec<_>, String>>()
        .map_err(|e| JsError::new(&e))?;
    Ok(serde_json::Value::Array(list).to_string())
}

/// Opens WebGPU on `canvas` and starts `scene` on the GPU `method` (`"gather"` or
/// `"scatter/<accumulation>"`). Fails with a message when the browser has no WebGPU.
#[cfg(target_arch = "wasm32")]
#[wasm_bindgen]
pub async fn open(
    canvas: wgpu::web_sys::HtmlCanvasElement,
    scene: String,
    method: String,
) -> Result<Page, JsError> {
    let size = [canvas.width().max(1), canvas.height().max(1)];
    let (context, surface) = GpuContext::for_canvas(canvas)
        .await
        .map_err(|e| JsError::new(&e.to_string()))?;
    Page::new(context, surface, size, &scene, &method).map_err(|e| JsError::new(&e))
}

/// One simulation drawn into one canvas.
#[wasm_bindgen]
#[derive(Debug)]
pub struct Page {
    // Shared with the future of a pending read-back (`positions`), which outlives the call.
    inner: Rc<RefCell<Inner>>,
}

#[derive(Debug)]
struct Inner {
    context: Arc<GpuContext>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    view: LiveView,
    simulation: LiveSimulation,
    clock: FrameClock,
}

/// Frames and steps per second, smoothed over about ten frames.
#[derive(Debug, Default)]
struct FrameClock {
    last: Option<(f64, u64)>,
    frames_per_second: f64,
    steps_per_second: f64,
}

impl FrameClock {
    fn tick(&mut self, now_ms: f64, steps_taken: u64) {
        if let Some((then, steps_then)) = self.last {
            let seconds = (now_ms - then) / 1000.0;
            if seconds > 0.0 {
                let smooth = |old: f64, new: f64| {
                    if old == 0.0 {
                        new
                    } else {
                        0.9 * old + 0.1 * new
                    }
                };
                self.frames_per_second = smooth(self.frames_per_second, 1.0 / seconds);
                self.steps_per_second = smooth(
                    self.steps_per_second,
                    steps_taken.saturating_sub(steps_then) as f64 / seconds,
                );
            }
        }
        self.last = Some((now_ms, steps_taken));
    }
}

#[cfg_attr(not(target_arch = "wasm32"), allow(dead_code))]
impl Page {
    fn new(
        context: Arc<GpuContext>,
        surface: wgpu::Surface<'static>,
        size: [u32; 2],
        scene: &str,
        method: &str,
    ) -> Result<Self, String> {
        let scene = scenes::find(scene)?.build()?;
        let choice = choice_named(&context, method)?;
        let capabilities = surface.get_capabilities(&context.adapter);
        let format = capabilities
            .formats
            .first()
            .copied()
            .ok_or("the canvas offers no texture format")?;
        // The renderer shades in linear light and writes an sRGB view, as on a native window.
        let view_format = format.add_srgb_suffix();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            width: size[0],
            height: size[1],
            present_mode: wgpu::PresentMode::AutoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: capabilities
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: if view_format == format {
                vec![]
            } else {
                vec![view_format]
            },
            color_space: wgpu::SurfaceColorSpace::Auto,
        };
        surface.configure(&context.device, &config);
        let mut simulation =
            LiveSimulation::new(Arc::clone(&context), scene, choice).map_err(|e| e.to_string())?;
        let view =
            LiveView::new(&context, &simulation, view_format, size).map_err(|e| e.to_string())?;
        simulation.apply();
        Ok(Self {
            inner: Rc::new(RefCell::new(Inner {
                clock: FrameClock::default(),
                context,
                surface,
                config,
                view,
                simulation,
            })),
        })
    }
}

/// The live choice for a method name, if this adapter can run it.
fn choice_named(context: &GpuContext, name: &str) -> Result<Choice, String> {
    let offered = hooke::live::gpu_methods(context);
    match GpuMethod::from_name(name) {
        Some(method) if offered.contains(&method) => Ok(Choice::Gpu(method)),
        _ => Err(format!(
            "no GPU method {name:?} on {}; it offers {}",
            context.info.name,
            offered
                .iter()
                .map(|m| m.name())
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

fn js_error(message: impl std::fmt::Display) -> JsError {
    JsError::new(&message.to_string())
}

#[wasm_bindgen]
impl Page {
    /// The adapter, as `hooke info --gpu` names it.
    pub fn adapter(&self) -> String {
        self.inner.borrow().context.describe()
    }

    /// One line per optional feature: granted, or what hooke does without it.
    pub fn features(&self) -> Vec<String> {
        self.inner.borrow().context.feature_report()
    }

    /// The GPU methods this adapter runs (no `scatter/atomic-f32`: WebGPU has no float atomics).
    pub fn methods(&self) -> Vec<String> {
        hooke::live::gpu_methods(&self.inner.borrow().context)
            .into_iter()
            .map(GpuMethod::name)
            .collect()
    }

    /// Switches the method; the scene starts again (a browser cannot wait for the state to be
    /// read back and carried over, as the viewer does).
    pub fn set_method(&self, name: &str) -> Result<(), JsError> {
        let mut inner = self.inner.borrow_mut();
        let choice = choice_named(&inner.context, name).map_err(js_error)?;
        let paused = inner.simulation.paused;
        inner.simulation.restart_on(choice);
        inner.simulation.paused = paused;
        match inner.simulation.message.take() {
            Some(message) => Err(js_error(message)),
            None => Ok(()),
        }
    }

    /// Starts the scene again with the controls as they are, paused if it was (the page's
    /// pause button keeps its state).
    pub fn reset(&self) {
        let simulation = &mut self.inner.borrow_mut().simulation;
        let paused = simulation.paused;
        simulation.reset();
        simulation.paused = paused;
    }

    /// The canvas's drawing buffer changed size (pixels).
    pub fn resize(&self, width: u32, height: u32) {
        let inner = &mut *self.inner.borrow_mut();
        inner.config.width = width.max(1);
        inner.config.height = height.max(1);
        inner
            .surface
            .configure(&inner.context.device, &inner.config);
        inner.view.pointer.size = [inner.config.width, inner.config.height];
    }

    /// Simulates this frame's steps and draws; `now_ms` is the animation frame's timestamp.
    pub fn frame(&self, now_ms: f64) -> Result<(), JsError> {
        let inner = &mut *self.inner.borrow_mut();
        inner.frame().map_err(js_error)?;
        inner.clock.tick(now_ms, inner.simulation.steps_taken());
        Ok(())
    }

    /// Records exactly `steps` steps and submits them, without drawing (paused or not).
    pub fn step(&self, steps: u32) -> Result<(), JsError> {
        let inner = &mut *self.inner.borrow_mut();
        let mut encoder =
            inner
                .context
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("page steps"),
                });
        inner.simulation.encode_steps(&mut encoder, steps);
        inner.context.queue.submit([encoder.finish()]);
        inner.simulation.after_submit();
        match &inner.simulation.message {
            Some(message) => Err(js_error(message)),
            None => Ok(()),
        }
    }

    /// Pointer pressed at canvas pixel (`x`, `y`); `button` 0 grabs or orbits, others pan.
    pub fn pointer_down(&self, x: f32, y: f32, button: u32) {
        let inner = &mut *self.inner.borrow_mut();
        inner.view.pointer.cursor = Vec2::new(x, y);
        if button == 0 {
            inner.view.pointer.press_primary();
        } else {
            inner.view.pointer.press_secondary();
        }
    }

    pub fn pointer_move(&self, x: f32, y: f32) {
        let inner = &mut *self.inner.borrow_mut();
        let view = &mut inner.view;
        view.pointer
            .move_to(Vec2::new(x, y), &mut view.camera, &mut inner.simulation);
    }

    pub fn pointer_up(&self) {
        let inner = &mut *self.inner.borrow_mut();
        inner.view.pointer.release(&mut inner.simulation);
    }

    /// The wheel turned by `lines` (positive zooms in).
    pub fn wheel(&self, lines: f32) {
        let inner = &mut *self.inner.borrow_mut();
        let view = &mut inner.view;
        view.pointer.wheel(lines, &mut view.camera);
    }

    pub fn set_paused(&self, paused: bool) {
        self.inner.borrow_mut().simulation.paused = paused;
    }

    pub fn set_steps_per_frame(&self, steps: u32) {
        self.inner.borrow_mut().simulation.steps_per_frame = steps.clamp(1, 1000);
    }

    /// Multiplies every spring's stiffness (dt follows the stability bound).
    pub fn set_stiffness_scale(&self, scale: f64) {
        let mut inner = self.inner.borrow_mut();
        inner.simulation.stiffness_scale = scale.clamp(0.01, 100.0);
        inner.simulation.apply();
    }

    /// Wind on or off, its heading (degrees from +x toward +z) and speed (m/s).
    pub fn set_wind(&self, enabled: bool, heading_degrees: f64, speed: f64) {
        let mut inner = self.inner.borrow_mut();
        let simulation = &mut inner.simulation;
        simulation.wind_enabled = enabled;
        simulation.wind_heading_degrees = heading_degrees;
        simulation.wind_speed = speed.clamp(0.0, 100.0);
        simulation.apply();
    }

    pub fn set_self_collision(&self, enabled: bool) {
        let mut inner = self.inner.borrow_mut();
        inner.simulation.self_collision_enabled = enabled;
        inner.simulation.apply();
    }

    pub fn set_wireframe(&self, wireframe: bool) {
        self.inner.borrow_mut().view.options.wireframe = wireframe;
    }

    /// Pushes the first dynamic ball `"left"`, `"right"`, `"away"`, `"toward"` (relative to the
    /// view) or `"up"`, until called with `""`.
    pub fn push(&self, direction: &str) -> Result<(), JsError> {
        let inner = &mut *self.inner.borrow_mut();
        let force = match direction {
            "" => DVec3::ZERO,
            name => PushDirection::from_name(name)
                .ok_or_else(|| js_error(format!("no push direction {name:?}")))?
                .relative_to(&inner.view.camera),
        };
        inner.simulation.push(force);
        Ok(())
    }

    /// The pixel where world point (`x`, `y`, `z`) is drawn.
    pub fn project(&self, x: f32, y: f32, z: f32) -> Vec<f32> {
        let inner = self.inner.borrow();
        let view = &inner.view;
        let pixel = view.camera.to_pixels(Vec3::new(x, y, z), view.pointer.size);
        vec![pixel.x, pixel.y]
    }

    /// What the page shows under the canvas, as JSON.
    pub fn stats(&self) -> String {
        let inner = self.inner.borrow();
        let simulation = &inner.simulation;
        let model = simulation.model();
        serde_json::json!({
            "scene": simulation.scene_name(),
            "method": match simulation.choice {
                Choice::Gpu(method) => method.name(),
                Choice::Cpu(method) => format!("cpu {}", method.name()),
            },
            "vertices": model.vertex_count(),
            "springs": model.spring_ends.len(),
            "steps": simulation.steps_taken(),
            "time": simulation.steps_taken() as f64 * simulation.dt(),
            "dt": simulation.dt(),
            "steps_per_frame": simulation.steps_per_frame,
            "paused": simulation.paused,
            "fps": inner.clock.frames_per_second,
            "steps_per_second": inner.clock.steps_per_second,
            "balls": simulation.balls().len(),
            "wind": {
                "enabled": simulation.wind_enabled,
                "heading": simulation.wind_heading_degrees,
                "speed": simulation.wind_speed,
            },
            "self_collision": simulation.self_collision_enabled,
            "holding": inner.view.pointer.holding(),
            "grab_target": simulation.grab.map(|(_, target)| target.to_array()),
            "message": simulation.message,
        })
        .to_string()
    }

    /// The positions now, `x y z` per vertex in the scene's vertex order: a read-back the
    /// caller awaits (frames go on meanwhile).
    pub fn positions(&self) -> js_sys::Promise {
        let inner = Rc::clone(&self.inner);
        wasm_bindgen_futures::future_to_promise(async move {
            let staging = inner
                .borrow()
                .copy_positions()
                .map_err(|e| JsValue::from(js_error(e)))?;
            let (sender, receiver) = futures_channel::oneshot::channel();
            staging
                .slice(..)
                .map_async(wgpu::MapMode::Read, move |result| {
                    let _ = sender.send(result);
                });
            receiver
                .await
                .map_err(|e| JsValue::from(js_error(e)))?
                .map_err(|e| JsValue::from(js_error(e)))?;
            let xyz: Vec<f32> = {
                let view = staging
                    .slice(..)
                    .get_mapped_range()
                    .map_err(|e| JsValue::from(js_error(e)))?;
                let vec4s: &[[f32; 4]] = bytemuck::cast_slice(&view);
                vec4s.iter().flat_map(|v| [v[0], v[1], v[2]]).collect()
            };
            staging.unmap();
            Ok(js_sys::Float32Array::from(xyz.as_slice()).into())
        })
    }
}

impl Inner {
    fn frame(&mut self) -> Result<(), String> {
        self.view.take_pick(&self.context, &mut self.simulation);
        let Some(surface_texture) =
            hooke_gpu::gpu::current_texture(&self.context, &self.surface, &self.config)
        else {
            return Ok(());
        };
        let view = surface_texture
            .texture
            .create_view(&wgpu::TextureViewDescriptor {
                format: Some(self.config.format.add_srgb_suffix()),
                ..Default::default()
            });
        let mut encoder =
            self.context
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("page frame"),
                });
        self.simulation.encode_frame(&mut encoder);
        let picking = self
            .view
            .encode(&self.context, &mut encoder, &self.simulation, &view)
            .map_err(|e| e.to_string())?;
        self.context.queue.submit([encoder.finish()]);
        self.view.submitted(picking);
        self.simulation.after_submit();
        self.context.queue.present(surface_texture);
        self.context.take_error().map_err(|e| e.to_string())
    }

    /// Records and submits a copy of the current positions into a new mappable buffer.
    fn copy_positions(&self) -> Result<wgpu::Buffer, String> {
        let source = self
            .simulation
            .cloth()
            .ok_or("the page's solver has no position buffer")?
            .positions;
        let bytes = 16 * self.simulation.model().vertex_count() as u64;
        let staging = hooke_gpu::gpu::copy_to_staging(&self.context, &[(source, bytes)]);
        Ok(staging)
    }
}
