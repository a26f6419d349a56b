//! The changing part of a mass-spring system: the two position sets Verlet integration needs.

use glam::DVec3;

/// Current and previous positions (m); the velocity is implicit in their difference (paper eq. 3).
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// `x(t)`, length `n_vertices`.
    pub positions: Vec<DVec3>,
    /// `x(t - dt)`, length `n_vertices`.
    pub previous_positions: Vec<DVec3>,
}

impl State {
    /// A system at rest at `positions` (zero velocity).
    pub fn at_rest(positions: Vec<DVec3>) -> Self {
        Self {
            previous_positions: positions.clone(),
            positions,
        }
    }

    /// Verlet velocity estimate `(x(t) - x(t - dt)) / dt` of one vertex, m/s.
    pub fn velocity(&self, vertex: usize, dt: f64) -> DVec3 {
        (self.positions[vertex] - self.previous_positions[vertex]) / dt
    }
}
