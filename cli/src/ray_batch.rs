//! Batches of random rays against a mesh, in named classes, for benchmarking and
//! cross-checking ray casters.

use antumbra_core::Ray;
use glam::{Vec2, Vec3};

use crate::mesh::TriangleMesh;
use crate::sampling::{SampleRng, uniform_sphere};

/// A kind of query ray, to report results per kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayClass {
    /// From a sphere around the mesh towards a random point of its bounding box,
    /// unbounded: camera-like rays, about half of them hit.
    Inbound,
    /// From a random point on a random triangle in a uniformly random direction,
    /// `t_min = 0`, half unbounded and half limited to a tenth of the diagonal:
    /// shadow and occlusion rays leaving a surface.
    FromSurface,
    /// From outside straight at a mesh vertex: hits land exactly on shared
    /// vertices, where the watertight test must resolve ties.
    AtVertex,
    /// From outside at the midpoint of a triangle edge: hits on shared edges.
    AtEdge,
    /// Like `FromSurface` (unbounded), with the direction scaled to 1000 times the
    /// bounding-box diagonal, so every hit has a tiny `t`: checks that `t` is in
    /// units of the direction's length (as the core documents) with no absolute
    /// epsilon anywhere.
    LongDirection,
}

impl RayClass {
    /// The classes `verify` uses: all of them.
    pub const ALL: [RayClass; 5] = [
        RayClass::Inbound,
        RayClass::FromSurface,
        RayClass::AtVertex,
        RayClass::AtEdge,
        RayClass::LongDirection,
    ];

    /// The classes `bench` uses: the workloads renderers produce.
    pub const WORKLOAD: [RayClass; 2] = [RayClass::Inbound, RayClass::FromSurface];

    /// Short name for tables.
    pub fn name(self) -> &'static str {
        match self {
            RayClass::Inbound => "inbound",
            RayClass::FromSurface => "from surface",
            RayClass::AtVertex => "at vertex",
            RayClass::AtEdge => "at edge",
            RayClass::LongDirection => "long direction",
        }
    }
}

/// `count` rays split evenly over `classes` (in that order), reproducible from `seed`.
pub fn random_rays(
    mesh: &TriangleMesh,
    classes: &[RayClass],
    count: usize,
    seed: u64,
) -> Vec<(RayClass, Ray)> {
    let mut rng = SampleRng::new(seed);
    let bounds = mesh.bounds();
    let center = bounds.center();
    let radius = 0.5 * bounds.diagonal().max(f32::MIN_POSITIVE);
    let view = mesh.view();
    let outside = |rng: &mut SampleRng| center + 1.5 * radius * uniform_sphere(rng.next_vec2());
    (0..count)
        .map(|i| {
            let class = classes[i * classes.len() / count];
            let ray = match class {
                RayClass::Inbound => {
                    let origin = outside(&mut rng);
                    let target = bounds.min
                        + bounds.size() * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                    Ray::new(origin, target - origin, f32::INFINITY)
                }
                RayClass::FromSurface => {
                    let [a, b, c] = view.triangle(rng.below(view.triangle_count()));
                    let origin = point_in_triangle(a, b, c, rng.next_vec2());
                    let direction = uniform_sphere(rng.next_vec2());
                    let t_max = if i % 2 == 0 {
                        f32::INFINITY
                    } else {
                        0.2 * radius
                    };
                    Ray::new(origin, direction, t_max)
                }
                RayClass::AtVertex => {
                    let origin = outside(&mut rng);
                    let target = view.position(rng.below(view.vertex_count()));
                    // The vertex is at t = 1, inside the unbounded interval.
                    Ray::new(origin, target - origin, f32::INFINITY)
                }
                RayClass::LongDirection => {
                    let [a, b, c] = view.triangle(rng.below(view.triangle_count()));
                    let origin = point_in_triangle(a, b, c, rng.next_vec2());
                    let direction = uniform_sphere(rng.next_vec2()) * (2000.0 * radius);
                    Ray::new(origin, direction, f32::INFINITY)
                }
                RayClass::AtEdge => {
                    let triangle = view.triangle(rng.below(view.triangle_count()));
                    let k = rng.below(3);
                    let target = 0.5 * (triangle[k] + triangle[(k + 1) % 3]);
                    let origin = outside(&mut rng);
                    Ray::new(origin, target - origin, f32::INFINITY)
                }
            };
            (class, ray)
        })
        .collect()
}

/// A uniformly distributed point of triangle `(a, b, c)` from a uniform point of the square.
fn point_in_triangle(a: Vec3, b: Vec3, c: Vec3, u: Vec2) -> Vec3 {
    let (mut s, mut t) = (u.x, u.y);
    if s + t > 1.0 {
        (s, t) = (1.0 - s, 1.0 - t);
    }
    a + s * (b - a) + t * (c - a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes_are_split_evenly_and_rays_are_valid() {
        let mesh = crate::builtin::teapot().unwrap();
        let rays = random_rays(&mesh, &RayClass::ALL, 500, 3);
        assert_eq!(rays.len(), 500);
        for class in RayClass::ALL {
            assert_eq!(rays.iter().filter(|(c, _)| *c == class).count(), 100);
        }
        assert!(rays.iter().all(|(_, ray)| ray.is_valid()));
        assert_eq!(rays, random_rays(&mesh, &RayClass::ALL, 500, 3));
    }
}
