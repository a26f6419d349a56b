//! Drawing the cloth straight from the simulation's position buffer (paper Sections 3 and 6):
//! displaced positions never leave GPU memory. A frame is one encoder: the simulation passes,
//! a compute pass for normals, then one render pass into any `TextureView` (a window's surface
//! or an offscreen texture: the same code).

mod camera;
mod image_file;
mod offscreen;
mod pick;
mod readback;

pub use camera::Camera;
pub use image_file::{Image, ImageError};
pub use offscreen::OffscreenTarget;
pub use pick::{PickAt, PickedVertex, Picker};
pub use readback::AsyncReadback;

use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec3};
use hooke_core::Model;
use hooke_core::collide::{Collider, Shape};
use hooke_core::tearing;
use wgpu::util::DeviceExt;

use crate::context::GpuContext;
use crate::gpu::{self, bind_group, compute_pipeline, storage};

const NORMALS: &str = concat!(
    include_str!("../kernels/workgroup.wgsl"),
    include_str!("normals.wgsl")
);
const SCENE: &str = include_str!("scene.wgsl");
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// What to draw besides the shaded cloth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Colour by the largest strain of each triangle instead of a checker pattern.
    pub color_by_strain: bool,
    /// Strain shown at full red.
    pub strain_scale: f32,
    /// Draw every spring as a line.
    pub wireframe: bool,
    /// Mark pinned vertices.
    pub show_pins: bool,
    /// Wind velocity (m/s) to draw as arrows, if any.
    pub wind: Option<Vec3>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            color_by_strain: false,
            strain_scale: 0.2,
            wireframe: false,
            show_pins: true,
            wind: None,
        }
    }
}

/// `Frame` in scene.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct FrameUniforms {
    view_projection: [[f32; 4]; 4],
    eye: [f32; 4],
    center: [f32; 4],
    light: [f32; 4],
    ground: [f32; 4],
    wind: [f32; 4],
    wind_origin: [f32; 4],
    style: [f32; 4],
}

/// Where the scene sits, for framing the camera and placing the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneBounds {
    pub min: Vec3,
    pub max: Vec3,
    /// The ground's height: below the cloth, at y = 0 when the cloth starts above it.
    pub ground_height: f32,
}

impl SceneBounds {
    pub fn of(model: &Model) -> Self {
        let (lo, hi) = model.initial_positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let (min, max) = (lo.as_vec3(), hi.as_vec3());
        let extent = (max - min).max_element().max(1e-3);
        Self {
            min,
            max,
            ground_height: 0f32.min(min.y - 0.5 * extent),
        }
    }

    pub fn extent(&self) -> f32 {
        (self.max - self.min).max_element().max(1e-3)
    }

    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
}

/// The solver's buffers a frame draws: positions (`vec4` per vertex) and, when springs can
/// break, the broken flags (`u32` per spring).
#[derive(Clone, Copy, Debug)]
pub struct ClothBuffers<'a> {
    pub positions: &'a wgpu::Buffer,
    pub broken_springs: Option<&'a wgpu::Buffer>,
}

