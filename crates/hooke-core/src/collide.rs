//! Collisions with analytic objects (paper Section 5): spheres and planes.
//!
//! The response fits the Verlet scheme: after a step, a vertex that ended inside a collider
//! (inflated by the cloth's thickness) is moved out along the collider's normal to its surface,
//! and `friction` (0..1) removes that share of the step's tangential motion, a simple
//! velocity-level Coulomb model. The new velocity, `(x_new - x) / dt`, follows from the
//! corrected position, so bounce and sliding need no separate velocity update.
//!
//! A kinematic collider moves on a script: a straight path (at time `t` it sits at its scene
//! position plus `velocity * t`) or a [`KeyframePath`] through keyframes, linear between them, held
//! at the ends or repeated. Friction then acts on motion relative to the collider, so a moving
//! ball drags the cloth it touches along.
//!
//! A dynamic ball (a sphere with [`Dynamics`]) is a rigid body: gravity, an applied force and
//! the cloth's reaction move it. The reaction is the momentum the collision response gave the
//! cloth, taken back from the ball: a vertex of mass `m` moved by `c` in a step of `dt` gained
//! momentum `m c / dt`, so the ball feels `-m c / dt^2` ([`advance_balls`]). Balls then meet
//! planes and other spheres: pushed out, their approach speed reversed times the restitution,
//! and friction at the contact point (Coulomb, the obstacle's `friction` as the coefficient)
//! turning sliding into rolling: a solid ball (moment of inertia 2/5 m r^2) that slides is
//! brought to rolling, spinning up as it slows. The cloth's friction does not spin a ball.

use glam::{DVec3, Vec3};

use crate::BallPush;

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
    /// Every point within `radius` of the segment from `start` to `end`.
    Capsule {
        start: DVec3,
        end: DVec3,
        radius: f64,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    /// Where the collider is at time 0.
    pub shape: Shape,
    /// Share of tangential motion removed per contact step, 0 (ice) to 1 (glue).
    pub friction: f64,
    /// Scripted velocity, m/s (zero for a static collider); a dynamic ball's current velocity.
    pub velocity: DVec3,
    /// Set for a dynamic ball (a sphere that moves under forces).
    pub dynamics: Option<Dynamics>,
    /// A dynamic ball's angular velocity, rad/s.
    pub spin: DVec3,
    /// A scripted path through keyframes (then `velocity` is the path's, set by [`Collider::at`]).
    pub path: Option<KeyframePath>,
}

/// Most keyframes a path holds.
pub const MAX_KEYFRAMES: usize = 8;

/// Keyframes `(time s, position m)` of a collider's centre or point; between them it moves in
/// straight lines at constant speed. Before the first it waits there, after the last it stays
/// there, unless `repeat`, when the path starts over every `last - first` seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyframePath {
    keys: [(f64, DVec3); MAX_KEYFRAMES],
    count: usize,
    pub repeat: bool,
}

impl KeyframePath {
    /// `None` unless there are 2..=MAX_KEYFRAMES keyframes with strictly increasing times.
    pub fn new(keyframes: &[(f64, DVec3)], repeat: bool) -> Option<Self> {
        let ordered = keyframes.windows(2).all(|w| w[1].0 > w[0].0);
        if !(2..=MAX_KEYFRAMES).contains(&keyframes.len()) || !ordered {
            return None;
        }
        let mut keys = [(0.0, DVec3::ZERO); MAX_KEYFRAMES];
        keys[..keyframes.len()].copy_from_slice(keyframes);
        Some(Self {
            keys,
            count: keyframes.len(),
            repeat,
        })
    }

    pub fn keyframes(&self) -> &[(f64, DVec3)] {
        &self.keys[..self.count]
    }

    /// Position and velocity at time `t`.
    pub fn sample(&self, t: f64) -> (DVec3, DVec3) {
        let keys = self.keyframes();
        let (first, last) = (keys[0], keys[self.count - 1]);
        let t = if self.repeat {
            first.0 + (t - first.0).rem_euclid(last.0 - first.0)
        } else {
            t
        };
        if t <= first.0 {
            return (first.1, DVec3::ZERO);
        }
        for pair in keys.windows(2) {
            let ((t0, p0), (t1, p1)) = (pair[0], pair[1]);
            if t < t1 {
                let velocity = (p1 - p0) / (t1 - t0);
                return (p0 + velocity * (t - t0), velocity);
            }
        }
        (last.1, DVec3::ZERO)
    }
}

