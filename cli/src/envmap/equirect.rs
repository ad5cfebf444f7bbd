//! The equirectangular (latitude–longitude) mapping between directions and image
//! coordinates, used for every environment map the command reads or writes.
//!
//! Convention (matching the +Y-up OBJ data):
//!
//! - `v` runs from 0 at the top row, straight up (+Y), to 1 at the bottom row,
//!   straight down (−Y): `v = acos(y) / π`.
//! - `u` runs left to right around the vertical axis:
//!   `u = 0.5 + atan2(z, x) / (2π)`. So `u = 0` (and 1) looks along −X, `u = 0.25`
//!   along −Z, `u = 0.5` (the image centre) along +X and `u = 0.75` along +Z.
//!
//! Standing inside the sphere with +Y up and facing −Z (`u = 0.25`), +X
//! (`u = 0.5`) is on the right: `u` grows to the right as in any panorama viewer,
//! so images are not mirrored. A texel `(column, row)` of a `w × h` image covers
//! `u ∈ [column/w, (column+1)/w)`, `v ∈ [row/h, (row+1)/h)`.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

/// `(u, v)` in `[0, 1]²` of a direction (any non-zero length).
pub fn direction_to_uv(direction: Vec3) -> Vec2 {
    let d = direction.normalize();
    let u = 0.5 + d.z.atan2(d.x) / TAU;
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    Vec2::new(u, v)
}

/// The unit direction at `(u, v)`; the inverse of [`direction_to_uv`].
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    let phi = (uv.x - 0.5) * TAU;
    let theta = uv.y * PI;
    let (sin_theta, cos_theta) = theta.sin_cos();
    let (sin_phi, cos_phi) = phi.sin_cos();
    Vec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi)
}

/// The texel `(column, row)` holding `uv` in a `width × height` image; `u` wraps
/// around, `v` is clamped to the image.
pub fn uv_to_texel(uv: Vec2, width: usize, height: usize) -> (usize, usize) {
    let column = ((uv.x * width as f32).floor() as isize).rem_euclid(width as isize) as usize;
    let row = ((uv.y * height as f32) as usize).min(height - 1);
    (column, row)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec2, b: Vec2) -> bool {
        (a - b).abs().max_element() < 1e-6
    }

    #[test]
    fn axes_land_where_the_convention_says() {
        assert!((direction_to_uv(Vec3::Y).y - 0.0).abs() < 1e-6);
        assert!((direction_to_uv(-Vec3::Y).y - 1.0).abs() < 1e-6);
        assert!(close(direction_to_uv(Vec3::X), Vec2::new(0.5, 0.5)));
        assert!(close(direction_to_uv(Vec3::Z), Vec2::new(0.75, 0.5)));
        assert!(close(direction_to_uv(-Vec3::Z), Vec2::new(0.25, 0.5)));
        // −X sits on the seam: u is 0 or 1 depending on the sign of z's zero.
        let u = direction_to_uv(-Vec3::X).x;
        assert!(u.abs() < 1e-6 || (u - 1.0).abs() < 1e-6, "{u}");
    }

    #[test]
    fn uv_and_direction_round_trip() {
        for i in 1..40 {
            for j in 1..20 {
                let uv = Vec2::new(i as f32 / 40.0, j as f32 / 20.0);
                let back = direction_to_uv(uv_to_direction(uv));
                assert!(close(uv, back), "{uv} -> {back}");
                let d = uv_to_direction(uv);
                assert!((d.length() - 1.0).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn upper_half_of_the_image_is_the_upper_hemisphere() {
        assert!(uv_to_direction(Vec2::new(0.3, 0.2)).y > 0.0);
        assert!(uv_to_direction(Vec2::new(0.3, 0.8)).y < 0.0);
    }

    #[test]
    fn texel_lookup_wraps_and_clamps() {
        assert_eq!(uv_to_texel(Vec2::new(0.0, 0.0), 8, 4), (0, 0));
        assert_eq!(uv_to_texel(Vec2::new(1.0, 1.0), 8, 4), (0, 3));
        assert_eq!(uv_to_texel(Vec2::new(0.99, 0.5), 8, 4), (7, 2));
        assert_eq!(uv_to_texel(Vec2::new(-0.01, 0.5), 8, 4), (7, 2));
    }
}