/// Pipelines and static buffers for drawing one model.
#[derive(Debug)]
pub struct SceneRenderer {
    normals_pipeline: wgpu::ComputePipeline,
    cloth: wgpu::RenderPipeline,
    ground: wgpu::RenderPipeline,
    springs: wgpu::RenderPipeline,
    pins: wgpu::RenderPipeline,
    wind: wgpu::RenderPipeline,
    sphere: wgpu::RenderPipeline,
    /// Unit sphere triangles (vec4 per corner), and collider spheres (centre, radius).
    sphere_mesh: wgpu::Buffer,
    sphere_mesh_vertices: u32,
    spheres: wgpu::Buffer,
    sphere_count: u32,
    /// Per sphere: applied force direction and arrow length (zero length: no arrow).
    sphere_forces: wgpu::Buffer,
    ball_force: wgpu::RenderPipeline,
    capsule: wgpu::RenderPipeline,
    /// Per capsule: (start, radius), (end, 0).
    capsules: wgpu::Buffer,
    capsule_count: u32,
    frame: wgpu::Buffer,
    counts: wgpu::Buffer,
    triangles: wgpu::Buffer,
    vertex_triangles: wgpu::Buffer,
    uvs: wgpu::Buffer,
    rest_edges: wgpu::Buffer,
    spring_ends: wgpu::Buffer,
    pinned: wgpu::Buffer,
    normals: wgpu::Buffer,
    /// Per triangle the springs of its edges (when the model tears; else a placeholder).
    triangle_edges: wgpu::Buffer,
    /// Zeros, bound in place of the solver's broken flags when it has none yet.
    no_tears: wgpu::Buffer,
    /// True if the model tears: triangles with a broken edge are not drawn.
    tears: bool,
    vertex_count: u32,
    triangle_count: u32,
    spring_count: u32,
    pin_count: u32,
    bounds: SceneBounds,
    depth: Option<(wgpu::TextureView, [u32; 2])>,
}

