//! Convolution with zonal (rotationally symmetric) kernels, by the Funk–Hecke
//! theorem: for a kernel `h(n·ω)`,
//!
//! ```text
//! (h ⋆ f)(n) = ∫ h(n·ω) f(ω) dω   has coefficients   A_l f_{l,m},
//! A_l = 2π ∫_{-1}^{1} h(t) P_l(t) dt = √(4π/(2l+1)) z_l,   z_l = ∫ h(ω_z) Y_l^0(ω) dω,
//! ```
//!
//! where `z_l` are the SH coefficients of the kernel turned to point along +z. A
//! [`ZonalKernel`] stores the per-band factors `A_l`. Two kernels are built in: the
//! clamped cosine `max(0, t)` (Ramamoorthi & Hanrahan, "An Efficient Representation
//! for Irradiance Environment Maps", SIGGRAPH 2001: irradiance is radiance convolved
//! with it) and the normalised Phong lobe `((s+1)/2π) max(0, t)^s`, whose integral
//! over the sphere is 1. Both have closed-form factors computed by ratios of small
//! numbers (no factorials, no cancellation), for any band.

use glam::Vec3;

use super::{MAX_BANDS, Sh, eval_basis};

use core::f64::consts::PI;

/// `A_l` of the clamped cosine `max(0, t)`, for any `l`:
///
/// ```text
/// A_0 = π,  A_1 = 2π/3,  A_l = 0 for odd l > 1,
/// A_l = 2π (-1)^(l/2 - 1) / ((l + 2)(l - 1)) · C(l, l/2) / 2^l   for even l,
/// ```
///
/// that is π, 2π/3, π/4, 0, -π/24, 0, π/64 for l = 0..6. The central binomial over
/// `2^l` is the product `Π_{k=1}^{l/2} (2k-1)/(2k)`, which never overflows.
pub const fn clamped_cosine_factor(l: usize) -> f64 {
    if l == 1 {
        return 2.0 * PI / 3.0;
    }
    if l % 2 == 1 {
        return 0.0;
    }
    let mut central = 1.0;
    let mut k = 1;
    while k <= l / 2 {
        central *= (2 * k - 1) as f64 / (2 * k) as f64;
        k += 1;
    }
    let sign = if (l / 2) % 2 == 1 { 1.0 } else { -1.0 };
    // (l + 2)(l - 1) is -2 at l = 0, which with the sign gives A_0 = π.
    let denom = (l as f64 + 2.0) * (l as f64 - 1.0);
    2.0 * PI * sign / denom * central
}

/// `A_l` of the normalised Phong lobe `((s+1)/2π) max(0, t)^s`, exponent `s ≥ 0`:
///
/// ```text
/// A_l = (s+1) ∫_0^1 t^s P_l(t) dt,
/// A_0 = 1,  A_1 = (s+1)/(s+2),  A_l = A_{l-2} (s - l + 2)/(s + l + 1).
/// ```
///
/// The recurrence follows from integrating `t^s` against Bonnet's recurrence by
/// parts; every step multiplies by a ratio of moderate numbers, so it is accurate
/// for any `s` and `l`. At `s = 1` this is the clamped cosine divided by π; as
/// `s → ∞`, `A_l → 1` (a delta function).
pub fn phong_factor(l: usize, exponent: f64) -> f64 {
    let s = exponent;
    let mut a = if l.is_multiple_of(2) {
        1.0
    } else {
        (s + 1.0) / (s + 2.0)
    };
    let mut k = 2 + l % 2;
    while k <= l {
        let kf = k as f64;
        a *= (s - kf + 2.0) / (s + kf + 1.0);
        k += 2;
    }
    a
}

/// The per-band factors `A_l` of a zonal kernel (see the module docs): convolving
/// `f` with it multiplies band `l` of `f` by `A_l` ([`Sh::convolved`]).
///
/// Bands at or beyond [`MAX_BANDS`] are not stored (their factor reads as 0).
///
/// ```
/// use antumbra_core::sh::{Sh9, ZonalKernel};
/// use antumbra_core::glam::Vec3;
///
/// // Irradiance from constant radiance 1 is π.
/// let radiance = Sh9::new([2.0 * core::f32::consts::PI.sqrt(), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
/// let irradiance = radiance.convolved(&ZonalKernel::clamped_cosine());
/// assert!((irradiance.eval(Vec3::Z) - core::f32::consts::PI).abs() < 1e-5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZonalKernel {
    factors: [f32; MAX_BANDS],
}

impl ZonalKernel {
    /// The delta kernel: every factor 1, convolution changes nothing.
    pub const IDENTITY: Self = ZonalKernel {
        factors: [1.0; MAX_BANDS],
    };

    /// The clamped cosine `max(0, n·ω)`: radiance convolved with it is irradiance
    /// (factors [`clamped_cosine_factor`]).
    pub const fn clamped_cosine() -> Self {
        let mut factors = [0.0; MAX_BANDS];
        let mut l = 0;
        while l < MAX_BANDS {
            factors[l] = clamped_cosine_factor(l) as f32;
            l += 1;
        }
        ZonalKernel { factors }
    }

