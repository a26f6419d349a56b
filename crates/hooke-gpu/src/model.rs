//! [`GpuModel`]: the model's buffers on the GPU (what stays fixed while stepping, and the
//! material's constants, rewritten in place when the material changes).

use hooke_core::{Material, Model};

use crate::context::{GpuContext, GpuError};
use crate::gpu::{self, storage, zeroed};
use crate::layout::{GatherEntry, GpuSpring, GpuStencil, StepUniforms};
use crate::methods::{Accumulation, GpuMethod};
use crate::stencil::Stencil;

/// Texels per row of the blend force target.
pub(crate) const BLEND_WIDTH: u32 = 2048;

/// Bytes of `count` `vec4` values.
pub(crate) fn vec4s(count: usize) -> u64 {
    count as u64 * 16
}

pub(crate) fn bytes_of<T>(data: &[T]) -> u64 {
    std::mem::size_of_val(data) as u64
}

/// The springs as the force kernels read them (the material's stiffness scale is a uniform, so
/// these never change).
#[derive(Debug)]
pub enum GpuTopology {
    /// Per vertex in valence-sorted order (the paper's layout): its springs in CSR rows.
    Gather {
        /// Per processing slot `[vertex, first entry]`, and one more whose `[1]` ends the last
        /// row (one buffer, so the fused gather and integration fits WebGPU's default limit
        /// of 8 storage buffers).
        rows: wgpu::Buffer,
        entries: wgpu::Buffer,
    },
    /// The gather of a structured mesh whose records never change. No CSR rows:
    /// [`GpuModel::let_records_change`] builds them when a snapshot's tears need them.
    Stencil(StencilKinds),
    /// One record per spring, and for the atomic accumulations of a structured mesh whose
    /// records never change the stencil their kernels read instead.
    Scatter {
        springs: wgpu::Buffer,
        stencil: Option<StencilKinds>,
    },
}

/// A structured mesh's stencil and its kinds as the kernels bind them (`GpuStencil`); the
/// masks travel in [`GpuModel::scales`].
#[derive(Debug)]
pub struct StencilKinds {
    pub stencil: Stencil,
    pub kinds: wgpu::Buffer,
}

impl StencilKinds {
    /// Bytes of the kinds' table on the GPU.
    const BYTES: u64 = std::mem::size_of::<GpuStencil>() as u64;

    /// The model's stencil, if it has one (see [`Stencil::of`]).
    fn of(context: &GpuContext, model: &Model) -> Option<Self> {
        let stencil = Stencil::of(model)?;
        let kinds = gpu::uniform(context, &stencil.table());
        Some(Self { stencil, kinds })
    }
}

/// The model on the GPU: step uniforms, per-vertex integration constants, springs, and the
/// triangle lists wind needs. Built once; [`GpuModel::set_material`] rewrites it in place.
#[derive(Debug)]
pub struct GpuModel {
    /// The host model, its collision set-up included.
    pub model: Model,
    pub material: Material,
    pub method: GpuMethod,
    /// The host copy of the step uniforms; [`GpuModel::write_uniforms`] sends it.
    pub uniforms: StepUniforms,
    /// Two copies of the uniforms, `uniform_slot` bytes apart, differing only in `parity`:
    /// a kernel binds the one for the current position buffer ([`GpuModel::uniforms_binding`]).
    uniform_buffer: wgpu::Buffer,
    uniform_slot: u64,
    /// Per vertex `(dt^2 / m, 1 - c dt / m, stencil mask, 0)`, the first two zero for pinned
    /// vertices (the mask: [`Stencil::mask_as_float`] with a [`GpuTopology::Stencil`], else 0).
    pub scales: wgpu::Buffer,
    pub topology: GpuTopology,
    /// Whether the force records' stiffness may be rewritten (zero for torn springs: the
    /// model tears, or a restored snapshot carried tears). Kernels must then read each
    /// record's stiffness; otherwise the gather may read less (a stencil, one stiffness).
    pub records_change: bool,
    /// Triangles as `vec4<u32>` (for wind).
    pub triangles: wgpu::Buffer,
    /// `vertex_count + 1` offsets, then each vertex's triangles (for wind, in a fixed order).
    pub vertex_triangles: wgpu::Buffer,
    /// Bytes of the topology buffers.
    pub topology_bytes: u64,
    /// Bytes of the triangle lists.
    pub triangle_bytes: u64,
}

