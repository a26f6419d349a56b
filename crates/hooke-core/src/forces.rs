//! External forces of [`SimParams`] in float64 (the formulas are documented in [`crate::params`]).

use glam::DVec3;

use crate::{Model, SimParams, State};

/// Adds gravity, point forces, drags and wind to `forces` (N), one entry per vertex.
pub fn add_external_forces(model: &Model, state: &State, params: &SimParams, forces: &mut [DVec3]) {
    for (force, mass) in forces.iter_mut().zip(&model.masses) {
        *force += *mass * params.gravity;
    }
    for point in &params.point_forces {
        forces[point.vertex as usize] += point.force;
    }
    for drag in &params.drags {
        for &v in &drag.vertices {
            forces[v as usize] += drag.stiffness * (drag.target - state.positions[v as usize]);
        }
    }
    if let Some(wind) = params.wind {
        for t in &model.triangles {
            let [a, b, c] = t.map(|i| i as usize);
            let [pa, pb, pc] = [a, b, c].map(|i| state.positions[i]);
            let cross = (pb - pa).cross(pc - pa);
            let twice_area = cross.length();
            if twice_area == 0.0 {
                continue;
            }
            let normal = cross / twice_area;
            let velocity = (state.velocity(a, params.dt)
                + state.velocity(b, params.dt)
                + state.velocity(c, params.dt))
                / 3.0;
            let relative = wind.velocity - velocity;
            let force = wind.coefficient * 0.5 * twice_area * relative.dot(normal) * normal;
            for i in [a, b, c] {
                forces[i] += force / 3.0;
            }
        }
    }
}
