//! Certified geometric predicates for soft shadow volumes: the sign of
//! `orient3d(a, b, c, d) = det[a - d, b - d, c - d]` on `f32` points, by a floating
//! point filter with Shewchuk's forward error bound and an exact fallback in
//! expansion arithmetic (Shewchuk, "Adaptive Precision Floating-Point Arithmetic
//! and Fast Robust Geometric Predicates", 1997; written here from the paper).
//!
//! Exactness: every `f32` is exactly an `f64`; the differences are kept as
//! two-term expansions and every product and sum as a non-overlapping expansion,
//! so the sign is the sign of the true determinant for every finite `f32` input
//! (products of three differences stay below `2^390` and above `2^-610`, far
//! inside `f64`'s range, so nothing overflows or underflows).
//!
//! The exact segment–triangle test [`segment_meets_triangle`] built on it is the
//! oracle the soft shadow results are defined by (and tested against).

use glam::Vec3;

/// Relative error bound of the `f64` determinant evaluated as
/// `((a-d) × (b-d)) · (c-d)` against its permanent (Shewchuk's `o3derrboundA`,
/// `(7 + 56ε)ε`, rounded up generously to `8ε`; `ε = 2^-53`).
pub(crate) const ORIENT_BOUND: f64 = 8.0 * UNIT_ROUNDOFF;

/// `ε = 2^-53`, the unit roundoff of `f64`.
const UNIT_ROUNDOFF: f64 = f64::EPSILON * 0.5;

#[inline]
fn wide(v: Vec3) -> [f64; 3] {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}

