//! Point forces, drags, wind and bending springs' dampers in float32 (models documented in
//! `hooke_core::control`; dampers in [`hooke_core::diagnostics::damper_force_on_a`]).
//!
//! Gravity is folded into the integrator; everything else lands in an extra per-vertex force
//! buffer that exists only when the parameters ask for it, so the common gravity-only step
//! streams no extra memory. Wind is computed per triangle, then gathered per vertex over its
//! triangles in a fixed order, which keeps it deterministic for any thread count.

use glam::Vec3;
use hooke_core::{Control, Model};
use rayon::prelude::*;

use crate::kernels::Soa;
use crate::layout::{LANES, Numbering};

#[derive(Debug)]
struct Drag {
    vertices: Vec<u32>,
    target: Vec3,
    stiffness: f32,
}

#[derive(Debug)]
struct WindField {
    velocity: Vec3,
    coefficient: f32,
    /// Triangles in internal numbering.
    triangles: Vec<[u32; 3]>,
    /// Vertex -> incident triangles (CSR over internal vertices).
    vertex_offsets: Vec<u32>,
    vertex_triangles: Vec<u32>,
    /// Force each triangle puts on each of its vertices (a third of its total), N.
    triangle_force: Vec<Vec3>,
}

/// Bending springs' dampers, per internal vertex in a fixed order (CSR).
#[derive(Debug)]
struct Dampers {
    offsets: Vec<u32>,
    others: Vec<u32>,
    damping: f32,
}

/// The non-gravity forces of one control and the model's dampers.
#[derive(Debug)]
pub struct ExternalForces {
    constant: Soa,
    drags: Vec<Drag>,
    wind: Option<WindField>,
    dampers: Option<Dampers>,
    inverse_dt: f32,
}

impl ExternalForces {
    /// `None` when the control puts no force on the cloth and nothing damps. `broken` flags
    /// the torn springs (they damp no more).
    pub fn new(
        model: &Model,
        numbering: &Numbering,
        control: &Control,
        dt: f64,
        broken: &[bool],
    ) -> Option<Self> {
        let dampers = model.dampers(broken);
        if !control.acts_on_cloth() && dampers.neighbors.is_empty() {
            return None;
        }
        let internal = |v: u32| numbering.internal[v as usize];
        let mut constant = Soa::zeros(numbering.slice_count());
        for point in &control.point_forces {
            let k = internal(point.vertex) as usize;
            let sum = Vec3::from(constant.get(k)) + point.force.as_vec3();
            constant.set(k, sum.to_array());
        }
        let drags = control
            .drags
            .iter()
            .map(|d| Drag {
                vertices: d.vertices.iter().map(|&v| internal(v)).collect(),
                target: d.target.as_vec3(),
                stiffness: d.stiffness as f32,
            })
            .collect();
        let wind = control.wind.map(|wind| {
            let triangles: Vec<[u32; 3]> =
                model.triangles.iter().map(|t| t.map(internal)).collect();
            let mut vertex_offsets = vec![0u32; numbering.padded_len + 1];
            for t in &triangles {
                for &v in t {
                    vertex_offsets[v as usize + 1] += 1;
                }
            }
            for i in 0..numbering.padded_len {
                vertex_offsets[i + 1] += vertex_offsets[i];
            }
            let mut cursor = vertex_offsets.clone();
            let mut vertex_triangles = vec![0u32; 3 * triangles.len()];
            for (index, t) in triangles.iter().enumerate() {
                for &v in t {
                    vertex_triangles[cursor[v as usize] as usize] = index as u32;
                    cursor[v as usize] += 1;
                }
            }
            WindField {
                velocity: wind.velocity.as_vec3(),
                coefficient: wind.coefficient as f32,
                triangle_force: vec![Vec3::ZERO; triangles.len()],
                triangles,
                vertex_offsets,
                vertex_triangles,
            }
        });
        let dampers = (!dampers.neighbors.is_empty()).then(|| {
            let mut offsets = Vec::with_capacity(numbering.padded_len + 1);
            let mut others = Vec::with_capacity(dampers.neighbors.len());
            offsets.push(0);
            for k in 0..numbering.padded_len {
                if let Some(&v) = numbering.original.get(k) {
                    let range = dampers.range(v as usize);
                    others.extend(dampers.neighbors[range].iter().map(|&j| internal(j)));
                }
                offsets.push(others.len() as u32);
            }
            Dampers {
                offsets,
                others,
                damping: model.bending_damping as f32,
            }
        });
        Some(Self {
            constant,
            drags,
            wind,
            dampers,
            inverse_dt: (1.0 / dt) as f32,
        })
    }

