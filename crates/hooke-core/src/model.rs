//! The fixed part of a mass-spring system (paper Section 2): springs, masses, pins, adjacency.
//!
//! Everything here stays constant while stepping, colliders' shapes and the self-collision
//! set-up included; what changes lives in [`crate::State`].

use glam::DVec3;

use crate::collide::Collider;
use crate::handles::Handle;
use crate::mesh::{BendingPair, Mesh};
use crate::selfcollide::SelfCollision;
use crate::tearing::Tearing;

/// How spring stiffnesses `D_ij` (paper eq. 1) are assigned.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StiffnessModel {
    /// Every spring has the same stiffness in N/m.
    Uniform(f64),
    /// `D_ij = value * mean_rest_length / rest_length_ij`: a material whose stretching response does
    /// not depend on how finely it is meshed, which irregular meshes need.
    InverseRestLength(f64),
}

/// How point masses are assigned.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MassModel {
    /// Every vertex has this mass in kg.
    PerVertex(f64),
    /// The total mass in kg, split evenly over the vertices.
    TotalUniform(f64),
    /// Areal density in kg/m^2: each vertex gets a third of the area of its triangles.
    AreaDensity(f64),
}

/// Options for building a [`Model`] from a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelOptions {
    pub stiffness: StiffnessModel,
    pub mass: MassModel,
    /// Rest length = initial length times this factor (1 = the mesh is at rest as given).
    pub rest_length_scale: f64,
    /// Indices of pinned vertices; they never move.
    pub pinned: Vec<u32>,
}

/// Compressed sparse rows of vertex -> incident springs: the point-centric (PCA) view.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Adjacency {
    /// Length `n_vertices + 1`; the incident entries of vertex `i` are `offsets[i]..offsets[i+1]`.
    pub offsets: Vec<u32>,
    /// Length `2 * n_springs`: the vertex at the other end of each entry's spring.
    pub neighbors: Vec<u32>,
    /// Length `2 * n_springs`: the spring of each entry (index into the model's spring arrays).
    pub springs: Vec<u32>,
}

impl Adjacency {
    /// Builds the CSR from spring endpoints; within a vertex, entries are in spring order.
    pub fn from_springs(vertex_count: usize, ends: &[[u32; 2]]) -> Self {
        let mut offsets = vec![0u32; vertex_count + 1];
        for [a, b] in ends {
            offsets[*a as usize + 1] += 1;
            offsets[*b as usize + 1] += 1;
        }
        for i in 0..vertex_count {
            offsets[i + 1] += offsets[i];
        }
        let mut cursor = offsets.clone();
        let mut neighbors = vec![0u32; 2 * ends.len()];
        let mut springs = vec![0u32; 2 * ends.len()];
        for (s, [a, b]) in ends.iter().enumerate() {
            for (from, to) in [(*a, *b), (*b, *a)] {
                let slot = cursor[from as usize] as usize;
                neighbors[slot] = to;
                springs[slot] = s as u32;
                cursor[from as usize] += 1;
            }
        }
        Self {
            offsets,
            neighbors,
            springs,
        }
    }

    pub fn valence(&self, vertex: usize) -> u32 {
        self.offsets[vertex + 1] - self.offsets[vertex]
    }

    pub fn range(&self, vertex: usize) -> std::ops::Range<usize> {
        self.offsets[vertex] as usize..self.offsets[vertex + 1] as usize
    }

    /// The vertices a spring joins to `vertex`.
    pub fn neighbors_of(&self, vertex: u32) -> &[u32] {
        &self.neighbors[self.range(vertex as usize)]
    }
}

/// A mass-spring system: all arrays in SI units, indexed by vertex or by spring.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// Length `n_vertices`: positions the system starts from (m).
    pub initial_positions: Vec<DVec3>,
    /// Triangles of the surface (for wind, rendering and output); may be empty for bare springs.
    pub triangles: Vec<[u32; 3]>,
    /// Length `n_springs`: the two vertices of each spring.
    pub spring_ends: Vec<[u32; 2]>,
    /// Length `n_springs`: rest length `|l0_ij|` (m).
    pub rest_lengths: Vec<f64>,
    /// Length `n_springs`: stiffness `D_ij` (N/m).
    pub stiffnesses: Vec<f64>,
    /// The last this many springs are bending springs (see [`Model::add_bending_springs`]);
    /// the others join the mesh's edges.
    pub bending_springs: usize,
    /// Each bending spring's own damping, N s/m: a force against the rate its length changes,
    /// `-c ((v_a - v_b) . u) u` on its end `a` (`u` the unit vector from `b` to `a`).
    pub bending_damping: f64,
    /// Length `bending_springs`: per bending spring, the edge springs of the two triangles it
    /// joins, the edge it crosses first (a triangle that tears takes its hinges with it).
    pub bending_hinges: Vec<[u32; 5]>,
    /// Length `n_vertices`: point mass `m_i` (kg).
    pub masses: Vec<f64>,
    /// Length `n_vertices`: whether the vertex is held in place.
    pub pinned: Vec<bool>,
    /// Vertex -> incident springs.
    pub adjacency: Adjacency,
    /// Colliders and self-collision: fixed while stepping.
    pub collision: Collision,
    /// Pinned vertices moved by a path or a collider (their vertices are also `pinned`).
    pub handles: Vec<Handle>,
    /// When springs break (see [`crate::tearing`]); never when `None`.
    pub tearing: Option<Tearing>,
}

