//! [`Control`]: the per-step inputs a user or a script changes while the simulation runs
//! (drags, point forces, wind, pushes on balls). A solver writes them into buffers it already
//! has. What stays fixed while stepping is in [`crate::Model`], the integrator's constants in
//! [`crate::Material`].
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

/// A force on a dynamic ball, added to the constant force its collider was given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallPush {
    /// Index of the dynamic ball among the model's colliders.
    pub collider: usize,
    /// N.
    pub force: DVec3,
}

/// The per-step inputs: what a user or a script changes while the simulation runs. A solver
/// writes them into buffers it already has.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Control {
    pub wind: Option<Wind>,
    pub point_forces: Vec<PointForce>,
    pub drags: Vec<Drag>,
    pub ball_pushes: Vec<BallPush>,
}

impl Control {
    /// True if the control puts forces on the cloth (point forces, drags or wind).
    pub fn acts_on_cloth(&self) -> bool {
        self.wind.is_some() || !self.point_forces.is_empty() || !self.drags.is_empty()
    }

    /// Checks the control against `model`: every vertex it names exists and every ball push
    /// is on a dynamic ball. Front ends that take controls from users (Python, the browser)
    /// call this before handing one to a solver, which assumes it holds.
    pub fn check(&self, model: &crate::Model) -> Result<(), String> {
        let n = model.vertex_count();
        let vertices = self
            .drags
            .iter()
            .flat_map(|d| d.vertices.iter().map(|v| (*v, "drag")))
            .chain(self.point_forces.iter().map(|f| (f.vertex, "point force")));
        for (vertex, what) in vertices {
            if vertex as usize >= n {
                return Err(format!(
                    "a {what} names vertex {vertex}, but the mesh has {n} vertices"
                ));
            }
        }
        let colliders = &model.collision.colliders;
        for push in &self.ball_pushes {
            let dynamic = colliders
                .get(push.collider)
                .is_some_and(|c| c.dynamics.is_some());
            if !dynamic {
                return Err(format!(
                    "collider {} is not a dynamic ball (the scene has {} colliders)",
                    push.collider,
                    colliders.len()
                ));
            }
        }
        Ok(())
    }
}
