//! A pinhole camera, and framing one around a bounding box.

use glam::{Vec2, Vec3};

use crate::bounds::Bounds;

/// A pinhole camera: rays start at `position` and pass through a virtual screen
/// one unit ahead. Image coordinates are `(0, 0)` at the top left and `(1, 1)` at
/// the bottom right.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    position: Vec3,
    forward: Vec3,
    /// Screen-space +x, scaled to half the screen width.
    right: Vec3,
    /// Screen-space +y (up), scaled to half the screen height.
    up: Vec3,
}

/// Where to look from, as angles around a target (Y up).
#[derive(Clone, Copy, Debug)]
pub struct ViewAngles {
    /// Angle around +Y, in radians: 0 looks from +Z towards −Z, π/2 from +X.
    pub azimuth: f32,
    /// Angle above the horizontal plane, in radians.
    pub elevation: f32,
    /// Vertical field of view, in radians.
    pub vertical_fov: f32,
}

impl Camera {
    /// A camera at `position` looking at `target`, with `world_up` (not parallel to
    /// the view direction) pointing up on screen.
    pub fn look_at(
        position: Vec3,
        target: Vec3,
        world_up: Vec3,
        vertical_fov: f32,
        aspect: f32,
    ) -> Self {
        let forward = (target - position).normalize();
        let right = forward.cross(world_up).normalize();
        let up = right.cross(forward);
        let half_height = (0.5 * vertical_fov).tan();
        Camera {
            position,
            forward,
            right: right * half_height * aspect,
            up: up * half_height,
        }
    }

    /// A camera that looks at the centre of `bounds` from the direction `view`,
    /// just far enough that all eight corners of the box fit in the picture with a
    /// `margin` (e.g. 0.1 for 10 %) around them.
    pub fn framing(bounds: &Bounds, view: ViewAngles, aspect: f32, margin: f32) -> Self {
        let target = bounds.center();
        let (sin_a, cos_a) = view.azimuth.sin_cos();
        let (sin_e, cos_e) = view.elevation.sin_cos();
        // Unit vector from the target towards the camera.
        let back = Vec3::new(cos_e * sin_a, sin_e, cos_e * cos_a);
        let unit = Camera::look_at(target + back, target, Vec3::Y, view.vertical_fov, aspect);
        let tan_y = (0.5 * view.vertical_fov).tan() / (1.0 + margin);
        let tan_x = tan_y * aspect;
        let right = unit.right.normalize();
        let up = unit.up.normalize();
        // A corner at offset (x, y, z) in view space (z towards the camera) fits when
        // |x| <= tan_x * (distance - z) and |y| <= tan_y * (distance - z).
        let distance = bounds
            .corners()
            .iter()
            .map(|&corner| {
                let offset = corner - target;
                let z = offset.dot(back);
                let needed_x = offset.dot(right).abs() / tan_x + z;
                let needed_y = offset.dot(up).abs() / tan_y + z;
                needed_x.max(needed_y)
            })
            .fold(f32::MIN_POSITIVE, f32::max);
        Camera::look_at(
            target + back * distance,
            target,
            Vec3::Y,
            view.vertical_fov,
            aspect,
        )
    }

    /// Where rays start.
    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// Where `point` appears in the image: its image coordinates (see [`Camera`];
    /// inside the picture when both are in `[0, 1]`) and its depth along the view
    /// axis. `None` for points at or behind the camera's plane. The inverse of
    /// [`Camera::direction`].
    pub fn project(&self, point: Vec3) -> Option<(Vec2, f32)> {
        let d = point - self.position;
        let depth = d.dot(self.forward);
        // Also rejects NaN.
        if depth.is_nan() || depth <= 0.0 {
            return None;
        }
        let x = d.dot(self.right) / (self.right.length_squared() * depth);
        let y = d.dot(self.up) / (self.up.length_squared() * depth);
        Some((Vec2::new(0.5 * (x + 1.0), 0.5 * (1.0 - y)), depth))
    }

    /// Unnormalised direction of the ray through image point `p` (see [`Camera`]).
    pub fn direction(&self, p: Vec2) -> Vec3 {
        let ndc = Vec2::new(2.0 * p.x - 1.0, 1.0 - 2.0 * p.y);
        self.forward + ndc.x * self.right + ndc.y * self.up
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_of_the_image_looks_at_the_target() {
        let camera = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 1.0);
        let d = camera.direction(Vec2::splat(0.5)).normalize();
        assert!((d - Vec3::NEG_Z).length() < 1e-6);
        // Top of the image is up, left is −X when looking down −Z.
        assert!(camera.direction(Vec2::new(0.5, 0.0)).y > 0.0);
        assert!(camera.direction(Vec2::new(0.0, 0.5)).x < 0.0);
    }

    #[test]
    fn projection_inverts_the_ray_directions() {
        let camera = Camera::look_at(
            Vec3::new(1.0, 2.0, 5.0),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::Y,
            0.7,
            1.5,
        );
        for p in [
            Vec2::new(0.5, 0.5),
            Vec2::new(0.1, 0.8),
            Vec2::new(0.9, 0.3),
        ] {
            let point = camera.position() + 3.0 * camera.direction(p);
            let (uv, depth) = camera.project(point).unwrap();
            assert!((uv - p).abs().max_element() < 1e-5, "{uv} vs {p}");
            assert!((depth - 3.0).abs() < 1e-4, "{depth}");
        }
        assert!(camera.project(camera.position() - camera.forward).is_none());
    }

    #[test]
    fn framing_keeps_every_corner_in_view() {
        let bounds = Bounds {
            min: Vec3::new(-5.0, 0.0, -3.0),
            max: Vec3::new(5.0, 9.0, 4.0),
        };
        let view = ViewAngles {
            azimuth: 0.6,
            elevation: 0.4,
            vertical_fov: 0.6,
        };
        let camera = Camera::framing(&bounds, view, 1.5, 0.0);
        let forward = camera.forward;
        let right = camera.right;
        let up = camera.up;
        let mut touches = false;
        for corner in bounds.corners() {
            let d = corner - camera.position();
            let depth = d.dot(forward);
            let x = d.dot(right) / right.length_squared() / depth;
            let y = d.dot(up) / up.length_squared() / depth;
            assert!(x.abs() <= 1.0 + 1e-4 && y.abs() <= 1.0 + 1e-4, "{x} {y}");
            touches |= x.abs() > 0.999 || y.abs() > 0.999;
        }
        assert!(touches, "framing should be tight");
    }
}
