//! External forces in float64 (the formulas are documented in [`crate::control`]).

use glam::DVec3;

use crate::{Control, Material, Model, State};

/// Adds gravity, point forces, drags and wind to `forces` (N), one entry per vertex.
pub fn add_external_forces(
    model: &Model,
    state: &State,
    material: &Material,
    control: &Control,
    forces: &mut [DVec3],
) {
    for (force, mass) in forces.iter_mut().zip(&model.masses) {
        *force += *mass * material.gravity;
    }
    for point in &control.point_forces {
        forces[point.vertex as usize] += point.force;
    }
    for drag in &control.drags {
        for &v in &drag.vertices {
            forces[v as usize] += drag.stiffness * (drag.target - state.positions[v as usize]);
        }
    }
    if let Some(wind) = control.wind {
        for t in &model.triangles {
            let [a, b, c] = t.map(|i| i as usize);
            let [pa, pb, pc] = [a, b, c].map(|i| state.positions[i]);
            let cross = (pb - pa).cross(pc - pa);
            let twice_area = cross.length();
            if twice_area == 0.0 {
                continue;
            }
            let normal = cross / twice_area;
            let velocity = (state.velocity(a, material.dt)
                + state.velocity(b, material.dt)
                + state.velocity(c, material.dt))
                / 3.0;
            let relative = wind.velocity - velocity;
            let force = wind.coefficient * 0.5 * twice_area * relative.dot(normal) * normal;
            for i in [a, b, c] {
                forces[i] += force / 3.0;
            }
        }
    }
}