/// What makes a ball dynamic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dynamics {
    /// kg.
    pub mass: f64,
    /// A constant applied force, N (the viewer's pushes change it).
    pub force: DVec3,
    /// Share of the approach speed a ball keeps, reversed, after meeting a plane or sphere.
    pub restitution: f64,
}

impl Shape {
    /// Signed distance from the surface to `p`, m: negative inside.
    pub fn clearance(&self, p: DVec3) -> f64 {
        match *self {
            Shape::Sphere { center, radius } => p.distance(center) - radius,
            Shape::Plane { point, normal } => (p - point).dot(normal),
            Shape::Capsule { start, end, radius } => {
                p.distance(closest_on_segment(start, end, p)) - radius
            }
        }
    }

    /// The sphere that stands in for this shape near `p`: a sphere itself, or for a capsule the
    /// sphere of its radius around the axis point closest to `p`.
    #[inline]
    fn sphere_near(&self, p: DVec3) -> Option<(DVec3, f64)> {
        match *self {
            Shape::Sphere { center, radius } => Some((center, radius)),
            Shape::Capsule { start, end, radius } => {
                Some((closest_on_segment(start, end, p), radius))
            }
            Shape::Plane { .. } => None,
        }
    }
}

/// The point of the segment `start..end` closest to `p`.
#[inline]
pub fn closest_on_segment(start: DVec3, end: DVec3, p: DVec3) -> DVec3 {
    let axis = end - start;
    let length2 = axis.length_squared();
    if length2 == 0.0 {
        return start;
    }
    start + axis * ((p - start).dot(axis) / length2).clamp(0.0, 1.0)
}

impl Collider {
    /// A collider that stays where it is.
    pub fn fixed(shape: Shape, friction: f64) -> Self {
        Self {
            shape,
            friction,
            velocity: DVec3::ZERO,
            dynamics: None,
            spin: DVec3::ZERO,
            path: None,
        }
    }

    /// The collider moved to where its script puts it at time `t` (a dynamic ball is where
    /// its state says, whatever `t`).
    pub fn at(&self, t: f64) -> Self {
        if self.dynamics.is_some() {
            return *self;
        }
        let (place, velocity) = match self.path {
            Some(path) => path.sample(t),
            None => (self.anchor() + self.velocity * t, self.velocity),
        };
        let shape = match self.shape {
            Shape::Sphere { radius, .. } => Shape::Sphere {
                center: place,
                radius,
            },
            Shape::Plane { normal, .. } => Shape::Plane {
                point: place,
                normal,
            },
            Shape::Capsule {
                start, end, radius, ..
            } => Shape::Capsule {
                start: place,
                end: place + (end - start),
                radius,
            },
        };
        Self {
            shape,
            velocity,
            ..*self
        }
    }

    /// The centre of a sphere, the point of a plane, the start of a capsule's axis.
    pub fn anchor(&self) -> DVec3 {
        match self.shape {
            Shape::Sphere { center, .. } => center,
            Shape::Plane { point, .. } => point,
            Shape::Capsule { start, .. } => start,
        }
    }

