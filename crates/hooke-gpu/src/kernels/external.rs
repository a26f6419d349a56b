//! `external.wgsl`: the forces of a [`Control`] (point forces, drags, wind; models in
//! `hooke_core::control`) into the per-vertex extra-force buffer that `integrate` adds. Wind is
//! computed per triangle, then gathered per vertex over its triangles in a fixed order.
//!
//! Every buffer exists from the start, so taking a new control (a drag that follows the mouse, a
//! wind slider) writes a few bytes and creates nothing: only the vertices whose point force or
//! drag changed are rewritten.

use std::collections::BTreeMap;

use glam::DVec3;
use hooke_core::{Control, Model};

use crate::context::{GpuContext, GpuError};
use crate::gpu::{Kernel, storage, zeroed};
use crate::model::{GpuModel, vec4s};
use crate::state::GpuState;

/// Above this many changed vertices a control is written as one whole buffer.
const SPARSE_WRITES: usize = 64;

/// Per vertex: point force and drag stiffness, then drag target (two `vec4`).
type Entry = [[f32; 4]; 2];

#[derive(Debug)]
pub struct External {
    /// Wind force per triangle.
    pub wind: Kernel,
    /// Per vertex: point force, drag and the wind of its triangles, into the extra forces.
    pub vertices: Kernel,
    /// Two `vec4` per vertex (see [`Entry`]).
    point_and_drag: wgpu::Buffer,
    /// Wind velocity xyz and coefficient w (uniform).
    wind_uniform: wgpu::Buffer,
    /// Per vertex: the control's force, which `integrate` adds (when `has_extra` is set).
    pub extra_forces: wgpu::Buffer,
    /// Vertices whose entry is non-zero now.
    touched: Vec<u32>,
    triangle_count: u32,
    wind_on: bool,
    /// True if the model has dampers (they act whatever the control).
    damps: bool,
    bytes: u64,
}

impl External {
    /// The passes of `model`; a torn spring's damper stops when `broken` (the per-spring flags,
    /// when springs can break) says so.
    pub fn new(
        context: &GpuContext,
        model: &GpuModel,
        state: &GpuState,
        broken: Option<&wgpu::Buffer>,
    ) -> Result<Self, GpuError> {
        let n = model.model.vertex_count();
        let none = wgpu::BufferUsages::empty();
        let dampers = model.model.dampers(&[]);
        let mut damper_words = vec![(model.model.bending_damping as f32).to_bits()];
        damper_words.extend(&dampers.offsets);
        for (other, spring) in dampers.neighbors.iter().zip(&dampers.springs) {
            damper_words.extend([*other, *spring]);
        }
        let damper_buffer = storage(context, "dampers", &damper_words, none);
        let never_broken = storage(context, "no broken springs", &[0u32; 4], none);
        let broken = broken.unwrap_or(&never_broken);
        let extra_forces = zeroed(
            context,
            "extra forces",
            vec4s(n),
            wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        );
        let triangle_count = model.model.triangles.len();
        let copy = wgpu::BufferUsages::COPY_DST;
        let point_and_drag = zeroed(context, "point forces and drags", 2 * vec4s(n), copy);
        let wind = context.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("wind"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | copy,
            mapped_at_creation: false,
        });
        let triangle_forces = zeroed(
            context,
            "wind triangle forces",
            vec4s(triangle_count),
            wgpu::BufferUsages::empty(),
        );
        let vertices = Kernel::new(
            context,
            "external forces",
            super::EXTERNAL,
            "vertices",
            n as u32,
            |current| {
                vec![
                    (0, model.uniforms_binding(current)),
                    (1, state.positions[current].as_entire_binding()),
                    (3, point_and_drag.as_entire_binding()),
                    (6, triangle_forces.as_entire_binding()),
                    (2, state.deltas.as_entire_binding()),
                    (7, model.vertex_triangles.as_entire_binding()),
                    (8, extra_forces.as_entire_binding()),
                    (9, damper_buffer.as_entire_binding()),
                    (10, broken.as_entire_binding()),
                ]
            },
        )?;
        let wind_kernel = Kernel::new(
            context,
            "wind per triangle",
            super::EXTERNAL,
            "wind_triangles",
            triangle_count as u32,
            |current| {
                vec![
                    (0, model.uniforms_binding(current)),
                    (1, state.positions[current].as_entire_binding()),
                    (2, state.deltas.as_entire_binding()),
                    (4, wind.as_entire_binding()),
                    (5, model.triangles.as_entire_binding()),
                    (6, triangle_forces.as_entire_binding()),
                ]
            },
        )?;
        Ok(Self {
            wind: wind_kernel,
            vertices,
            point_and_drag,
            wind_uniform: wind,
            extra_forces,
            touched: Vec::new(),
            triangle_count: triangle_count as u32,
            wind_on: false,
            damps: !dampers.neighbors.is_empty(),
            // Point forces and drags, wind triangle forces, the extra forces themselves, dampers.
            bytes: 2 * vec4s(n) + vec4s(triangle_count) + vec4s(n) + damper_buffer.size(),
        })
    }

    /// Bytes held (the model's triangle lists are counted there).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Writes `control` into the buffers. Returns whether the control or the dampers put forces
    /// on the cloth (`has_extra`) and how many triangles wind acts on (`triangle_count`), for the uniforms.
    pub fn write(&mut self, context: &GpuContext, model: &Model, control: &Control) -> (bool, u32) {
        let entries = entries_of(control);
        let stale: Vec<u32> = self
            .touched
            .iter()
            .copied()
            .filter(|v| !entries.contains_key(v))
            .collect();
        let queue = &context.queue;
        if entries.len() + stale.len() > SPARSE_WRITES {
            let mut all = vec![[[0.0f32; 4]; 2]; model.vertex_count()];
            for (&v, entry) in &entries {
                all[v as usize] = *entry;
            }
            queue.write_buffer(&self.point_and_drag, 0, bytemuck::cast_slice(&all));
        } else {
            let entry_bytes = std::mem::size_of::<Entry>() as u64;
            for v in stale {
                let zero: Entry = [[0.0; 4]; 2];
                queue.write_buffer(
                    &self.point_and_drag,
                    u64::from(v) * entry_bytes,
                    bytemuck::cast_slice(&zero),
                );
            }
            for (&v, entry) in &entries {
                queue.write_buffer(
                    &self.point_and_drag,
                    u64::from(v) * entry_bytes,
                    bytemuck::cast_slice(entry),
                );
            }
        }
        self.touched = entries.keys().copied().collect();
        let wind = control.wind.map_or([0.0; 4], |w| {
            let v = w.velocity.as_vec3();
            [v.x, v.y, v.z, w.coefficient as f32]
        });
        queue.write_buffer(&self.wind_uniform, 0, bytemuck::cast_slice(&wind));
        self.wind_on = control.wind.is_some();
        let triangles = if self.wind_on { self.triangle_count } else { 0 };
        (control.acts_on_cloth() || self.damps, triangles)
    }

    /// True if the model's dampers act (so the pass runs even without a control).
    pub fn damps(&self) -> bool {
        self.damps
    }

    /// True if the control has wind (then [`External::encode_wind`] runs before the sums).
    pub fn wind_on(&self) -> bool {
        self.wind_on
    }
}

