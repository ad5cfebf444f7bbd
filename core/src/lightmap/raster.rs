//! Which texels the triangles' UV footprints cover or touch, and the receiver
//! of each: the centre test in exact integer arithmetic, the touched texels by
//! a separating-axis test and the nearest point, in texel units (`f64`).

use alloc::vec::Vec;

use glam::{DVec2, Vec3};

use super::{AtlasError, Coverage, EMPTY, TexelReceiver};
use crate::fallible;
use crate::geom::MeshView;

/// Sub-texel steps of the snapped UVs the centre test uses: a texel centre is
/// `(256 x + 128, 256 y + 128)` in these units.
const SUBTEXEL: i64 = 256;

/// A triangle's footprint in texel units (`u W`, `v H`), counter-clockwise.
struct Footprint {
    /// Corners in texel units, in the mesh's corner order.
    corners: [DVec2; 3],
    /// Twice the signed area (positive when the corners run counter-clockwise).
    double_area: f64,
}

impl Footprint {
    /// Barycentric weights of `p` (any point of the plane).
    fn weights(&self, p: DVec2) -> [f64; 3] {
        let [a, b, c] = self.corners;
        let w1 = (p - a).perp_dot(c - a) / self.double_area;
        let w2 = (b - a).perp_dot(p - a) / self.double_area;
        [1.0 - w1 - w2, w1, w2]
    }

    /// The point of the triangle nearest `p`, as barycentric weights, and its
    /// distance.
    fn nearest(&self, p: DVec2) -> ([f64; 3], f64) {
        let weights = self.weights(p);
        if weights.iter().all(|&w| w >= 0.0) {
            return (weights, 0.0);
        }
        let mut best = ([1.0, 0.0, 0.0], f64::INFINITY);
        for edge in 0..3 {
            let (i, j) = (edge, (edge + 1) % 3);
            let (a, b) = (self.corners[i], self.corners[j]);
            let along = b - a;
            let s = ((p - a).dot(along) / along.length_squared()).clamp(0.0, 1.0);
            let distance = (a + along * s).distance(p);
            if distance < best.1 {
                let mut w = [0.0; 3];
                w[i] = 1.0 - s;
                w[j] = s;
                best = (w, distance);
            }
        }
        best
    }

    /// Whether the triangle and the closed texel square `[x, x + 1] × [y, y + 1]`
    /// share a point: no separating axis among the square's two and the
    /// triangle's three edge normals.
    fn overlaps(&self, x: u32, y: u32) -> bool {
        let lo = DVec2::new(f64::from(x), f64::from(y));
        let square = [lo, lo + DVec2::X, lo + DVec2::Y, lo + DVec2::ONE];
        let axes = [
            DVec2::X,
            DVec2::Y,
            (self.corners[1] - self.corners[0]).perp(),
            (self.corners[2] - self.corners[1]).perp(),
            (self.corners[0] - self.corners[2]).perp(),
        ];
        axes.iter().all(|&axis| {
            let span = |points: &[DVec2]| {
                points
                    .iter()
                    .map(|p| p.dot(axis))
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), d| {
                        (lo.min(d), hi.max(d))
                    })
            };
            let (a_lo, a_hi) = span(&self.corners);
            let (b_lo, b_hi) = span(&square);
            a_lo <= b_hi && b_lo <= a_hi
        })
    }

    /// The texels (inclusive ranges) the footprint's box spans in a
    /// `width × height` atlas.
    fn texel_box(&self, width: u32, height: u32) -> ([u32; 2], [u32; 2]) {
        let lo = self.corners[0].min(self.corners[1]).min(self.corners[2]);
        let hi = self.corners[0].max(self.corners[1]).max(self.corners[2]);
        // UVs are in [0, 1], so these are in [0, side]; `as` saturates.
        let clamp = |t: f64, side: u32| (libm::floor(t) as u32).min(side - 1);
        (
            [clamp(lo.x, width), clamp(hi.x, width)],
            [clamp(lo.y, height), clamp(hi.y, height)],
        )
    }
}

/// Whether a point on an edge of a counter-clockwise triangle, the edge running
/// along `(dx, dy)`, belongs to the triangle: of the two directions an edge
/// between two triangles has, exactly one is owned, so each point on a shared
/// edge (and each shared vertex inside a fan) belongs to exactly one triangle.
fn owns_edge(dx: i64, dy: i64) -> bool {
    dy < 0 || (dy == 0 && dx > 0)
}

