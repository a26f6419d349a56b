//! An orbit camera: it circles a target point at a distance, and can pan, zoom and cast rays.

use glam::camera::rh::proj::directx;
use glam::camera::rh::view::look_at_mat4;
use glam::{Mat4, Vec2, Vec3};

use super::SceneBounds;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub target: Vec3,
    pub distance: f32,
    /// Around the vertical axis, radians.
    pub yaw: f32,
    /// Above the horizon, radians.
    pub pitch: f32,
    /// Vertical field of view, radians.
    pub fov_y: f32,
}

impl Camera {
    /// A three-quarter view from above of everything between the ground and the top of the
    /// scene, where a falling or hanging cloth will be.
    pub fn framing(bounds: &SceneBounds) -> Self {
        let extent = bounds.extent();
        let floor = bounds.ground_height.max(bounds.min.y - extent);
        let span = extent.max(bounds.max.y - floor);
        let center = bounds.center();
        Self {
            target: Vec3::new(
                center.x,
                0.5 * (bounds.max.y + floor) + 0.1 * span,
                center.z,
            ),
            distance: 1.6 * span,
            yaw: 0.6,
            pitch: 0.5,
            fov_y: 45f32.to_radians(),
        }
    }

    pub fn eye(&self) -> Vec3 {
        let (sin_yaw, cos_yaw) = self.yaw.sin_cos();
        let (sin_pitch, cos_pitch) = self.pitch.sin_cos();
        self.target + self.distance * Vec3::new(cos_pitch * sin_yaw, sin_pitch, cos_pitch * cos_yaw)
    }

    pub fn view_projection(&self, aspect: f32) -> Mat4 {
        let view = look_at_mat4(self.eye(), self.target, Vec3::Y);
        let near = (0.01 * self.distance).max(1e-4);
        // WebGPU's clip space is DirectX's: z in [0, 1], y up.
        let projection =
            directx::perspective(self.fov_y, aspect.max(1e-3), near, 100.0 * self.distance);
        projection * view
    }

    /// Turns the camera by `delta` radians (yaw, pitch), keeping it above and below the poles.
    pub fn orbit(&mut self, delta: Vec2) {
        self.yaw -= delta.x;
        self.pitch = (self.pitch + delta.y).clamp(-1.5, 1.5);
    }

    /// Moves the target in the view plane by `delta` in units of the distance.
    pub fn pan(&mut self, delta: Vec2) {
        let forward = (self.target - self.eye()).normalize_or(Vec3::NEG_Z);
        let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
        let up = right.cross(forward);
        self.target += (-right * delta.x + up * delta.y) * self.distance;
    }

    /// Multiplies the distance by `factor`.
    pub fn zoom(&mut self, factor: f32) {
        self.distance = (self.distance * factor).clamp(1e-3, 1e4);
    }

    /// The pixel (from the top left of an image of `size`) where `point` is drawn.
    pub fn to_pixels(&self, point: Vec3, size: [u32; 2]) -> Vec2 {
        let aspect = size[0] as f32 / size[1].max(1) as f32;
        let ndc = self.view_projection(aspect).project_point3(point);
        Vec2::new(
            (ndc.x + 1.0) * 0.5 * size[0] as f32,
            (1.0 - ndc.y) * 0.5 * size[1] as f32,
        )
    }

    /// The world-space ray through a point given in normalised device coordinates.
    pub fn ray(&self, ndc: Vec2, aspect: f32) -> (Vec3, Vec3) {
        let inverse = self.view_projection(aspect).inverse();
        let near = inverse.project_point3(ndc.extend(0.0));
        let far = inverse.project_point3(ndc.extend(1.0));
        (near, (far - near).normalize_or(Vec3::NEG_Z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tilted() -> Camera {
        Camera {
            target: Vec3::new(1.0, 2.0, 3.0),
            distance: 4.0,
            yaw: 0.3,
            pitch: 0.4,
            fov_y: 0.8,
        }
    }

    #[test]
    fn ray_through_the_centre_points_at_the_target() {
        let camera = tilted();
        let (origin, direction) = camera.ray(Vec2::ZERO, 1.5);
        let to_target = (camera.target - origin).normalize();
        assert!(direction.dot(to_target) > 0.9999);
    }

    #[test]
    fn the_target_is_drawn_at_the_image_centre() {
        let camera = tilted();
        let pixel = camera.to_pixels(camera.target, [300, 200]);
        assert!((pixel - Vec2::new(150.0, 100.0)).length() < 1e-3, "{pixel}");
        let above = camera.to_pixels(camera.target + Vec3::Y, [300, 200]);
        assert!(above.y < 100.0, "up is drawn higher: {above}");
    }
}
