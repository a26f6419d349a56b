//! The springs of a structured mesh as a stencil: a few kinds of spring (an index offset to
//! the neighbour, a rest length and a stiffness) that every vertex shares, and per vertex a
//! bit mask of the kinds it has. A generated grid has six kinds (offsets ±1, ±columns,
//! ±(columns + 1)), so the gather kernel reads a mask per vertex (carried in the spare word of
//! the integration constants it reads anyway) instead of a CSR row of six 8-byte entries and
//! its row offsets, and computes each neighbour's index.
//!
//! A vertex sums its springs in the model's adjacency order; the kinds are numbered in an
//! order that agrees with every vertex's (a topological order of "comes before"), and the
//! kernel visits a vertex's bits from the lowest, so it sums in the same order as the CSR
//! kernel and gives the same bits.

use hooke_core::Model;

use crate::layout::{GpuStencil, GpuStencilEntry, STENCIL_KINDS};

/// Kinds of spring a stencil can hold: the mantissa bits of a float32 (see
/// [`Stencil::mask_as_float`]).
pub const MAX_KINDS: usize = 23;

/// The stencil of a model (see the module's description).
#[derive(Clone, Debug, PartialEq)]
pub struct Stencil {
    /// The kinds in summation order, at most [`MAX_KINDS`].
    pub kinds: Vec<GpuStencilEntry>,
    /// Per vertex, bit `k` set if the vertex has a spring of kind `k`.
    pub masks: Vec<u32>,
}

impl Stencil {
    /// Vertex `v`'s mask as the float that carries it in the integration scales' spare `z`
    /// (so the kernel reads no buffer of its own): the mask in the mantissa of a float in
    /// [2, 4), a normal number that no GPU flushes or canonicalizes.
    pub fn mask_as_float(&self, v: usize) -> f32 {
        f32::from_bits(2f32.to_bits() | self.masks[v])
    }

    /// The kinds as the kernel's uniform table holds them.
    pub fn table(&self) -> GpuStencil {
        let mut kinds = [GpuStencilEntry::default(); STENCIL_KINDS];
        kinds[..self.kinds.len()].copy_from_slice(&self.kinds);
        GpuStencil {
            kinds,
            len: self.kinds.len() as u32,
            pad: [0; 3],
        }
    }
}

/// A spring as seen from one end: the offset to the other end, its rest length and stiffness
/// as float32 bits (two springs are of one kind only if the kernels would read the same
/// floats).
type Kind = (i64, u32, u32);

impl Stencil {
    /// The model's stencil, or `None` when its springs are not that regular: more than
    /// [`MAX_KINDS`] kinds (any irregular mesh has hundreds of offsets), a vertex with two
    /// springs of one kind, or vertices that sum kinds in contradicting orders.
    pub fn of(model: &Model) -> Option<Self> {
        if model.spring_count() == 0 {
            return None;
        }
        let adjacency = &model.adjacency;
        let mut kinds: Vec<Kind> = Vec::new();
        // before[a] has bit b set when some vertex sums kind a right before kind b.
        let mut before = [0u32; MAX_KINDS];
        // Per vertex, its kinds as numbered when first seen (renumbered below).
        let mut seen_masks: Vec<u32> = Vec::with_capacity(model.vertex_count());
        for v in 0..model.vertex_count() {
            let (mut mask, mut previous) = (0u32, None::<usize>);
            for e in adjacency.range(v) {
                let spring = adjacency.springs[e] as usize;
                let kind = (
                    i64::from(adjacency.neighbors[e]) - v as i64,
                    (model.rest_lengths[spring] as f32).to_bits(),
                    (model.stiffnesses[spring] as f32).to_bits(),
                );
                let k = match kinds.iter().position(|known| *known == kind) {
                    Some(k) => k,
                    None if kinds.len() < MAX_KINDS => {
                        kinds.push(kind);
                        kinds.len() - 1
                    }
                    None => return None,
                };
                if mask & (1 << k) != 0 {
                    return None;
                }
                mask |= 1 << k;
                if let Some(p) = previous {
                    before[p] |= 1 << k;
                }
                previous = Some(k);
            }
            seen_masks.push(mask);
        }
        let rank = summation_order(&before[..kinds.len()])?;
        let mut stencil = Self {
            kinds: vec![GpuStencilEntry::default(); kinds.len()],
            masks: seen_masks
                .iter()
                .map(|&mask| {
                    (0..kinds.len())
                        .filter(|k| mask & (1 << k) != 0)
                        .fold(0, |m, k| m | 1 << rank[k])
                })
                .collect(),
        };
        for (k, (offset, rest_length, stiffness)) in kinds.into_iter().enumerate() {
            stencil.kinds[rank[k]] = GpuStencilEntry {
                offset: i32::try_from(offset).ok()?,
                rest_length: f32::from_bits(rest_length),
                stiffness: f32::from_bits(stiffness),
                pad: 0,
            };
        }
        Some(stencil)
    }
}