/// What the cloth collides with, fixed while stepping (see [`crate::collide`] and
/// [`crate::selfcollide`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Collision {
    /// Spheres, planes and capsules the cloth cannot enter, as they start.
    pub colliders: Vec<Collider>,
    /// How far from a collider's surface the cloth is held, m (its half thickness).
    pub thickness: f64,
    /// Approximate self-collision by binning; off when `None`.
    pub self_collision: Option<SelfCollision>,
}

impl Collision {
    /// True if a step has collision work: colliders or self-collision.
    pub fn any(&self) -> bool {
        !self.colliders.is_empty() || self.self_collision.is_some()
    }
}

/// A model that cannot be simulated.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    #[error("pinned vertex {index} does not exist (mesh has {vertex_count} vertices)")]
    PinOutOfRange { index: u32, vertex_count: usize },
    #[error("{field} must be positive and finite, found {value}")]
    NotPositive { field: &'static str, value: f64 },
    #[error("bending spring: the mesh has no edge {ends:?}")]
    NoSuchEdge { ends: [u32; 2] },
    #[error(
        "vertex {vertex} has zero mass (it belongs to no triangle); use a per-vertex or total mass"
    )]
    ZeroMass { vertex: usize },
}

fn positive(field: &'static str, value: f64) -> Result<f64, ModelError> {
    if value > 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::NotPositive { field, value })
    }
}

impl Model {
    /// Builds the mass-spring system of a (validated) mesh: one spring per unique edge.
    pub fn from_mesh(mesh: &Mesh, options: &ModelOptions) -> Result<Self, ModelError> {
        let ends: Vec<[u32; 2]> = mesh.edges().iter().map(|e| [e.a, e.b]).collect();
        let masses = match options.mass {
            MassModel::PerVertex(m) => vec![positive("mass.per_vertex", m)?; mesh.vertex_count()],
            MassModel::TotalUniform(total) => {
                let total = positive("mass.total", total)?;
                vec![total / mesh.vertex_count() as f64; mesh.vertex_count()]
            }
            MassModel::AreaDensity(density) => {
                let density = positive("mass.area_density", density)?;
                let mut masses = vec![0.0; mesh.vertex_count()];
                for (t, area) in mesh.triangles.iter().zip(mesh.triangle_areas()) {
                    for &i in t {
                        masses[i as usize] += density * area / 3.0;
                    }
                }
                if let Some(vertex) = masses.iter().position(|m| *m <= 0.0) {
                    return Err(ModelError::ZeroMass { vertex });
                }
                masses
            }
        };
        let mut model = Self::from_springs(mesh.positions.clone(), ends, masses, options)?;
        model.triangles = mesh.triangles.clone();
        Ok(model)
    }