impl GpuModel {
    pub fn new(
        context: &GpuContext,
        model: &Model,
        material: &Material,
        method: GpuMethod,
    ) -> Result<Self, GpuError> {
        let n = model.vertex_count();
        gpu::check_binding_size(context, "positions", vec4s(n))?;
        let uniform_slot = (std::mem::size_of::<StepUniforms>() as u64).next_multiple_of(
            u64::from(context.device.limits().min_uniform_buffer_offset_alignment),
        );
        let uniform_buffer = context.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("step uniforms"),
            size: 2 * uniform_slot,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let scales = zeroed(
            context,
            "integration scales",
            vec4s(n),
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        );
        let none = wgpu::BufferUsages::empty();
        let records_change = model.tearing.is_some();
        // Kernels that can read a stencil instead of records that never change.
        let reads_stencil = !records_change
            && matches!(
                method,
                GpuMethod::Gather
                    | GpuMethod::Scatter(Accumulation::AtomicF32 | Accumulation::AtomicFixed)
            );
        let stencil = reads_stencil
            .then(|| StencilKinds::of(context, model))
            .flatten();
        let (topology, topology_bytes) = match (method, stencil) {
            (GpuMethod::Gather, Some(stencil)) => {
                (GpuTopology::Stencil(stencil), StencilKinds::BYTES)
            }
            (GpuMethod::Gather, None) => gather_adjacency(context, model)?,
            (GpuMethod::Scatter(_), stencil) => {
                let springs = spring_records(model);
                gpu::check_binding_size(context, "springs", bytes_of(&springs))?;
                let bytes =
                    bytes_of(&springs) + stencil.as_ref().map_or(0, |_| StencilKinds::BYTES);
                // Tearing's restore rewrites the records.
                let springs = storage(context, "springs", &springs, wgpu::BufferUsages::COPY_DST);
                (GpuTopology::Scatter { springs, stencil }, bytes)
            }
        };
        let triangles: Vec<[u32; 4]> = model
            .triangles
            .iter()
            .map(|t| [t[0], t[1], t[2], 0])
            .collect();
        let lists = gpu::vertex_triangle_lists(n, &model.triangles);
        let mut gpu_model = Self {
            uniforms: StepUniforms {
                vertex_count: n as u32,
                spring_count: model.spring_count() as u32,
                collider_count: model.collision.colliders.len() as u32,
                dynamic_count: model
                    .collision
                    .colliders
                    .iter()
                    .filter(|c| c.dynamics.is_some())
                    .count() as u32,
                collision_thickness: model.collision.thickness as f32,
                stiffness_scale: material.stiffness_scale as f32,
                uniform_stiffness: uniform_stiffness(model).unwrap_or(0.0),
                ..Default::default()
            },
            triangles: storage(context, "wind triangles", &triangles, none),
            vertex_triangles: storage(context, "vertex triangles", &lists, none),
            triangle_bytes: bytes_of(&triangles) + bytes_of(&lists),
            model: model.clone(),
            material: *material,
            method,
            uniform_buffer,
            uniform_slot,
            scales,
            topology,
            topology_bytes,
            records_change,
        };
        gpu_model.set_accumulation_scales();
        gpu_model.write_scales(context);
        Ok(gpu_model)
    }

    /// Takes a new material: integration constants, gravity, `1/dt` and the stiffness scale
    /// (with the accumulation scales that follow it) rewritten in place. Creates nothing.
    pub fn set_material(&mut self, context: &GpuContext, material: &Material) {
        self.material = *material;
        self.write_scales(context);
        self.uniforms.stiffness_scale = material.stiffness_scale as f32;
        self.set_accumulation_scales();
        self.write_uniforms(context);
    }

    /// Sends the host copy of the step uniforms, once per parity.
    pub fn write_uniforms(&self, context: &GpuContext) {
        for parity in 0..2 {
            let uniforms = StepUniforms {
                parity,
                ..self.uniforms
            };
            context.queue.write_buffer(
                &self.uniform_buffer,
                u64::from(parity) * self.uniform_slot,
                bytemuck::bytes_of(&uniforms),
            );
        }
    }

