//! Procedural scenes and ray sets for cross-checks.

use antumbra_core::Ray;
use glam::Vec3;
use rand::{Rng, rngs::SmallRng};

use crate::data::Mesh;

/// `triangles` random triangles of edge length up to about `size` inside the cube
/// `[-1, 1]^3`: many intersecting, overlapping and sliver triangles.
pub fn triangle_soup(rng: &mut SmallRng, triangles: usize, size: f32) -> Mesh {
    let mut mesh = Mesh::default();
    for t in 0..triangles {
        let center = random_in_cube(rng, 1.0);
        for _ in 0..3 {
            let corner = center + random_in_cube(rng, size * 0.5);
            mesh.positions.push(corner.to_array());
        }
        let base = 3 * t as u32;
        mesh.indices.extend_from_slice(&[base, base + 1, base + 2]);
    }
    mesh
}

/// A point uniformly inside `[-half, half]^3`.
pub fn random_in_cube(rng: &mut SmallRng, half: f32) -> Vec3 {
    Vec3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

/// A uniformly distributed unit vector.
pub fn random_unit(rng: &mut SmallRng) -> Vec3 {
    loop {
        let v = random_in_cube(rng, 1.0);
        let l2 = v.length_squared();
        if l2 > 1e-4 && l2 <= 1.0 {
            return v / l2.sqrt();
        }
    }
}

/// A mix of the rays the algorithms cast, for a mesh with the given bounds:
/// - from outside the bounds toward random points inside (camera-like, unbounded);
/// - from random points on triangles, offset along the normal, in random directions
///   with a finite length (ambient-occlusion-like, the common query);
/// - segments that end anywhere from well before to past their target.
///
/// Directions have random lengths: `t` is in units of the direction.
pub fn mixed_rays(rng: &mut SmallRng, mesh: &Mesh, count: usize) -> Vec<Ray> {
    rays_of_kinds(rng, mesh, count, &[0, 1, 3])
}

/// Rays aimed exactly at vertices and edge midpoints from outside the bounds: the
/// adversarial cases where rounding decides which triangle, if any, is hit (a
/// silhouette vertex touched from outside may count either way).
pub fn vertex_and_edge_rays(rng: &mut SmallRng, mesh: &Mesh, count: usize) -> Vec<Ray> {
    rays_of_kinds(rng, mesh, count, &[2])
}

fn rays_of_kinds(rng: &mut SmallRng, mesh: &Mesh, count: usize, kinds: &[usize]) -> Vec<Ray> {
    let (lo, hi) = mesh.bounds();
    let center = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let view = mesh.view();
    let mut rays = Vec::with_capacity(count);
    while rays.len() < count {
        let scale = rng.random_range(0.5..3.0);
        let ray = match kinds[rays.len() % kinds.len()] {
            0 => {
                let origin = center + random_unit(rng) * radius * rng.random_range(1.2..3.0);
                let target = center + random_in_cube(rng, 1.0) * (hi - lo) * 0.5;
                Ray::new(origin, (target - origin) * scale, f32::INFINITY)
            }
            1 => {
                let t = rng.random_range(0..view.triangle_count());
                let [a, b, c] = view.triangle(t);
                let (u, v) = (rng.random::<f32>(), rng.random::<f32>());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let point = a + (b - a) * u + (c - a) * v;
                let normal = (b - a).cross(c - a).normalize_or_zero();
                let mut dir = random_unit(rng);
                if dir.dot(normal) < 0.0 {
                    dir = -dir;
                }
                let origin = point + normal * radius * 1e-3;
                Ray::new(
                    origin,
                    dir * scale,
                    radius * rng.random_range(0.05..2.0) / scale,
                )
            }
            2 => {
                let t = rng.random_range(0..view.triangle_count());
                let [a, b, c] = view.triangle(t);
                let target = match rng.random_range(0..4) {
                    0 => a,
                    1 => (a + b) * 0.5,
                    2 => (b + c) * 0.5,
                    _ => (c + a) * 0.5,
                };
                let origin = center + random_unit(rng) * radius * rng.random_range(1.2..3.0);
                Ray::new(origin, (target - origin) * scale, f32::INFINITY)
            }
            _ => {
                let origin = center + random_unit(rng) * radius * rng.random_range(1.2..3.0);
                let target = center + random_in_cube(rng, 1.0) * (hi - lo) * 0.5;
                let dir = target - origin;
                // Segments that stop anywhere from well before to past the target.
                Ray::new(origin, dir * scale, rng.random_range(0.3..1.2) / scale)
            }
        };
        rays.push(ray);
    }
    rays
}
