//! [`Material`]: the integrator's constants (dt, damping, gravity) and a stiffness scale,
//! changed by an explicit call that updates a solver in place, never by rebuilding it.

use glam::DVec3;

/// The integrator's constants and the material's stiffness: changed by an explicit call that
/// updates a solver in place, never by rebuilding it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Time step `dt`, s.
    pub dt: f64,
    /// Damping constant `c` of eq. 2, kg/s.
    pub damping: f64,
    /// Gravitational acceleration, m/s^2.
    pub gravity: DVec3,
    /// Every spring's stiffness is the model's times this factor (1: as built).
    pub stiffness_scale: f64,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            dt: 1e-3,
            damping: 0.0,
            gravity: DVec3::new(0.0, -9.81, 0.0),
            stiffness_scale: 1.0,
        }
    }
}
