//! Importance sampling of an environment map: directions are drawn with a
//! density proportional to each texel's luminance times its solid angle, so the
//! few texels of a sun, which carry most of the light, get most of the samples.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::{EnvironmentMap, equirect};
use crate::sampling::Distribution2D;
use crate::tonemap::luminance;

/// Draws directions from an [`EnvironmentMap`] in proportion to its brightness.
#[derive(Clone, Debug)]
pub struct EnvironmentSampler {
    distribution: Distribution2D,
}

impl EnvironmentSampler {
    /// Tabulates `luminance × sin θ` over the texels of `env` (the `sin θ` turns the
    /// density over the image into one over solid angle without favouring the poles).
    pub fn new(env: &EnvironmentMap) -> Self {
        let image = env.image();
        let (width, height) = (image.width(), image.height());
        let mut weights = Vec::with_capacity(width * height);
        for row in 0..height {
            let sin_theta = (PI * (row as f32 + 0.5) / height as f32).sin();
            weights.extend((0..width).map(|column| luminance(image.get(column, row)) * sin_theta));
        }
        EnvironmentSampler {
            distribution: Distribution2D::new(&weights, width, height),
        }
    }

    /// A direction and its density in solid angle (steradian⁻¹), from a uniform
    /// point in `[0, 1)²`. The density is 0 only at the poles, where the
    /// caller must skip the sample.
    pub fn sample(&self, u: Vec2) -> (Vec3, f32) {
        let (uv, density_uv) = self.distribution.sample(u);
        let direction = equirect::uv_to_direction(uv);
        (direction, solid_angle_density(density_uv, uv.y))
    }

    /// Density in solid angle with which [`sample`](Self::sample) returns `direction`.
    pub fn density(&self, direction: Vec3) -> f32 {
        let uv = equirect::direction_to_uv(direction);
        solid_angle_density(self.distribution.density(uv), uv.y)
    }
}

/// Converts a density over the unit square of `(u, v)` to one over solid angle:
/// `dω = 2π² sin θ du dv` with `θ = π v`.
fn solid_angle_density(density_uv: f32, v: f32) -> f32 {
    let sin_theta = (PI * v).sin();
    if sin_theta <= 0.0 {
        0.0
    } else {
        density_uv / (2.0 * PI * PI * sin_theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::picture::HdrImage;
    use crate::sampling::{SampleRng, uniform_sphere};

    #[test]
    fn density_integrates_to_one_over_the_sphere() {
        let env = EnvironmentMap::decode("sunrise", crate::builtin::SUNRISE_EXR).unwrap();
        let sampler = EnvironmentSampler::new(&env);
        // E[1 / p(ω)] over ω ~ p is the sphere's area, 4π; and E_uniform[p] · 4π = 1.
        let mut rng = SampleRng::new(2);
        let n = 200_000;
        let mut inverse = 0.0f64;
        let mut disagreements = 0;
        for _ in 0..n {
            let (direction, density) = sampler.sample(rng.next_vec2());
            assert!((direction.length() - 1.0).abs() < 1e-4);
            // A sample on a texel border may round into the neighbour; that must be rare.
            let again = sampler.density(direction);
            if (again - density).abs() > 1e-3 * density.max(1.0) {
                disagreements += 1;
            }
            inverse += 1.0 / f64::from(density);
        }
        assert!(
            disagreements < n / 1000,
            "{disagreements} densities disagree"
        );
        let area = inverse / f64::from(n);
        assert!(
            (area / (4.0 * std::f64::consts::PI) - 1.0).abs() < 0.05,
            "{area}"
        );
    }

    #[test]
    fn estimates_the_mean_radiance_of_a_constant_map() {
        let mut image = HdrImage::new(64, 32);
        image.fill(Vec3::splat(0.5));
        let env = EnvironmentMap::from_image(image);
        let sampler = EnvironmentSampler::new(&env);
        let mut rng = SampleRng::new(4);
        let n = 20_000;
        let mut irradiance_up = 0.0f64;
        for _ in 0..n {
            let (d, density) = sampler.sample(rng.next_vec2());
            irradiance_up += f64::from(env.radiance(d).x * d.y.max(0.0) / density);
        }
        // Irradiance of a constant sky L on an upward plane: π L.
        let mean = irradiance_up / f64::from(n);
        assert!(
            (mean / (std::f64::consts::PI * 0.5) - 1.0).abs() < 0.03,
            "{mean}"
        );
        // And the density of a constant map is uniform: 1 / 4π.
        let d = sampler.density(uniform_sphere(Vec2::new(0.3, 0.6)));
        assert!((d * 4.0 * PI - 1.0).abs() < 0.05, "{d}");
    }
}