/// The sign (`-1`, `0`, `1`) of `det[a - d, b - d, c - d]`, exact for every finite
/// input. Positive when `d` lies below the plane through `a`, `b`, `c` seen
/// counter-clockwise from above, i.e. `((b - a) × (c - a)) · (d - a) < 0`.
pub fn orient3d(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> i32 {
    let (a, b, c, d) = (wide(a), wide(b), wide(c), wide(d));
    let ad = [a[0] - d[0], a[1] - d[1], a[2] - d[2]];
    let bd = [b[0] - d[0], b[1] - d[1], b[2] - d[2]];
    let cd = [c[0] - d[0], c[1] - d[1], c[2] - d[2]];
    let (det, permanent) = det3_with_permanent(ad, bd, cd);
    if det.abs() > ORIENT_BOUND * permanent {
        return if det > 0.0 { 1 } else { -1 };
    }
    orient3d_exact(a, b, c, d)
}

/// `det[x, y, z]` as `(x × y) · z` and its permanent (the same sum with every
/// product taken in absolute value), the quantity [`ORIENT_BOUND`] scales.
#[inline]
pub(crate) fn det3_with_permanent(x: [f64; 3], y: [f64; 3], z: [f64; 3]) -> (f64, f64) {
    let c0 = x[1] * y[2] - x[2] * y[1];
    let c1 = x[2] * y[0] - x[0] * y[2];
    let c2 = x[0] * y[1] - x[1] * y[0];
    let p0 = (x[1] * y[2]).abs() + (x[2] * y[1]).abs();
    let p1 = (x[2] * y[0]).abs() + (x[0] * y[2]).abs();
    let p2 = (x[0] * y[1]).abs() + (x[1] * y[0]).abs();
    (
        c0 * z[0] + c1 * z[1] + c2 * z[2],
        p0 * z[0].abs() + p1 * z[1].abs() + p2 * z[2].abs(),
    )
}

/// The exact sign of `det[a - d, b - d, c - d]` for `f64` inputs that are `f32`
/// values (the range argument of the module docs needs that).
#[cold]
pub(crate) fn orient3d_exact(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> i32 {
    let diff = |p: [f64; 3], i: usize| -> [f64; 2] {
        let (x, y) = two_diff(p[i], d[i]);
        [y, x]
    };
    let (ax, ay, az) = (diff(a, 0), diff(a, 1), diff(a, 2));
    let (bx, by, bz) = (diff(b, 0), diff(b, 1), diff(b, 2));
    let (cx, cy, cz) = (diff(c, 0), diff(c, 1), diff(c, 2));
    // det = ax (by cz - bz cy) + ay (bz cx - bx cz) + az (bx cy - by cx)
    let mut total = Expansion::<TOTAL>::new();
    for (x, (p, q), (r, s)) in [
        (ax, (by, cz), (bz, cy)),
        (ay, (bz, cx), (bx, cz)),
        (az, (bx, cy), (by, cx)),
    ] {
        let mut minor = Expansion::<MINOR>::product(&p, &q);
        let other = Expansion::<PRODUCT>::product(&r, &s);
        minor.subtract(&other);
        let term = minor.times::<TERM>(&x);
        total.add(&term);
    }
    total.sign()
}

/// The sign of the first non-zero component of `(x1 - x0) × (y1 - y0)`, exactly
/// (0 when the product is zero), for `f64` inputs that are `f32` values.
///
/// This is the sign, for every small enough `ε > 0`, of
/// `det[x1 - x0, y1 - y0, ε e₁ + ε² e₂ + ε³ e₃]`: the term a determinant gains
/// when the point in its third column moves by that infinitesimal amount. The
/// soft shadow sweep breaks ties at its start point this way ([`super`] module
/// docs), so that every determinant sees one and the same moved point.
pub(crate) fn cross_sign_sequence(x1: [f64; 3], x0: [f64; 3], y1: [f64; 3], y0: [f64; 3]) -> i32 {
    let diff = |p: [f64; 3], q: [f64; 3], i: usize| -> [f64; 2] {
        let (high, low) = two_diff(p[i], q[i]);
        [low, high]
    };
    for k in 0..3 {
        // (x × y)_k = x_i y_j - x_j y_i
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let mut minor = Expansion::<MINOR>::product(&diff(x1, x0, i), &diff(y1, y0, j));
        let other = Expansion::<PRODUCT>::product(&diff(x1, x0, j), &diff(y1, y0, i));
        minor.subtract(&other);
        let sign = minor.sign();
        if sign != 0 {
            return sign;
        }
    }
    0
}

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let x = a + b;
    let bv = x - a;
    let av = x - bv;
    (x, (a - av) + (b - bv))
}

#[inline]
fn two_diff(a: f64, b: f64) -> (f64, f64) {
    let x = a - b;
    let bv = a - x;
    let av = x + bv;
    (x, (a - av) + (bv - b))
}

#[inline]
fn split(a: f64) -> (f64, f64) {
    // 2^27 + 1: splits a 53-bit significand into two 26-bit halves.
    let c = 134_217_729.0 * a;
    let hi = c - (c - a);
    (hi, a - hi)
}

#[inline]
fn two_product(a: f64, b: f64) -> (f64, f64) {
    let x = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let e = x - ah * bh - al * bh - ah * bl;
    (x, al * bl - e)
}

// Capacities of the determinant's stages, each the most components its inputs
// can produce (GROW-EXPANSION adds at most one component per value grown in,
// SCALE-EXPANSION two per component): a product of two two-term differences
// 2 × 2 × 2 = 8; a minor, a product less another, 16; a minor times a
// difference 2 × 2 × 16 = 64; the sum of three such terms 192. Sized per stage
// so that an exact call zeroes about 1.9 KiB of stack, not 10 × 2 KiB.
const PRODUCT: usize = 8;
const MINOR: usize = 2 * PRODUCT;
const TERM: usize = 2 * 2 * MINOR;
const TOTAL: usize = 3 * TERM;

/// A non-overlapping expansion of at most `C` components, in increasing
/// magnitude, no zeros.
struct Expansion<const C: usize> {
    len: usize,
    terms: [f64; C],
}

impl<const C: usize> Expansion<C> {
    fn new() -> Self {
        Expansion {
            len: 0,
            terms: [0.0; C],
        }
    }

    fn terms(&self) -> &[f64] {
        &self.terms[..self.len]
    }

    /// Adds one `f64` (Shewchuk's GROW-EXPANSION with zero elimination).
    fn grow(&mut self, b: f64) {
        let mut q = b;
        let mut out = 0;
        for i in 0..self.len {
            let (sum, err) = two_sum(q, self.terms[i]);
            q = sum;
            if err != 0.0 {
                self.terms[out] = err;
                out += 1;
            }
        }
        if q != 0.0 {
            self.terms[out] = q;
            out += 1;
        }
        self.len = out;
    }

    fn add<const D: usize>(&mut self, other: &Expansion<D>) {
        for &t in other.terms() {
            self.grow(t);
        }
    }

    fn subtract<const D: usize>(&mut self, other: &Expansion<D>) {
        for &t in other.terms() {
            self.grow(-t);
        }
    }

    /// `self * b` (SCALE-EXPANSION), accumulated into `out`.
    fn scaled(terms: &[f64], b: f64, out: &mut Self) {
        for &t in terms {
            let (x, y) = two_product(t, b);
            out.grow(y);
            out.grow(x);
        }
    }

    fn product(p: &[f64; 2], q: &[f64; 2]) -> Self {
        let mut out = Self::new();
        for &b in q {
            Self::scaled(p, b, &mut out);
        }
        out
    }

    fn times<const D: usize>(&self, q: &[f64; 2]) -> Expansion<D> {
        let mut out = Expansion::<D>::new();
        for &b in q {
            Expansion::<D>::scaled(self.terms(), b, &mut out);
        }
        out
    }

    /// The sign of the sum: the sign of the largest component.
    fn sign(&self) -> i32 {
        match self.terms().last() {
            Some(&t) if t > 0.0 => 1,
            Some(_) => -1,
            None => 0,
        }
    }
}

/// Whether the open segment from `p` to `s` meets the closed triangle `(a, b, c)`,
/// exactly. The rules, shared by every soft shadow result:
///
/// - the segment must cross the triangle's plane at an interior point: `p` and `s`
///   strictly on opposite sides (an endpoint on the plane touches it only at that
///   endpoint, which the open segment excludes);
/// - the crossing point may lie on the triangle's boundary (closed triangle);
/// - a degenerate triangle (collinear corners) and a segment lying in the
///   triangle's plane never meet it, as with the watertight ray test of
///   [`crate::raycast`] (whose determinant is zero there).
pub fn segment_meets_triangle(p: Vec3, s: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let op = orient3d(a, b, c, p);
    let os = orient3d(a, b, c, s);
    if op * os >= 0 {
        return false;
    }
    crossing_in_triangle(p, s, a, b, c)
}

/// The second half of [`segment_meets_triangle`], for a segment already known to
/// have `p` and `s` strictly on opposite sides of the triangle's plane: whether
/// the point where it pierces the plane lies in the closed triangle.
#[inline]
pub(crate) fn crossing_in_triangle(p: Vec3, s: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    // The line p→s pierces the plane; the point is in the closed triangle when
    // the three edge orientations have no strictly opposite signs.
    let e0 = orient3d(p, s, a, b);
    let e1 = orient3d(p, s, b, c);
    let e2 = orient3d(p, s, c, a);
    !((e0 < 0 || e1 < 0 || e2 < 0) && (e0 > 0 || e1 > 0 || e2 > 0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;
    use proptest::prelude::*;

    proptest! {
        /// The first non-zero component of the cross product, against integers
        /// (small values, so every `f32` and product is exact there).
        #[test]
        fn cross_sign_sequence_is_the_first_nonzero_component(
            v in proptest::array::uniform12(-4i64..=4),
        ) {
            let p = |i: usize| [v[i], v[i + 1], v[i + 2]];
            let (x1, x0, y1, y0) = (p(0), p(3), p(6), p(9));
            let x = [x1[0] - x0[0], x1[1] - x0[1], x1[2] - x0[2]];
            let y = [y1[0] - y0[0], y1[1] - y0[1], y1[2] - y0[2]];
            let cross = [
                x[1] * y[2] - x[2] * y[1],
                x[2] * y[0] - x[0] * y[2],
                x[0] * y[1] - x[1] * y[0],
            ];
            let expected = cross.iter().find(|&&c| c != 0).map_or(0, |c| c.signum() as i32);
            let wide = |q: [i64; 3]| q.map(|c| c as f64);
            prop_assert_eq!(
                cross_sign_sequence(wide(x1), wide(x0), wide(y1), wide(y0)),
                expected
            );
        }
    }

    fn det_i128(a: [i64; 3], b: [i64; 3], c: [i64; 3], d: [i64; 3]) -> i32 {
        let v = |p: [i64; 3]| {
            [
                (p[0] - d[0]) as i128,
                (p[1] - d[1]) as i128,
                (p[2] - d[2]) as i128,
            ]
        };
        let (x, y, z) = (v(a), v(b), v(c));
        let det = x[0] * (y[1] * z[2] - y[2] * z[1]) - x[1] * (y[0] * z[2] - y[2] * z[0])
            + x[2] * (y[0] * z[1] - y[1] * z[0]);
        det.signum() as i32
    }

    fn to_vec(p: [i64; 3], scale: f32) -> Vec3 {
        Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) * scale
    }

    fn point(range: i64) -> impl Strategy<Value = [i64; 3]> {
        [-range..=range, -range..=range, -range..=range]
    }

    proptest! {
        // Small integer grids make exact zeros common; a power-of-two scale keeps
        // the values exact in f32 and the sign unchanged, and the huge and tiny
        // scales exercise the far ends of the exponent range.
        #[test]
        fn orient_matches_integer_determinant(
            a in point(8), b in point(8), c in point(8), d in point(8),
            scale_exp in prop::sample::select(vec![-120i32, -30, 0, 30, 100]),
        ) {
            let scale = 2f32.powi(scale_exp);
            let got = orient3d(to_vec(a, scale), to_vec(b, scale), to_vec(c, scale), to_vec(d, scale));
            prop_assert_eq!(got, det_i128(a, b, c, d));
        }

        #[test]
        fn orient_matches_integer_determinant_wide(
            a in point(1 << 23), b in point(1 << 23), c in point(1 << 23), d in point(1 << 23),
        ) {
            let got = orient3d(to_vec(a, 1.0), to_vec(b, 1.0), to_vec(c, 1.0), to_vec(d, 1.0));
            prop_assert_eq!(got, det_i128(a, b, c, d));
        }

        // Points exactly on a plane built from f32 values that the filter cannot
        // certify: the exact path must return 0 and flip with a one-ulp nudge.
        #[test]
        fn exact_fallback_on_nearly_coplanar(x in -1000i64..1000, y in -1000i64..1000) {
            let a = Vec3::new(0.0, 0.0, 0.0);
            let b = Vec3::new(3.0, 1.0, 7.0);
            let c = Vec3::new(1.0, 5.0, 2.0);
            // d = a + x/16 (b - a) + y/16 (c - a): exact in f32 for these ranges.
            let d = (b * x as f32 + c * y as f32) / 16.0;
            prop_assert_eq!(orient3d(a, b, c, d), 0);
            // The plane's normal (-33, 1, 14) has a z component: the nudge leaves it.
            let up = Vec3::new(d.x, d.y, f32::from_bits(d.z.to_bits() + 1));
            prop_assert_ne!(orient3d(a, b, c, up), 0);
        }
    }

    #[test]
    fn segment_rules() {
        let (a, b, c) = (
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        );
        let p = Vec3::new(0.0, 0.0, -1.0);
        assert!(segment_meets_triangle(p, Vec3::new(0.0, 0.0, 1.0), a, b, c));
        // Ends on the plane: the open segment does not reach it.
        assert!(!segment_meets_triangle(
            p,
            Vec3::new(0.0, 0.0, 0.0),
            a,
            b,
            c
        ));
        // Through an edge (closed triangle).
        assert!(segment_meets_triangle(
            Vec3::new(0.0, -1.0, -1.0),
            Vec3::new(0.0, -1.0, 1.0),
            a,
            b,
            c
        ));
        // Just outside.
        assert!(!segment_meets_triangle(
            Vec3::new(0.0, -1.5, -1.0),
            Vec3::new(0.0, -1.5, 1.0),
            a,
            b,
            c
        ));
        // In the plane: never.
        assert!(!segment_meets_triangle(
            Vec3::new(-2.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            a,
            b,
            c
        ));
    }
}
