//! `hooke view`: the interactive viewer (winit window, egui panel).
//!
//! Each frame is one encoder: the simulation's passes, a pick (only while the mouse asks for
//! one), the scene render pass drawing from the solver's position buffer, and egui's pass. The
//! frame loop never waits for the GPU to read anything back: picks and solver status arrive
//! through non-blocking read-backs a frame or two later.

mod panel;
mod script;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use glam::Vec2;
use hooke_gpu::GpuContext;
use hooke_gpu::render::Image;
use hooke_gpu::wgpu;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

use crate::scene_loading::load_scene;
use hooke::live::{Choice, LiveSimulation};
use hooke::live_view::LiveView;
use hooke::pointer::PushDirection;

#[derive(Debug, Args)]
pub struct ViewArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Close after this many frames (for scripted runs).
    #[arg(long)]
    pub frames: Option<u64>,
    /// Save the last frame's window contents as PNG (with --frames).
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Window size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x800", value_parser = crate::commands::render::parse_size)]
    pub size: [u32; 2],
    /// Run even if dt exceeds the stability bound.
    #[arg(long)]
    pub allow_unstable: bool,
    /// Feed scripted input through the viewer's handlers (for tests and demos; use with
    /// --frames): `drag` presses on the cloth, drags it, changes stiffness, damping and dt.
    #[arg(long, value_enum)]
    pub script: Option<script::Script>,
    /// The solver to start with (the panel can switch); the reference backend is not offered.
    #[command(flatten)]
    pub solver: crate::solvers::SolverArgs,
}

pub fn run(args: ViewArgs) -> anyhow::Result<()> {
    let scene = load_scene(&args.scene, args.allow_unstable)?;
    let event_loop = EventLoop::new()
        .context("cannot open a window (no display?); `hooke render` draws without one")?;
    let mut app = App {
        args,
        scene: Some(scene),
        viewer: None,
        error: None,
    };
    event_loop.run_app(&mut app).context("window event loop")?;
    match app.error {
        Some(error) => Err(error),
        None => Ok(()),
    }
}

struct App {
    args: ViewArgs,
    scene: Option<hooke_core::scene::Scene>,
    viewer: Option<Viewer>,
    error: Option<anyhow::Error>,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.viewer.is_some() {
            return;
        }
        let Some(scene) = self.scene.take() else {
            return;
        };
        match Viewer::new(event_loop, scene, &self.args) {
            Ok(viewer) => self.viewer = Some(viewer),
            Err(error) => {
                self.error = Some(error);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(viewer) = &mut self.viewer else {
            return;
        };
        match viewer.handle(&event) {
            Ok(true) => {}
            Ok(false) => event_loop.exit(),
            Err(error) => {
                self.error = Some(error);
                event_loop.exit();
            }
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(viewer) = &self.viewer {
            viewer.window.request_redraw();
        }
    }
}

struct Viewer {
    window: Arc<Window>,
    context: Arc<GpuContext>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    view: LiveView,
    egui: egui::Context,
    egui_state: egui_winit::State,
    egui_renderer: egui_wgpu::Renderer,
    simulation: LiveSimulation,
    frames: u64,
    frame_limit: Option<u64>,
    screenshot: Option<PathBuf>,
    last_frame: Instant,
    frame_seconds: f64,
    /// The context's blocking read-back count when the frame loop started.
    blocking_reads_before: u64,
    /// The context's pipeline count when the frame loop started.
    pipelines_before: u64,
    /// The drag script's progress, when `--script drag` runs.
    drag_script: Option<script::DragScript>,
}

impl Viewer {
    fn new(
        event_loop: &ActiveEventLoop,
        scene: hooke_core::scene::Scene,
        args: &ViewArgs,
    ) -> anyhow::Result<Self> {
        let attributes = Window::default_attributes()
            .with_title(format!("hooke: {}", scene.name))
            .with_inner_size(winit::dpi::PhysicalSize::new(args.size[0], args.size[1]));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .context("creating the window")?,
        );
        let (context, surface) =
            GpuContext::for_window(Arc::clone(&window)).context("opening the GPU")?;
        eprintln!("gpu: {}", context.describe());
        let size = window.inner_size();
        let capabilities = surface.get_capabilities(&context.adapter);
        let format = capabilities
            .formats
            .iter()
            .copied()
            .find(wgpu::TextureFormat::is_srgb)
            .or_else(|| capabilities.formats.first().copied())
            .context("the window's surface offers no format")?;
        // Copying the surface lets --screenshot save exactly what the window shows.
        let copyable = capabilities.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | if copyable {
                    wgpu::TextureUsages::COPY_SRC
                } else {
                    wgpu::TextureUsages::empty()
                },
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::AutoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: capabilities
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
            color_space: wgpu::SurfaceColorSpace::Auto,
        };
        surface.configure(&context.device, &config);
        let simulation = LiveSimulation::new(
            Arc::clone(&context),
            scene,
            Choice::from_solver(args.solver.choice(crate::solvers::Backend::Gpu))
                .context("the viewer runs the cpu or gpu backend, not the reference")?,
        )?;
        let view = LiveView::new(
            &context,
            &simulation,
            format,
            [size.width.max(1), size.height.max(1)],
        )?;
        let egui = egui::Context::default();
        let egui_state = egui_winit::State::new(
            egui.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(context.device.limits().max_texture_dimension_2d as usize),
        );
        let egui_renderer = egui_wgpu::Renderer::new(
            &context.device,
            format,
            egui_wgpu::RendererOptions::default(),
        );
        let mut viewer = Self {
            view,
            window,
            context,
            surface,
            config,
            egui,
            egui_state,
            egui_renderer,
            simulation,
            frames: 0,
            frame_limit: args.frames,
            screenshot: args.screenshot.clone(),
            last_frame: Instant::now(),
            frame_seconds: 1.0 / 60.0,
            blocking_reads_before: 0,
            pipelines_before: 0,
            drag_script: args.script.map(|script::Script::Drag| Default::default()),
        };
        viewer.simulation.apply();
        viewer.blocking_reads_before = viewer.context.blocking_reads();
        viewer.pipelines_before = viewer.context.pipelines_created();
        Ok(viewer)
    }

