//! Diffuse surfaces lit by an environment map, with ray-traced visibility.
//!
//! Per sample, one primary ray finds the surface; its outgoing radiance
//! `albedo/π ∫ L(ω) V(ω) cos θ dω` is estimated with two rays combined by multiple
//! importance sampling (Veach 1997, balance heuristic): one from the map's
//! brightness (finds the sun) and one cosine-weighted (finds the broad sky).
//! Pixels that miss the scene show the map itself.

use std::f32::consts::FRAC_1_PI;

use antumbra_core::{Frame, Ray};
use glam::{Vec2, Vec3};

use super::{RenderSettings, camera_ray, render_pixels};
use crate::camera::Camera;
use crate::envmap::{EnvironmentMap, EnvironmentSampler};
use crate::picture::HdrImage;
use crate::sampling::{R2Sequence, cosine_hemisphere, cosine_hemisphere_pdf};
use crate::scene::{Scene, SurfacePoint};

/// Seed of the picture's random numbers.
const SEED: u64 = 0xE0;

/// An environment map and its importance sampler.
pub struct EnvironmentLighting<'a> {
    /// Incoming radiance.
    pub env: &'a EnvironmentMap,
    /// Directions distributed like the map's brightness.
    pub sampler: &'a EnvironmentSampler,
}

impl EnvironmentLighting<'_> {
    /// Renders linear radiance (tone-map it for display).
    pub fn render(&self, scene: &Scene, camera: &Camera, settings: &RenderSettings) -> HdrImage {
        let epsilon = scene.ray_epsilon();
        render_pixels(settings, "environment lighting", SEED, |x, y, rng| {
            let light_points = R2Sequence::new(rng.next_vec2());
            let cosine_points = R2Sequence::new(rng.next_vec2());
            let mut sum = Vec3::ZERO;
            for s in 0..settings.samples {
                let ray = camera_ray(camera, settings, x, y, rng);
                sum += match scene.intersect(&ray) {
                    None => self.env.radiance(ray.direction),
                    Some(surface) => {
                        let origin = surface.position + epsilon * surface.geometric_normal;
                        let incoming = self.light_sample_contribution(
                            scene,
                            &surface,
                            origin,
                            light_points.point(s),
                        ) + self.cosine_sample_contribution(
                            scene,
                            &surface,
                            origin,
                            cosine_points.point(s),
                        );
                        surface.albedo * FRAC_1_PI * incoming
                    }
                };
            }
            sum / settings.samples.max(1) as f32
        })
    }

    /// MIS-weighted `L cos θ / pdf` for a direction drawn from the map.
    fn light_sample_contribution(
        &self,
        scene: &Scene,
        surface: &SurfacePoint,
        origin: Vec3,
        u: Vec2,
    ) -> Vec3 {
        let (direction, light_pdf) = self.sampler.sample(u);
        let cos_theta = surface.shading_normal.dot(direction);
        if light_pdf <= 0.0 || cos_theta <= 0.0 || surface.geometric_normal.dot(direction) <= 0.0 {
            return Vec3::ZERO;
        }
        if scene.occluded(&Ray::new(origin, direction, f32::INFINITY)) {
            return Vec3::ZERO;
        }
        let weight = cos_theta / (light_pdf + cosine_hemisphere_pdf(cos_theta));
        self.env.radiance(direction) * weight
    }

    /// MIS-weighted `L cos θ / pdf` for a cosine-distributed direction.
    fn cosine_sample_contribution(
        &self,
        scene: &Scene,
        surface: &SurfacePoint,
        origin: Vec3,
        u: Vec2,
    ) -> Vec3 {
        let local = cosine_hemisphere(u);
        let direction = Frame::from_normal(surface.shading_normal).to_world(local);
        let cos_theta = local.z;
        if cos_theta <= 0.0 || surface.geometric_normal.dot(direction) <= 0.0 {
            return Vec3::ZERO;
        }
        if scene.occluded(&Ray::new(origin, direction, f32::INFINITY)) {
            return Vec3::ZERO;
        }
        let weight =
            cos_theta / (cosine_hemisphere_pdf(cos_theta) + self.sampler.density(direction));
        self.env.radiance(direction) * weight
    }
}
