//! Square roots that compile to the processor's instruction in the encoding of
//! the code around them.
//!
//! libm's x86 square roots are inline assembly in the legacy SSE encoding. In
//! code compiled with AVX enabled (`-C target-cpu=native`, `x86-64-v3`, or a
//! `#[target_feature]` function), a legacy SSE instruction after 256-bit code
//! makes the processor save or merge the upper halves of the vector registers,
//! and the hemisphere rasterizer, with a square root in most triangles'
//! set-up, runs several times slower for it. The SSE intrinsics below are
//! encoded like their surroundings (VEX under AVX) and, like libm's assembly,
//! give the correctly rounded root, so the results are the same bits on every
//! target. Other architectures use libm.
//!
//! Unsafe code: the intrinsics are `#[target_feature]` functions, callable
//! only in `unsafe` from a function without the attribute, though SSE and SSE2
//! are part of every x86_64 target.
#![allow(unsafe_code)]

use glam::{DVec3, Vec3, Vec4};

/// The correctly rounded square root of `x` (NaN for negative `x`).
#[inline(always)]
pub(crate) fn sqrtf(x: f32) -> f32 {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_cvtss_f32, _mm_set_ss, _mm_sqrt_ss};
        // SAFETY: SSE is part of every x86_64 target; no memory is touched.
        unsafe { _mm_cvtss_f32(_mm_sqrt_ss(_mm_set_ss(x))) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        libm::sqrtf(x)
    }
}

/// The correctly rounded square root of `x` (NaN for negative `x`).
#[inline(always)]
pub(crate) fn sqrt(x: f64) -> f64 {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_cvtsd_f64, _mm_set_sd, _mm_sqrt_pd};
        // SAFETY: SSE2 is part of every x86_64 target; no memory is touched.
        unsafe { _mm_cvtsd_f64(_mm_sqrt_pd(_mm_set_sd(x))) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        libm::sqrt(x)
    }
}

/// The correctly rounded square root of each lane of `v`: one vector
/// instruction on x86_64 (glam's `Vec4::sqrt` takes four scalar roots when it
/// uses libm).
#[inline(always)]
pub(crate) fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::_mm_sqrt_ps;
        // SAFETY: SSE is part of every x86_64 target; no memory is touched.
        Vec4::from(unsafe { _mm_sqrt_ps(v.into()) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        v.sqrt()
    }
}

/// `v`'s length, `sqrtf(v.dot(v))`: glam's `Vec3::length`, bit for bit.
#[inline(always)]
pub(crate) fn length(v: Vec3) -> f32 {
    sqrtf(v.dot(v))
}

/// `v` scaled to unit length, or zero where its reciprocal length is not a
/// positive finite number: glam's `Vec3::normalize_or_zero`, bit for bit.
#[inline(always)]
pub(crate) fn normalize_or_zero(v: Vec3) -> Vec3 {
    let rcp = 1.0 / length(v);
    if rcp.is_finite() && rcp > 0.0 {
        v * rcp
    } else {
        Vec3::ZERO
    }
}

/// `v`'s length, `sqrt(v.dot(v))`: glam's `DVec3::length`, bit for bit.
#[inline(always)]
pub(crate) fn length_f64(v: DVec3) -> f64 {
    sqrt(v.dot(v))
}

/// `v` scaled to unit length: glam's `DVec3::normalize`, bit for bit.
#[inline(always)]
pub(crate) fn normalize_f64(v: DVec3) -> DVec3 {
    v * (1.0 / length_f64(v))
}

/// `v` scaled to unit length, or zero where its reciprocal length is not a
/// positive finite number: glam's `DVec3::normalize_or_zero`, bit for bit.
#[inline(always)]
pub(crate) fn normalize_or_zero_f64(v: DVec3) -> DVec3 {
    let rcp = 1.0 / length_f64(v);
    if rcp.is_finite() && rcp > 0.0 {
        v * rcp
    } else {
        DVec3::ZERO
    }
}

#[cfg(test)]
mod tests {
    use super::{
        length, length_f64, normalize_f64, normalize_or_zero, normalize_or_zero_f64, sqrt, sqrt4,
        sqrtf,
    };
    use glam::{DVec3, Vec3, Vec4};

    /// The same bits as libm's correctly rounded roots and glam's lengths, on
    /// values spread over every exponent and on the special cases.
    #[test]
    fn roots_equal_libm_bit_for_bit() {
        let mut bits = 0x0000_0001u32;
        while bits < 0x7f80_0000 {
            let x = f32::from_bits(bits);
            assert_eq!(sqrtf(x).to_bits(), libm::sqrtf(x).to_bits(), "sqrtf({x:e})");
            let lanes = Vec4::new(x, x * 0.75, x * 1.5, x * 3.0);
            let four = sqrt4(lanes).to_array().map(f32::to_bits);
            assert_eq!(four, lanes.to_array().map(|l| libm::sqrtf(l).to_bits()));
            let v = Vec3::new(x, -0.5 * x, 2.0 * x);
            assert_eq!(length(v).to_bits(), v.length().to_bits());
            let unit = normalize_or_zero(v).to_array().map(f32::to_bits);
            assert_eq!(unit, v.normalize_or_zero().to_array().map(f32::to_bits));
            let y = f64::from(x) * 1.000_000_1;
            assert_eq!(sqrt(y).to_bits(), libm::sqrt(y).to_bits(), "sqrt({y:e})");
            let w = DVec3::new(y, 3.0 * y, -y);
            assert_eq!(length_f64(w).to_bits(), w.length().to_bits());
            let bits_of = |v: DVec3| v.to_array().map(f64::to_bits);
            assert_eq!(bits_of(normalize_f64(w)), bits_of(w.normalize()));
            assert_eq!(
                bits_of(normalize_or_zero_f64(w)),
                bits_of(w.normalize_or_zero())
            );
            bits += 0x0001_3579;
        }
        let special = [
            0.0f32,
            -0.0,
            1.0,
            4.0,
            f32::INFINITY,
            f32::MAX,
            f32::MIN_POSITIVE,
        ];
        for x in special {
            assert_eq!(sqrtf(x).to_bits(), libm::sqrtf(x).to_bits(), "sqrtf({x:e})");
            let y = f64::from(x);
            assert_eq!(sqrt(y).to_bits(), libm::sqrt(y).to_bits(), "sqrt({y:e})");
        }
        assert!(sqrtf(-1.0).is_nan() && sqrt(-1.0).is_nan() && sqrtf(f32::NAN).is_nan());
        assert!(sqrt4(Vec4::new(-1.0, 1.0, 1.0, 1.0)).x.is_nan());
        for v in [
            Vec3::ZERO,
            Vec3::splat(1e-30),
            Vec3::splat(1e30),
            Vec3::NAN,
            Vec3::INFINITY,
        ] {
            let unit = normalize_or_zero(v).to_array().map(f32::to_bits);
            assert_eq!(
                unit,
                v.normalize_or_zero().to_array().map(f32::to_bits),
                "{v}"
            );
        }
        for w in [
            DVec3::ZERO,
            DVec3::splat(1e-300),
            DVec3::splat(1e300),
            DVec3::NAN,
            DVec3::INFINITY,
        ] {
            let bits_of = |v: DVec3| v.to_array().map(f64::to_bits);
            assert_eq!(
                bits_of(normalize_or_zero_f64(w)),
                bits_of(w.normalize_or_zero())
            );
        }
    }
}