    /// Handles one window event; `Ok(false)` closes the viewer.
    fn handle(&mut self, event: &WindowEvent) -> anyhow::Result<bool> {
        let response = self.egui_state.on_window_event(&self.window, event);
        match event {
            WindowEvent::CloseRequested => return Ok(false),
            WindowEvent::Resized(size) => {
                self.config.width = size.width.max(1);
                self.config.height = size.height.max(1);
                self.surface.configure(&self.context.device, &self.config);
                self.view.pointer.size = self.size();
            }
            WindowEvent::RedrawRequested => return self.frame(),
            _ if response.consumed => {}
            WindowEvent::CursorMoved { position, .. } => {
                let cursor = Vec2::new(position.x as f32, position.y as f32);
                self.view
                    .pointer
                    .move_to(cursor, &mut self.view.camera, &mut self.simulation);
            }
            WindowEvent::MouseInput { state, button, .. } => self.mouse_button(*state, *button),
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => *y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.view.pointer.wheel(lines, &mut self.view.camera);
            }
            WindowEvent::KeyboardInput { event, .. }
                if let Some(direction) = push_key(&event.logical_key) =>
            {
                let pushing = event.state == ElementState::Pressed;
                self.simulation.push(if pushing {
                    direction.relative_to(&self.view.camera)
                } else {
                    glam::DVec3::ZERO
                });
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                match &event.logical_key {
                    Key::Named(NamedKey::Space) => self.simulation.paused = !self.simulation.paused,
                    Key::Named(NamedKey::Escape) => return Ok(false),
                    Key::Character(c) if c == "r" => self.simulation.reset(),
                    Key::Character(c) if c == "s" => self.simulation.step_once = true,
                    Key::Character(c) if c == "w" => {
                        self.view.options.wireframe = !self.view.options.wireframe
                    }
                    Key::Character(c) if c == "p" => {
                        // Let go of the cloth, leaving the grabbed vertex pinned where it is held.
                        let grab = self.simulation.grab;
                        self.view.pointer.release(&mut self.simulation);
                        self.simulation.pin_grabbed(grab);
                    }
                    Key::Character(c) if c == "u" => self.simulation.unpin_added(),
                    _ => {}
                }
            }
            _ => {}
        }
        Ok(true)
    }

    fn size(&self) -> [u32; 2] {
        [self.config.width, self.config.height]
    }

    fn mouse_button(&mut self, state: ElementState, button: MouseButton) {
        match (button, state) {
            (MouseButton::Left, ElementState::Pressed) => self.view.pointer.press_primary(),
            (MouseButton::Right | MouseButton::Middle, ElementState::Pressed) => {
                self.view.pointer.press_secondary()
            }
            (_, ElementState::Pressed) => {}
            (_, ElementState::Released) => self.view.pointer.release(&mut self.simulation),
        }
    }

    /// The drag script's next action, through the same handlers as real input.
    fn run_script(&mut self) {
        let Some(mut script) = self.drag_script.take() else {
            return;
        };
        let holding = self.view.pointer.holding();
        let model = self.simulation.model();
        let centroid = model.initial_positions.iter().sum::<glam::DVec3>()
            / model.vertex_count().max(1) as f64;
        let middle = model
            .initial_positions
            .iter()
            .min_by(|a, b| a.distance(centroid).total_cmp(&b.distance(centroid)))
            .copied()
            .unwrap_or(centroid);
        let size = self.size();
        let target = self.view.camera.to_pixels(middle.as_vec3(), size);
        match script.next(self.frames, holding, target) {
            script::Action::Press(at) => {
                self.view.pointer.cursor = at;
                self.mouse_button(ElementState::Pressed, MouseButton::Left);
            }
            script::Action::Move(delta) => {
                let cursor = self.view.pointer.cursor + delta;
                self.view
                    .pointer
                    .move_to(cursor, &mut self.view.camera, &mut self.simulation);
            }
            script::Action::Tune => {
                // Three panel edits, each applied on its own as the sliders do.
                self.simulation.stiffness_scale *= 2.0;
                self.simulation.apply();
                self.simulation.damping += 0.001;
                self.simulation.apply();
                self.simulation.dt_fraction *= 0.8;
                self.simulation.apply();
            }
            script::Action::Release => {
                self.mouse_button(ElementState::Released, MouseButton::Left);
            }
            script::Action::Nothing => {}
        }
        self.drag_script = Some(script);
    }

    fn frame(&mut self) -> anyhow::Result<bool> {
        self.run_script();
        let now = Instant::now();
        self.frame_seconds =
            0.9 * self.frame_seconds + 0.1 * now.duration_since(self.last_frame).as_secs_f64();
        self.last_frame = now;
        self.view.take_pick(&self.context, &mut self.simulation);
        let Some(surface_texture) =
            hooke_gpu::gpu::current_texture(&self.context, &self.surface, &self.config)
        else {
            return Ok(true);
        };
        let view = surface_texture.texture.create_view(&Default::default());
        let mut encoder =
            self.context
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("viewer frame"),
                });
        self.simulation.encode_frame(&mut encoder);
        let picking = self
            .view
            .encode(&self.context, &mut encoder, &self.simulation, &view)?;
        self.encode_panel(&mut encoder, &view)?;
        let last = self
            .frame_limit
            .is_some_and(|limit| self.frames + 1 >= limit);
        let screenshot = match (&self.screenshot, last) {
            (Some(_), true) => Some(self.encode_screenshot(&mut encoder, &surface_texture.texture)),
            _ => None,
        };
        self.context.queue.submit([encoder.finish()]);
        self.view.submitted(picking);
        self.simulation.after_submit();
        if last {
            eprintln!(
                "viewer: {} frames, {} steps; in the frame loop: {} blocking GPU read-backs, {} pipelines created",
                self.frames + 1,
                self.simulation.steps_taken(),
                self.context.blocking_reads() - self.blocking_reads_before,
                self.context.pipelines_created() - self.pipelines_before
            );
            if let Some(script) = &self.drag_script {
                eprintln!("{}", script.report());
            }
            if self.simulation.model().tearing.is_some() {
                // As the panel shows it: on the GPU, the count last read back without waiting.
                eprintln!("viewer: {} springs torn", self.simulation.broken_springs());
            }
        }
        if let (Some((buffer, padded_row)), Some(path)) = (screenshot, &self.screenshot) {
            self.save_screenshot(&buffer, padded_row, path)?;
        }
        self.context.queue.present(surface_texture);
        self.frames += 1;
        Ok(!last)
    }

    fn encode_panel(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        view: &wgpu::TextureView,
    ) -> anyhow::Result<()> {
        let input = self.egui_state.take_egui_input(&self.window);
        let fps = 1.0 / self.frame_seconds.max(1e-6);
        let bounds = self.view.renderer.bounds();
        let egui = self.egui.clone();
        let output = egui.run_ui(input, |ui| {
            panel::show(
                ui,
                &mut self.simulation,
                &mut self.view.options,
                &mut self.view.camera,
                &bounds,
                fps,
            );
        });
        self.egui_state
            .handle_platform_output(&self.window, output.platform_output);
        let jobs = self.egui.tessellate(output.shapes, output.pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: self.size(),
            pixels_per_point: output.pixels_per_point,
        };
        let mut textures = output.textures_delta;
        for (id, deltas) in &textures.set {
            for delta in deltas {
                self.egui_renderer.update_texture(
                    &self.context.device,
                    &self.context.queue,
                    *id,
                    delta,
                );
            }
        }
        self.egui_renderer.update_buffers(
            &self.context.device,
            &self.context.queue,
            encoder,
            &jobs,
            &screen,
        );
        {
            let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("panel"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            self.egui_renderer
                .render(&mut pass.forget_lifetime(), &jobs, &screen);
        }
        for id in &textures.free {
            self.egui_renderer.free_texture(id);
        }
        // Applied above; clearing tells egui so.
        textures.clear();
        Ok(())
    }

    /// Records a copy of the window's image; returns the buffer and its padded row length.
    fn encode_screenshot(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        texture: &wgpu::Texture,
    ) -> (wgpu::Buffer, u32) {
        let [w, h] = self.size();
        let padded_row = (4 * w).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = self.context.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("screenshot"),
            size: u64::from(padded_row) * u64::from(h),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        if self.config.usage.contains(wgpu::TextureUsages::COPY_SRC) {
            encoder.copy_texture_to_buffer(
                texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(padded_row),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
        }
        (buffer, padded_row)
    }

    /// Saves the copied window image (the last frame only; this waits for the GPU).
    fn save_screenshot(
        &self,
        buffer: &wgpu::Buffer,
        padded_row: u32,
        path: &std::path::Path,
    ) -> anyhow::Result<()> {
        anyhow::ensure!(
            self.config.usage.contains(wgpu::TextureUsages::COPY_SRC),
            "this window's surface cannot be copied; use `hooke render` for images"
        );
        hooke_gpu::gpu::map_blocking(&self.context, buffer)?;
        let [w, h] = self.size();
        let bgra = matches!(
            self.config.format,
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        );
        let rgba: Vec<u8> = {
            let view = buffer.slice(..).get_mapped_range()?;
            view.chunks(padded_row as usize)
                .flat_map(|row| {
                    row[..4 * w as usize].chunks(4).flat_map(|p| {
                        if bgra {
                            [p[2], p[1], p[0], 255]
                        } else {
                            [p[0], p[1], p[2], 255]
                        }
                    })
                })
                .collect()
        };
        buffer.unmap();
        Image { size: [w, h], rgba }.save_png(path)?;
        eprintln!("screenshot written to {}", path.display());
        Ok(())
    }
}

/// The ball push an arrow key or PageUp stands for.
fn push_key(key: &Key) -> Option<PushDirection> {
    match key {
        Key::Named(NamedKey::ArrowLeft) => Some(PushDirection::Left),
        Key::Named(NamedKey::ArrowRight) => Some(PushDirection::Right),
        Key::Named(NamedKey::ArrowUp) => Some(PushDirection::Away),
        Key::Named(NamedKey::ArrowDown) => Some(PushDirection::Toward),
        Key::Named(NamedKey::PageUp) => Some(PushDirection::Up),
        _ => None,
    }
}
