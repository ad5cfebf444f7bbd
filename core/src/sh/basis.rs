//! Evaluation of the real SH basis at a unit direction.
//!
//! Two paths compute the same values: closed-form polynomials in `(x, y, z)` for
//! bands 0..=4 (the forms tabulated in Sloan, "Stupid Spherical Harmonics (SH)
//! Tricks", GDC 2008, appendix 2, written for unit vectors) and, for more bands, the
//! fully normalised associated-Legendre recurrence in `z` combined with
//! `(x + iy)^m` for the azimuthal part (so no `atan2`, `acos` or division by `sin θ`
//! is needed, and the poles are regular). The recurrence keeps every intermediate
//! value of the size of the result (no factorials), which is what makes it stable.
//! Every constant is computed at compile time from its closed form.

use glam::Vec3;

use super::{MAX_BANDS, MAX_COEFFS, Sh, ShError, bands_for_len};

use core::f64::consts::PI;

/// `√x` at compile time: Newton's iteration started above the root, which decreases
/// monotonically and stops when it no longer does (within an ulp of the true root).
pub(crate) const fn const_sqrt(x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let mut guess = if x > 1.0 { x } else { 1.0 };
    let mut i = 0;
    while i < 200 {
        let next = 0.5 * (guess + x / guess);
        if next >= guess {
            break;
        }
        guess = next;
        i += 1;
    }
    guess
}

/// Bands evaluated by the hard-coded polynomials (l ≤ 4, 25 coefficients).
pub const POLYNOMIAL_BANDS: usize = 5;

// Band constants of the polynomial path, named by (l, |m|) and the monomial they scale.
const Y00: f32 = (0.5 / const_sqrt(PI)) as f32;
const Y1: f32 = const_sqrt(3.0 / (4.0 * PI)) as f32;
const Y2_MIXED: f32 = (0.5 * const_sqrt(15.0 / PI)) as f32;
const Y20: f32 = (0.25 * const_sqrt(5.0 / PI)) as f32;
const Y22: f32 = (0.25 * const_sqrt(15.0 / PI)) as f32;
const Y33: f32 = (0.25 * const_sqrt(35.0 / (2.0 * PI))) as f32;
const Y32_XYZ: f32 = (0.5 * const_sqrt(105.0 / PI)) as f32;
const Y32: f32 = (0.25 * const_sqrt(105.0 / PI)) as f32;
const Y31: f32 = (0.25 * const_sqrt(21.0 / (2.0 * PI))) as f32;
const Y30: f32 = (0.25 * const_sqrt(7.0 / PI)) as f32;
const Y44_XY: f32 = (0.75 * const_sqrt(35.0 / PI)) as f32;
const Y43: f32 = (0.75 * const_sqrt(35.0 / (2.0 * PI))) as f32;
const Y42_XY: f32 = (0.75 * const_sqrt(5.0 / PI)) as f32;
const Y41: f32 = (0.75 * const_sqrt(5.0 / (2.0 * PI))) as f32;
const Y40: f32 = (3.0 / 16.0 * const_sqrt(1.0 / PI)) as f32;
const Y42: f32 = (3.0 / 8.0 * const_sqrt(5.0 / PI)) as f32;
const Y44: f32 = (3.0 / 16.0 * const_sqrt(35.0 / PI)) as f32;

/// Normalised associated Legendre functions without the `sin^m θ` factor,
/// `Q_l^m(z) = K_l^m P_l^m(z) / sin^m θ`, obey
/// `Q_m^m = -√((2m+1)/(2m)) Q_{m-1}^{m-1}` (the minus sign is the Condon–Shortley
/// phase), `Q_{m+1}^m = √(2m+3) z Q_m^m` and
/// `Q_l^m = a_l^m (z Q_{l-1}^m - b_l^m Q_{l-2}^m)`.
struct LegendreTables {
    diagonal: [f32; MAX_BANDS],
    next_to_diagonal: [f32; MAX_BANDS],
    a: [[f32; MAX_BANDS]; MAX_BANDS],
    b: [[f32; MAX_BANDS]; MAX_BANDS],
}

