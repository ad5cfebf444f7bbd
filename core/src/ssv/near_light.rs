//! The band around the light's plane: triangles there are tested against
//! every sample directly, with the sides of axis-aligned planes taken without
//! determinants.

use super::*;

/// The plane of a triangle whose corners share one coordinate exactly
/// (`corner[axis] == value`, a floor or a wall), where `orient3d(a, b, c, p)`
/// needs no determinant: with column `axis` constant (`value - p[axis]`) in
/// `det[a - p, b - p, c - p]`, the determinant is that difference times the
/// triangle's projected 2D orientation, which does not depend on `p`. So the
/// sign is `sign(p[axis] - value)` times `up`, the sign at one point above the
/// plane (exact, taken once). This spares the exact expansion that a receiver
/// lying on such a plane (a floor receiver) would otherwise need.
#[derive(Clone, Copy, Debug)]
pub(super) struct AxisPlane {
    pub(super) axis: usize,
    pub(super) value: f32,
    pub(super) up: i32,
}

impl AxisPlane {
    pub(super) fn of(&[a, b, c]: &[Vec3; 3]) -> Option<AxisPlane> {
        let axis = (0..3).find(|&k| a[k] == b[k] && b[k] == c[k])?;
        let value = a[axis];
        // A representable point strictly above the plane (finite, so that
        // orient3d is exact on it).
        let above = [value + 1.0, value * 2.0, value * 0.5]
            .into_iter()
            .find(|&v| v > value && v.is_finite())?;
        let mut q = a;
        q[axis] = above;
        let up = orient3d(a, b, c, q);
        (up != 0).then_some(AxisPlane { axis, value, up })
    }

    /// `orient3d(a, b, c, p)` for the triangle this was made from.
    #[inline]
    pub(super) fn side(&self, p: Vec3) -> i32 {
        let x = p[self.axis];
        if x > self.value {
            self.up
        } else if x < self.value {
            -self.up
        } else {
            0
        }
    }
}

/// The side of every sample of each triangle's plane, as
/// [`segment_meets_triangle`] computes it (`orient3d(a, b, c, s)`, exact): per
/// triangle `words` words with bit `i` set where sample `i` is strictly above
/// (`> 0`), then `words` words where it is strictly below (`< 0`).
pub(super) fn plane_sides(
    triangles: &[[Vec3; 3]],
    samples: &[Vec3],
    words: usize,
) -> Result<Vec<u64>, OutOfMemory> {
    let mut sides = fallible::filled(0u64, 2 * words * triangles.len())?;
    for (&[a, b, c], side) in triangles.iter().zip(sides.chunks_exact_mut(2 * words)) {
        for (i, &s) in samples.iter().enumerate() {
            match orient3d(a, b, c, s) {
                1 => side[i / 64] |= 1 << (i % 64),
                -1 => side[words + i / 64] |= 1 << (i % 64),
                _ => {}
            }
        }
    }
    Ok(sides)
}
