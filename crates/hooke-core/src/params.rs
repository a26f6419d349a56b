//! Per-run simulation parameters in SI units: time step, damping and external forces.
//!
//! External forces `F_ext` (paper eq. 2, 4) are the sum of:
//! - gravity: `m_i * gravity`;
//! - constant point forces on chosen vertices;
//! - drags: a spring-like pull `stiffness * (target - x_i)` of chosen vertices toward a target,
//!   which is how the viewer's mouse grabs the cloth ("forces exerted by user interaction");
//! - wind: a linear drag model per triangle. With unit normal `n`, area `A` and triangle velocity
//!   `v` (mean of its vertices' Verlet velocities `(x - x_prev)/dt`), the force is
//!   `coefficient * A * ((wind_velocity - v) . n) n`, split equally over the three vertices. It acts
//!   only along the normal (a sheet edge-on to the wind feels nothing) and vanishes once the cloth
//!   moves with the air, so it cannot pump energy into the system without bound.

use glam::DVec3;

use crate::collide::Collider;
use crate::selfcollide::SelfCollision;

/// A constant force on one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointForce {
    pub vertex: u32,
    /// N.
    pub force: DVec3,
}

/// A pull of some vertices toward a target point.
#[derive(Clone, Debug, PartialEq)]
pub struct Drag {
    pub vertices: Vec<u32>,
    /// m.
    pub target: DVec3,
    /// N/m per vertex.
    pub stiffness: f64,
}

/// Wind acting on the triangles of the surface (see the module docs for the model).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wind {
    /// Air velocity, m/s.
    pub velocity: DVec3,
    /// Drag coefficient per unit area, N s/m^3.
    pub coefficient: f64,
}

/// Everything that drives a step besides the model and the state.
#[derive(Clone, Debug, PartialEq)]
pub struct SimParams {
    /// Time step `dt`, s.
    pub dt: f64,
    /// Damping constant `c` of eq. 2, kg/s.
    pub damping: f64,
    /// Gravitational acceleration, m/s^2.
    pub gravity: DVec3,
    pub wind: Option<Wind>,
    pub point_forces: Vec<PointForce>,
    pub drags: Vec<Drag>,
    /// Spheres and planes the cloth cannot enter (see [`crate::collide`]).
    pub colliders: Vec<Collider>,
    /// How far from a collider's surface the cloth is held, m (its half thickness).
    pub collision_thickness: f64,
    /// Approximate self-collision by binning (see [`crate::selfcollide`]); off when `None`.
    pub self_collision: Option<SelfCollision>,
}

impl SimParams {
    /// True if a step has collision work: colliders or self-collision.
    pub fn collides(&self) -> bool {
        !self.colliders.is_empty() || self.self_collision.is_some()
    }
}

impl Default for SimParams {
    fn default() -> Self {
        Self {
            dt: 1e-3,
            damping: 0.0,
            gravity: DVec3::new(0.0, -9.81, 0.0),
            wind: None,
            point_forces: Vec::new(),
            drags: Vec::new(),
            colliders: Vec::new(),
            collision_thickness: 0.0,
            self_collision: None,
        }
    }
}