    /// Writes this step's forces (N) into `out`, from positions `current` and deltas
    /// `x(t) - x(t - dt)`.
    pub fn compute(&mut self, current: &Soa, delta: &Soa, out: &mut Soa) {
        for (o, c) in out.axes_mut().into_iter().zip(self.constant.axes()) {
            o.copy_from_slice(c);
        }
        for drag in &self.drags {
            for &v in &drag.vertices {
                let pull = drag.stiffness * (drag.target - Vec3::from(current.get(v as usize)));
                let sum = Vec3::from(out.get(v as usize)) + pull;
                out.set(v as usize, sum.to_array());
            }
        }
        if let Some(wind) = &mut self.wind {
            let inverse_dt = self.inverse_dt;
            let (velocity, coefficient) = (wind.velocity, wind.coefficient);
            wind.triangle_force
                .par_iter_mut()
                .zip(&wind.triangles)
                .for_each(|(force, t)| {
                    let p = t.map(|v| Vec3::from(current.get(v as usize)));
                    let cross = (p[1] - p[0]).cross(p[2] - p[0]);
                    let twice_area = cross.length();
                    *force = if twice_area > 0.0 {
                        let normal = cross / twice_area;
                        let mean_velocity = t
                            .iter()
                            .map(|&v| Vec3::from(delta.get(v as usize)) * inverse_dt)
                            .sum::<Vec3>()
                            / 3.0;
                        let relative = velocity - mean_velocity;
                        coefficient * 0.5 * twice_area * relative.dot(normal) * normal / 3.0
                    } else {
                        Vec3::ZERO
                    };
                });
            let wind = &*wind;
            add_per_vertex(out, |v, sum| {
                let range = wind.vertex_offsets[v] as usize..wind.vertex_offsets[v + 1] as usize;
                for &t in &wind.vertex_triangles[range] {
                    *sum += wind.triangle_force[t as usize];
                }
            });
        }
        if let Some(dampers) = &self.dampers {
            let inverse_dt = self.inverse_dt;
            add_per_vertex(out, |v, sum| {
                let (x, d) = (Vec3::from(current.get(v)), Vec3::from(delta.get(v)));
                let range = dampers.offsets[v] as usize..dampers.offsets[v + 1] as usize;
                for &j in &dampers.others[range] {
                    let u = (x - Vec3::from(current.get(j as usize))).normalize_or_zero();
                    let rate = (d - Vec3::from(delta.get(j as usize))) * inverse_dt;
                    *sum -= dampers.damping * rate.dot(u) * u;
                }
            });
        }
    }

    pub fn bytes(&self) -> usize {
        self.constant.bytes()
            + self.dampers.as_ref().map_or(0, |d| {
                std::mem::size_of_val(d.offsets.as_slice())
                    + std::mem::size_of_val(d.others.as_slice())
            })
            + self.wind.as_ref().map_or(0, |w| {
                std::mem::size_of_val(w.triangles.as_slice())
                    + std::mem::size_of_val(w.vertex_offsets.as_slice())
                    + std::mem::size_of_val(w.vertex_triangles.as_slice())
                    + std::mem::size_of_val(w.triangle_force.as_slice())
            })
    }
}

/// Lets `add(vertex, sum)` add its forces to each vertex's entry of `out`, one after another in
/// its own order (so the sums do not depend on the thread count), in parallel over blocks.
fn add_per_vertex(out: &mut Soa, add: impl Fn(usize, &mut Vec3) + Sync) {
    let [ox, oy, oz] = out.axes_mut();
    ox.par_iter_mut()
        .zip(oy.par_iter_mut())
        .zip(oz.par_iter_mut())
        .enumerate()
        .for_each(|(block, ((bx, by), bz))| {
            for lane in 0..LANES {
                let mut sum = Vec3::new(bx[lane], by[lane], bz[lane]);
                add(block * LANES + lane, &mut sum);
                [bx[lane], by[lane], bz[lane]] = sum.to_array();
            }
        });
}