const LEGENDRE: LegendreTables = {
    let mut t = LegendreTables {
        diagonal: [0.0; MAX_BANDS],
        next_to_diagonal: [0.0; MAX_BANDS],
        a: [[0.0; MAX_BANDS]; MAX_BANDS],
        b: [[0.0; MAX_BANDS]; MAX_BANDS],
    };
    let mut m = 0;
    while m < MAX_BANDS {
        let mf = m as f64;
        if m > 0 {
            t.diagonal[m] = -const_sqrt((2.0 * mf + 1.0) / (2.0 * mf)) as f32;
        }
        t.next_to_diagonal[m] = const_sqrt(2.0 * mf + 3.0) as f32;
        let mut l = m + 2;
        while l < MAX_BANDS {
            let lf = l as f64;
            t.a[l][m] = const_sqrt((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)) as f32;
            t.b[l][m] = const_sqrt(
                ((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0),
            ) as f32;
            l += 1;
        }
        m += 1;
    }
    t
};

const SQRT_2: f32 = core::f32::consts::SQRT_2;

/// The basis functions `Y_i(dir)`, `i = l(l+1) + m`, for the `N = bands²` coefficients
/// of [`Sh<N>`].
///
/// `dir` must be unit length: the polynomials are only the harmonics on the unit
/// sphere. Bands 0..=4 (`N ≤ 25`) use closed-form polynomials, larger `N` the
/// normalised Legendre recurrence; the two agree to `f32` rounding (tested).
///
/// ```
/// use antumbra_core::sh::eval_basis;
/// use antumbra_core::glam::Vec3;
///
/// let y = eval_basis::<4>(Vec3::Y);
/// assert!((y[0] - 0.282095).abs() < 1e-6);
/// assert!((y[1] + 0.488603).abs() < 1e-6); // Y_1^{-1} = -0.488603 y
/// ```
#[inline]
pub fn eval_basis<const N: usize>(dir: Vec3) -> [f32; N] {
    let bands = Sh::<N>::BANDS;
    let mut out = [0.0; N];
    if bands <= POLYNOMIAL_BANDS {
        eval_polynomial(dir, bands, &mut out);
    } else {
        eval_recurrence(dir, bands, &mut out);
    }
    out
}

/// The same values as [`eval_basis`], always computed by the Legendre recurrence.
///
/// Exposed so that benchmarks and tests can compare the two paths; prefer
/// [`eval_basis`].
#[inline]
pub fn eval_basis_recurrence<const N: usize>(dir: Vec3) -> [f32; N] {
    let bands = Sh::<N>::BANDS;
    let mut out = [0.0; N];
    eval_recurrence(dir, bands, &mut out);
    out
}

/// [`eval_basis`] for a band count chosen at run time: fills `out`, whose length must
/// be a supported coefficient count (1, 4, 9, …, [`MAX_COEFFS`]).
///
/// On error `out` is left untouched.
pub fn eval_basis_into(dir: Vec3, out: &mut [f32]) -> Result<(), ShError> {
    let bands = bands_for_len(out.len()).ok_or(ShError::CoefficientCount { len: out.len() })?;
    debug_assert!(out.len() <= MAX_COEFFS);
    if bands <= POLYNOMIAL_BANDS {
        eval_polynomial(dir, bands, out);
    } else {
        eval_recurrence(dir, bands, out);
    }
    Ok(())
}

/// Closed forms for bands `0..bands` (at most [`POLYNOMIAL_BANDS`]); `out` holds at
/// least `bands²` values.
#[inline]
fn eval_polynomial(dir: Vec3, bands: usize, out: &mut [f32]) {
    debug_assert!((1..=POLYNOMIAL_BANDS).contains(&bands) && out.len() >= bands * bands);
    let Vec3 { x, y, z } = dir;
    out[0] = Y00;
    if bands < 2 {
        return;
    }
    out[1] = -Y1 * y;
    out[2] = Y1 * z;
    out[3] = -Y1 * x;
    if bands < 3 {
        return;
    }
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, yz, xz) = (x * y, y * z, x * z);
    out[4] = Y2_MIXED * xy;
    out[5] = -Y2_MIXED * yz;
    out[6] = Y20 * (3.0 * zz - 1.0);
    out[7] = -Y2_MIXED * xz;
    out[8] = Y22 * (xx - yy);
    if bands < 4 {
        return;
    }
    // On the unit sphere 4z² - x² - y² = 5z² - 1 and 2z² - 3x² - 3y² = 5z² - 3.
    let five_zz_1 = 5.0 * zz - 1.0;
    out[9] = -Y33 * y * (3.0 * xx - yy);
    out[10] = Y32_XYZ * xy * z;
    out[11] = -Y31 * y * five_zz_1;
    out[12] = Y30 * z * (5.0 * zz - 3.0);
    out[13] = -Y31 * x * five_zz_1;
    out[14] = Y32 * z * (xx - yy);
    out[15] = -Y33 * x * (xx - 3.0 * yy);
    if bands < 5 {
        return;
    }
    let seven_zz_1 = 7.0 * zz - 1.0;
    let seven_zz_3 = 7.0 * zz - 3.0;
    out[16] = Y44_XY * xy * (xx - yy);
    out[17] = -Y43 * yz * (3.0 * xx - yy);
    out[18] = Y42_XY * xy * seven_zz_1;
    out[19] = -Y41 * yz * seven_zz_3;
    out[20] = Y40 * (35.0 * zz * zz - 30.0 * zz + 3.0);
    out[21] = -Y41 * xz * seven_zz_3;
    out[22] = Y42 * (xx - yy) * seven_zz_1;
    out[23] = -Y43 * xz * (xx - 3.0 * yy);
    out[24] = Y44 * (xx * (xx - 3.0 * yy) - yy * (3.0 * xx - yy));
}