    /// Builds a system from explicit springs (no surface), e.g. a single oscillator.
    pub fn from_springs(
        positions: Vec<DVec3>,
        spring_ends: Vec<[u32; 2]>,
        masses: Vec<f64>,
        options: &ModelOptions,
    ) -> Result<Self, ModelError> {
        let scale = positive("springs.rest_length_scale", options.rest_length_scale)?;
        let initial_lengths: Vec<f64> = spring_ends
            .iter()
            .map(|[a, b]| positions[*a as usize].distance(positions[*b as usize]))
            .collect();
        let rest_lengths: Vec<f64> = initial_lengths.iter().map(|l| l * scale).collect();
        let stiffnesses = match options.stiffness {
            StiffnessModel::Uniform(k) => {
                vec![positive("springs.stiffness", k)?; spring_ends.len()]
            }
            StiffnessModel::InverseRestLength(k) => {
                let k = positive("springs.stiffness", k)?;
                let mean = rest_lengths.iter().sum::<f64>() / rest_lengths.len().max(1) as f64;
                rest_lengths.iter().map(|l| k * mean / l).collect()
            }
        };
        let mut pinned = vec![false; positions.len()];
        for &index in &options.pinned {
            *pinned
                .get_mut(index as usize)
                .ok_or(ModelError::PinOutOfRange {
                    index,
                    vertex_count: positions.len(),
                })? = true;
        }
        let adjacency = Adjacency::from_springs(positions.len(), &spring_ends);
        Ok(Self {
            initial_positions: positions,
            triangles: Vec::new(),
            spring_ends,
            rest_lengths,
            stiffnesses,
            bending_springs: 0,
            bending_damping: 0.0,
            bending_hinges: Vec::new(),
            masses,
            pinned,
            adjacency,
            collision: Collision::default(),
            handles: Vec::new(),
            tearing: None,
        })
    }

    /// Adds bending springs of `stiffness` N/m between `pairs` of vertices (the mesh's
    /// [`Mesh::bending_pairs`]), at rest at their initial length times the rest-length scale
    /// as the edge springs are. They are ordinary springs to every solver: they only join
    /// vertices two triangles apart, which resists folding across the edge between them.
    pub fn add_bending_springs(
        &mut self,
        pairs: &[BendingPair],
        stiffness: f64,
        rest_length_scale: f64,
    ) -> Result<(), ModelError> {
        let stiffness = positive("bending.stiffness", stiffness)?;
        let edges = self.edge_springs();
        let edge = |p: u32, q: u32| {
            let ends = [p.min(q), p.max(q)];
            edges
                .get(&ends)
                .copied()
                .ok_or(ModelError::NoSuchEdge { ends })
        };
        for pair in pairs {
            let ([c, d], [a, b]) = (pair.far, pair.across);
            let hinge = [
                edge(a, b)?,
                edge(a, c)?,
                edge(b, c)?,
                edge(a, d)?,
                edge(b, d)?,
            ];
            let length =
                self.initial_positions[c as usize].distance(self.initial_positions[d as usize]);
            self.spring_ends.push([c, d]);
            self.rest_lengths.push(length * rest_length_scale);
            self.stiffnesses.push(stiffness);
            self.bending_hinges.push(hinge);
        }
        self.bending_springs += pairs.len();
        self.adjacency = Adjacency::from_springs(self.vertex_count(), &self.spring_ends);
        Ok(())
    }

    /// The edge springs (bending springs aside) by their ends, lower index first.
    pub fn edge_springs(&self) -> std::collections::HashMap<[u32; 2], u32> {
        self.spring_ends
            .iter()
            .enumerate()
            .filter(|(s, _)| !self.is_bending(*s))
            .map(|(s, [a, b])| ([*a.min(b), *a.max(b)], s as u32))
            .collect()
    }

    /// The edge springs of the two triangles bending spring `spring` joins (the crossed edge
    /// first); `None` for an edge spring.
    pub fn bending_hinge(&self, spring: usize) -> Option<&[u32; 5]> {
        spring
            .checked_sub(self.first_bending_spring())
            .map(|k| &self.bending_hinges[k])
    }

    /// The index of the first bending spring (the spring count when there are none).
    pub fn first_bending_spring(&self) -> usize {
        self.spring_count() - self.bending_springs
    }

    /// This model with the `broken` springs (flags in spring order) exerting no force: zero
    /// stiffness (their rest lengths stay, so strains stay finite). What solvers that build
    /// tables from a model, and diagnostics, see once springs have torn.
    pub fn with_springs_broken(&self, broken: &[bool]) -> Model {
        let mut torn = self.clone();
        for (s, _) in broken.iter().enumerate().filter(|(_, b)| **b) {
            torn.stiffnesses[s] = 0.0;
        }
        torn
    }

    /// The vertex -> bending spring lists of the springs that damp: none without bending
    /// damping, and none that is `broken` (flags in spring order, or empty for none).
    pub fn dampers(&self, broken: &[bool]) -> Adjacency {
        let springs: Vec<u32> = (0..self.spring_count() as u32)
            .filter(|&s| {
                self.bending_damping > 0.0
                    && self.is_bending(s as usize)
                    && !broken.get(s as usize).copied().unwrap_or(false)
            })
            .collect();
        let ends: Vec<[u32; 2]> = springs
            .iter()
            .map(|&s| self.spring_ends[s as usize])
            .collect();
        let mut dampers = Adjacency::from_springs(self.vertex_count(), &ends);
        // Entries name the model's springs, not their place in `springs`.
        for spring in &mut dampers.springs {
            *spring = springs[*spring as usize];
        }
        dampers
    }