/// The receivers of every covered and touched texel, in no particular order.
pub(super) fn receivers(
    mesh: &MeshView<'_>,
    uvs: &[[f32; 2]],
    normals: &[Vec3],
    width: u32,
    height: u32,
) -> Result<Vec<TexelReceiver>, AtlasError> {
    let texels = width as usize * height as usize;
    let mut slots = fallible::filled(EMPTY, texels)?;
    let mut receivers: Vec<TexelReceiver> = Vec::new();
    // Per receiver, its distance from its texel's centre (0 for centres).
    let mut distances: Vec<f64> = Vec::new();
    let scale = DVec2::new(f64::from(width), f64::from(height));
    let footprint = |triangle: usize| {
        let corners = mesh
            .triangle_indices(triangle)
            .map(|v| DVec2::from(uvs[v as usize].map(f64::from)) * scale);
        let double_area = (corners[1] - corners[0]).perp_dot(corners[2] - corners[0]);
        Footprint {
            corners,
            double_area,
        }
    };
    // `shape` is the triangle's footprint: its area in texels gives the
    // texel's world size.
    let receiver = |triangle: usize, shape: &Footprint, weights: [f64; 3], texel, coverage| {
        let indices = mesh.triangle_indices(triangle).map(|v| v as usize);
        let w = weights.map(|w| w.clamp(0.0, 1.0) as f32);
        let sum = w[0] + w[1] + w[2];
        let w = w.map(|w| w / sum);
        let position = indices
            .iter()
            .zip(w)
            .fold(Vec3::ZERO, |p, (&v, w)| p + mesh.position(v) * w);
        let [a, b, c] = mesh.triangle(triangle);
        let cross = (b - a).cross(c - a);
        let geometric = cross.normalize_or_zero();
        let interpolated = indices
            .iter()
            .zip(w)
            .fold(Vec3::ZERO, |n, (&v, w)| {
                n + normals[v].normalize_or_zero() * w
            })
            .normalize_or_zero();
        let normal = if interpolated != Vec3::ZERO {
            interpolated
        } else if geometric != Vec3::ZERO {
            geometric
        } else {
            Vec3::Z
        };
        let world_area = cross.length();
        let texel_area = shape.double_area.abs();
        TexelReceiver {
            texel,
            position,
            normal,
            triangle: triangle as u32,
            barycentric: [w[1], w[2]],
            coverage,
            texel_size: crate::geom::sqrt(f64::from(world_area) / texel_area) as f32,
        }
    };

    // Centres first, so that touched texels are only those no centre claims.
    for triangle in 0..mesh.triangle_count() {
        let shape = footprint(triangle);
        if shape.double_area == 0.0 {
            return Err(AtlasError::DegenerateUv { triangle });
        }
        let mut snapped = shape.corners.map(|p| {
            [
                libm::round(p.x * SUBTEXEL as f64) as i64,
                libm::round(p.y * SUBTEXEL as f64) as i64,
            ]
        });
        let edge = |a: [i64; 2], b: [i64; 2], p: [i64; 2]| {
            (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        };
        let area = edge(snapped[0], snapped[1], snapped[2]);
        if area == 0 {
            // Thinner than the snapping: no centre inside; touched texels below.
            continue;
        }
        if area < 0 {
            snapped.swap(1, 2);
        }
        let (xs, ys) = shape.texel_box(width, height);
        for y in ys[0]..=ys[1] {
            for x in xs[0]..=xs[1] {
                let centre = [
                    i64::from(x) * SUBTEXEL + SUBTEXEL / 2,
                    i64::from(y) * SUBTEXEL + SUBTEXEL / 2,
                ];
                let inside = (0..3).all(|k| {
                    let (a, b) = (snapped[k], snapped[(k + 1) % 3]);
                    let e = edge(a, b, centre);
                    e > 0 || (e == 0 && owns_edge(b[0] - a[0], b[1] - a[1]))
                });
                if !inside {
                    continue;
                }
                let slot = &mut slots[y as usize * width as usize + x as usize];
                if *slot != EMPTY {
                    return Err(AtlasError::Overlap {
                        first: receivers[*slot as usize].triangle as usize,
                        second: triangle,
                        texel: [x, y],
                    });
                }
                let point = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                *slot = receivers.len() as u32;
                fallible::push(
                    &mut receivers,
                    receiver(
                        triangle,
                        &shape,
                        shape.weights(point),
                        [x, y],
                        Coverage::Centre,
                    ),
                )?;
                fallible::push(&mut distances, 0.0)?;
            }
        }
    }

    // Then every texel a footprint overlaps without a centre: the nearest
    // triangle's nearest point.
    for triangle in 0..mesh.triangle_count() {
        let shape = footprint(triangle);
        let (xs, ys) = shape.texel_box(width, height);
        for y in ys[0]..=ys[1] {
            for x in xs[0]..=xs[1] {
                let slot = &mut slots[y as usize * width as usize + x as usize];
                if *slot != EMPTY && receivers[*slot as usize].coverage == Coverage::Centre {
                    continue;
                }
                if !shape.overlaps(x, y) {
                    continue;
                }
                let centre = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                let (weights, distance) = shape.nearest(centre);
                let touched = receiver(triangle, &shape, weights, [x, y], Coverage::Touched);
                if *slot == EMPTY {
                    *slot = receivers.len() as u32;
                    fallible::push(&mut receivers, touched)?;
                    fallible::push(&mut distances, distance)?;
                } else if distance < distances[*slot as usize] {
                    receivers[*slot as usize] = touched;
                    distances[*slot as usize] = distance;
                }
            }
        }
    }
    Ok(receivers)
}