    /// Outward normal and depth of `p` inside the collider grown by `thickness`, if inside.
    #[inline]
    pub fn penetration(&self, p: DVec3, thickness: f64) -> Option<(DVec3, f64)> {
        match (self.shape, self.shape.sphere_near(p)) {
            (_, Some((center, radius))) => {
                let offset = p - center;
                // Most vertices are far outside: rejected without a square root. The margin
                // keeps the test conservative, so the ones it passes on meet the exact test.
                let reach = radius + thickness;
                if offset.length_squared() > reach * reach * (1.0 + 1e-9) {
                    return None;
                }
                let distance = offset.length();
                let depth = radius + thickness - distance;
                (depth > 0.0).then(|| (offset.try_normalize().unwrap_or(DVec3::Y), depth))
            }
            (Shape::Plane { point, normal }, None) => {
                let depth = thickness - (p - point).dot(normal);
                (depth > 0.0).then_some((normal, depth))
            }
            (_, None) => None,
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
    for (k, collider) in colliders.iter().enumerate() {
        p = push_out(
            &collider.at(t),
            k,
            thickness,
            dt,
            current,
            p,
            &mut |_, _| {},
        );
    }
    p
}

/// [`resolve`] with the colliders already placed at the step's end ([`placed`]`(colliders,
/// t)`), telling `moved(collider, c)` how far each collider moved the vertex. Solvers place
/// the colliders once per step: placing one copies it (a few hundred bytes with its path),
/// which once per vertex cost more than the tests themselves.
pub fn resolve_placed(
    placed: &[Collider],
    thickness: f64,
    dt: f64,
    current: DVec3,
    next: DVec3,
    mut moved: impl FnMut(usize, DVec3),
) -> DVec3 {
    let mut p = next;
    for (k, collider) in placed.iter().enumerate() {
        p = push_out(collider, k, thickness, dt, current, p, &mut moved);
    }
    p
}

/// Moves `p` out of collider `k` (placed), with friction, if it is inside.
#[inline(always)]
fn push_out(
    collider: &Collider,
    k: usize,
    thickness: f64,
    dt: f64,
    current: DVec3,
    mut p: DVec3,
    moved: &mut impl FnMut(usize, DVec3),
) -> DVec3 {
    if let Some((normal, depth)) = collider.penetration(p, thickness) {
        let before = p;
        p += normal * depth;
        let step = p - current - collider.velocity * dt;
        let tangential = step - normal * step.dot(normal);
        p -= tangential * collider.friction;
        moved(k, p - before);
    }
    p
}

/// Sets each dynamic ball's applied force to the one its setting gives plus the pushes on it.
pub fn apply_pushes(running: &mut [Collider], settings: &[Collider], pushes: &[BallPush]) {
    for (k, (now, setting)) in running.iter_mut().zip(settings).enumerate() {
        if let (Some(dynamics), Some(set)) = (now.dynamics.as_mut(), setting.dynamics) {
            dynamics.force = pushes
                .iter()
                .filter(|p| p.collider == k)
                .fold(set.force, |total, p| total + p.force);
        }
    }
}

/// Puts the dynamic balls where `saved` has them, moving as they moved there (a restore).
pub fn restore_balls(running: &mut [Collider], saved: &[Collider]) {
    for (now, then) in running.iter_mut().zip(saved) {
        if now.dynamics.is_some() {
            (now.shape, now.velocity, now.spin) = (then.shape, then.velocity, then.spin);
        }
    }
}

/// A float32 bound that a vertex must be inside to touch a placed collider: a ball around a
/// sphere or capsule, a half-space above a plane. Outside every collider's reach a vertex
/// meets no collider, so solvers skip the exact test there (most vertices, most steps). The
/// bound is wider than the collider by 1e-4 of the sizes involved, and [`Reach::may_touch`]
/// adds 1e-6 of the point's coordinates: far more than float32's rounding of either.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reach {
    Ball {
        center: Vec3,
        radius: f32,
    },
    /// Points with `p . normal <= limit`.
    HalfSpace {
        normal: Vec3,
        limit: f32,
    },
}

impl Reach {
    /// The reach of `collider` (placed), grown by `thickness`.
    pub fn of(collider: &Collider, thickness: f64) -> Self {
        let ball = |center: DVec3, reach: f64| Self::Ball {
            center: center.as_vec3(),
            radius: (reach * (1.0 + 1e-4) + 1e-4 * (1.0 + center.length())) as f32,
        };
        match collider.shape {
            Shape::Sphere { center, radius } => ball(center, radius + thickness),
            Shape::Capsule { start, end, radius } => ball(
                0.5 * (start + end),
                0.5 * start.distance(end) + radius + thickness,
            ),
            Shape::Plane { point, normal } => Self::HalfSpace {
                normal: normal.as_vec3(),
                limit: (point.dot(normal) + thickness + 1e-4 * (1.0 + point.length() + thickness))
                    as f32,
            },
        }
    }

