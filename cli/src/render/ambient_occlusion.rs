//! Ambient occlusion: the cosine-weighted fraction of the hemisphere above a point
//! from which no geometry is seen within a maximum distance.

use antumbra_core::{Frame, Ray, RayCaster};
use glam::{Vec2, Vec3};

use super::{RenderSettings, camera_ray, render_pixels};
use crate::bounds::Bounds;
use crate::camera::Camera;
use crate::picture::HdrImage;
use crate::sampling::{R2Sequence, cosine_hemisphere};
use crate::scene::Scene;

/// Ambient occlusion seen through a camera: each pixel is the unoccluded fraction
/// (1 = open sky, 0 = fully enclosed), as a grey value. Rays that miss the scene
/// see open sky (1).
#[derive(Clone, Copy, Debug)]
pub struct AmbientOcclusion {
    /// Occluders farther than this (world units) do not count.
    pub max_distance: f32,
}

/// Seed of the picture's random numbers.
const SEED: u64 = 0xA0;

impl AmbientOcclusion {
    /// The usual setting for an object of these bounds: occluders count up to half
    /// its diagonal, enough for creases, self-shadowing and a contact shadow
    /// while distant ground stays open.
    pub fn for_object(bounds: &Bounds) -> Self {
        AmbientOcclusion {
            max_distance: 0.5 * bounds.diagonal(),
        }
    }

    /// Renders the picture: per sample, a primary ray (closest hit) through a
    /// random point of the pixel and one cosine-distributed occlusion ray from the
    /// surface it reaches.
    pub fn render(&self, scene: &Scene, camera: &Camera, settings: &RenderSettings) -> HdrImage {
        let epsilon = scene.ray_epsilon();
        render_pixels(settings, "ambient occlusion", SEED, |x, y, rng| {
            let directions = R2Sequence::new(rng.next_vec2());
            let mut open = 0u32;
            for s in 0..settings.samples {
                let ray = camera_ray(camera, settings, x, y, rng);
                let escapes = match scene.intersect(&ray) {
                    None => true,
                    Some(surface) => ambient_ray_escapes(
                        scene.caster(),
                        surface.position + epsilon * surface.geometric_normal,
                        surface.shading_normal,
                        directions.point(s),
                        self.max_distance,
                    ),
                };
                open += u32::from(escapes);
            }
            Vec3::splat(open as f32 / settings.samples.max(1) as f32)
        })
    }
}

/// Casts one cosine-distributed ray from `origin` around the unit `normal`, the
/// direction chosen by the uniform point `u`; true when nothing is hit within
/// `max_distance`.
pub fn ambient_ray_escapes(
    caster: &impl RayCaster,
    origin: Vec3,
    normal: Vec3,
    u: Vec2,
    max_distance: f32,
) -> bool {
    let direction = Frame::from_normal(normal).to_world(cosine_hemisphere(u));
    // The direction is unit length, so t is a distance.
    !caster.occluded(&Ray::new(origin, direction, max_distance))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriangleMesh;
    use crate::sampling::SampleRng;
    use antumbra_core::BruteForceCaster;

    #[test]
    fn a_point_in_a_right_angle_corner_sees_half_the_weighted_hemisphere() {
        // A wall (the x = 0 plane, y >= 0) next to the floor point at the origin
        // blocks all directions with x < 0: half of the cosine-weighted hemisphere.
        let wall = TriangleMesh::new(
            "wall",
            vec![[0.0, 0.0, -1e3], [0.0, 0.0, 1e3], [0.0, 1e3, 0.0]],
            vec![0, 1, 2],
        )
        .unwrap();
        let caster = BruteForceCaster::new(wall.view());
        let mut rng = SampleRng::new(1);
        let n = 20_000;
        let open = (0..n)
            .filter(|_| {
                ambient_ray_escapes(
                    &caster,
                    Vec3::new(1e-3, 1e-3, 0.0),
                    Vec3::Y,
                    rng.next_vec2(),
                    f32::INFINITY,
                )
            })
            .count();
        let fraction = open as f32 / n as f32;
        assert!((fraction - 0.5).abs() < 0.02, "{fraction}");
    }
}
