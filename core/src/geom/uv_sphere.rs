//! Closed latitude–longitude spheres, the procedural mesh of the examples,
//! tests and benchmarks: one home for the grid's index pattern, with each
//! caller choosing the surface (bumps, twists) through the point it places at
//! each grid coordinate.

use alloc::vec::Vec;

/// A closed mesh over the `(rings + 1) × segments` grid of polar angles
/// `θ = π r / rings` and azimuths `φ = 2π s / segments`: vertex
/// `r * segments + s` is `point(θ, φ)`, and each grid quad becomes two
/// triangles, counter-clockwise seen from outside for a sphere-like `point`.
/// The pole rows (`r = 0` and `r = rings`) collapse to a point on a sphere, so
/// the zero-area half of each quad touching them is left out:
/// `2 * (rings - 1) * segments` triangles.
///
/// `rings` and `segments` must be at least 2 and 3 for a closed surface; fewer
/// give a mesh without triangles.
pub fn uv_sphere(
    rings: u32,
    segments: u32,
    mut point: impl FnMut(f32, f32) -> [f32; 3],
) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::new();
    for r in 0..=rings {
        let theta = core::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = core::f32::consts::TAU * s as f32 / segments as f32;
            positions.push(point(theta, phi));
        }
    }
    let mut indices = Vec::new();
    if rings < 2 || segments < 3 {
        return (positions, indices);
    }
    for r in 0..rings {
        for s in 0..segments {
            let a = r * segments + s;
            let b = r * segments + (s + 1) % segments;
            let (c, d) = (a + segments, b + segments);
            if r != 0 {
                indices.extend_from_slice(&[a, c, b]);
            }
            if r != rings - 1 {
                indices.extend_from_slice(&[b, c, d]);
            }
        }
    }
    (positions, indices)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::MeshView;

    #[test]
    fn a_unit_sphere_is_closed_with_outward_winding() {
        let (rings, segments) = (6, 9);
        let (positions, indices) = uv_sphere(rings, segments, |theta, phi| {
            [
                libm::sinf(theta) * libm::cosf(phi),
                libm::sinf(theta) * libm::sinf(phi),
                libm::cosf(theta),
            ]
        });
        let mesh = MeshView::new(&positions, &indices).unwrap();
        assert_eq!(mesh.vertex_count(), ((rings + 1) * segments) as usize);
        assert_eq!(mesh.triangle_count(), (2 * (rings - 1) * segments) as usize);
        // Outward: every triangle's normal points away from the center, and
        // none has zero area.
        let mut volume = 0.0f32;
        for [a, b, c] in mesh.triangles() {
            let n = (b - a).cross(c - a);
            assert!(n.length() > 0.0);
            assert!(n.dot(a + b + c) > 0.0);
            volume += a.dot(b.cross(c)) / 6.0;
        }
        // The inscribed polyhedron's volume, a little under the ball's.
        let ball = 4.0 / 3.0 * core::f32::consts::PI;
        assert!(volume > 0.7 * ball && volume < ball, "{volume}");
    }

    #[test]
    fn too_coarse_grids_have_no_triangles() {
        let point = |_: f32, _: f32| [0.0; 3];
        assert!(uv_sphere(1, 8, point).1.is_empty());
        assert!(uv_sphere(4, 2, point).1.is_empty());
    }
}
