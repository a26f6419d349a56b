//! The mouse (or touch) on a live simulation, the same in the viewer's window and the browser
//! page: the primary button grabs the cloth under the cursor (or orbits the camera when there is
//! none), the secondary button pans, the wheel zooms.
//!
//! Whether the cloth is under the cursor is a GPU question: a press asks for a pick, the front
//! end records it into a frame ([`Pointer::pick_request`]) and hands the answer back a frame or
//! two later ([`Pointer::picked`]); nothing waits for it.

use glam::{Vec2, Vec3};
use hooke_gpu::render::{Camera, PickAt, PickedVertex};

use crate::live::LiveSimulation;

/// Radians of orbit per pixel of motion.
const ORBIT_PER_PIXEL: f32 = 0.008;
/// Pan per pixel, as a fraction of the camera's distance.
const PAN_PER_PIXEL: f32 = 0.0015;
/// How far from the cursor, in pixels, a vertex can be and still be grabbed.
const PICK_RADIUS_PIXELS: f32 = 12.0;

/// What the buttons are doing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gesture {
    Idle,
    /// Pressed; waiting for the GPU to say whether the cloth is under the cursor. Motion so far.
    Picking(Vec2),
    Orbiting,
    Grabbing {
        vertex: u32,
        anchor: Vec3,
    },
    Panning,
}

/// The cursor, in pixels of an image of `size`, and the gesture in progress.
#[derive(Clone, Debug)]
pub struct Pointer {
    pub gesture: Gesture,
    pub cursor: Vec2,
    pub size: [u32; 2],
    pick_requested: bool,
}

impl Pointer {
    pub fn new(size: [u32; 2]) -> Self {
        Self {
            gesture: Gesture::Idle,
            cursor: Vec2::ZERO,
            size,
            pick_requested: false,
        }
    }

    /// The cursor in normalised device coordinates.
    pub fn cursor_ndc(&self) -> Vec2 {
        let [w, h] = self.size;
        Vec2::new(
            2.0 * self.cursor.x / w.max(1) as f32 - 1.0,
            1.0 - 2.0 * self.cursor.y / h.max(1) as f32,
        )
    }

    fn aspect(&self) -> f32 {
        self.size[0] as f32 / self.size[1].max(1) as f32
    }

    /// The grabbed vertex, if the cloth is held.
    pub fn holding(&self) -> Option<u32> {
        match self.gesture {
            Gesture::Grabbing { vertex, .. } => Some(vertex),
            _ => None,
        }
    }

    /// The primary button went down: grab or orbit, once the pick answers.
    pub fn press_primary(&mut self) {
        self.gesture = Gesture::Picking(Vec2::ZERO);
        self.pick_requested = true;
    }

    /// The secondary (or middle) button went down: pan.
    pub fn press_secondary(&mut self) {
        self.gesture = Gesture::Panning;
    }

    /// A button went up: lets go of the cloth.
    pub fn release(&mut self, simulation: &mut LiveSimulation) {
        if matches!(self.gesture, Gesture::Grabbing { .. }) {
            simulation.grab = None;
            simulation.apply();
        }
        self.gesture = Gesture::Idle;
    }

    /// The cursor moved to `cursor` (pixels).
    pub fn move_to(&mut self, cursor: Vec2, camera: &mut Camera, simulation: &mut LiveSimulation) {
        let delta = cursor - self.cursor;
        self.cursor = cursor;
        match &mut self.gesture {
            Gesture::Picking(pending) => *pending += delta,
            Gesture::Orbiting => camera.orbit(delta * ORBIT_PER_PIXEL),
            Gesture::Panning => camera.pan(delta * PAN_PER_PIXEL),
            Gesture::Grabbing { vertex, anchor } => {
                let (vertex, anchor) = (*vertex, *anchor);
                self.drag_to(vertex, anchor, camera, simulation);
            }
            Gesture::Idle => {}
        }
    }

    /// The wheel turned by `lines` (positive: away from the user, closer in).
    pub fn wheel(&self, lines: f32, camera: &mut Camera) {
        camera.zoom(0.9f32.powf(lines));
    }