impl SceneRenderer {
    /// Builds pipelines for drawing `model` into targets of `format`.
    pub fn new(
        context: &GpuContext,
        model: &Model,
        format: wgpu::TextureFormat,
    ) -> Result<Self, crate::GpuError> {
        let n = model.vertex_count();
        let none = wgpu::BufferUsages::empty();
        let triangles: Vec<[u32; 4]> = model
            .triangles
            .iter()
            .map(|t| [t[0], t[1], t[2], 0])
            .collect();
        let lists = gpu::vertex_triangle_lists(n, &model.triangles);
        let bounds = SceneBounds::of(model);
        let uvs = texture_coordinates(model, &bounds);
        let rest_edges: Vec<[f32; 4]> = model
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| model.initial_positions[i as usize]);
                [
                    p[0].distance(p[1]),
                    p[1].distance(p[2]),
                    p[2].distance(p[0]),
                    1.0,
                ]
                .map(|l| l.max(1e-12) as f32)
            })
            .collect();
        let unit_sphere = unit_sphere_triangles(24, 16);
        let pinned: Vec<u32> = (0..n as u32)
            .filter(|&v| model.pinned[v as usize])
            .collect();
        let tears = model.tearing.is_some();
        let triangle_edges: Vec<[u32; 4]> = if tears {
            tearing::triangle_edge_springs(model)
                .iter()
                .map(|e| [e[0], e[1], e[2], 0])
                .collect()
        } else {
            vec![[0; 4]]
        };
        let counts = context
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("render counts"),
                contents: bytemuck::cast_slice(&[n as u32, u32::from(tears), 0, 0]),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let frame = context.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniforms"),
            size: std::mem::size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let scene_module = shader(context, "scene", SCENE);
        let depth = wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        };
        let pipeline =
            |label: &str, vertex: &str, fragment: &str, topology: wgpu::PrimitiveTopology| {
                gpu::render_pipeline(
                    context,
                    &wgpu::RenderPipelineDescriptor {
                        label: Some(label),
                        layout: None,
                        vertex: wgpu::VertexState {
                            module: &scene_module,
                            entry_point: Some(vertex),
                            compilation_options: Default::default(),
                            buffers: &[],
                        },
                        primitive: wgpu::PrimitiveState {
                            topology,
                            ..Default::default()
                        },
                        depth_stencil: Some(depth.clone()),
                        multisample: Default::default(),
                        fragment: Some(wgpu::FragmentState {
                            module: &scene_module,
                            entry_point: Some(fragment),
                            compilation_options: Default::default(),
                            targets: &[Some(format.into())],
                        }),
                        multiview_mask: None,
                        cache: None,
                    },
                )
            };
        let list = wgpu::PrimitiveTopology::TriangleList;
        let lines = wgpu::PrimitiveTopology::LineList;
        crate::gpu::validated(context, "renderer", || -> Result<Self, crate::GpuError> {
            Ok(Self {
                normals_pipeline: compute_pipeline(context, "normals", NORMALS, "main")?,
                cloth: pipeline("cloth", "vs_cloth", "fs_cloth", list)?,
                ground: pipeline("ground", "vs_ground", "fs_ground", list)?,
                springs: pipeline("springs", "vs_springs", "fs_flat", lines)?,
                pins: pipeline("pins", "vs_pins", "fs_flat", list)?,
                wind: pipeline("wind arrows", "vs_wind", "fs_flat", lines)?,
                sphere: pipeline("collider spheres", "vs_sphere", "fs_sphere", list)?,
                sphere_mesh: storage(context, "unit sphere", &unit_sphere, none),
                sphere_mesh_vertices: unit_sphere.len() as u32,
                spheres: storage(context, "collider spheres", &[[0.0f32; 4]], none),
                sphere_count: 0,
                sphere_forces: storage(context, "ball forces", &[[0.0f32; 4]], none),
                ball_force: pipeline("ball forces", "vs_ball_force", "fs_flat", lines)?,
                capsule: pipeline("collider capsules", "vs_capsule", "fs_sphere", list)?,
                capsules: storage(context, "collider capsules", &[[0.0f32; 4]; 2], none),
                capsule_count: 0,
                frame,
                counts,
                triangles: storage(context, "render triangles", &triangles, none),
                vertex_triangles: storage(context, "render vertex triangles", &lists, none),
                uvs: storage(context, "texture coordinates", &uvs, none),
                rest_edges: storage(context, "rest edge lengths", &rest_edges, none),
                spring_ends: storage(context, "spring ends", &model.spring_ends, none),
                pinned: storage(context, "pinned vertices", &pinned, none),
                normals: gpu::zeroed(context, "normals", 16 * n as u64, none),
                triangle_edges: storage(context, "triangle edges", &triangle_edges, none),
                no_tears: storage(context, "no broken springs", &[0u32; 4], none),
                tears,
                vertex_count: n as u32,
                triangle_count: model.triangles.len() as u32,
                spring_count: model.spring_count() as u32,
                pin_count: pinned.len() as u32,
                bounds,
                depth: None,
            })
        })?
    }

    pub fn bounds(&self) -> SceneBounds {
        self.bounds
    }

    /// Marks the vertices `pinned` says (the model's pins as they are now: a viewer pins and
    /// unpins while running). One small buffer is replaced; nothing else is created.
    pub fn set_pins(&mut self, context: &GpuContext, pinned: &[bool]) {
        let list: Vec<u32> = (0..pinned.len() as u32)
            .filter(|&v| pinned[v as usize])
            .collect();
        let none = wgpu::BufferUsages::empty();
        self.pinned = storage(context, "pinned vertices", &list, none);
        self.pin_count = list.len() as u32;
    }

    /// The spheres drawn, one `vec4` (centre, radius) each in collider order, `COPY_DST`: a
    /// solver may copy its balls' current places in (`GpuSolver::copy_spheres`) after
    /// [`SceneRenderer::set_colliders`] and before drawing.
    pub fn sphere_buffer(&self) -> &wgpu::Buffer {
        &self.spheres
    }

    /// Shows the scene's colliders (placed where they are now; call again as they move):
    /// spheres are drawn, and the ground moves to the highest horizontal plane below the cloth.
    pub fn set_colliders(&mut self, context: &GpuContext, colliders: &[Collider]) {
        let spheres: Vec<[f32; 4]> = colliders
            .iter()
            .filter_map(|c| match c.shape {
                Shape::Sphere { center, radius } => {
                    let c = center.as_vec3();
                    Some([c.x, c.y, c.z, radius as f32])
                }
                Shape::Plane { .. } | Shape::Capsule { .. } => None,
            })
            .collect();
        let capsules: Vec<[f32; 4]> = colliders
            .iter()
            .flat_map(|c| match c.shape {
                Shape::Capsule { start, end, radius } => {
                    let (a, b) = (start.as_vec3(), end.as_vec3());
                    vec![[a.x, a.y, a.z, radius as f32], [b.x, b.y, b.z, 0.0]]
                }
                _ => Vec::new(),
            })
            .collect();
        // Called every frame: the buffer is made once per capsule count and rewritten after.
        if !capsules.is_empty() && capsules.len() as u32 == 2 * self.capsule_count {
            context
                .queue
                .write_buffer(&self.capsules, 0, bytemuck::cast_slice(&capsules));
        } else if !capsules.is_empty() {
            self.capsules = storage(
                context,
                "collider capsules",
                &capsules,
                wgpu::BufferUsages::COPY_DST,
            );
        }
        self.capsule_count = capsules.len() as u32 / 2;
        let forces: Vec<[f32; 4]> = colliders
            .iter()
            .filter(|c| matches!(c.shape, Shape::Sphere { .. }))
            .map(|c| match (c.dynamics, c.shape) {
                (Some(d), Shape::Sphere { radius, .. }) if d.force.length() > 0.0 => {
                    // One radius long, up to three as the push reaches the ball's weight.
                    let weight = d.mass * 9.81;
                    let length = radius * (1.0 + 2.0 * (d.force.length() / weight).min(1.0));
                    let f = d.force.normalize().as_vec3();
                    [f.x, f.y, f.z, length as f32]
                }
                _ => [0.0; 4],
            })
            .collect();
        if !spheres.is_empty() && spheres.len() as u32 == self.sphere_count {
            // Moving colliders: same spheres, new places.
            context
                .queue
                .write_buffer(&self.spheres, 0, bytemuck::cast_slice(&spheres));
            context
                .queue
                .write_buffer(&self.sphere_forces, 0, bytemuck::cast_slice(&forces));
        } else if !spheres.is_empty() {
            self.spheres = storage(
                context,
                "collider spheres",
                &spheres,
                wgpu::BufferUsages::COPY_DST,
            );
            self.sphere_forces = storage(
                context,
                "ball forces",
                &forces,
                wgpu::BufferUsages::COPY_DST,
            );
        }
        self.sphere_count = spheres.len() as u32;
        let floor = colliders
            .iter()
            .filter_map(|c| match c.shape {
                Shape::Plane { point, normal }
                    if normal.y > 0.999 && point.y as f32 <= self.bounds.min.y =>
                {
                    Some(point.y as f32)
                }
                _ => None,
            })
            .reduce(f32::max);
        if let Some(height) = floor {
            self.bounds.ground_height = height;
        }
    }

    fn depth_view(&mut self, context: &GpuContext, size: [u32; 2]) -> wgpu::TextureView {
        if let Some((view, depth_size)) = &self.depth
            && *depth_size == size
        {
            return view.clone();
        }
        let texture = context.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("depth"),
            size: wgpu::Extent3d {
                width: size[0],
                height: size[1],
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        self.depth = Some((view.clone(), size));
        view
    }

    /// Records the normals pass and the render pass drawing `cloth` (the solver's current
    /// buffers) into `target` of `size` pixels.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &mut self,
        context: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        cloth: ClothBuffers<'_>,
        target: &wgpu::TextureView,
        size: [u32; 2],
        camera: &Camera,
        options: &RenderOptions,
    ) {
        let aspect = size[0] as f32 / size[1].max(1) as f32;
        let uniforms = self.frame_uniforms(camera, aspect, options);
        context
            .queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniforms));
        let positions = cloth.positions;
        let broken = cloth.broken_springs.unwrap_or(&self.no_tears);
        let normals_group = bind_group(
            context,
            "normals",
            &self.normals_pipeline.get_bind_group_layout(0),
            &[
                (0, positions.as_entire_binding()),
                (1, self.triangles.as_entire_binding()),
                (2, self.vertex_triangles.as_entire_binding()),
                (3, self.normals.as_entire_binding()),
                (4, self.counts.as_entire_binding()),
                (5, self.triangle_edges.as_entire_binding()),
                (6, broken.as_entire_binding()),
            ],
        );
        gpu::dispatch(
            encoder,
            "normals",
            &self.normals_pipeline,
            &normals_group,
            self.vertex_count,
            None,
        );
        let group_for = |pipeline: &wgpu::RenderPipeline, bindings: &[u32]| {
            let all = [
                (0, self.frame.as_entire_binding()),
                (1, positions.as_entire_binding()),
                (2, self.normals.as_entire_binding()),
                (3, self.triangles.as_entire_binding()),
                (4, self.uvs.as_entire_binding()),
                (5, self.rest_edges.as_entire_binding()),
                (6, self.spring_ends.as_entire_binding()),
                (7, self.pinned.as_entire_binding()),
                (12, self.triangle_edges.as_entire_binding()),
                (13, broken.as_entire_binding()),
            ];
            let used: Vec<(u32, wgpu::BindingResource<'_>)> = all
                .into_iter()
                .filter(|(b, _)| bindings.contains(b))
                .collect();
            bind_group(context, "scene", &pipeline.get_bind_group_layout(0), &used)
        };
        let cloth_group = group_for(&self.cloth, &[0, 1, 2, 3, 4, 5, 12, 13]);
        let ground_group = group_for(&self.ground, &[0]);
        let springs_group = group_for(&self.springs, &[0, 1, 6, 13]);
        let pins_group = group_for(&self.pins, &[0, 1, 7]);
        let wind_group = group_for(&self.wind, &[0]);
        let sphere_group = bind_group(
            context,
            "collider spheres",
            &self.sphere.get_bind_group_layout(0),
            &[
                (0, self.frame.as_entire_binding()),
                (8, self.spheres.as_entire_binding()),
                (9, self.sphere_mesh.as_entire_binding()),
            ],
        );
        let force_group = bind_group(
            context,
            "ball forces",
            &self.ball_force.get_bind_group_layout(0),
            &[
                (0, self.frame.as_entire_binding()),
                (8, self.spheres.as_entire_binding()),
                (10, self.sphere_forces.as_entire_binding()),
            ],
        );
        let capsule_group = bind_group(
            context,
            "collider capsules",
            &self.capsule.get_bind_group_layout(0),
            &[
                (0, self.frame.as_entire_binding()),
                (9, self.sphere_mesh.as_entire_binding()),
                (11, self.capsules.as_entire_binding()),
            ],
        );
        let depth = self.depth_view(context, size);
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: 0.80,
                        g: 0.85,
                        b: 0.92,
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.ground);
        pass.set_bind_group(0, &ground_group, &[]);
        pass.draw(0..6, 0..1);
        if self.sphere_count > 0 {
            pass.set_pipeline(&self.sphere);
            pass.set_bind_group(0, &sphere_group, &[]);
            pass.draw(0..self.sphere_mesh_vertices, 0..self.sphere_count);
            pass.set_pipeline(&self.ball_force);
            pass.set_bind_group(0, &force_group, &[]);
            pass.draw(0..6, 0..self.sphere_count);
        }
        if self.capsule_count > 0 {
            pass.set_pipeline(&self.capsule);
            pass.set_bind_group(0, &capsule_group, &[]);
            pass.draw(0..self.sphere_mesh_vertices, 0..self.capsule_count);
        }
        pass.set_pipeline(&self.cloth);
        pass.set_bind_group(0, &cloth_group, &[]);
        pass.draw(0..3 * self.triangle_count, 0..1);
        if options.wireframe {
            pass.set_pipeline(&self.springs);
            pass.set_bind_group(0, &springs_group, &[]);
            pass.draw(0..2 * self.spring_count, 0..1);
        }
        if options.show_pins && self.pin_count > 0 {
            pass.set_pipeline(&self.pins);
            pass.set_bind_group(0, &pins_group, &[]);
            pass.draw(0..6, 0..self.pin_count);
        }
        if options.wind.is_some_and(|w| w.length() > 0.0) {
            pass.set_pipeline(&self.wind);
            pass.set_bind_group(0, &wind_group, &[]);
            pass.draw(0..6, 0..16);
        }
    }

    fn frame_uniforms(
        &self,
        camera: &Camera,
        aspect: f32,
        options: &RenderOptions,
    ) -> FrameUniforms {
        let extent = self.bounds.extent();
        let center = self.bounds.center();
        let eye = camera.eye();
        let wind = options.wind.unwrap_or(Vec3::ZERO);
        let direction = wind.normalize_or(Vec3::X);
        // Arrows upwind of the scene, as long as the wind is strong (capped to the scene size).
        let length = (0.1 * wind.length()).clamp(0.1 * extent, 0.4 * extent);
        let origin = center - direction * (0.9 * extent);
        let v4 = |v: Vec3, w: f32| [v.x, v.y, v.z, w];
        FrameUniforms {
            view_projection: camera.view_projection(aspect).to_cols_array_2d(),
            eye: v4(eye, 1.0),
            center: v4(center, 1.0),
            light: v4(Vec3::new(0.6, 0.8, 0.35).normalize(), 0.0),
            ground: [
                self.bounds.ground_height,
                3.0 * extent,
                0.25 * extent,
                8.0 * extent,
            ],
            wind: v4(direction, length),
            wind_origin: v4(origin, 0.25 * extent),
            style: [
                if options.color_by_strain { 1.0 } else { 0.0 },
                options.strain_scale,
                0.012 * extent,
                if self.tears { 1.0 } else { 0.0 },
            ],
        }
    }
}