/// The non-zero per-vertex entries of a control. Several drags on one vertex combine into one
/// of summed stiffness toward their stiffness-weighted target.
fn entries_of(control: &Control) -> BTreeMap<u32, Entry> {
    let mut sums: BTreeMap<u32, (DVec3, f64, DVec3)> = BTreeMap::new();
    for point in &control.point_forces {
        sums.entry(point.vertex).or_default().0 += point.force;
    }
    for drag in &control.drags {
        for &v in &drag.vertices {
            let sum = sums.entry(v).or_default();
            sum.1 += drag.stiffness;
            sum.2 += drag.stiffness * drag.target;
        }
    }
    sums.into_iter()
        .map(|(v, (force, stiffness, weighted_target))| {
            let target = if stiffness > 0.0 {
                weighted_target / stiffness
            } else {
                DVec3::ZERO
            };
            let (f, t) = (force.as_vec3(), target.as_vec3());
            (v, [[f.x, f.y, f.z, stiffness as f32], [t.x, t.y, t.z, 0.0]])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use hooke_core::forces::add_external_forces;
    use hooke_core::{Drag, Material, PointForce, Wind};

    use super::*;
    use crate::kernels::testing::{
        as_gpu_sees, assert_close, context, read_vec3s, run, stretched_scene,
    };
    use crate::methods::GpuMethod;

    /// float32 triangle normals, areas and velocities against float64 from the same float32
    /// state: a few ulps of the largest force.
    const TOLERANCE: f64 = 1e-5;

    #[test]
    fn control_forces_are_the_references_and_a_new_control_replaces_the_old() {
        let Some(context) = context() else { return };
        let (scene, state) = stretched_scene();
        let n = scene.model.vertex_count();
        let mut model = GpuModel::new(&context, &scene.model, &scene.material, GpuMethod::Gather)
            .expect("model");
        let gpu_state = GpuState::new(&context, n);
        gpu_state.write(&context, &state);
        let mut external = External::new(&context, &model, &gpu_state, None).expect("kernel");
        let first = Control {
            wind: Some(Wind {
                velocity: DVec3::new(3.0, 1.0, -2.0),
                coefficient: 0.7,
            }),
            point_forces: vec![PointForce {
                vertex: 5,
                force: DVec3::new(0.0, 0.2, 0.0),
            }],
            drags: (0..100)
                .map(|v| Drag {
                    vertices: vec![v, v + 1],
                    target: DVec3::new(0.1, 0.5, 0.0),
                    stiffness: 0.5,
                })
                .collect(),
            ..Default::default()
        };
        // Fewer vertices than the first: the ones it leaves must be cleared.
        let second = Control {
            wind: None,
            drags: vec![Drag {
                vertices: vec![30],
                target: DVec3::new(0.0, 2.0, 0.0),
                stiffness: 3.0,
            }],
            ..first.clone()
        };
        let no_gravity = Material {
            gravity: DVec3::ZERO,
            ..scene.material
        };
        for control in [first, second] {
            let (has_extra, triangles) = external.write(&context, &scene.model, &control);
            model.uniforms.has_extra = u32::from(has_extra);
            model.uniforms.triangle_count = triangles;
            model.write_uniforms(&context);
            run(&context, |e| {
                if external.wind_on() {
                    external.wind.encode(e, gpu_state.current, None);
                }
                external.vertices.encode(e, gpu_state.current, None);
            });
            let mut expected = vec![DVec3::ZERO; n];
            add_external_forces(
                &scene.model,
                &as_gpu_sees(&state),
                &no_gravity,
                &control,
                &mut expected,
            );
            let actual = read_vec3s(&context, &external.extra_forces, n);
            assert_close(&actual, &expected, TOLERANCE, "control forces");
        }
    }
}