/// The recurrence for bands `0..bands` (at most [`MAX_BANDS`]), column by column in
/// `m`; `out` holds at least `bands²` values.
#[inline]
fn eval_recurrence(dir: Vec3, bands: usize, out: &mut [f32]) {
    debug_assert!((1..=MAX_BANDS).contains(&bands) && out.len() >= bands * bands);
    let Vec3 { x, y, z } = dir;
    let mut q_mm = Y00;
    // (c, s) = Re, Im of (x + iy)^m = sin^m θ (cos mφ, sin mφ).
    let (mut c, mut s) = (1.0f32, 0.0f32);
    for m in 0..bands {
        if m > 0 {
            q_mm *= LEGENDRE.diagonal[m];
            (c, s) = (c * x - s * y, c * y + s * x);
        }
        // The √2 of the real harmonics with m ≠ 0, folded into the azimuthal factor.
        let (cos_part, sin_part) = if m == 0 {
            (1.0, 0.0)
        } else {
            (SQRT_2 * c, SQRT_2 * s)
        };
        let mut store = |l: usize, q: f32| {
            let centre = l * (l + 1);
            if m == 0 {
                out[centre] = q;
            } else {
                out[centre + m] = q * cos_part;
                out[centre - m] = q * sin_part;
            }
        };
        store(m, q_mm);
        if m + 1 >= bands {
            continue;
        }
        let mut q_before = q_mm;
        let mut q_last = LEGENDRE.next_to_diagonal[m] * z * q_mm;
        store(m + 1, q_last);
        for l in m + 2..bands {
            let q = LEGENDRE.a[l][m] * (z * q_last - LEGENDRE.b[l][m] * q_before);
            store(l, q);
            (q_before, q_last) = (q_last, q);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::test_support::{sphere_quadrature, unit_vector};
    use crate::sh::{MAX_COEFFS, sh_index};
    use alloc::vec::Vec;
    use proptest::prelude::*;

    #[test]
    fn const_sqrt_matches_libm() {
        for &x in &[0.0, 1e-6, 0.02, 0.5, 1.0, 2.0, 3.0, 10.0, 12345.678, 1e9] {
            let ours = const_sqrt(x);
            let libm = libm::sqrt(x);
            assert!(
                (ours - libm).abs() <= 2.0 * f64::EPSILON * libm,
                "{x}: {ours} {libm}"
            );
        }
    }

    #[test]
    fn band_one_is_the_documented_convention() {
        let v = Vec3::new(0.36, 0.48, 0.8);
        let y = eval_basis::<4>(v);
        assert!((y[0] - 0.282_095).abs() < 1e-6);
        assert!((y[1] - -0.488_603 * v.y).abs() < 1e-6);
        assert!((y[2] - 0.488_603 * v.z).abs() < 1e-6);
        assert!((y[3] - -0.488_603 * v.x).abs() < 1e-6);
    }

    /// Y_l^m(θ, φ) for l = 2, 3 written from the textbook closed forms in spherical
    /// coordinates, in f64 (independent of both the polynomial and the recurrence).
    fn closed_form_l2_l3(l: usize, m: isize, dir: Vec3) -> f64 {
        let (x, y, z) = (f64::from(dir.x), f64::from(dir.y), f64::from(dir.z));
        // Normalise in f64: an f32 "unit" vector is off by ~1e-7 in length, which
        // near a pole moves sin θ = sqrt(1 - z²) by far more than the tolerance.
        let length = libm::sqrt(x * x + y * y + z * z);
        let (x, y, z) = (x / length, y / length, z / length);
        let theta = libm::acos(z.clamp(-1.0, 1.0));
        let phi = libm::atan2(y, x);
        let (st, ct) = (libm::sin(theta), libm::cos(theta));
        let trig = |k: f64| {
            if m < 0 {
                libm::sin(k * phi)
            } else {
                libm::cos(k * phi)
            }
        };
        let sq = libm::sqrt;
        match (l, m.unsigned_abs()) {
            (2, 2) => 0.25 * sq(15.0 / PI) * st * st * trig(2.0),
            (2, 1) => -0.5 * sq(15.0 / PI) * st * ct * trig(1.0),
            (2, 0) => 0.25 * sq(5.0 / PI) * (3.0 * ct * ct - 1.0),
            (3, 3) => -0.25 * sq(35.0 / (2.0 * PI)) * st * st * st * trig(3.0),
            (3, 2) => 0.25 * sq(105.0 / PI) * st * st * ct * trig(2.0),
            (3, 1) => -0.25 * sq(21.0 / (2.0 * PI)) * st * (5.0 * ct * ct - 1.0) * trig(1.0),
            (3, 0) => 0.25 * sq(7.0 / PI) * (5.0 * ct * ct * ct - 3.0 * ct),
            _ => unreachable!(),
        }
    }

    /// Y_l^m from the unnormalised Legendre recurrence with factorials in f64 (Green,
    /// "Spherical Harmonic Lighting: The Gritty Details", 2003), in spherical
    /// coordinates: an implementation sharing no code or constants with ours.
    pub(crate) fn textbook_f64(l: usize, m: isize, dir: Vec3) -> f64 {
        let (x, y, z) = (f64::from(dir.x), f64::from(dir.y), f64::from(dir.z));
        // Normalise in f64: an f32 "unit" vector is off by ~1e-7 in length, which
        // near a pole moves sin θ = sqrt(1 - z²) by far more than the tolerance.
        let length = libm::sqrt(x * x + y * y + z * z);
        let (x, y, z) = (x / length, y / length, z / length);
        let theta = libm::acos(z.clamp(-1.0, 1.0));
        let phi = libm::atan2(y, x);
        let am = m.unsigned_abs();
        let ct = libm::cos(theta);
        // P_l^m(ct) with the Condon–Shortley phase.
        let legendre = {
            let mut pmm = 1.0;
            let somx2 = libm::sqrt((1.0 - ct) * (1.0 + ct));
            let mut fact = 1.0;
            for _ in 0..am {
                pmm *= -fact * somx2;
                fact += 2.0;
            }
            if l == am {
                pmm
            } else {
                let mut pmmp1 = ct * (2.0 * am as f64 + 1.0) * pmm;
                if l == am + 1 {
                    pmmp1
                } else {
                    let mut pll = 0.0;
                    for ll in am + 2..=l {
                        let llf = ll as f64;
                        pll = ((2.0 * llf - 1.0) * ct * pmmp1 - (llf + am as f64 - 1.0) * pmm)
                            / (llf - am as f64);
                        pmm = pmmp1;
                        pmmp1 = pll;
                    }
                    pll
                }
            }
        };
        let factorial = |n: usize| (1..=n).map(|k| k as f64).product::<f64>();
        let k =
            libm::sqrt((2.0 * l as f64 + 1.0) / (4.0 * PI) * factorial(l - am) / factorial(l + am));
        let amf = am as f64;
        match m.signum() {
            0 => k * legendre,
            1 => core::f64::consts::SQRT_2 * k * libm::cos(amf * phi) * legendre,
            _ => core::f64::consts::SQRT_2 * k * libm::sin(amf * phi) * legendre,
        }
    }

    #[test]
    fn bands_two_and_three_match_closed_forms_at_fixed_directions() {
        let dirs = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.48, 0.6, 0.64),
            Vec3::new(-0.6, 0.0, -0.8),
            Vec3::new(1.0, -2.0, 2.0) / 3.0,
        ];
        for dir in dirs {
            let poly = eval_basis::<16>(dir);
            let rec = eval_basis_recurrence::<16>(dir);
            for l in 2..4 {
                for m in -(l as isize)..=(l as isize) {
                    let want = closed_form_l2_l3(l, m, dir);
                    let i = sh_index(l, m);
                    assert!((f64::from(poly[i]) - want).abs() < 2e-6, "{l} {m} {dir}");
                    assert!((f64::from(rec[i]) - want).abs() < 2e-6, "{l} {m} {dir}");
                }
            }
        }
    }

    #[test]
    fn a_few_hand_checked_values() {
        // Y_2^0 at the pole is ¼√(5/π)·2; Y_3^{-2} at (1,1,1)/√3 is ½√(105/π)/(3√3).
        let pole = eval_basis::<9>(Vec3::Z);
        assert!((f64::from(pole[6]) - 0.5 * libm::sqrt(5.0 / PI)).abs() < 1e-6);
        let d = Vec3::ONE.normalize();
        let y = eval_basis::<16>(d);
        let want = 0.5 * libm::sqrt(105.0 / PI) / (3.0 * libm::sqrt(3.0));
        assert!((f64::from(y[sh_index(3, -2)]) - want).abs() < 1e-6);
    }

    #[test]
    fn poles_are_regular_and_non_zonal_terms_vanish() {
        for dir in [Vec3::Z, -Vec3::Z] {
            let y = eval_basis::<64>(dir);
            for l in 0..8 {
                for m in -(l as isize)..=(l as isize) {
                    let v = y[sh_index(l, m)];
                    assert!(v.is_finite());
                    if m != 0 {
                        assert_eq!(v, 0.0, "{l} {m}");
                    } else {
                        // P_l(±1) = (±1)^l, so Y_l^0 = ±√((2l+1)/4π).
                        let sign = if dir.z < 0.0 && l % 2 == 1 { -1.0 } else { 1.0 };
                        let want = sign * libm::sqrt((2.0 * l as f64 + 1.0) / (4.0 * PI));
                        assert!((f64::from(v) - want).abs() < 1e-5, "{l}");
                    }
                }
            }
        }
    }

    #[test]
    fn orthonormal_by_quadrature_for_all_supported_bands() {
        // 20 Gauss–Legendre nodes in cos θ × 40 uniform φ integrate every product of
        // two harmonics with l ≤ 7 (degree ≤ 14) exactly; what is left is f32 rounding.
        let quad = sphere_quadrature(20);
        let values: Vec<([f32; MAX_COEFFS], f64)> = quad
            .iter()
            .map(|&(d, w)| (eval_basis::<64>(d), w))
            .collect();
        let mut worst = 0.0f64;
        for i in 0..MAX_COEFFS {
            for j in 0..=i {
                let integral: f64 = values
                    .iter()
                    .map(|(y, w)| f64::from(y[i]) * f64::from(y[j]) * w)
                    .sum();
                let want = if i == j { 1.0 } else { 0.0 };
                worst = worst.max((integral - want).abs());
            }
        }
        assert!(worst < 1e-5, "worst Gram deviation {worst}");
    }

    #[test]
    fn every_truncation_is_a_prefix_of_the_largest() {
        let dir = Vec3::new(0.3, -0.5, 0.81).normalize();
        let full = eval_basis::<64>(dir);
        macro_rules! check {
            ($($n:literal),*) => {$(
                let part = eval_basis::<$n>(dir);
                for i in 0..$n {
                    assert!((part[i] - full[i]).abs() < 2e-6, "N={} i={i}", $n);
                }
            )*};
        }
        check!(1, 4, 9, 16, 25, 36, 49);
    }

    #[test]
    fn runtime_band_count_matches_const_and_rejects_bad_lengths() {
        let dir = Vec3::new(-0.2, 0.7, 0.3).normalize();
        let mut out = [0.0f32; 36];
        eval_basis_into(dir, &mut out).unwrap();
        assert_eq!(out, eval_basis::<36>(dir));
        let mut out = [7.0f32; 10];
        assert_eq!(
            eval_basis_into(dir, &mut out),
            Err(ShError::CoefficientCount { len: 10 })
        );
        assert_eq!(out, [7.0; 10]);
        assert!(eval_basis_into(dir, &mut [0.0; 81]).is_err());
        assert!(eval_basis_into(dir, &mut []).is_err());
    }

    proptest! {
        #[test]
        fn polynomials_match_recurrence(dir in unit_vector()) {
            let poly = eval_basis::<25>(dir);
            let rec = eval_basis_recurrence::<25>(dir);
            for i in 0..25 {
                prop_assert!((poly[i] - rec[i]).abs() < 2e-6, "i={} {} {}", i, poly[i], rec[i]);
            }
        }

        #[test]
        fn recurrence_matches_textbook_f64_for_all_bands(dir in unit_vector()) {
            let y = eval_basis::<64>(dir);
            for l in 0..8 {
                for m in -(l as isize)..=(l as isize) {
                    let want = textbook_f64(l, m, dir);
                    let got = f64::from(y[sh_index(l, m)]);
                    prop_assert!((got - want).abs() < 1e-5, "{} {}: {} vs {}", l, m, got, want);
                }
            }
        }
    }
}
