//! Direction samplers on the sphere and the hemisphere.

use std::f32::consts::{FRAC_1_PI, PI, TAU};

use glam::{Vec2, Vec3};

/// A cosine-weighted direction around +Z (local frame, z = cos θ), from a uniform
/// point in `[0, 1)²`; its density is [`cosine_hemisphere_pdf`].
///
/// Malley's method: a uniform point on the unit disk (Shirley–Chiu concentric
/// mapping, which keeps strata compact) lifted onto the hemisphere.
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let disk = concentric_disk(u);
    let z = (1.0 - disk.length_squared()).max(0.0).sqrt();
    Vec3::new(disk.x, disk.y, z)
}

/// Density in solid angle of [`cosine_hemisphere`]: `cos θ / π` (0 below the horizon).
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// A uniformly distributed unit vector from a uniform point in `[0, 1)²`.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin_phi, cos_phi) = (TAU * u.y).sin_cos();
    Vec3::new(r * cos_phi, r * sin_phi, z)
}

/// Shirley and Chiu's area-preserving map from the square to the unit disk.
fn concentric_disk(u: Vec2) -> Vec2 {
    let p = 2.0 * u - Vec2::ONE;
    if p == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, theta) = if p.x.abs() > p.y.abs() {
        (p.x, (PI / 4.0) * (p.y / p.x))
    } else {
        (p.y, (PI / 2.0) - (PI / 4.0) * (p.x / p.y))
    };
    let (sin, cos) = theta.sin_cos();
    r * Vec2::new(cos, sin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::SampleRng;

    #[test]
    fn cosine_samples_have_mean_cosine_two_thirds() {
        // E[cos θ] under p(ω) = cos θ / π is ∫ cos² θ / π dω = 2/3.
        let mut rng = SampleRng::new(11);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let d = cosine_hemisphere(rng.next_vec2());
            assert!((d.length() - 1.0).abs() < 1e-5);
            assert!(d.z >= 0.0);
            sum += f64::from(d.z);
        }
        let mean = sum / f64::from(n);
        assert!((mean - 2.0 / 3.0).abs() < 0.005, "mean cos θ = {mean}");
    }

    #[test]
    fn cosine_samples_are_balanced_around_the_axis() {
        let mut rng = SampleRng::new(5);
        let n = 100_000;
        let sum: Vec3 = (0..n).map(|_| cosine_hemisphere(rng.next_vec2())).sum();
        let mean = sum / n as f32;
        assert!(mean.x.abs() < 0.01 && mean.y.abs() < 0.01, "{mean}");
    }

    #[test]
    fn uniform_sphere_is_unit_and_centred() {
        let mut rng = SampleRng::new(3);
        let n = 100_000;
        let mut sum = Vec3::ZERO;
        for _ in 0..n {
            let d = uniform_sphere(rng.next_vec2());
            assert!((d.length() - 1.0).abs() < 1e-5);
            sum += d;
        }
        assert!((sum / n as f32).length() < 0.01);
    }
}