    /// False if `p` certainly does not touch the collider.
    #[inline]
    pub fn may_touch(&self, p: Vec3) -> bool {
        let slack = 1e-6 * (p.x.abs() + p.y.abs() + p.z.abs());
        match *self {
            Self::Ball { center, radius } => {
                (p - center).length_squared() <= (radius + slack) * (radius + slack)
            }
            Self::HalfSpace { normal, limit } => p.dot(normal) <= limit + slack,
        }
    }
}

/// The colliders placed at time `t` (scripted ones moved, dynamic ones where they are).
pub fn placed(colliders: &[Collider], t: f64) -> Vec<Collider> {
    colliders.iter().map(|c| c.at(t)).collect()
}

/// The first dynamic ball whose place or velocity is not finite.
pub fn first_non_finite_ball(colliders: &[Collider]) -> Option<usize> {
    colliders
        .iter()
        .position(|c| c.dynamics.is_some() && !(c.anchor().is_finite() && c.velocity.is_finite()))
}

/// True if any collider is a dynamic ball.
pub fn any_dynamic(colliders: &[Collider]) -> bool {
    colliders.iter().any(|c| c.dynamics.is_some())
}

/// Advances the dynamic balls among `colliders` by one step of `dt`. `pushes[k]` is the sum
/// over vertices of `m c` (kg m) for the moves `c` collider `k` made this step; the ball takes
/// the opposite momentum. Then each ball, in order, meets the planes and other spheres.
/// `t` is the time at the end of the step (where scripted obstacles are met).
pub fn advance_balls(
    colliders: &mut [Collider],
    pushes: &[DVec3],
    gravity: DVec3,
    dt: f64,
    t: f64,
) {
    for (collider, push) in colliders.iter_mut().zip(pushes) {
        let (Some(dynamics), Shape::Sphere { center, .. }) =
            (collider.dynamics, &mut collider.shape)
        else {
            continue;
        };
        let force = dynamics.force + gravity * dynamics.mass - *push / (dt * dt);
        collider.velocity += force / dynamics.mass * dt;
        *center += collider.velocity * dt;
    }
    for k in 0..colliders.len() {
        let (Some(dynamics), Shape::Sphere { .. }) = (colliders[k].dynamics, colliders[k].shape)
        else {
            continue;
        };
        for other in 0..colliders.len() {
            if other != k {
                let (ball, obstacle) = pair_mut(colliders, k, other);
                meet(ball, dynamics, obstacle, t);
            }
        }
    }
}

fn pair_mut<T>(items: &mut [T], a: usize, b: usize) -> (&mut T, &mut T) {
    if a < b {
        let (left, right) = items.split_at_mut(b);
        (&mut left[a], &mut right[0])
    } else {
        let (left, right) = items.split_at_mut(a);
        (&mut right[0], &mut left[b])
    }
}

/// A dynamic ball meets a plane or sphere: pushed out (a dynamic sphere shares the push and
/// the impulse by mass), approach speed reversed times the restitution, Coulomb friction on
/// the slip of the contact point.
fn meet(ball: &mut Collider, dynamics: Dynamics, obstacle: &mut Collider, t: f64) {
    let Shape::Sphere { center, radius } = ball.shape else {
        return;
    };
    let placed = obstacle.at(t);
    let (normal, depth) = match (placed.shape, placed.shape.sphere_near(center)) {
        (_, Some((other, other_radius))) => {
            let offset = center - other;
            let normal = offset.try_normalize().unwrap_or(DVec3::Y);
            (normal, radius + other_radius - offset.length())
        }
        (Shape::Plane { point, normal }, None) => (normal, radius - (center - point).dot(normal)),
        (_, None) => return,
    };
    if depth <= 0.0 {
        return;
    }
    // Share of the push and impulse the ball takes: all of it against a scripted obstacle.
    let share = match obstacle.dynamics {
        Some(other) => other.mass / (dynamics.mass + other.mass),
        None => 1.0,
    };
    let relative = ball.velocity - placed.velocity;
    let approach = relative.dot(normal);
    let bounce = if approach < 0.0 {
        -(1.0 + dynamics.restitution) * approach
    } else {
        0.0
    };
    // Slip of the contact point; stopping it takes 2/7 of it from the centre's velocity and
    // the rest from the spin (solid ball), within mu times the normal speed change.
    let arm = -normal * radius;
    let contact = relative + ball.spin.cross(arm);
    let slip = contact - normal * contact.dot(normal);
    let wanted = slip * (2.0 / 7.0);
    let limit = obstacle.friction * bounce;
    let friction = if wanted.length() > limit {
        wanted * (limit / wanted.length())
    } else {
        wanted
    };
    let change = normal * bounce - friction;
    ball.velocity += change * share;
    ball.spin += arm.cross(-friction) * (share * 2.5 / (radius * radius));
    if let Shape::Sphere { center, .. } = &mut ball.shape {
        *center += normal * (depth * share);
    }
    if obstacle.dynamics.is_some() {
        obstacle.velocity -= change * (1.0 - share);
        if let Shape::Sphere { center, .. } = &mut obstacle.shape {
            *center -= normal * (depth * (1.0 - share));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_inside_sphere_ends_on_its_grown_surface() {
        let sphere = Collider::fixed(
            Shape::Sphere {
                center: DVec3::ZERO,
                radius: 1.0,
            },
            0.0,
        );
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
            velocity: DVec3::X,
            ..Collider::fixed(
                Shape::Sphere {
                    center: DVec3::ZERO,
                    radius: 0.5,
                },
                0.0,
            )
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
        let plane = |friction| {
            Collider::fixed(
                Shape::Plane {
                    point: DVec3::ZERO,
                    normal: DVec3::Y,
                },
                friction,
            )
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

    #[test]
    fn a_pushed_ball_on_the_ground_rolls_at_five_sevenths_of_the_push() {
        let ground = Collider::fixed(
            Shape::Plane {
                point: DVec3::ZERO,
                normal: DVec3::Y,
            },
            0.5,
        );
        let (mass, radius, force) = (2.0, 0.1, 3.0);
        let ball = Collider {
            dynamics: Some(Dynamics {
                mass,
                force: DVec3::new(force, 0.0, 0.0),
                restitution: 0.0,
            }),
            ..Collider::fixed(
                Shape::Sphere {
                    center: DVec3::new(0.0, radius, 0.0),
                    radius,
                },
                0.0,
            )
        };
        let mut colliders = [ground, ball];
        let (dt, steps) = (1e-3, 1000);
        let run = |colliders: &mut [Collider; 2]| {
            for k in 1..=steps {
                let t = k as f64 * dt;
                advance_balls(
                    colliders,
                    &[DVec3::ZERO; 2],
                    DVec3::new(0.0, -9.81, 0.0),
                    dt,
                    t,
                );
            }
        };
        run(&mut colliders);
        // Rolling without slipping: a = F / (m (1 + 2/5)); spin = v / r about -z.
        let t = steps as f64 * dt;
        let expected = 5.0 / 7.0 * force / mass * t;
        let ball = colliders[1];
        assert!(
            (ball.velocity.x - expected).abs() < 1e-2 * expected,
            "{}",
            ball.velocity
        );
        assert!((ball.spin.z + ball.velocity.x / radius).abs() < 1e-2 * expected / radius);
        // Without friction it slides at the full F / m.
        colliders[0].friction = 0.0;
        colliders[1].velocity = DVec3::ZERO;
        run(&mut colliders);
        assert!((colliders[1].velocity.x - force / mass * t).abs() < 1e-2 * force / mass * t);
    }

    #[test]
    fn a_path_moves_through_its_keyframes_and_repeats() {
        let keys = [
            (1.0, DVec3::ZERO),
            (2.0, DVec3::new(2.0, 0.0, 0.0)),
            (4.0, DVec3::new(2.0, 4.0, 0.0)),
        ];
        let path = KeyframePath::new(&keys, false).expect("valid");
        assert_eq!(path.sample(0.0), (DVec3::ZERO, DVec3::ZERO));
        assert_eq!(path.sample(1.5), (DVec3::X, DVec3::new(2.0, 0.0, 0.0)));
        assert_eq!(
            path.sample(3.0),
            (DVec3::new(2.0, 2.0, 0.0), DVec3::new(0.0, 2.0, 0.0))
        );
        assert_eq!(path.sample(9.0), (keys[2].1, DVec3::ZERO));
        let looping = KeyframePath::new(&keys, true).expect("valid");
        assert_eq!(looping.sample(4.5).0, looping.sample(1.5).0);
        assert!(KeyframePath::new(&keys[..1], false).is_none());
        assert!(KeyframePath::new(&[keys[1], keys[0]], false).is_none());
    }

    #[test]
    fn a_capsule_pushes_out_from_its_axis_and_caps() {
        let capsule = Collider::fixed(
            Shape::Capsule {
                start: DVec3::ZERO,
                end: DVec3::new(2.0, 0.0, 0.0),
                radius: 0.5,
            },
            0.0,
        );
        let from = |p: DVec3| resolve(&[capsule], 0.1, 0.0, 0.01, p, p);
        // Beside the axis: out along the radius; past an end: out of the cap.
        assert!((from(DVec3::new(1.0, 0.3, 0.0)) - DVec3::new(1.0, 0.6, 0.0)).length() < 1e-12);
        assert!((from(DVec3::new(2.2, 0.0, 0.0)) - DVec3::new(2.6, 0.0, 0.0)).length() < 1e-12);
        assert!((capsule.shape.clearance(DVec3::new(-1.0, 0.0, 0.0)) - 0.5).abs() < 1e-12);
        // A scripted capsule moves whole.
        let moving = Collider {
            velocity: DVec3::Y,
            ..capsule
        };
        let Shape::Capsule { start, end, .. } = moving.at(2.0).shape else {
            panic!("a capsule")
        };
        assert_eq!(
            (start, end),
            (DVec3::new(0.0, 2.0, 0.0), DVec3::new(2.0, 2.0, 0.0))
        );
    }

    /// Every point a collider pushes is within its reach, however close to the surface and
    /// however far from the origin; points well outside are not.
    #[test]
    fn a_reach_holds_every_point_its_collider_touches() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let thickness = 0.01;
        for offset in [DVec3::ZERO, DVec3::new(300.0, -20.0, 7.0)] {
            let shapes = [
                Shape::Sphere {
                    center: offset + DVec3::new(0.1, 0.2, 0.3),
                    radius: 0.3,
                },
                Shape::Capsule {
                    start: offset,
                    end: offset + DVec3::new(1.0, 0.5, 0.0),
                    radius: 0.2,
                },
                Shape::Plane {
                    point: offset + DVec3::new(0.0, -0.1, 0.0),
                    normal: DVec3::new(0.3, 1.0, 0.2).normalize(),
                },
            ];
            for shape in shapes {
                let collider = Collider::fixed(shape, 0.0);
                let reach = Reach::of(&collider, thickness);
                let (mut touched, mut rejected) = (0, 0);
                for _ in 0..20_000 {
                    let p = offset
                        + DVec3::new(
                            rng.random_range(-1.5..2.5),
                            rng.random_range(-1.5..1.5),
                            rng.random_range(-1.5..1.5),
                        );
                    // As a solver holds it: float32.
                    let p = p.as_vec3();
                    let touches = collider.penetration(p.as_dvec3(), thickness).is_some();
                    if touches {
                        touched += 1;
                        assert!(reach.may_touch(p), "{shape:?}: {p} touches");
                    }
                    if !reach.may_touch(p) {
                        rejected += 1;
                    }
                }
                assert!(
                    touched > 20 && rejected > 1000,
                    "{shape:?}: {touched}, {rejected}"
                );
                // Just inside the grown surface, along a few directions.
                if let Shape::Sphere { center, radius } = shape {
                    for d in [
                        DVec3::X,
                        DVec3::NEG_Y,
                        DVec3::new(1.0, 1.0, 1.0).normalize(),
                    ] {
                        let p = (center + d * (radius + thickness) * (1.0 - 1e-7)).as_vec3();
                        if collider.penetration(p.as_dvec3(), thickness).is_some() {
                            assert!(reach.may_touch(p), "{p} just inside");
                        }
                    }
                }
            }
        }
    }
}