    /// The uniforms of a step whose current position buffer is `current`.
    pub fn uniforms_binding(&self, current: usize) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &self.uniform_buffer,
            offset: current as u64 * self.uniform_slot,
            size: wgpu::BufferSize::new(std::mem::size_of::<StepUniforms>() as u64),
        })
    }

    /// Per-vertex `(dt^2/m, 1 - c dt/m)` and the uniforms that depend on dt (not yet sent).
    fn write_scales(&mut self, context: &GpuContext) {
        let Material {
            dt,
            damping,
            gravity,
            ..
        } = self.material;
        let stencil = self.stencil().map(|s| &s.stencil);
        let scales: Vec<[f32; 4]> = self
            .model
            .masses
            .iter()
            .zip(&self.model.pinned)
            .enumerate()
            .map(|(v, (m, pinned))| {
                let mask = stencil.map_or(0.0, |s| s.mask_as_float(v));
                if *pinned {
                    [0.0, 0.0, mask, 0.0]
                } else {
                    [
                        (dt * dt / m) as f32,
                        (1.0 - damping * dt / m) as f32,
                        mask,
                        0.0,
                    ]
                }
            })
            .collect();
        context
            .queue
            .write_buffer(&self.scales, 0, bytemuck::cast_slice(&scales));
        let g = (gravity * dt * dt).as_vec3();
        self.uniforms.gravity_step = [g.x, g.y, g.z, 0.0];
        self.uniforms.inverse_dt = (1.0 / dt) as f32;
    }

    /// The scales of fixed-point and blend accumulation for the current stiffness.
    fn set_accumulation_scales(&mut self) {
        let model = &self.model;
        let range = force_range(model, self.material.stiffness_scale);
        let max_valence = (0..model.vertex_count())
            .map(|v| model.adjacency.valence(v))
            .max()
            .unwrap_or(0);
        // A vertex sums at most max_valence contributions, each within the limit: no wrap.
        let limit = (2f64.powi(31) / f64::from(max_valence + 1)).floor() - 256.0;
        self.uniforms.fixed_limit = limit as f32;
        self.uniforms.fixed_scale = (limit / range) as f32;
        let n = model.vertex_count() as u32;
        self.uniforms.blend_width = BLEND_WIDTH.min(n.max(1));
        self.uniforms.blend_height = n.div_ceil(self.uniforms.blend_width).max(1);
        // Float targets: a power of two near the range (exact rescaling). 8-bit targets: the
        // range times the valence, so a vertex's sum of either sign stays below 1.
        self.uniforms.blend_scale = match self.method {
            GpuMethod::Scatter(Accumulation::BlendRgba8) => {
                (range * f64::from(max_valence.max(1))) as f32
            }
            _ => 2f64.powi(range.log2().round() as i32) as f32,
        };
    }

    /// Lets the force records' stiffness be rewritten from now on (a restored snapshot's
    /// tears): a stencil gives way to the gather's CSR rows or scatter's records, and kernels
    /// built after this read each record's stiffness ([`GpuModel::records_change`]).
    pub fn let_records_change(&mut self, context: &GpuContext) -> Result<(), GpuError> {
        match &mut self.topology {
            GpuTopology::Stencil(_) => {
                (self.topology, self.topology_bytes) = gather_adjacency(context, &self.model)?;
            }
            GpuTopology::Scatter { stencil, .. } => {
                if stencil.take().is_some() {
                    self.topology_bytes -= StencilKinds::BYTES;
                }
            }
            GpuTopology::Gather { .. } => {}
        }
        self.records_change = true;
        Ok(())
    }

    /// The stencil the kernels read, if the model is a structured mesh whose records never
    /// change and the method reads one.
    pub fn stencil(&self) -> Option<&StencilKinds> {
        match &self.topology {
            GpuTopology::Stencil(stencil) => Some(stencil),
            GpuTopology::Scatter { stencil, .. } => stencil.as_ref(),
            GpuTopology::Gather { .. } => None,
        }
    }

    /// The buffer of the force records (gather entries or spring records); none for a
    /// stencil.
    pub fn force_records(&self) -> Option<&wgpu::Buffer> {
        match &self.topology {
            GpuTopology::Gather { entries, .. } => Some(entries),
            GpuTopology::Scatter { springs, .. } => Some(springs),
            GpuTopology::Stencil(_) => None,
        }
    }

    /// Per spring, the index of each 32-bit word holding its stiffness in
    /// [`GpuModel::force_records`]: gather has one per end, scatter one (the other `u32::MAX`).
    pub fn stiffness_words(&self) -> Vec<[u32; 2]> {
        let model = &self.model;
        match &self.topology {
            GpuTopology::Gather { .. } | GpuTopology::Stencil(_) => {
                const WORDS: usize = std::mem::size_of::<GatherEntry>() / 4;
                let stiffness = std::mem::offset_of!(GatherEntry, stiffness) / 4;
                let mut words = vec![[u32::MAX; 2]; model.spring_count()];
                let entries = valence_sorted_order(model)
                    .into_iter()
                    .flat_map(|v| model.adjacency.range(v as usize));
                for (slot, k) in entries.enumerate() {
                    let spring = &mut words[model.adjacency.springs[k] as usize];
                    let end = usize::from(spring[0] != u32::MAX);
                    spring[end] = (slot * WORDS + stiffness) as u32;
                }
                words
            }
            GpuTopology::Scatter { .. } => {
                const WORDS: usize = std::mem::size_of::<GpuSpring>() / 4;
                let stiffness = std::mem::offset_of!(GpuSpring, stiffness) / 4;
                (0..model.spring_count())
                    .map(|s| [(s * WORDS + stiffness) as u32, u32::MAX])
                    .collect()
            }
        }
    }

    /// Rewrites the force records with the `broken` springs (flags in spring order) at zero
    /// stiffness and every other spring whole: what restoring a snapshot's tears needs.
    pub fn write_force_records(&self, context: &GpuContext, broken: &[bool]) {
        let torn = self.model.with_springs_broken(broken);
        let (bytes, records): (Vec<u8>, _) = match &self.topology {
            GpuTopology::Gather { entries, .. } => (
                bytemuck::cast_slice(&gather_entries(&torn, &valence_sorted_order(&torn))).to_vec(),
                entries,
            ),
            GpuTopology::Scatter { springs, .. } => (
                bytemuck::cast_slice(&spring_records(&torn)).to_vec(),
                springs,
            ),
            // No records: a stencil's never change (see `let_records_change`).
            GpuTopology::Stencil(_) => return,
        };
        context.queue.write_buffer(records, 0, &bytes);
    }

    /// The springs buffer of the scatter method.
    pub fn springs(&self) -> Option<&wgpu::Buffer> {
        match &self.topology {
            GpuTopology::Scatter { springs, .. } => Some(springs),
            GpuTopology::Gather { .. } | GpuTopology::Stencil(_) => None,
        }
    }
}

