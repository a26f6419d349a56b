//! Handles: pinned vertices that move, the same rule on every solver.
//!
//! A handle carries a set of pinned vertices rigidly (by translation): at the end of each step
//! every one of them is placed at its initial position plus the handle's displacement at that
//! time. A handle is moved by a keyframed path of displacements (the colliders' path syntax)
//! or follows a collider: a scripted one along its script, a dynamic ball as the ball moves
//! (the cloth does not pull the ball back through a handle). Handles are placed after the
//! colliders and dynamic balls of the step and before self-collision, which never moves a
//! pinned vertex.

use glam::DVec3;

use crate::collide::{Collider, KeyframePath};

/// What moves a handle.
#[derive(Clone, Debug, PartialEq)]
pub enum HandleMotion {
    /// Keyframes `(t, displacement)` (boxed: the path's fixed keyframe slots are large).
    Path(Box<KeyframePath>),
    /// The collider of this index: the handle moves as its anchor (centre, point or capsule
    /// start) does.
    Collider(usize),
}

/// Pinned vertices moved together.
#[derive(Clone, Debug, PartialEq)]
pub struct Handle {
    pub vertices: Vec<u32>,
    pub motion: HandleMotion,
}

impl Handle {
    /// How far the handle has moved at time `t` from where its vertices start. `now` are the
    /// colliders as a solver keeps them (scripted ones as the model gives them, dynamic balls
    /// where they are now), `initial` as the model gives them.
    pub fn displacement(&self, t: f64, now: &[Collider], initial: &[Collider]) -> DVec3 {
        match &self.motion {
            HandleMotion::Path(path) => path.sample(t).0,
            &HandleMotion::Collider(k) => now[k].at(t).anchor() - initial[k].at(0.0).anchor(),
        }
    }
}

/// Places every handle's vertices for time `t` (see [`Handle::displacement`]): `place(vertex,
/// position)` is called once per handle vertex.
pub fn place_handles(
    handles: &[Handle],
    initial_positions: &[DVec3],
    t: f64,
    now: &[Collider],
    initial: &[Collider],
    mut place: impl FnMut(u32, DVec3),
) {
    for handle in handles {
        let d = handle.displacement(t, now, initial);
        for &v in &handle.vertices {
            place(v, initial_positions[v as usize] + d);
        }
    }
}
