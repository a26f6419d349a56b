//! Physical quantities of a state: energies, strain and the reactions at the pins. All in f64.

use glam::DVec3;

use crate::{Material, Model, SimError, State};

/// Energies in joules. Kinetic energy uses the Verlet velocity `(x - x_prev)/dt`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    pub kinetic: f64,
    /// `sum 1/2 D (|l| - |l0|)^2` over springs.
    pub elastic: f64,
    /// `-sum m g . x`.
    pub gravitational: f64,
}

impl Energy {
    pub fn total(&self) -> f64 {
        self.kinetic + self.elastic + self.gravitational
    }
}

pub fn energy(model: &Model, state: &State, material: &Material) -> Energy {
    let mut energy = Energy::default();
    for (i, mass) in model.masses.iter().enumerate() {
        energy.kinetic += 0.5 * mass * state.velocity(i, material.dt).length_squared();
        energy.gravitational -= mass * material.gravity.dot(state.positions[i]);
    }
    for (s, [a, b]) in model.spring_ends.iter().enumerate() {
        let length = state.positions[*a as usize].distance(state.positions[*b as usize]);
        let extension = length - model.rest_lengths[s];
        energy.elastic +=
            0.5 * model.stiffness(s, material.stiffness_scale) * extension * extension;
    }
    energy
}

/// `||a - b|| / ||b||` over all coordinates: how far positions `a` are from reference `b`.
pub fn relative_l2(a: &[DVec3], b: &[DVec3]) -> f64 {
    let error: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).length_squared())
        .sum();
    let norm: f64 = b.iter().map(|q| q.length_squared()).sum();
    (error / norm).sqrt()
}

/// Largest relative elongation `(|l| - |l0|) / |l0|` over the springs that exert a force (a
/// torn spring has zero stiffness: its ends may drift any distance apart), and the spring.
pub fn max_strain(model: &Model, positions: &[DVec3]) -> (f64, usize) {
    model
        .spring_ends
        .iter()
        .enumerate()
        .filter(|(s, _)| model.stiffnesses[*s] != 0.0)
        .map(|(s, [a, b])| {
            let length = positions[*a as usize].distance(positions[*b as usize]);
            ((length - model.rest_lengths[s]) / model.rest_lengths[s], s)
        })
        .fold(
            (f64::NEG_INFINITY, 0),
            |best, x| if x.0 > best.0 { x } else { best },
        )
}

/// A spring stretched beyond this many rest lengths means the integration has blown up.
pub const EXPLOSION_STRETCH: f64 = 100.0;

/// Checks a state for an explosion (see [`EXPLOSION_STRETCH`]) or a non-finite position.
pub fn check_health(model: &Model, positions: &[DVec3], step: u64) -> Result<(), SimError> {
    if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
        return Err(SimError::NonFinite { step, vertex });
    }
    let (strain, spring) = max_strain(model, positions);
    let stretch = strain + 1.0;
    if stretch > EXPLOSION_STRETCH {
        let [a, b] = model.spring_ends[spring];
        return Err(SimError::Exploded {
            step,
            spring,
            a,
            b,
            stretch,
        });
    }
    Ok(())
}

/// The force each pin's support exerts to hold its vertex still: minus the spring forces and the
/// weight acting on it. In static equilibrium these sum to minus the total weight.
pub fn pin_reactions(
    model: &Model,
    positions: &[DVec3],
    material: &Material,
) -> Vec<(usize, DVec3)> {
    let mut spring_force = vec![DVec3::ZERO; model.vertex_count()];
    for (s, [a, b]) in model.spring_ends.iter().enumerate() {
        let force = spring_force_on_a(
            positions[*a as usize],
            positions[*b as usize],
            model.rest_lengths[s],
            model.stiffness(s, material.stiffness_scale),
        );
        spring_force[*a as usize] += force;
        spring_force[*b as usize] -= force;
    }
    (0..model.vertex_count())
        .filter(|i| model.pinned[*i])
        .map(|i| (i, -(spring_force[i] + model.masses[i] * material.gravity)))
        .collect()
}

/// Force of a damper `c` (N s/m) along the spring `a`-`b` on `a`, against the rate the
/// spring's length changes: `-c ((v_a - v_b) . u) u` with `u` the unit vector from `b` to `a`
/// (zero when the ends coincide).
#[inline]
pub fn damper_force_on_a(a: DVec3, b: DVec3, va: DVec3, vb: DVec3, damping: f64) -> DVec3 {
    let u = (a - b).normalize_or_zero();
    -damping * (va - vb).dot(u) * u
}

/// Force of the spring `a`-`b` on `a` (paper eq. 1 with the sign of eq. 4): pulls `a` toward `b`
/// when stretched, pushes it away when compressed.
#[inline]
pub fn spring_force_on_a(a: DVec3, b: DVec3, rest_length: f64, stiffness: f64) -> DVec3 {
    let l = a - b;
    let length = l.length();
    -stiffness * (length - rest_length) / length * l
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MassModel, ModelOptions, StiffnessModel};

    #[test]
    fn a_damper_resists_only_the_rate_its_spring_changes_length() {
        let (a, b) = (DVec3::new(1.0, 0.0, 0.0), DVec3::ZERO);
        // Ends moving apart at 2 m/s along the spring: -c * 2 along it.
        let apart = damper_force_on_a(a, b, DVec3::X * 1.5, DVec3::X * -0.5, 0.1);
        assert!(
            (apart - DVec3::new(-0.2, 0.0, 0.0)).length() < 1e-15,
            "{apart}"
        );
        // Sideways motion (a turn) and a common motion are not damped.
        assert_eq!(
            damper_force_on_a(a, b, DVec3::Y, DVec3::ZERO, 0.1),
            DVec3::ZERO
        );
        assert_eq!(
            damper_force_on_a(a, b, DVec3::ONE, DVec3::ONE, 0.1),
            DVec3::ZERO
        );
        // Coincident ends: no direction, no force.
        assert_eq!(
            damper_force_on_a(b, b, DVec3::X, DVec3::ZERO, 0.1),
            DVec3::ZERO
        );
    }

    #[test]
    fn over_stretched_spring_is_an_explosion_and_nan_is_non_finite() {
        let options = ModelOptions {
            stiffness: StiffnessModel::Uniform(1.0),
            mass: MassModel::PerVertex(1.0),
            rest_length_scale: 1.0,
            pinned: vec![],
        };
        let model = Model::from_springs(
            vec![DVec3::ZERO, DVec3::X],
            vec![[0, 1]],
            vec![1.0, 1.0],
            &options,
        )
        .expect("model");
        assert_eq!(
            check_health(&model, &[DVec3::ZERO, DVec3::X * 50.0], 3),
            Ok(())
        );
        let error = check_health(&model, &[DVec3::ZERO, DVec3::X * 500.0], 7).unwrap_err();
        assert!(
            matches!(
                error,
                SimError::Exploded {
                    step: 7,
                    spring: 0,
                    ..
                }
            ),
            "{error}"
        );
        let error = check_health(&model, &[DVec3::ZERO, DVec3::NAN], 9).unwrap_err();
        assert_eq!(error, SimError::NonFinite { step: 9, vertex: 1 });
    }
}