/// A rank for each kind such that `a` ranks below `b` whenever `before[a]` has bit `b`
/// (Kahn's algorithm, the lowest-numbered ready kind first); `None` if the relation has a
/// cycle.
fn summation_order(before: &[u32]) -> Option<Vec<usize>> {
    let n = before.len();
    let mut incoming: Vec<u32> = (0..n)
        .map(|b| (0..n).filter(|&a| before[a] & (1 << b) != 0).count() as u32)
        .collect();
    let mut rank = vec![usize::MAX; n];
    for next in 0..n {
        let ready = (0..n).find(|&k| rank[k] == usize::MAX && incoming[k] == 0)?;
        rank[ready] = next;
        for (b, count) in incoming.iter_mut().enumerate() {
            if before[ready] & (1 << b) != 0 {
                *count -= 1;
            }
        }
    }
    Some(rank)
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use hooke_core::mesh::{GridPlane, grid, irregular};
    use hooke_core::{MassModel, ModelOptions, StiffnessModel};

    use super::*;

    fn model_of(mesh: &hooke_core::mesh::Mesh) -> Model {
        let options = ModelOptions {
            stiffness: StiffnessModel::Uniform(1.0),
            mass: MassModel::PerVertex(1.0),
            rest_length_scale: 1.0,
            pinned: vec![],
        };
        Model::from_mesh(mesh, &options).expect("model")
    }

    #[test]
    fn a_grid_is_six_kinds_in_its_vertices_summation_order() {
        let model = model_of(&grid(7, 5, [1.2, 1.0], GridPlane::Xz, DVec3::ZERO));
        let stencil = Stencil::of(&model).expect("a grid is a stencil");
        let offsets: Vec<i32> = stencil.kinds.iter().map(|k| k.offset).collect();
        assert_eq!(offsets, [-8, -7, -1, 1, 7, 8]);
        // Each vertex's set bits, lowest first, name its springs in the model's order.
        for v in 0..model.vertex_count() {
            let from_mask: Vec<(u32, f32)> = (0..MAX_KINDS)
                .filter(|k| stencil.masks[v] & (1 << k) != 0)
                .map(|k| {
                    let kind = stencil.kinds[k];
                    ((v as i64 + i64::from(kind.offset)) as u32, kind.rest_length)
                })
                .collect();
            let adjacency = &model.adjacency;
            let expected: Vec<(u32, f32)> = adjacency
                .range(v)
                .map(|e| {
                    let spring = adjacency.springs[e] as usize;
                    (adjacency.neighbors[e], model.rest_lengths[spring] as f32)
                })
                .collect();
            assert_eq!(from_mask, expected, "vertex {v}");
        }
    }

    #[test]
    fn irregular_meshes_and_contradicting_orders_are_no_stencil() {
        let irregular = model_of(&irregular(400, [1.0, 1.0], 1, GridPlane::Xz, DVec3::ZERO));
        assert_eq!(Stencil::of(&irregular), None);
        let mut model = model_of(&grid(4, 4, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO));
        assert!(Stencil::of(&model).is_some());
        // One vertex summing its first two springs the other way round: no order fits all.
        let first = model.adjacency.range(5).start;
        model.adjacency.neighbors.swap(first, first + 1);
        model.adjacency.springs.swap(first, first + 1);
        assert_eq!(Stencil::of(&model), None);
    }

    #[test]
    fn springs_of_other_stiffness_are_kinds_of_their_own() {
        let mut model = model_of(&grid(4, 4, [1.0, 1.0], GridPlane::Xz, DVec3::ZERO));
        let s = model.adjacency.springs[model.adjacency.range(5).start] as usize;
        model.stiffnesses[s] *= 2.0;
        let stencil = Stencil::of(&model).expect("still a stencil");
        // The spring seen from each of its ends.
        assert_eq!(stencil.kinds.len(), 8);
    }
}
