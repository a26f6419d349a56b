//! The largest stable time step of the damped Verlet scheme (paper eq. 3-4): a Courant-type bound.
//!
//! For a mode of angular frequency `w`, the scheme `x+ = (2 - g - w^2 dt^2) x - (1 - g) x-` with
//! `g = c dt / m` is stable iff `w^2 dt^2 <= 4 - 2 g` and `g < 2` (Jury criterion). The highest
//! frequency is bounded by block Gershgorin on `M^-1 K`: `w_max^2 <= max_i 2 * sum_j D_ij / m_i`,
//! the stiffest springs, smallest mass and highest valence together. Solving the quadratic
//! `w^2 dt^2 + 2 (c/m) dt - 4 = 0` per vertex gives the bound below. Compressed springs have a
//! softer tangent stiffness, so the bound holds for every configuration reached by stretching.
//! Bending springs' own dampers add to `c` the same way springs add to `w^2`: at most twice the
//! sum of a vertex's dampers (Gershgorin on the damping matrix).

use crate::Model;

/// The bound and the vertex that sets it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StabilityLimit {
    /// Largest stable dt in seconds (infinite for a model without springs or damping).
    pub max_dt: f64,
    /// Vertex whose springs and mass set the bound.
    pub limiting_vertex: Option<usize>,
}

/// Fraction of the bound `dt = "auto"` uses, leaving room for round-off and external forces.
pub const AUTO_DT_SAFETY: f64 = 0.9;

/// Largest stable time step for `model` with damping constant `damping` (kg/s).
pub fn stability_limit(model: &Model, damping: f64) -> StabilityLimit {
    let mut limit = StabilityLimit {
        max_dt: f64::INFINITY,
        limiting_vertex: None,
    };
    for vertex in 0..model.vertex_count() {
        if model.pinned[vertex] {
            continue;
        }
        let mass = model.masses[vertex];
        let stiffness_sum: f64 = model
            .adjacency
            .range(vertex)
            .map(|k| model.stiffnesses[model.adjacency.springs[k] as usize])
            .sum();
        let omega_squared = 2.0 * stiffness_sum / mass;
        let dampers = model
            .adjacency
            .range(vertex)
            .filter(|k| model.is_bending(model.adjacency.springs[*k] as usize))
            .count();
        let damping_rate = (damping + 2.0 * model.bending_damping * dampers as f64) / mass;
        let max_dt = if omega_squared > 0.0 {
            (-damping_rate + (damping_rate * damping_rate + 4.0 * omega_squared).sqrt())
                / omega_squared
        } else if damping_rate > 0.0 {
            2.0 / damping_rate
        } else {
            f64::INFINITY
        };
        if max_dt < limit.max_dt {
            limit = StabilityLimit {
                max_dt,
                limiting_vertex: Some(vertex),
            };
        }
    }
    limit
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MassModel, ModelOptions, StiffnessModel};
    use glam::DVec3;

    #[test]
    fn two_free_masses_bound_is_two_over_omega() {
        // Two masses m joined by spring k: w^2 = 2k/m exactly, and the bound is 2/w without damping.
        let options = ModelOptions {
            stiffness: StiffnessModel::Uniform(50.0),
            mass: MassModel::PerVertex(2.0),
            rest_length_scale: 1.0,
            pinned: vec![],
        };
        let model = Model::from_springs(
            vec![DVec3::ZERO, DVec3::X],
            vec![[0, 1]],
            vec![2.0, 2.0],
            &options,
        )
        .expect("model");
        let limit = stability_limit(&model, 0.0);
        let omega = (2.0f64 * 50.0 / 2.0).sqrt();
        assert!((limit.max_dt - 2.0 / omega).abs() < 1e-12);
    }
}