    /// The pick to record into this frame, if a press asked for one.
    pub fn pick_request(&self) -> Option<PickAt> {
        self.pick_requested.then(|| PickAt {
            cursor: self.cursor_ndc(),
            size: self.size,
            radius_pixels: PICK_RADIUS_PIXELS,
        })
    }

    /// The requested pick was recorded (the picker was free).
    pub fn pick_recorded(&mut self) {
        self.pick_requested = false;
    }

    /// The pick answered: grab the vertex found, or orbit by the motion so far.
    pub fn picked(
        &mut self,
        answer: Option<PickedVertex>,
        camera: &mut Camera,
        simulation: &mut LiveSimulation,
    ) {
        let Gesture::Picking(pending) = self.gesture else {
            return;
        };
        self.gesture = match answer {
            Some(hit) => {
                simulation.grab = Some((hit.vertex, hit.position));
                simulation.apply();
                Gesture::Grabbing {
                    vertex: hit.vertex,
                    anchor: hit.position,
                }
            }
            None => {
                camera.orbit(pending * ORBIT_PER_PIXEL);
                Gesture::Orbiting
            }
        };
    }

    /// Moves the grab target to where the cursor ray meets the plane through the grabbed point
    /// facing the camera.
    fn drag_to(&self, vertex: u32, anchor: Vec3, camera: &Camera, simulation: &mut LiveSimulation) {
        let (origin, direction) = camera.ray(self.cursor_ndc(), self.aspect());
        let normal = (camera.target - camera.eye()).normalize_or(Vec3::NEG_Z);
        let denominator = direction.dot(normal);
        if denominator.abs() > 1e-6 {
            let t = (anchor - origin).dot(normal) / denominator;
            simulation.grab = Some((vertex, origin + direction * t));
            simulation.apply();
        }
    }
}

/// Directions to push a ball, relative to the view (horizontal ones) or up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PushDirection {
    Left,
    Right,
    Away,
    Toward,
    Up,
}

impl PushDirection {
    pub const ALL: [Self; 5] = [Self::Left, Self::Right, Self::Away, Self::Toward, Self::Up];

    pub fn name(self) -> &'static str {
        match self {
            Self::Left => "left",
            Self::Right => "right",
            Self::Away => "away",
            Self::Toward => "toward",
            Self::Up => "up",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|d| d.name() == name)
    }

    /// The world direction for the camera's current heading.
    pub fn relative_to(self, camera: &Camera) -> glam::DVec3 {
        let (sin_yaw, cos_yaw) = f64::from(camera.yaw).sin_cos();
        // The camera sits at yaw around the target: away from it is -(sin, 0, cos).
        let away = glam::DVec3::new(-sin_yaw, 0.0, -cos_yaw);
        let right = glam::DVec3::new(cos_yaw, 0.0, -sin_yaw);
        match self {
            Self::Left => -right,
            Self::Right => right,
            Self::Away => away,
            Self::Toward => -away,
            Self::Up => glam::DVec3::Y,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hooke_gpu::render::SceneBounds;

    #[test]
    fn pushes_follow_the_view() {
        let mut camera = Camera::framing(&SceneBounds {
            min: glam::Vec3::splat(-1.0),
            max: glam::Vec3::splat(1.0),
            ground_height: 0.0,
        });
        // Yaw 0: the camera sits on +z looking toward -z, with +x to its right.
        camera.yaw = 0.0;
        let close = |a: glam::DVec3, b: glam::DVec3| (a - b).length() < 1e-12;
        assert!(close(
            PushDirection::Away.relative_to(&camera),
            -glam::DVec3::Z
        ));
        assert!(close(
            PushDirection::Right.relative_to(&camera),
            glam::DVec3::X
        ));
        assert!(close(
            PushDirection::Up.relative_to(&camera),
            glam::DVec3::Y
        ));
        // A quarter turn: the camera on +x looking toward -x, with -z to its right.
        camera.yaw = std::f32::consts::FRAC_PI_2;
        assert!((PushDirection::Away.relative_to(&camera) + glam::DVec3::X).length() < 1e-6);
        assert!((PushDirection::Right.relative_to(&camera) + glam::DVec3::Z).length() < 1e-6);
    }
}