    /// This model with every bending spring's stiffness times `scale` (0 turns them off; the
    /// edge springs keep theirs).
    pub fn with_bending_scale(&self, scale: f64) -> Model {
        self.with_stiffnesses_scaled_from(self.first_bending_spring(), scale)
    }

    /// True if spring `s` is a bending spring rather than a mesh edge.
    pub fn is_bending(&self, spring: usize) -> bool {
        spring >= self.first_bending_spring()
    }

    /// The stiffness of spring `s` under a material's stiffness scale, N/m.
    pub fn stiffness(&self, spring: usize, scale: f64) -> f64 {
        self.stiffnesses[spring] * scale
    }

    /// This model with every stiffness times `scale` (what a solver steps under a material).
    pub fn with_stiffness_scale(&self, scale: f64) -> Model {
        self.with_stiffnesses_scaled_from(0, scale)
    }

    /// This model with the stiffness of every spring from index `first` on times `scale`.
    fn with_stiffnesses_scaled_from(&self, first: usize, scale: f64) -> Model {
        let mut scaled = self.clone();
        for k in &mut scaled.stiffnesses[first..] {
            *k *= scale;
        }
        scaled
    }

    pub fn vertex_count(&self) -> usize {
        self.initial_positions.len()
    }

    pub fn spring_count(&self) -> usize {
        self.spring_ends.len()
    }

    /// `1/m_i`, or 0 for pinned vertices so that no force moves them.
    pub fn inverse_masses(&self) -> Vec<f64> {
        self.masses
            .iter()
            .zip(&self.pinned)
            .map(|(m, pinned)| if *pinned { 0.0 } else { 1.0 / m })
            .collect()
    }

    /// Number of vertices of each valence: `histogram[v]` vertices have `v` springs.
    pub fn valence_histogram(&self) -> Vec<usize> {
        let valences: Vec<u32> = (0..self.vertex_count())
            .map(|i| self.adjacency.valence(i))
            .collect();
        let max = valences.iter().copied().max().unwrap_or(0) as usize;
        let mut histogram = vec![0usize; max + 1];
        for v in valences {
            histogram[v as usize] += 1;
        }
        histogram
    }

    pub fn total_mass(&self) -> f64 {
        self.masses.iter().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{GridPlane, grid};

    fn options(mass: MassModel) -> ModelOptions {
        ModelOptions {
            stiffness: StiffnessModel::Uniform(10.0),
            mass,
            rest_length_scale: 1.0,
            pinned: vec![0],
        }
    }

    #[test]
    fn adjacency_lists_every_spring_at_both_ends() {
        let mesh = grid(4, 4, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let model = Model::from_mesh(&mesh, &options(MassModel::PerVertex(1.0))).expect("model");
        assert_eq!(model.adjacency.neighbors.len(), 2 * model.spring_count());
        for i in 0..model.vertex_count() {
            for k in model.adjacency.range(i) {
                let [a, b] = model.spring_ends[model.adjacency.springs[k] as usize];
                let j = model.adjacency.neighbors[k];
                assert!((a as usize == i && b == j) || (b as usize == i && a == j));
            }
        }
    }

    #[test]
    fn area_lumped_masses_sum_to_density_times_area() {
        let mesh = grid(9, 5, [2.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let model = Model::from_mesh(&mesh, &options(MassModel::AreaDensity(0.3))).expect("model");
        // Lumping redistributes mass, so the total is exact up to summation rounding.
        assert!((model.total_mass() - 0.3 * 2.0).abs() < 1e-12);
    }

    #[test]
    fn pin_out_of_range_is_an_error() {
        let mesh = grid(2, 2, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let mut opts = options(MassModel::PerVertex(1.0));
        opts.pinned = vec![4];
        assert_eq!(
            Model::from_mesh(&mesh, &opts).unwrap_err().to_string(),
            "pinned vertex 4 does not exist (mesh has 4 vertices)"
        );
    }

    #[test]
    fn rest_length_scale_shrinks_springs() {
        let mesh = grid(2, 2, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO);
        let mut opts = options(MassModel::PerVertex(1.0));
        opts.rest_length_scale = 0.5;
        let model = Model::from_mesh(&mesh, &opts).expect("model");
        assert!((model.rest_lengths[0] - 0.5).abs() < 1e-15);
    }
}
