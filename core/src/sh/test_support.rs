//! Test helpers: Gauss–Legendre quadrature, a product rule on the sphere, and
//! proptest strategies for directions, rotations and coefficient vectors.

use alloc::vec::Vec;
use core::f64::consts::PI;

use glam::{Mat3, Quat, Vec3};
use proptest::prelude::*;

use super::MAX_COEFFS;

/// `n`-point Gauss–Legendre rule on [-1, 1] as `(node, weight)`: Newton's method on
/// `P_n` from the usual cosine guesses. Exact for polynomials of degree ≤ 2n - 1.
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let nf = n as f64;
    (0..n)
        .map(|i| {
            let mut x = libm::cos(PI * (i as f64 + 0.75) / (nf + 0.5));
            let mut derivative = 1.0;
            for _ in 0..100 {
                // P_n(x) and P_n'(x) by Bonnet's recurrence.
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let kf = k as f64;
                    (p0, p1) = (p1, ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf);
                }
                let (pn, pn_1) = if n == 0 { (1.0, 0.0) } else { (p1, p0) };
                derivative = nf * (x * pn - pn_1) / (x * x - 1.0);
                let step = pn / derivative;
                x -= step;
                if step.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * derivative * derivative))
        })
        .collect()
}

/// `(direction, weight)` of the product rule: `n` Gauss–Legendre nodes in `cos θ` times
/// `2n` equally spaced `φ`. Integrates every spherical polynomial of degree ≤ 2n - 1
/// exactly; the weights sum to 4π.
pub fn sphere_quadrature(n: usize) -> Vec<(Vec3, f64)> {
    let mut out = Vec::with_capacity(2 * n * n);
    for (z, w) in gauss_legendre(n) {
        let r = libm::sqrt(1.0 - z * z);
        for j in 0..2 * n {
            let phi = PI * (j as f64 + 0.5) / n as f64;
            let dir = Vec3::new(
                (r * libm::cos(phi)) as f32,
                (r * libm::sin(phi)) as f32,
                z as f32,
            );
            out.push((dir, w * PI / n as f64));
        }
    }
    out
}

/// Integral of `f` over [a, b] by an `n`-point Gauss–Legendre rule.
pub fn integrate(a: f64, b: f64, n: usize, f: impl Fn(f64) -> f64) -> f64 {
    let half = 0.5 * (b - a);
    let mid = 0.5 * (b + a);
    gauss_legendre(n)
        .into_iter()
        .map(|(x, w)| w * half * f(mid + half * x))
        .sum()
}

/// The Legendre polynomial `P_l(x)` in f64 (Bonnet's recurrence).
pub fn legendre(l: usize, x: f64) -> f64 {
    let (mut p0, mut p1) = (1.0, x);
    if l == 0 {
        return 1.0;
    }
    for k in 2..=l {
        let kf = k as f64;
        (p0, p1) = (p1, ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf);
    }
    p1
}

/// Unit vectors, roughly uniform.
pub fn unit_vector() -> impl Strategy<Value = Vec3> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
        .prop_map(|(x, y, z)| Vec3::new(x, y, z))
        .prop_filter("away from zero", |v| v.length() > 0.1)
        .prop_map(Vec3::normalize)
}

/// Proper rotations from random unit quaternions.
pub fn rotation() -> impl Strategy<Value = Mat3> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
        .prop_filter("away from zero", |(x, y, z, w)| {
            x * x + y * y + z * z + w * w > 0.01
        })
        .prop_map(|(x, y, z, w)| Mat3::from_quat(Quat::from_xyzw(x, y, z, w).normalize()))
}

/// A full coefficient vector with entries in [-1, 1].
pub fn coefficients() -> impl Strategy<Value = [f32; MAX_COEFFS]> {
    proptest::collection::vec(-1.0f32..1.0, MAX_COEFFS).prop_map(|v| {
        let mut out = [0.0; MAX_COEFFS];
        out.copy_from_slice(&v);
        out
    })
}

#[test]
fn gauss_legendre_integrates_polynomials_exactly() {
    // ∫ x^k over [-1, 1] = 2/(k+1) for even k, 0 for odd.
    for n in [1, 2, 5, 20] {
        let rule = gauss_legendre(n);
        assert!((rule.iter().map(|&(_, w)| w).sum::<f64>() - 2.0).abs() < 1e-13);
        for k in 0..2 * n {
            let got: f64 = rule.iter().map(|&(x, w)| w * libm::pow(x, k as f64)).sum();
            let want = if k % 2 == 0 {
                2.0 / (k as f64 + 1.0)
            } else {
                0.0
            };
            assert!((got - want).abs() < 1e-13, "n={n} k={k}: {got}");
        }
    }
    let total: f64 = sphere_quadrature(8).iter().map(|&(_, w)| w).sum();
    assert!((total - 4.0 * PI).abs() < 1e-12);
}