    /// The normalised Phong lobe `((s+1)/2π) max(0, n·ω)^s` (factors
    /// [`phong_factor`]); `None` unless `exponent` is finite and `≥ 0`.
    pub fn phong(exponent: f32) -> Option<Self> {
        if !(exponent.is_finite() && exponent >= 0.0) {
            return None;
        }
        let mut factors = [0.0; MAX_BANDS];
        for (l, factor) in factors.iter_mut().enumerate() {
            *factor = phong_factor(l, f64::from(exponent)) as f32;
        }
        Some(ZonalKernel { factors })
    }

    /// From the kernel's own zonal SH coefficients `z_l = ∫ h(ω_z) Y_l^0(ω) dω`
    /// (the coefficient at index `l(l+1)` of the kernel pointing along +z), one per
    /// band: `A_l = √(4π/(2l+1)) z_l`. Missing bands are 0, extra ones ignored.
    pub fn from_zonal_coeffs(zonal: &[f32]) -> Self {
        let mut factors = [0.0; MAX_BANDS];
        for (l, (factor, z)) in factors.iter_mut().zip(zonal).enumerate() {
            *factor = (crate::geom::sqrt(4.0 * PI / (2 * l + 1) as f64) * f64::from(*z)) as f32;
        }
        ZonalKernel { factors }
    }

    /// From the factors `A_l` themselves. Missing bands are 0, extra ones ignored.
    pub fn from_factors(factors: &[f32]) -> Self {
        let mut out = [0.0; MAX_BANDS];
        for (o, f) in out.iter_mut().zip(factors) {
            *o = *f;
        }
        ZonalKernel { factors: out }
    }

    /// `A_l`; 0 for `l ≥ MAX_BANDS`.
    #[inline]
    pub fn factor(&self, l: usize) -> f32 {
        self.factors.get(l).copied().unwrap_or(0.0)
    }

    /// All stored factors, `A_0 ..= A_7`.
    #[inline]
    pub fn factors(&self) -> [f32; MAX_BANDS] {
        self.factors
    }

