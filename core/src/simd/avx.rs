//! AVX (256-bit, eight `f32` lanes) kernels for x86-64, each callable only from
//! code that checked [`super::avx_available`].
#![allow(unsafe_code)]

use core::arch::x86_64::{
    __m256, _CMP_LE_OQ, _mm256_add_ps, _mm256_andnot_ps, _mm256_cmp_ps, _mm256_loadu_ps,
    _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_sub_ps,
};

use super::{Planes8, SlabRay};

#[inline(always)]
fn load(eight: &[f32; 8]) -> __m256 {
    // SAFETY: `eight` is eight readable, contiguous `f32`; the load is unaligned.
    unsafe { _mm256_loadu_ps(eight.as_ptr()) }
}

/// Bit `i` set when the ray may enter child `i` of the node whose boxes are
/// `planes` at a distance up to `t_max`: per lane `near = max(max(max(nx, ny), nz), t_min)` and
/// `far = min(f + (|f| * slack + MIN_POSITIVE), t_max)` with
/// `f = min(min(fx, fy), fz)`, each slab distance `(plane - origin) * inverse`,
/// and the lane entered when `near <= far`. These are the operations, in the same
/// order and with the same operands, of the four-lane portable test in
/// `raycast/bvh.rs` (`TraversalRay::entered_planes`), so the two give the same
/// bits for every input (tested there).
#[target_feature(enable = "avx")]
#[inline]
pub(crate) fn entered8(planes: &Planes8, ray: &SlabRay, t_max: f32) -> u32 {
    let slab = |axis: usize| {
        let side = ray.negative[axis] & 1;
        let o = _mm256_set1_ps(ray.origin[axis]);
        let inv = _mm256_set1_ps(ray.inverse[axis]);
        (
            _mm256_mul_ps(_mm256_sub_ps(load(&planes.0[axis][side]), o), inv),
            _mm256_mul_ps(_mm256_sub_ps(load(&planes.0[axis][1 - side]), o), inv),
        )
    };
    let (near_x, far_x) = slab(0);
    let (near_y, far_y) = slab(1);
    let (near_z, far_z) = slab(2);
    let near = _mm256_max_ps(
        _mm256_max_ps(_mm256_max_ps(near_x, near_y), near_z),
        _mm256_set1_ps(ray.t_min),
    );
    let far = _mm256_min_ps(_mm256_min_ps(far_x, far_y), far_z);
    let magnitude = _mm256_andnot_ps(_mm256_set1_ps(-0.0), far);
    let pad = _mm256_add_ps(
        _mm256_mul_ps(magnitude, _mm256_set1_ps(ray.slack)),
        _mm256_set1_ps(f32::MIN_POSITIVE),
    );
    let far = _mm256_min_ps(_mm256_add_ps(far, pad), _mm256_set1_ps(t_max));
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32
}