/// Every spring's stiffness as a float32 record holds it, when all springs have the same one.
pub fn uniform_stiffness(model: &Model) -> Option<f32> {
    let first = *model.stiffnesses.first()? as f32;
    model
        .stiffnesses
        .iter()
        .all(|&k| k as f32 == first)
        .then_some(first)
}

/// A spring stretched to twice its rest length: the force scale fixed-point and 8-bit
/// accumulation are sized for (`max D l0`). Larger forces are clamped (fixed point: and
/// reported) or saturate (8-bit blending, as in the paper).
fn force_range(model: &Model, stiffness_scale: f64) -> f64 {
    (0..model.spring_count())
        .map(|s| model.stiffness(s, stiffness_scale) * model.rest_lengths[s])
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE)
}

/// The gather's CSR rows in valence-sorted order (the paper's layout) and their bytes.
fn gather_adjacency(context: &GpuContext, model: &Model) -> Result<(GpuTopology, u64), GpuError> {
    let order = valence_sorted_order(model);
    let mut rows: Vec<[u32; 2]> = Vec::with_capacity(order.len() + 1);
    let mut first = 0u32;
    for &v in &order {
        rows.push([v, first]);
        first += model.adjacency.valence(v as usize);
    }
    rows.push([u32::MAX, first]);
    let entries = gather_entries(model, &order);
    gpu::check_binding_size(context, "gather adjacency", bytes_of(&entries))?;
    let bytes = bytes_of(&rows) + bytes_of(&entries);
    let none = wgpu::BufferUsages::empty();
    let topology = GpuTopology::Gather {
        rows: storage(context, "gather rows", &rows, none),
        // Tearing's restore rewrites the records.
        entries: storage(
            context,
            "gather entries",
            &entries,
            wgpu::BufferUsages::COPY_DST,
        ),
    };
    Ok((topology, bytes))
}

/// Valence-sorted processing order (the paper's layout): slot -> vertex.
fn valence_sorted_order(model: &Model) -> Vec<u32> {
    let mut order: Vec<u32> = (0..model.vertex_count() as u32).collect();
    order.sort_by_key(|&v| std::cmp::Reverse(model.adjacency.valence(v as usize)));
    order
}

/// The gather adjacency rows of the vertices in `order`.
fn gather_entries(model: &Model, order: &[u32]) -> Vec<GatherEntry> {
    let adjacency = &model.adjacency;
    let mut entries = Vec::with_capacity(adjacency.neighbors.len());
    for &v in order {
        for k in adjacency.range(v as usize) {
            let spring = adjacency.springs[k] as usize;
            entries.push(GatherEntry {
                neighbor: adjacency.neighbors[k],
                rest_length: model.rest_lengths[spring] as f32,
                stiffness: model.stiffnesses[spring] as f32,
            });
        }
    }
    entries
}

/// One record per spring for the scatter kernels.
fn spring_records(model: &Model) -> Vec<GpuSpring> {
    model
        .spring_ends
        .iter()
        .enumerate()
        .map(|(s, [a, b])| GpuSpring {
            a: *a,
            b: *b,
            rest_length: model.rest_lengths[s] as f32,
            stiffness: model.stiffnesses[s] as f32,
        })
        .collect()
}