fn shader(context: &GpuContext, label: &str, source: &str) -> wgpu::ShaderModule {
    context
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        })
}

/// Corners of a unit UV sphere's triangles (vec4, w unused), for instanced drawing.
fn unit_sphere_triangles(segments: u32, rings: u32) -> Vec<[f32; 4]> {
    let point = |segment: u32, ring: u32| {
        let theta = std::f32::consts::PI * ring as f32 / rings as f32;
        let phi = std::f32::consts::TAU * segment as f32 / segments as f32;
        [
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
            0.0,
        ]
    };
    let mut corners = Vec::with_capacity((6 * segments * rings) as usize);
    for ring in 0..rings {
        for segment in 0..segments {
            let [a, b, c, d] = [
                point(segment, ring),
                point(segment + 1, ring),
                point(segment, ring + 1),
                point(segment + 1, ring + 1),
            ];
            corners.extend([a, c, b, b, c, d]);
        }
    }
    corners
}

/// Texture coordinates from the rest shape, over the two axes of largest extent.
fn texture_coordinates(model: &Model, bounds: &SceneBounds) -> Vec<[f32; 2]> {
    let extent = bounds.max - bounds.min;
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|a, b| extent[*b].total_cmp(&extent[*a]));
    let size = extent[axes[0]].max(1e-6);
    model
        .initial_positions
        .iter()
        .map(|p| {
            let q = p.as_vec3() - bounds.min;
            [q[axes[0]] / size, q[axes[1]] / size]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn render_shaders_validate() {
        for (name, source) in [
            ("normals", super::NORMALS),
            ("scene", super::SCENE),
            ("pick", super::pick::PICK),
        ] {
            let module = naga::front::wgsl::parse_str(source)
                .unwrap_or_else(|e| panic!("{name}.wgsl: {}", e.emit_to_string(source)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::empty(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}.wgsl: {}", e.emit_to_string(source)));
        }
    }
}
