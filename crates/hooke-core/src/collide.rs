//! Collisions with analytic objects (paper Section 5): spheres and planes.
//!
//! The response fits the Verlet scheme: after a step, a vertex that ended inside a collider
//! (inflated by the cloth's thickness) is moved out along the collider's normal to its surface,
//! and `friction` (0..1) removes that share of the step's tangential motion, a simple
//! velocity-level Coulomb model. The new velocity, `(x_new - x) / dt`, follows from the
//! corrected position, so bounce and sliding need no separate velocity update.
//!
//! A kinematic collider moves on a scripted straight path: at time `t` it sits at its scene
//! position plus `velocity * t`. Friction then acts on motion relative to the collider, so a
//! moving ball drags the cloth it touches along.

use glam::DVec3;

/// A collider's geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    Sphere {
        center: DVec3,
        radius: f64,
    },
    /// The half-space behind `point` along `-normal` is solid; `normal` has unit length.
    Plane {
        point: DVec3,
        normal: DVec3,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    /// Where the collider is at time 0.
    pub shape: Shape,
    /// Share of tangential motion removed per contact step, 0 (ice) to 1 (glue).
    pub friction: f64,
    /// Scripted velocity, m/s (zero for a static collider).
    pub velocity: DVec3,
}

impl Shape {
    /// Signed distance from the surface to `p`, m: negative inside.
    pub fn clearance(&self, p: DVec3) -> f64 {
        match *self {
            Shape::Sphere { center, radius } => p.distance(center) - radius,
            Shape::Plane { point, normal } => (p - point).dot(normal),
        }
    }
}

impl Collider {
    /// The collider moved to where its script puts it at time `t`.
    pub fn at(&self, t: f64) -> Self {
        let offset = self.velocity * t;
        let shape = match self.shape {
            Shape::Sphere { center, radius } => Shape::Sphere {
                center: center + offset,
                radius,
            },
            Shape::Plane { point, normal } => Shape::Plane {
                point: point + offset,
                normal,
            },
        };
        Self { shape, ..*self }
    }

    /// Outward normal and depth of `p` inside the collider grown by `thickness`, if inside.
    pub fn penetration(&self, p: DVec3, thickness: f64) -> Option<(DVec3, f64)> {
        match self.shape {
            Shape::Sphere { center, radius } => {
                let offset = p - center;
                let distance = offset.length();
                let depth = radius + thickness - distance;
                (depth > 0.0).then(|| (offset.try_normalize().unwrap_or(DVec3::Y), depth))
            }
            Shape::Plane { point, normal } => {
                let depth = thickness - (p - point).dot(normal);
                (depth > 0.0).then_some((normal, depth))
            }
        }
    }
}

/// Where a vertex that moved from `current` to `next` during a step of `dt` ending at time `t`
/// ends after meeting `colliders`.
pub fn resolve(
    colliders: &[Collider],
    thickness: f64,
    t: f64,
    dt: f64,
    current: DVec3,
    next: DVec3,
) -> DVec3 {
    let mut p = next;
    for collider in colliders {
        if let Some((normal, depth)) = collider.at(t).penetration(p, thickness) {
            p += normal * depth;
            let step = p - current - collider.velocity * dt;
            let tangential = step - normal * step.dot(normal);
            p -= tangential * collider.friction;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_inside_sphere_ends_on_its_grown_surface() {
        let sphere = Collider {
            shape: Shape::Sphere {
                center: DVec3::ZERO,
                radius: 1.0,
            },
            friction: 0.0,
            velocity: DVec3::ZERO,
        };
        let p = resolve(
            &[sphere],
            0.1,
            1.0,
            0.01,
            DVec3::new(0.0, 1.2, 0.0),
            DVec3::new(0.0, 0.9, 0.0),
        );
        assert!((p.length() - 1.1).abs() < 1e-12);
    }

    #[test]
    fn a_moving_ball_is_met_where_its_script_puts_it() {
        let ball = Collider {
            shape: Shape::Sphere {
                center: DVec3::ZERO,
                radius: 0.5,
            },
            friction: 0.0,
            velocity: DVec3::X,
        };
        // At t = 2 the ball is centred at x = 2: a point at x = 2.2 is inside and pushed out.
        let p = resolve(
            &[ball],
            0.0,
            2.0,
            0.01,
            DVec3::new(2.2, 0.0, 0.0),
            DVec3::new(2.2, 0.0, 0.0),
        );
        assert!((p - DVec3::new(2.5, 0.0, 0.0)).length() < 1e-12);
        let untouched = resolve(
            &[ball],
            0.0,
            0.0,
            0.01,
            DVec3::new(2.2, 0.0, 0.0),
            DVec3::new(2.2, 0.0, 0.0),
        );
        assert_eq!(untouched, DVec3::new(2.2, 0.0, 0.0));
    }

    #[test]
    fn friction_removes_tangential_motion_on_a_plane() {
        let plane = |friction| Collider {
            shape: Shape::Plane {
                point: DVec3::ZERO,
                normal: DVec3::Y,
            },
            friction,
            velocity: DVec3::ZERO,
        };
        let (from, to) = (DVec3::new(0.0, 0.01, 0.0), DVec3::new(0.5, -0.1, 0.0));
        let slippery = resolve(&[plane(0.0)], 0.0, 1.0, 0.01, from, to);
        assert_eq!(slippery, DVec3::new(0.5, 0.0, 0.0));
        let sticky = resolve(&[plane(1.0)], 0.0, 1.0, 0.01, from, to);
        assert!((sticky - DVec3::ZERO).length() < 1e-12);
        // A point outside is left alone.
        assert_eq!(
            resolve(&[plane(1.0)], 0.0, 1.0, 0.01, from, from + DVec3::X),
            from + DVec3::X
        );
    }
}
