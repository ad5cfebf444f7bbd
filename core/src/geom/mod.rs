//! Geometry shared by every algorithm: validated mesh views and receiver frames.
//!
//! Everything here borrows caller data and allocates nothing, except
//! [`uv_sphere()`], which builds a procedural mesh.

mod frame;
mod mesh;
mod sqrt;
mod uv_sphere;

pub use frame::Frame;
pub use mesh::{MeshError, MeshView, POSITION_BYTES};
pub(crate) use sqrt::{
    length, length_f64, normalize_f64, normalize_or_zero, normalize_or_zero_f64, sqrt, sqrt4, sqrtf,
};
pub use uv_sphere::uv_sphere;

use glam::Vec3;

/// `m` scaled by a power of two so that its largest component lies in `[1, 2)`;
/// zero and non-finite `m` unchanged.
///
/// Scaling by a power of two is exact, so any sign or ratio computed from the
/// scaled vector is the one computed from `m` wherever computing it on `m`
/// neither overflows nor underflows, and `-m` scales to exactly `-(scaled m)`.
/// Uses: the hemisphere rasterizer's half-space predicate keeps normals from tiny
/// or huge triangles (cross products of 1e-20 or 1e19 coordinates) out of the
/// subnormal and infinite ranges, where its rounding would be too coarse to be
/// solved per row; vectors are normalised through it where their squared length
/// could overflow or underflow (the result is `m.normalize()`'s, bit for bit,
/// wherever no square in that under- or overflows).
#[inline]
pub(crate) fn normalize_exponent(m: Vec3) -> Vec3 {
    let max = m.x.abs().max(m.y.abs()).max(m.z.abs());
    if !(max > 0.0 && max.is_finite()) {
        return m;
    }
    // Lift subnormals into the normal range first (exact: scaling up by 2^64).
    let (m, max) = if max < f32::MIN_POSITIVE {
        (m * TWO_POW_64, max * TWO_POW_64)
    } else {
        (m, max)
    };
    // max = 1.f * 2^e; multiply by 2^-e in two halves so neither factor leaves
    // the normal range (e can be 127).
    let e = ((max.to_bits() >> 23) & 0xff) as i32 - 127;
    let half = e / 2;
    m * pow2(-half) * pow2(half - e)
}

/// `v` normalised, or zero for a zero or non-finite `v`. A finite vector whose
/// squared length leaves `f32`'s range (where glam's `normalize_or_zero` gives
/// zero) is first scaled by a power of two ([`normalize_exponent`]); elsewhere
/// the result is `v.normalize_or_zero()` itself.
#[inline]
pub(crate) fn unit_or_zero(v: Vec3) -> Vec3 {
    let unit = normalize_or_zero(v);
    if unit != Vec3::ZERO || v == Vec3::ZERO || !v.is_finite() {
        return unit;
    }
    normalize_or_zero(normalize_exponent(v))
}

const TWO_POW_64: f32 = 18_446_744_073_709_551_616.0;

/// `2^k` for `|k| <= 126`.
#[inline(always)]
fn pow2(k: i32) -> f32 {
    f32::from_bits(((127 + k) as u32) << 23)
}

/// `x` rounded to the nearest `f32` at or below it (conservative lower bounds).
pub(crate) fn f32_down(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x { y.next_down() } else { y }
}

/// `x` rounded to the nearest `f32` at or above it (conservative upper bounds).
pub(crate) fn f32_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x { y.next_up() } else { y }
}