    /// The SH coefficients of the kernel pointing along the unit vector `axis`,
    /// `h(axis·ω)`: `c_{l,m} = A_l Y_l^m(axis)` (Funk–Hecke applied to `Y_l^m`). For the
    /// clamped cosine this is the unshadowed diffuse transfer vector of a normal.
    #[inline]
    pub fn along<const N: usize>(&self, axis: Vec3) -> Sh<N> {
        let mut coeffs = eval_basis::<N>(axis);
        for l in 0..Sh::<N>::BANDS {
            for c in &mut coeffs[l * l..(l + 1) * (l + 1)] {
                *c *= self.factors[l];
            }
        }
        Sh { coeffs }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Frame;
    use crate::sh::test_support::{coefficients, gauss_legendre, integrate, legendre, unit_vector};
    use crate::sh::{Sh64, sh_index};
    use alloc::vec::Vec;
    use proptest::prelude::*;

    #[test]
    fn clamped_cosine_matches_the_published_table() {
        let table = [
            PI,
            2.0 * PI / 3.0,
            PI / 4.0,
            0.0,
            -PI / 24.0,
            0.0,
            PI / 64.0,
        ];
        for (l, want) in table.into_iter().enumerate() {
            assert!((clamped_cosine_factor(l) - want).abs() < 1e-15, "{l}");
        }
    }

    #[test]
    fn clamped_cosine_formula_matches_integration_for_many_bands() {
        for l in 0..30 {
            // t P_l(t) is a polynomial of degree ≤ 31: 32 nodes are exact.
            let numeric = 2.0 * PI * integrate(0.0, 1.0, 32, |t| t * legendre(l, t));
            assert!(
                (clamped_cosine_factor(l) - numeric).abs() < 1e-13,
                "{l}: {} vs {numeric}",
                clamped_cosine_factor(l)
            );
        }
    }

    #[test]
    fn phong_matches_integration() {
        for s in [0.0, 0.5, 1.0, 2.5, 7.0, 20.0, 64.0, 300.0] {
            for l in 0..12 {
                let numeric =
                    (s + 1.0) * integrate(0.0, 1.0, 400, |t| libm::pow(t, s) * legendre(l, t));
                let closed = phong_factor(l, s);
                assert!(
                    (closed - numeric).abs() < 1e-7,
                    "s={s} l={l}: {closed} vs {numeric}"
                );
            }
        }
    }

    #[test]
    fn phong_one_is_the_clamped_cosine_over_pi_and_sharp_lobes_tend_to_delta() {
        let cosine = ZonalKernel::clamped_cosine();
        let phong = ZonalKernel::phong(1.0).unwrap();
        for l in 0..MAX_BANDS {
            assert!((phong.factor(l) - cosine.factor(l) / core::f32::consts::PI).abs() < 1e-7);
        }
        let sharp = ZonalKernel::phong(1e6).unwrap();
        for l in 0..MAX_BANDS {
            assert!((sharp.factor(l) - 1.0).abs() < 1e-4);
        }
        assert_eq!(ZonalKernel::phong(-0.5), None);
        assert_eq!(ZonalKernel::phong(f32::NAN), None);
        assert_eq!(ZonalKernel::phong(f32::INFINITY), None);
    }

    /// `(direction, weight)` covering the hemisphere `axis·ω ≥ 0`: Gauss–Legendre in
    /// `t = axis·ω` times uniform azimuth around `axis`. Exact for polynomials in ω of
    /// degree ≤ 2n - 1 on that hemisphere, so a clamped-cosine integrand (a polynomial
    /// there) is integrated exactly.
    fn hemisphere_quadrature(axis: Vec3, n: usize) -> Vec<(Vec3, f64)> {
        let frame = Frame::from_normal(axis);
        let mut out = Vec::new();
        for (x, w) in gauss_legendre(n) {
            let t = 0.5 * (x + 1.0);
            let r = libm::sqrt(1.0 - t * t);
            for j in 0..2 * n {
                let phi = PI * (j as f64 + 0.5) / n as f64;
                let local = Vec3::new(
                    (r * libm::cos(phi)) as f32,
                    (r * libm::sin(phi)) as f32,
                    t as f32,
                );
                out.push((frame.to_world(local), 0.5 * w * PI / n as f64));
            }
        }
        out
    }

    #[test]
    fn clamped_cosine_along_an_axis_is_its_projection() {
        let kernel = ZonalKernel::clamped_cosine();
        for axis in [
            Vec3::Z,
            Vec3::new(0.48, -0.6, 0.64),
            Vec3::new(-1.0, 2.0, -2.0) / 3.0,
        ] {
            let along = kernel.along::<64>(axis);
            let quad = hemisphere_quadrature(axis, 12);
            let mut projected = [0.0f64; 64];
            for &(d, w) in &quad {
                let y = eval_basis::<64>(d);
                let h = f64::from(axis.dot(d).max(0.0));
                for (p, yi) in projected.iter_mut().zip(y) {
                    *p += w * h * f64::from(yi);
                }
            }
            for i in 0..64 {
                assert!(
                    (f64::from(along[i]) - projected[i]).abs() < 2e-6,
                    "{axis} {i}"
                );
            }
        }
    }

    #[test]
    fn zonal_coefficients_and_factors_agree() {
        // The clamped cosine along +z has z_l = A_l Y_l^0(+z) = A_l √((2l+1)/4π).
        let z: Vec<f32> = (0..MAX_BANDS)
            .map(|l| {
                (clamped_cosine_factor(l) * libm::sqrt((2 * l + 1) as f64 / (4.0 * PI))) as f32
            })
            .collect();
        let along = ZonalKernel::clamped_cosine().along::<64>(Vec3::Z);
        for (l, zl) in z.iter().enumerate() {
            assert!((along[sh_index(l, 0)] - zl).abs() < 1e-6);
        }
        let from_z = ZonalKernel::from_zonal_coeffs(&z);
        for l in 0..MAX_BANDS {
            let want = ZonalKernel::clamped_cosine().factor(l);
            assert!((from_z.factor(l) - want).abs() < 1e-6, "{l}");
        }
        assert_eq!(ZonalKernel::from_zonal_coeffs(&[1.0]).factor(1), 0.0);
        assert_eq!(
            ZonalKernel::from_factors(&[1.0, 2.0]).factors()[..3],
            [1.0, 2.0, 0.0]
        );
        assert_eq!(ZonalKernel::IDENTITY.factor(MAX_BANDS), 0.0);
    }

    proptest! {
        #[test]
        fn convolution_is_the_integral_against_the_kernel(
            c in coefficients(), n in unit_vector(), s in 0.0f32..6.0,
        ) {
            // With integer exponents the integrand is a polynomial on the hemisphere;
            // round s so the quadrature is exact and only rounding remains.
            let s = libm::roundf(s);
            let radiance = Sh64::new(c);
            let quad = hemisphere_quadrature(n, 12);
            let kernels = [
                (ZonalKernel::clamped_cosine(), 1.0, 1.0),
                (ZonalKernel::phong(s).unwrap(), (f64::from(s) + 1.0) / (2.0 * PI), f64::from(s)),
            ];
            for (kernel, scale, power) in kernels {
                let numeric: f64 = quad
                    .iter()
                    .map(|&(d, w)| {
                        w * scale * libm::pow(f64::from(n.dot(d).max(0.0)), power)
                            * f64::from(radiance.eval(d))
                    })
                    .sum();
                let got = f64::from(radiance.convolved(&kernel).eval(n));
                let size: f64 = c.iter().map(|x| f64::from(x.abs())).sum();
                prop_assert!((got - numeric).abs() < 2e-6 * size, "{} vs {}", got, numeric);
            }
        }
    }
}
