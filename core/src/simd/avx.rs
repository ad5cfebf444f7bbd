//! AVX (256-bit, eight `f32` lanes) kernels for x86-64, each callable only from
//! code that checked [`super::avx_available`].
#![allow(unsafe_code)]

use core::arch::x86_64::{
    __m128, __m128i, __m256, __m256d, __m256i, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ,
    _CMP_LT_OQ, _CMP_NEQ_UQ, _CMP_UNORD_Q, _mm_add_epi32, _mm_loadu_ps, _mm_loadu_si128,
    _mm_storeu_ps, _mm_storeu_si128, _mm256_add_ps, _mm256_and_pd, _mm256_and_ps, _mm256_andnot_pd,
    _mm256_andnot_ps, _mm256_blendv_pd, _mm256_blendv_ps, _mm256_broadcast_ss, _mm256_castps_si256,
    _mm256_castsi256_ps, _mm256_castsi256_si128, _mm256_cmp_pd, _mm256_cmp_ps, _mm256_cvtpd_ps,
    _mm256_cvtps_pd, _mm256_cvttps_epi32, _mm256_div_pd, _mm256_div_ps, _mm256_extractf128_si256,
    _mm256_loadu_ps, _mm256_max_pd, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps,
    _mm256_mul_pd, _mm256_mul_ps, _mm256_or_ps, _mm256_set_m128, _mm256_set1_epi32, _mm256_set1_pd,
    _mm256_set1_ps, _mm256_setzero_ps, _mm256_shuffle_ps, _mm256_sqrt_ps, _mm256_storeu_ps,
    _mm256_storeu_si256, _mm256_sub_pd, _mm256_sub_ps, _mm256_unpackhi_ps, _mm256_unpacklo_ps,
    _mm256_xor_ps,
};

#[cfg(test)]
use super::EdgePlanes8;
use super::{EdgeCorners8, SetupMasks8, SweepPlanes8, SweepReceiver8};

#[cfg(feature = "bvh")]
use glam::Vec4;

#[cfg(feature = "bvh")]
use super::{LaneHits8, Planes8, ShearedRay, SlabRay};

/// Adds the eight `i32` lanes of `add` to `eight`, in two 128-bit halves
/// (AVX without AVX2 has no 256-bit integer addition).
#[target_feature(enable = "avx")]
#[inline]
fn add_i32x8(eight: &mut [i32; 8], add: __m256) {
    let add = _mm256_castps_si256(add);
    let halves = [
        _mm256_castsi256_si128(add),
        _mm256_extractf128_si256::<1>(add),
    ];
    for (four, half) in eight.chunks_exact_mut(4).zip(halves) {
        let four = four.as_mut_ptr().cast::<__m128i>();
        // SAFETY: `four` points at four readable and writable, contiguous
        // `i32`; both accesses are unaligned.
        unsafe { _mm_storeu_si128(four, _mm_add_epi32(_mm_loadu_si128(four), half)) };
    }
}

#[inline(always)]
fn load(eight: &[f32; 8]) -> __m256 {
    // SAFETY: `eight` is eight readable, contiguous `f32`; the load is unaligned.
    unsafe { _mm256_loadu_ps(eight.as_ptr()) }
}

#[cfg(feature = "bvh")]
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

#[cfg(feature = "bvh")]
/// The watertight triangle test on two blocks of four triangles at once, lanes
/// 0–3 from `low` and 4–7 from `high` (`[corner][axis]` coordinates in lanes):
/// per lane the `f32` operations, comparisons and masks of the four-lane
/// `raycast::PreparedRay::intersect_lanes`, in the same order with the same
/// operands (comparison predicates chosen to match SSE's ordered ones, and the
/// unordered `!=` of `Vec4::cmpne`), so every lane's answer equals that of the
/// four-lane test on its block bit for bit (tested in `raycast/tests.rs`).
/// `wide_extent` and `wide_determinant` are the thresholds below which the
/// scalar test leaves its common path; `t_max` the interval's end now.
#[target_feature(enable = "avx")]
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn intersect8(
    ray: &ShearedRay,
    t_max: f32,
    low: &[[Vec4; 3]; 3],
    high: &[[Vec4; 3]; 3],
    wide_extent: f32,
    wide_determinant: f32,
) -> LaneHits8 {
    let [kx, ky, kz] = ray.axes;
    let both = |corner: usize, axis: usize| {
        let (l, h): (&[f32; 4], &[f32; 4]) =
            (low[corner][axis].as_ref(), high[corner][axis].as_ref());
        // SAFETY: `l` and `h` are four readable, contiguous `f32` each.
        unsafe { _mm256_set_m128(_mm_loadu_ps(h.as_ptr()), _mm_loadu_ps(l.as_ptr())) }
    };
    let splat = |x: f32| _mm256_set1_ps(x);
    let sign = splat(-0.0);
    let abs = |v: __m256| _mm256_andnot_ps(sign, v);
    let all = _mm256_cmp_ps::<_CMP_EQ_OQ>(_mm256_setzero_ps(), _mm256_setzero_ps());
    let not = |m: __m256| _mm256_andnot_ps(m, all);
    let (sx, sy, sz) = (
        splat(ray.shear[0]),
        splat(ray.shear[1]),
        splat(ray.shear[2]),
    );
    let relative =
        |corner: usize, axis: usize| _mm256_sub_ps(both(corner, axis), splat(ray.origin[axis]));
    let sheared = |corner: usize| {
        let depth = relative(corner, kz);
        (
            _mm256_sub_ps(relative(corner, kx), _mm256_mul_ps(sx, depth)),
            _mm256_sub_ps(relative(corner, ky), _mm256_mul_ps(sy, depth)),
            depth,
        )
    };
    let (ax, ay, a_depth) = sheared(0);
    let (bx, by, b_depth) = sheared(1);
    let (cx, cy, c_depth) = sheared(2);
    let extent = splat(wide_extent);
    let reaches = |v: __m256| _mm256_cmp_ps::<_CMP_GE_OQ>(abs(v), extent);
    let wide_enough = _mm256_or_ps(
        _mm256_or_ps(
            _mm256_or_ps(_mm256_or_ps(reaches(ax), reaches(ay)), reaches(bx)),
            reaches(by),
        ),
        _mm256_or_ps(reaches(cx), reaches(cy)),
    );
    let edge = |p: __m256, q: __m256, r: __m256, s: __m256| {
        _mm256_sub_ps(_mm256_mul_ps(p, q), _mm256_mul_ps(r, s))
    };
    let eu = edge(cx, by, cy, bx);
    let ev = edge(ax, cy, ay, cx);
    let ew = edge(bx, ay, by, ax);
    let zero = _mm256_setzero_ps();
    let some_zero = _mm256_or_ps(
        _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_EQ_OQ>(eu, zero),
            _mm256_cmp_ps::<_CMP_EQ_OQ>(ev, zero),
        ),
        _mm256_cmp_ps::<_CMP_EQ_OQ>(ew, zero),
    );
    let infinity = splat(f32::INFINITY);
    let finite_mask = |v: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(abs(v), infinity);
    let finite = _mm256_and_ps(
        _mm256_and_ps(finite_mask(eu), finite_mask(ev)),
        finite_mask(ew),
    );
    let negative = _mm256_or_ps(
        _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_LT_OQ>(eu, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(ev, zero),
        ),
        _mm256_cmp_ps::<_CMP_LT_OQ>(ew, zero),
    );
    let positive = _mm256_or_ps(
        _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(eu, zero),
            _mm256_cmp_ps::<_CMP_GT_OQ>(ev, zero),
        ),
        _mm256_cmp_ps::<_CMP_GT_OQ>(ew, zero),
    );
    let inside = not(_mm256_and_ps(negative, positive));
    let det = _mm256_add_ps(_mm256_add_ps(eu, ev), ew);
    let crossed = _mm256_and_ps(inside, _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero));
    let scaled_t = _mm256_add_ps(
        _mm256_add_ps(
            _mm256_mul_ps(eu, _mm256_mul_ps(sz, a_depth)),
            _mm256_mul_ps(ev, _mm256_mul_ps(sz, b_depth)),
        ),
        _mm256_mul_ps(ew, _mm256_mul_ps(sz, c_depth)),
    );
    let threshold = splat(wide_determinant);
    let imprecise = _mm256_or_ps(
        _mm256_or_ps(
            not(finite_mask(scaled_t)),
            _mm256_cmp_ps::<_CMP_LT_OQ>(abs(det), threshold),
        ),
        _mm256_cmp_ps::<_CMP_LT_OQ>(abs(scaled_t), threshold),
    );
    let undecided = _mm256_or_ps(
        _mm256_or_ps(_mm256_or_ps(not(wide_enough), some_zero), not(finite)),
        _mm256_and_ps(crossed, imprecise),
    );
    let inv_det = _mm256_div_ps(splat(1.0), det);
    let t = _mm256_mul_ps(scaled_t, inv_det);
    let accepted = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GT_OQ>(t, splat(ray.t_min)),
        _mm256_cmp_ps::<_CMP_LT_OQ>(t, splat(t_max)),
    );
    let hits = _mm256_and_ps(_mm256_and_ps(crossed, accepted), not(undecided));
    let store = |v: __m256| {
        let mut lanes = [0.0f32; 8];
        // SAFETY: `lanes` is eight writable, contiguous `f32`.
        unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), v) };
        lanes
    };
    LaneHits8 {
        hits: _mm256_movemask_ps(hits) as u32,
        undecided: _mm256_movemask_ps(undecided) as u32,
        t: store(t),
        u: store(_mm256_mul_ps(ev, inv_det)),
        v: store(_mm256_mul_ps(ew, inv_det)),
    }
}

/// The eight-octant edge tests of the soft-shadow hierarchy: bits of the
/// octants that may see the edge as a silhouette (when `silhouette`, else all
/// eight) and may meet its wedge (when `wedge`, else all eight), for the
/// record `record` (layout [`super::edge_record`]). The `f32` operations,
/// comparisons and combinations of the portable `ssv::edge_bounds` tests
/// (`silhouette_lanes`, `wedge_lanes`), in the same order with the same
/// operands, so the bits are the same (tested there). The planes and the axes
/// take the octants as lanes; for the directions, stored eight to a group, the
/// directions are the lanes instead, one octant after another, which shares
/// each direction's projection among the octants (about a third less time per
/// edge).
#[target_feature(enable = "avx")]
#[inline]
pub(crate) fn edge_octants8(
    record: &[f32],
    octants: &super::Octants8,
    silhouette: bool,
    wedge: bool,
) -> u8 {
    use super::OCTANT_SIGN as SIGN;
    use super::edge_record::*;
    // Every value splatted from memory or computed in the lanes (AVX has no
    // broadcast from a register): the same `f32` operations on each lane as
    // the portable code's on the scalar.
    let splat = |x: &f32| _mm256_broadcast_ss(x);
    let sign = [load(&SIGN[0]), load(&SIGN[1]), load(&SIGN[2])];
    let centre = octants.centre.each_ref().map(splat);
    let quarter = octants.quarter.each_ref().map(splat);
    // A direction `n` (per lane) against the parent: `t = n * quarter`,
    // `base = (n0 c0 + n1 c1) + n2 c2` and `rad = (|t0| + |t1|) + |t2|`;
    // octant `s` projects to `mid = ((base + s0 t0) + s1 t1) + s2 t2`.
    let spread = |n: [__m256; 3]| {
        let t = [
            _mm256_mul_ps(n[0], quarter[0]),
            _mm256_mul_ps(n[1], quarter[1]),
            _mm256_mul_ps(n[2], quarter[2]),
        ];
        let base = _mm256_add_ps(
            _mm256_add_ps(
                _mm256_mul_ps(n[0], centre[0]),
                _mm256_mul_ps(n[1], centre[1]),
            ),
            _mm256_mul_ps(n[2], centre[2]),
        );
        let rad = _mm256_add_ps(_mm256_add_ps(abs8(t[0]), abs8(t[1])), abs8(t[2]));
        (t, base, rad)
    };
    // One direction, the octants as lanes: their mids and common radius.
    let project = |n: &[f32]| {
        let (t, base, rad) = spread([splat(&n[0]), splat(&n[1]), splat(&n[2])]);
        let mid = _mm256_add_ps(
            _mm256_add_ps(
                _mm256_add_ps(base, _mm256_mul_ps(sign[0], t[0])),
                _mm256_mul_ps(sign[1], t[1]),
            ),
            _mm256_mul_ps(sign[2], t[2]),
        );
        (mid, rad)
    };
    let all = _mm256_cmp_ps::<_CMP_EQ_OQ>(_mm256_setzero_ps(), _mm256_setzero_ps());
    let mut keep = 0xFF;
    if silhouette {
        let margin = splat(&octants.margin);
        let minus = -octants.margin;
        let minus_margin = splat(&minus);
        let one = _mm256_set1_ps(1.0);
        let mut weight = _mm256_setzero_ps();
        let mut open = _mm256_setzero_ps();
        for plane in record[PLANES..PLANES + 8].chunks_exact(4) {
            let (mid, rad) = project(&plane[..3]);
            let m = _mm256_sub_ps(mid, splat(&plane[3]));
            let above = _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_sub_ps(m, rad), margin);
            let below = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_add_ps(m, rad), minus_margin);
            weight = _mm256_add_ps(
                weight,
                _mm256_sub_ps(_mm256_and_ps(above, one), _mm256_and_ps(below, one)),
            );
            open = _mm256_or_ps(open, _mm256_andnot_ps(_mm256_or_ps(above, below), all));
        }
        let nonzero = _mm256_cmp_ps::<_CMP_NEQ_UQ>(weight, _mm256_setzero_ps());
        keep = _mm256_movemask_ps(_mm256_or_ps(open, nonzero)) as u8;
        if keep == 0 {
            return 0;
        }
    }
    if wedge {
        let inverse = record[INVERSE];
        let side = record[SIDE];
        let reach = if side > 0.0 {
            _mm256_mul_ps(load(&octants.above), splat(&inverse))
        } else if side < 0.0 {
            _mm256_mul_ps(load(&octants.below), splat(&inverse))
        } else {
            _mm256_set1_ps(f32::MAX)
        };
        let margin = splat(&octants.margin);
        let separate = |bounds: &[f32], mid: __m256, rad: __m256| {
            let top = _mm256_add_ps(splat(&bounds[1]), margin);
            let bottom = _mm256_sub_ps(splat(&bounds[0]), margin);
            let hi = _mm256_add_ps(top, _mm256_mul_ps(reach, splat(&bounds[2])));
            let lo = _mm256_sub_ps(bottom, _mm256_mul_ps(reach, splat(&bounds[3])));
            let over = _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_sub_ps(mid, rad), hi);
            let under = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_add_ps(mid, rad), lo);
            _mm256_or_ps(over, under)
        };
        let mut separated = _mm256_setzero_ps();
        for (axis, bounds) in record[AXES..AXES + 12].chunks_exact(4).enumerate() {
            let mid = load(&octants.axis_mid[axis]);
            separated = _mm256_or_ps(separated, separate(bounds, mid, quarter[axis]));
        }
        keep &= !(_mm256_movemask_ps(separated) as u8);
        // The directions eight at a time, lanes over directions, octant after
        // octant: per lane the operations above on the same operands.
        let mut reach_lanes = [0.0f32; 8];
        // SAFETY: `reach_lanes` is eight writable, contiguous `f32`.
        unsafe { _mm256_storeu_ps(reach_lanes.as_mut_ptr(), reach) };
        let count = record[COUNT] as usize;
        for group in record[DIRECTIONS..]
            .chunks_exact(GROUP)
            .take(count.div_ceil(GROUP_LANES))
        {
            if keep == 0 {
                break;
            }
            let field = |f: usize| -> __m256 {
                load(
                    group[f * GROUP_LANES..][..GROUP_LANES]
                        .try_into()
                        .expect("eight lanes"),
                )
            };
            let (t, base, rad) = spread([field(0), field(1), field(2)]);
            let top = _mm256_add_ps(field(4), margin);
            let bottom = _mm256_sub_ps(field(3), margin);
            let (climb, fall) = (field(5), field(6));
            // `base + s t` is `base - t` for the sign -1 (IEEE subtraction
            // is the addition of the negation), so octants sharing their
            // lower axes share those sums.
            let step = |m: __m256, t: __m256| [_mm256_sub_ps(m, t), _mm256_add_ps(m, t)];
            let x = step(base, t[0]);
            let xy = [step(x[0], t[1]), step(x[1], t[1])];
            let mut far = 0u8;
            for o in 0..8 {
                let mid = step(xy[o & 1][o >> 1 & 1], t[2])[o >> 2 & 1];
                let reach = _mm256_broadcast_ss(&reach_lanes[o]);
                let hi = _mm256_add_ps(top, _mm256_mul_ps(reach, climb));
                let lo = _mm256_sub_ps(bottom, _mm256_mul_ps(reach, fall));
                let over = _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_sub_ps(mid, rad), hi);
                let under = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_add_ps(mid, rad), lo);
                far |= u8::from(_mm256_movemask_ps(_mm256_or_ps(over, under)) != 0) << o;
            }
            keep &= !far;
        }
    }
    keep
}

/// `f32` unit roundoff, `2^-24`.
const U: f32 = f32::EPSILON / 2.0;

/// Relative bound, against the permanent `Σ (|x_j e_k| + |x_k e_j|) |f_i|`,
/// on how far [`silhouette_setup8`]'s `f32` value of `det[x, e, f]` (for
/// `x = a - p`, `e = b - a`, `f = w - a`, each difference rounded once to
/// `f32`) may be from the exact one: the rounded differences (`u` each, three
/// per term), the cross product's products and difference (`2u`), the dot
/// product's products and sums (`3u`) and the permanent's own rounding (`4u`)
/// make about `12u`; this is `32u`.
pub(crate) const SIDE_BOUND: f32 = 32.0 * U;

/// Relative bound, against `Σ |x_i| |t_i|`, on the `f32` height `x · t` of a
/// rounded difference `x` along a rounded unit direction `t` (about `5u`).
const HEIGHT_BOUND: f32 = 16.0 * U;

/// Added to every bound: far above what underflow to subnormal `f32` values
/// (at most `2^-149` each) can change, so the relative bounds are what count.
pub(crate) const FLOOR: f32 = 1e-30;

/// Relative slack of the `f32` bounds on the sweep's `f64` tolerances (their
/// own roundings are a few `u`).
const SLACK: f32 = 1e-5;

/// `|v|` per lane.
#[target_feature(enable = "avx")]
#[inline]
fn abs8(v: __m256) -> __m256 {
    _mm256_andnot_ps(_mm256_set1_ps(-0.0), v)
}

/// `x · y` per lane, `(x₀ y₀ + x₁ y₁) + x₂ y₂`.
#[target_feature(enable = "avx")]
#[inline]
fn dot3(x: [__m256; 3], y: [__m256; 3]) -> __m256 {
    _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(x[0], y[0]), _mm256_mul_ps(x[1], y[1])),
        _mm256_mul_ps(x[2], y[2]),
    )
}

/// An endpoint's height `w · toward` per lane, with the bound on its
/// distance from the exact value (`HEIGHT_BOUND` times the permanent, plus
/// `floor`), as both sweep kernels take it.
#[target_feature(enable = "avx")]
#[inline]
fn bounded_height(w: [__m256; 3], toward: [__m256; 3], floor: __m256) -> (__m256, __m256) {
    let permanent = dot3(w.map(|v| abs8(v)), toward.map(|v| abs8(v)));
    let err = _mm256_add_ps(
        _mm256_mul_ps(_mm256_set1_ps(HEIGHT_BOUND), permanent),
        floor,
    );
    (dot3(w, toward), err)
}

/// `(v₀ + v₁) + v₂` per lane.
#[target_feature(enable = "avx")]
#[inline]
fn sum3(v: [__m256; 3]) -> __m256 {
    _mm256_add_ps(_mm256_add_ps(v[0], v[1]), v[2])
}

/// The largest `|v_i|` per lane.
#[target_feature(enable = "avx")]
#[inline]
fn largest3(v: [__m256; 3]) -> __m256 {
    _mm256_max_ps(_mm256_max_ps(abs8(v[0]), abs8(v[1])), abs8(v[2]))
}

/// Component pairs of a cross product: component `i` is `x_j y_k - x_k y_j`.
const CROSS_PAIRS: [(usize, usize); 3] = [(1, 2), (2, 0), (0, 1)];

/// `x × y` per lane.
#[target_feature(enable = "avx")]
#[inline]
fn cross3(x: [__m256; 3], y: [__m256; 3]) -> [__m256; 3] {
    CROSS_PAIRS.map(|(j, k)| _mm256_sub_ps(_mm256_mul_ps(x[j], y[k]), _mm256_mul_ps(x[k], y[j])))
}

/// The permanent of `x × y` per lane: `|x_j y_k| + |x_k y_j|` per component.
#[target_feature(enable = "avx")]
#[inline]
fn permanent3(x: [__m256; 3], y: [__m256; 3]) -> [__m256; 3] {
    CROSS_PAIRS.map(|(j, k)| {
        _mm256_add_ps(
            abs8(_mm256_mul_ps(x[j], y[k])),
            abs8(_mm256_mul_ps(x[k], y[j])),
        )
    })
}

/// The set-up of [`Kernel::add_edge`](crate::ssv) for eight candidate edges at
/// `receiver`, in `f32` lanes, each decision taken only where it is certain
/// to be the `f64` sweep's:
/// - the quick rejection (both endpoints behind the receiver, or both
///   beyond the light's plane, within the sweep's slack);
/// - the silhouette weight: the signs of `det[a - p, b - p, w - p]` for the
///   third vertices `u` and `v`, each beyond [`SIDE_BOUND`] times its
///   permanent (so the exact signs);
/// - whether the plane through the receiver and the edge cuts the light grown
///   by its tolerance (swept), and whether it passes near it (recorded): each
///   light vertex's side against the sweep's `f64` tolerance, decided where
///   the `f32` value and bounds put it beyond that tolerance's own bounds.
///
/// A lane any of whose needed decisions is not certain (an overflow to
/// infinity or NaN included) is `undecided`; the caller gives those to the
/// scalar set-up.
#[target_feature(enable = "avx")]
#[inline(never)]
pub(crate) fn silhouette_setup8(receiver: &SweepReceiver8, corners: &EdgeCorners8) -> SetupMasks8 {
    let splat = |x: f32| _mm256_set1_ps(x);
    let zero = _mm256_setzero_ps();
    let all = _mm256_cmp_ps::<_CMP_EQ_OQ>(zero, zero);
    let not = |m: __m256| _mm256_andnot_ps(m, all);
    let p = receiver.p;
    let relative = |w: &[[f32; 8]; 3]| -> [__m256; 3] {
        core::array::from_fn(|axis| _mm256_sub_ps(load(&w[axis]), splat(p[axis])))
    };
    let (x, y) = (relative(&corners.a), relative(&corners.b));
    // Differences from `a`: `det[a - p, b - p, w - p] = det[a - p, b - a,
    // w - a]`, whose permanent (the rounding's scale) is smaller by about the
    // edge's size over its distance, so far fewer signs are left open.
    let from_a = |w: &[[f32; 8]; 3]| -> [__m256; 3] {
        core::array::from_fn(|axis| _mm256_sub_ps(load(&w[axis]), load(&corners.a[axis])))
    };
    let e = from_a(&corners.b);
    // `x × e` (that is `x × y`) and its permanent, and the permanent of `x × y`
    // (the scale of the sweep's own `f64` rounding).
    let (cross, permanent, far_permanent) = (cross3(x, e), permanent3(x, e), permanent3(x, y));
    let floor = splat(FLOOR);
    // The weight: each third vertex's side, (certainly positive, negative).
    let side = |w: &[[f32; 8]; 3]| {
        let z = from_a(w);
        let det = dot3(cross, z);
        let perm = dot3(permanent, z.map(|v| abs8(v)));
        let margin = _mm256_add_ps(_mm256_mul_ps(splat(SIDE_BOUND), perm), floor);
        (
            _mm256_cmp_ps::<_CMP_GT_OQ>(det, margin),
            _mm256_cmp_ps::<_CMP_LT_OQ>(det, _mm256_sub_ps(zero, margin)),
        )
    };
    let (u_pos, u_neg) = side(&corners.u);
    let (v_pos, v_neg) = side(&corners.v);
    let weighed = _mm256_and_ps(_mm256_or_ps(u_pos, u_neg), _mm256_or_ps(v_pos, v_neg));
    let weightless = _mm256_or_ps(_mm256_and_ps(u_pos, v_neg), _mm256_and_ps(u_neg, v_pos));
    // The quick rejection: heights along `toward` against `[-S, hc + S]`,
    // `S` the sweep's slack (at most `1e-9` of the largest coordinate).
    let toward = receiver.toward.map(splat);
    let slack = _mm256_mul_ps(
        splat(2e-9),
        _mm256_max_ps(
            _mm256_max_ps(largest3(x), largest3(y)),
            splat(receiver.cp_max),
        ),
    );
    let hc = splat(receiver.hc);
    let hc_err = _mm256_add_ps(splat(2.0 * U * receiver.hc.abs()), floor);
    // (certainly below `-S`, possibly below; certainly above `hc + S`,
    // possibly above) for one endpoint.
    let height = |w: [__m256; 3]| {
        let (h, err) = bounded_height(w, toward, floor);
        let behind = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_add_ps(h, err), _mm256_sub_ps(zero, slack));
        let maybe_behind = not(_mm256_cmp_ps::<_CMP_GE_OQ>(_mm256_sub_ps(h, err), zero));
        let beyond = _mm256_cmp_ps::<_CMP_GT_OQ>(
            _mm256_sub_ps(h, err),
            _mm256_add_ps(_mm256_add_ps(hc, hc_err), slack),
        );
        let maybe_beyond = not(_mm256_cmp_ps::<_CMP_LE_OQ>(
            _mm256_add_ps(h, err),
            _mm256_sub_ps(hc, hc_err),
        ));
        (behind, maybe_behind, beyond, maybe_beyond)
    };
    let (a_behind, a_maybe_behind, a_beyond, a_maybe_beyond) = height(x);
    let (b_behind, b_maybe_behind, b_beyond, b_maybe_beyond) = height(y);
    let rejected = _mm256_or_ps(
        _mm256_and_ps(a_behind, b_behind),
        _mm256_and_ps(a_beyond, b_beyond),
    );
    let maybe_rejected = _mm256_or_ps(
        _mm256_and_ps(a_maybe_behind, b_maybe_behind),
        _mm256_and_ps(a_maybe_beyond, b_maybe_beyond),
    );
    // The plane against the light: the sweep's `f64` tolerance `err` of each
    // light vertex lies in `[err_lo, err_hi]`, its `near` in `[near_lo,
    // near_hi]`.
    let length = _mm256_sqrt_ps(dot3(cross, cross));
    // The `f32` length's rounding (against the edge's own permanent) and the
    // sweep's `f64` one (against the far permanent).
    let length_err = _mm256_add_ps(
        _mm256_add_ps(
            _mm256_mul_ps(splat(8.0 * U), sum3(permanent)),
            _mm256_mul_ps(splat(8.0 * U), length),
        ),
        _mm256_add_ps(_mm256_mul_ps(splat(1e-14), sum3(far_permanent)), floor),
    );
    let length_lo = _mm256_max_ps(_mm256_sub_ps(length, length_err), zero);
    let length_hi = _mm256_add_ps(length, length_err);
    let (lo, hi) = (splat(1.0 - SLACK), splat(1.0 + SLACK));
    let tolerance2 = splat(receiver.tolerance2);
    let reach_lo = _mm256_mul_ps(_mm256_mul_ps(length_lo, tolerance2), lo);
    let reach_hi = _mm256_mul_ps(_mm256_mul_ps(length_hi, tolerance2), hi);
    // Over the light's vertices, (certain, possible) for: some vertex above
    // the plane, some below, some above within the near band, some below it.
    let mut flags = [(zero, zero); 4];
    let lights = receiver.lights[..receiver.light_count].iter();
    for (l, &near) in lights.zip(&receiver.light_near) {
        let l = l.map(splat);
        let d = dot3(cross, l);
        let spread = dot3(permanent, l.map(|v| abs8(v)));
        // The sweep's `f64` value and its tolerance's first term are within
        // `1e-14` of the far permanent's spread (`8 · 2^-53` of it and less).
        let far_spread = _mm256_mul_ps(splat(1e-14), dot3(far_permanent, l.map(|v| abs8(v))));
        let d_err = _mm256_add_ps(
            _mm256_add_ps(_mm256_mul_ps(splat(SIDE_BOUND), spread), far_spread),
            floor,
        );
        let err_lo = reach_lo;
        let err_hi = _mm256_mul_ps(_mm256_add_ps(reach_hi, far_spread), hi);
        let near_lo = _mm256_mul_ps(
            _mm256_add_ps(
                err_lo,
                _mm256_mul_ps(splat(near * (1.0 - SLACK)), length_lo),
            ),
            lo,
        );
        let near_hi = _mm256_mul_ps(
            _mm256_add_ps(
                err_hi,
                _mm256_mul_ps(splat(near * (1.0 + SLACK)), length_hi),
            ),
            hi,
        );
        let (d_lo, d_hi) = (_mm256_sub_ps(d, d_err), _mm256_add_ps(d, d_err));
        // `d > -t` for a tolerance `t` in `[t_lo, t_hi]`: certain, possible.
        let over = |t_lo: __m256, t_hi: __m256| {
            (
                _mm256_cmp_ps::<_CMP_GT_OQ>(d_lo, _mm256_sub_ps(zero, t_lo)),
                not(_mm256_cmp_ps::<_CMP_LE_OQ>(d_hi, _mm256_sub_ps(zero, t_hi))),
            )
        };
        // `d < t`: certain, possible.
        let under = |t_lo: __m256, t_hi: __m256| {
            (
                _mm256_cmp_ps::<_CMP_LT_OQ>(d_hi, t_lo),
                not(_mm256_cmp_ps::<_CMP_GE_OQ>(d_lo, t_hi)),
            )
        };
        let tests = [
            over(err_lo, err_hi),
            under(err_lo, err_hi),
            over(near_lo, near_hi),
            under(near_lo, near_hi),
        ];
        for ((certain, possible), (is, may)) in flags.iter_mut().zip(tests) {
            *certain = _mm256_or_ps(*certain, is);
            *possible = _mm256_or_ps(*possible, may);
        }
    }
    let [above, below, near_above, near_below] = flags;
    let sweep = _mm256_and_ps(above.0, below.0);
    let maybe_sweep = _mm256_and_ps(above.1, below.1);
    let near = _mm256_and_ps(near_above.0, near_below.0);
    let maybe_near = _mm256_and_ps(near_above.1, near_below.1);
    let idle = _mm256_or_ps(rejected, weightless);
    let unsure = _mm256_or_ps(
        _mm256_or_ps(not(weighed), _mm256_andnot_ps(rejected, maybe_rejected)),
        _mm256_or_ps(
            _mm256_andnot_ps(sweep, maybe_sweep),
            _mm256_andnot_ps(near, maybe_near),
        ),
    );
    let mask = |m: __m256| _mm256_movemask_ps(m) as u32;
    let idle = mask(idle);
    SetupMasks8 {
        undecided: mask(unsure) & !idle,
        idle,
        positive: mask(u_pos),
        near: mask(near),
        sweep: mask(sweep),
    }
}

/// Magnitude above which [`silhouette_planes8`] leaves a lane undecided: with
/// every difference (the samples' from the receiver included) below it, no
/// product of three overflows and an underflow (at most `2^-149` a product,
/// times at most this) changes a value by far less than [`FLOOR`].
const PLANE_RANGE: f32 = 1e8;

/// Per lane, the normal a soft-shadow query records for a silhouette edge
/// (`ssv::reference`'s `scaled_normal` of `(a - p) × (b - p)`, with `a` and
/// `b` the lane's endpoints in `corners` widened to `f64` and `p` the
/// receiver), by axis: the same operations in the same order, so the same
/// values bit for bit. The power of two that brings the largest component
/// into `[0.5, 1)` is `0.5` over that component's exponent bits alone (a
/// division by a power of two, exact), where the component is a normal
/// `f64` below `2¹⁰²²` (`2045 << 52` as bits); elsewhere (a zero normal)
/// the scale is 1.
#[target_feature(enable = "avx")]
#[inline(never)]
pub(crate) fn recorded_normals8(p: [f64; 3], corners: &EdgeCorners8) -> [[f32; 8]; 3] {
    let mut out = [[0.0f32; 8]; 3];
    for half in 0..2 {
        let widen = |lanes: &[f32; 8]| -> __m256d {
            let four: &[f32; 4] = lanes[4 * half..4 * half + 4]
                .try_into()
                .expect("four lanes");
            // SAFETY: `four` is four readable, contiguous `f32`; the load is
            // unaligned.
            _mm256_cvtps_pd(unsafe { _mm_loadu_ps(four.as_ptr()) })
        };
        let relative = |w: &[[f32; 8]; 3]| -> [__m256d; 3] {
            core::array::from_fn(|axis| _mm256_sub_pd(widen(&w[axis]), _mm256_set1_pd(p[axis])))
        };
        let ([ax, ay, az], [bx, by, bz]) = (relative(&corners.a), relative(&corners.b));
        let difference = |x: __m256d, y: __m256d, z: __m256d, w: __m256d| {
            _mm256_sub_pd(_mm256_mul_pd(x, y), _mm256_mul_pd(z, w))
        };
        // glam's `cross`: `(a.y b.z - b.y a.z, a.z b.x - b.z a.x, a.x b.y - b.x a.y)`.
        let n = [
            difference(ay, bz, by, az),
            difference(az, bx, bz, ax),
            difference(ax, by, bx, ay),
        ];
        let magnitude = |v: __m256d| _mm256_andnot_pd(_mm256_set1_pd(-0.0), v);
        let largest = _mm256_max_pd(
            magnitude(n[0]),
            _mm256_max_pd(magnitude(n[1]), magnitude(n[2])),
        );
        let exponent = _mm256_and_pd(largest, _mm256_set1_pd(f64::INFINITY));
        let scalable = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GE_OQ>(largest, _mm256_set1_pd(f64::MIN_POSITIVE)),
            _mm256_cmp_pd::<_CMP_LT_OQ>(largest, _mm256_set1_pd(f64::from_bits(2045 << 52))),
        );
        let scale = _mm256_blendv_pd(
            _mm256_set1_pd(1.0),
            _mm256_div_pd(_mm256_set1_pd(0.5), exponent),
            scalable,
        );
        for (axis, v) in n.into_iter().enumerate() {
            let rounded = _mm256_cvtpd_ps(_mm256_mul_pd(v, scale));
            // SAFETY: the four `f32` of lanes `4 half..4 half + 4` are
            // writable and contiguous; the store is unaligned.
            unsafe { _mm_storeu_ps(out[axis][4 * half..].as_mut_ptr(), rounded) };
        }
    }
    out
}

/// Relative bound, against the computed `|det| + |vs| + |va| + |vb|`, on the
/// rounding of [`CrossingTest8::classify`]'s three-term sum (about `3u`).
const SUM_BOUND: f32 = 8.0 * U;

/// The rest of the sweep's set-up ([`Kernel::add_silhouette`](crate::ssv))
/// for eight silhouette edges at `receiver`, in `f32` lanes: the planes of
/// the per-sample crossing test and the side of the light's centroid `c`,
/// and the arc of samples the edge may cross.
///
/// The planes are `(a - p) × (b - a)`, `(a - p) × (c - a)` and
/// `(b - p) × (c - b)`, which equal `(a - p) × (b - p)`, `(a - p) × (c - p)`
/// and `(b - p) × (c - p)` exactly; each value `v · s'` (for any sample's
/// rounded `s'`) is within [`SIDE_BOUND`] times its permanent, bounded with
/// the samples' largest `|s'|`, of the exact determinant (the roundings are
/// those of [`SIDE_BOUND`]'s determinant). A lane is `decided` when its
/// values are in range and the centroid's side is certain.
///
/// The arc: each endpoint projected from the receiver onto the light's plane
/// and taken in its axes, with a bound `e` on each coordinate's distance from
/// the exact projection (the heights' relative error, then about `6u` more
/// per operation, doubled). It is used only where both endpoints are above
/// the receiver by `10⁻³` of the centroid's height beyond their error, each
/// projection is at least `64 e` from the centroid (so its angle is within
/// `1.5 e / r` radians, as a pseudo-angle changes by at most one unit per
/// radian) and the sign of the cross product of the two projections is
/// certain (so the short way round is the exact one). The margin is twice
/// the angles' bounds, the samples' shift off the plane, and `4 · 10⁻⁶` for
/// the pseudo-angles' own rounding (under `10⁻⁶` each).
#[target_feature(enable = "avx")]
#[inline(never)]
pub(crate) fn silhouette_planes8(
    receiver: &SweepReceiver8,
    corners: &EdgeCorners8,
) -> SweepPlanes8 {
    let splat = |x: f32| _mm256_set1_ps(x);
    let zero = _mm256_setzero_ps();
    let floor = splat(FLOOR);
    let lanes = |w: &[[f32; 8]; 3]| -> [__m256; 3] { core::array::from_fn(|i| load(&w[i])) };
    let minus = |x: [__m256; 3], y: [__m256; 3]| -> [__m256; 3] {
        core::array::from_fn(|i| _mm256_sub_ps(x[i], y[i]))
    };
    let (a, b) = (lanes(&corners.a), lanes(&corners.b));
    let p = receiver.p.map(splat);
    let c = receiver.centroid.map(splat);
    let (x, y) = (minus(a, p), minus(b, p));
    let (e, ca, cb) = (minus(b, a), minus(c, a), minus(c, b));
    let (nrm, amat, bmat) = (cross3(x, e), cross3(x, ca), cross3(y, cb));
    let nperm = permanent3(x, e);
    let smax = receiver.smax.map(splat);
    let bound = |perm: __m256| _mm256_add_ps(_mm256_mul_ps(splat(SIDE_BOUND), perm), floor);
    let det = dot3(nrm, ca);
    let err_c = bound(dot3(nperm, ca.map(|v| abs8(v))));
    let errs = [
        bound(dot3(nperm, smax)),
        bound(dot3(permanent3(x, ca), smax)),
        bound(dot3(permanent3(y, cb), smax)),
        err_c,
    ];
    // The samples' `|s - p|` too: they scale each plane's underflow.
    let range = [x, y, e, ca, cb, smax]
        .into_iter()
        .fold(zero, |m, w| _mm256_max_ps(m, largest3(w)));
    // NaN compares false: such a lane is out of range too.
    let in_range = _mm256_cmp_ps::<_CMP_LT_OQ>(range, splat(PLANE_RANGE));
    let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(det, err_c);
    let negative = _mm256_cmp_ps::<_CMP_LT_OQ>(det, _mm256_sub_ps(zero, err_c));
    let decided = _mm256_and_ps(in_range, _mm256_or_ps(positive, negative));
    let mask = |m: __m256| _mm256_movemask_ps(m) as u32;
    let mut out = SweepPlanes8 {
        decided: mask(decided),
        centroid_positive: mask(positive),
        ..SweepPlanes8::default()
    };
    let store = |to: &mut [f32; 8], v: __m256| {
        // SAFETY: `to` is eight writable, contiguous `f32`; the store is
        // unaligned.
        unsafe { _mm256_storeu_ps(to.as_mut_ptr(), v) }
    };
    for axis in 0..3 {
        store(&mut out.nrm[axis], nrm[axis]);
        store(&mut out.amat[axis], amat[axis]);
        store(&mut out.bmat[axis], bmat[axis]);
    }
    store(&mut out.det, det);
    // The per-sample test takes the sum's bound in place of `det`'s: four
    // positive terms, whose rounded sum is within `2u` of the exact one, far
    // inside the bounds' own slack.
    let [en, ea, eb, ec] = errs;
    let sum = _mm256_mul_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(ec, en), ea), eb),
        splat(1.0 + 4.0 * f32::EPSILON),
    );
    for (to, v) in out.errs.iter_mut().zip([en, ea, eb, sum]) {
        store(to, v);
    }
    let Some(shift_margin) = receiver.shift_margin else {
        return out;
    };
    // The arc.
    let toward = receiver.toward.map(splat);
    let (hc, cp) = (splat(receiver.hc), receiver.cp.map(splat));
    let (u_axis, v_axis) = (receiver.u_axis.map(splat), receiver.v_axis.map(splat));
    let cp_norm = sum3(cp.map(|v| abs8(v)));
    let u = splat(U);
    // Per endpoint: the projection's coordinates, their bound, the lower
    // bound of the distance from the centroid, and whether it is usable.
    let project = |w: [__m256; 3]| {
        let (h, h_err) = bounded_height(w, toward, floor);
        let h_lo = _mm256_sub_ps(h, h_err);
        let above = _mm256_cmp_ps::<_CMP_GT_OQ>(h_lo, _mm256_mul_ps(splat(1e-3), hc));
        let relative = _mm256_div_ps(h_err, h_lo);
        let scale = _mm256_div_ps(hc, h);
        let q: [__m256; 3] =
            core::array::from_fn(|i| _mm256_sub_ps(_mm256_mul_ps(w[i], scale), cp[i]));
        let (qx, qy) = (dot3(q, u_axis), dot3(q, v_axis));
        let err = _mm256_add_ps(
            _mm256_mul_ps(
                splat(2.0),
                _mm256_add_ps(
                    _mm256_mul_ps(
                        _mm256_add_ps(relative, _mm256_mul_ps(splat(8.0), u)),
                        _mm256_mul_ps(scale, sum3(w.map(|v| abs8(v)))),
                    ),
                    _mm256_mul_ps(
                        _mm256_mul_ps(splat(8.0), u),
                        _mm256_add_ps(cp_norm, sum3(q.map(|v| abs8(v)))),
                    ),
                ),
            ),
            floor,
        );
        let r = _mm256_sub_ps(_mm256_max_ps(abs8(qx), abs8(qy)), err);
        let far = _mm256_cmp_ps::<_CMP_GE_OQ>(r, _mm256_mul_ps(splat(64.0), err));
        // The pseudo-angle, branch-free.
        let t = _mm256_div_ps(qy, _mm256_add_ps(abs8(qx), abs8(qy)));
        let x_neg = _mm256_cmp_ps::<_CMP_LT_OQ>(qx, zero);
        let t_neg = _mm256_cmp_ps::<_CMP_LT_OQ>(t, zero);
        let right = _mm256_blendv_ps(t, _mm256_add_ps(splat(4.0), t), t_neg);
        let angle = _mm256_blendv_ps(right, _mm256_sub_ps(splat(2.0), t), x_neg);
        (qx, qy, err, r, _mm256_and_ps(above, far), angle)
    };
    let (xa, ya, ea, ra, usable_a, pa) = project(x);
    let (xb, yb, eb, rb, usable_b, pb) = project(y);
    let turn = _mm256_sub_ps(_mm256_mul_ps(xa, yb), _mm256_mul_ps(ya, xb));
    let turn_err = _mm256_mul_ps(
        splat(2.0),
        _mm256_add_ps(
            _mm256_add_ps(
                _mm256_mul_ps(ea, _mm256_add_ps(_mm256_add_ps(abs8(xb), abs8(yb)), eb)),
                _mm256_mul_ps(eb, _mm256_add_ps(_mm256_add_ps(abs8(xa), abs8(ya)), ea)),
            ),
            _mm256_mul_ps(
                _mm256_mul_ps(splat(3.0), u),
                _mm256_add_ps(abs8(_mm256_mul_ps(xa, yb)), abs8(_mm256_mul_ps(ya, xb))),
            ),
        ),
    );
    let certain_turn = _mm256_cmp_ps::<_CMP_GT_OQ>(abs8(turn), turn_err);
    let margin = _mm256_add_ps(
        _mm256_mul_ps(
            splat(2.0),
            _mm256_add_ps(_mm256_div_ps(ea, ra), _mm256_div_ps(eb, rb)),
        ),
        splat(shift_margin + 4e-6),
    );
    // Counter-clockwise from the first to the second is the short way.
    let counter_clockwise = _mm256_cmp_ps::<_CMP_GT_OQ>(turn, zero);
    let from = _mm256_blendv_ps(pb, pa, counter_clockwise);
    let to = _mm256_blendv_ps(pa, pb, counter_clockwise);
    let wrap = |t: __m256| {
        let low = _mm256_cmp_ps::<_CMP_LT_OQ>(t, zero);
        let high = _mm256_cmp_ps::<_CMP_GE_OQ>(t, splat(4.0));
        let t = _mm256_blendv_ps(t, _mm256_add_ps(t, splat(4.0)), low);
        _mm256_blendv_ps(t, _mm256_sub_ps(t, splat(4.0)), high)
    };
    let (lo, hi) = (
        wrap(_mm256_sub_ps(from, margin)),
        wrap(_mm256_add_ps(to, margin)),
    );
    store(&mut out.lo, lo);
    store(&mut out.hi, hi);
    // The buckets: `t` times a power of two (exact) truncated, as the
    // sweep's `f64` does with the same `t` (clamped as its saturating cast
    // is, NaN to 0, though only arc lanes, in `[0, 4]`, are read).
    let scale = splat(crate::ssv::ANGLE_SCALE as f32);
    let last = splat((crate::ssv::ANGLE_BUCKETS - 1) as f32);
    for (to, t) in out.buckets.iter_mut().zip([lo, hi]) {
        let scaled = _mm256_max_ps(_mm256_mul_ps(t, scale), zero);
        let bucket = _mm256_cvttps_epi32(_mm256_min_ps(scaled, last));
        // SAFETY: `to` is eight writable, contiguous `i32`; the store is
        // unaligned.
        unsafe { _mm256_storeu_si256(to.as_mut_ptr().cast::<__m256i>(), bucket) };
    }
    // A margin of a quarter turn or more (or NaN) is no arc worth taking.
    let narrow = _mm256_cmp_ps::<_CMP_LT_OQ>(margin, splat(1.0));
    let arc = _mm256_and_ps(
        _mm256_and_ps(usable_a, usable_b),
        _mm256_and_ps(certain_turn, narrow),
    );
    out.arc = mask(arc) & out.decided;
    out
}

/// The sign flip that makes the wanted side of an edge's planes positive:
/// `-0.0` (the sign bit) where it is the negative one, `0.0` where it is
/// the positive one (no branch).
#[inline]
fn flip_unless(want: bool) -> f32 {
    f32::from_bits(u32::from(!want) << 31)
}

/// Eight rows of four `f32` (row `i` from `rows[i]`) as four vectors, one
/// per column, lane `i` from row `i`: the rows of lanes `i` and `i + 4`
/// share a vector, so one 4×4 transpose in both halves does it.
#[target_feature(enable = "avx")]
#[inline]
fn columns4(rows: [&[f32; 4]; 8]) -> [__m256; 4] {
    let pair = |lane: usize| {
        // SAFETY: each row is four readable, contiguous `f32`; the loads
        // are unaligned.
        let part = |lane: usize| -> __m128 { unsafe { _mm_loadu_ps(rows[lane].as_ptr()) } };
        _mm256_set_m128(part(lane + 4), part(lane))
    };
    let (t0, t1) = (pair(0), pair(1));
    let (t2, t3) = (pair(2), pair(3));
    let (lo01, hi01) = (_mm256_unpacklo_ps(t0, t1), _mm256_unpackhi_ps(t0, t1));
    let (lo23, hi23) = (_mm256_unpacklo_ps(t2, t3), _mm256_unpackhi_ps(t2, t3));
    [
        _mm256_shuffle_ps::<0x44>(lo01, lo23),
        _mm256_shuffle_ps::<0xEE>(lo01, lo23),
        _mm256_shuffle_ps::<0x44>(hi01, hi23),
        _mm256_shuffle_ps::<0xEE>(hi01, hi23),
    ]
}

/// The corners of eight edges by lane (lane `i` from `records[i]`: the
/// triples `a`, `b`, `u`, `v` one after another), into `out`; returns the
/// lanes whose `u` is NaN. Transposed in registers, each record read as
/// three rows of four ([`columns4`]).
#[target_feature(enable = "avx")]
#[inline]
pub(crate) fn edge_corners8(records: [&[f32; 12]; 8], out: &mut EdgeCorners8) -> u32 {
    let mut rows = [_mm256_setzero_ps(); 12];
    for (quarter, four) in rows.chunks_exact_mut(4).enumerate() {
        let part = |lane: usize| -> &[f32; 4] {
            records[lane][4 * quarter..4 * quarter + 4]
                .try_into()
                .expect("a quarter")
        };
        four.copy_from_slice(&columns4(core::array::from_fn(part)));
    }
    let corners = [&mut out.a, &mut out.b, &mut out.u, &mut out.v];
    for (three, corner) in rows.chunks_exact(3).zip(corners) {
        for (row, lanes) in three.iter().zip(corner.iter_mut()) {
            // SAFETY: `lanes` is eight writable, contiguous `f32`; the store
            // is unaligned.
            unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), *row) };
        }
    }
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_UNORD_Q>(rows[6], rows[6])) as u32
}

/// The lanes whose plane certainly keeps direction `s` away, for eight
/// recorded silhouettes: lane `i` takes the normal `n` from the first three
/// of `normals[i]` (the fourth is ignored) and is set when `n · n >= 1/4`
/// and `(n · s)² > threshold (n · n)`, all in `f32` (the reference sample's
/// prefilter: the soft shadows' `Silhouettes::clear_of` takes `threshold`
/// from `lane_threshold`, so that a set lane passes its `f64` test too).
#[target_feature(enable = "avx")]
#[inline(never)]
pub(crate) fn beyond_planes8(normals: [&[f32; 4]; 8], s: [f32; 3], threshold: f32) -> u32 {
    let [nx, ny, nz, _] = columns4(normals);
    let n = [nx, ny, nz];
    let along = dot3(n, s.map(|x| _mm256_set1_ps(x)));
    let length2 = dot3(n, n);
    let far = _mm256_cmp_ps::<_CMP_GT_OQ>(
        _mm256_mul_ps(along, along),
        _mm256_mul_ps(_mm256_set1_ps(threshold), length2),
    );
    let scaled = _mm256_cmp_ps::<_CMP_GE_OQ>(length2, _mm256_set1_ps(0.25));
    _mm256_movemask_ps(_mm256_and_ps(far, scaled)) as u32
}

/// One silhouette edge's per-sample crossing test, the same edge in every
/// lane (eight samples at a time, [`crossing_blocks`]): the `f32` planes,
/// their bounds and the sign flip that makes the wanted side positive, as
/// [`SweepPlanes8`] holds them for each edge.
#[derive(Clone, Copy)]
struct CrossingTest8 {
    planes: [[__m256; 3]; 3],
    det: __m256,
    det_abs: __m256,
    errs: [__m256; 4],
    neg: [__m256; 3],
    flip: __m256,
}

impl CrossingTest8 {
    #[target_feature(enable = "avx")]
    #[inline]
    fn new(planes: [[__m256; 3]; 3], det: __m256, errs: [__m256; 4], flip: __m256) -> Self {
        let zero = _mm256_setzero_ps();
        CrossingTest8 {
            planes,
            det,
            det_abs: abs8(det),
            errs,
            neg: [0, 1, 2].map(|k| _mm256_sub_ps(zero, errs[k])),
            flip,
        }
    }

    /// Which lanes' samples `s` (relative to the receiver) are certainly
    /// crossed, and which certainly not: each sign is taken only beyond its
    /// bound, the sum's with [`SUM_BOUND`] more.
    #[target_feature(enable = "avx")]
    #[inline]
    fn classify(&self, s: [__m256; 3]) -> (__m256, __m256) {
        let splat = |x: f32| _mm256_set1_ps(x);
        let zero = _mm256_setzero_ps();
        let [nrm, amat, bmat] = self.planes;
        let [err_n, err_a, err_b, err_base] = self.errs;
        let [neg_n, neg_a, neg_b] = self.neg;
        let (vs, va, vb) = (dot3(nrm, s), dot3(amat, s), dot3(bmat, s));
        let vo = _mm256_sub_ps(_mm256_add_ps(_mm256_sub_ps(self.det, vs), va), vb);
        let err_o = _mm256_add_ps(
            err_base,
            _mm256_mul_ps(
                splat(SUM_BOUND),
                _mm256_add_ps(
                    _mm256_add_ps(self.det_abs, abs8(vs)),
                    _mm256_add_ps(abs8(va), abs8(vb)),
                ),
            ),
        );
        let (sg, og) = (_mm256_xor_ps(vs, self.flip), _mm256_xor_ps(vo, self.flip));
        let gt = |v: __m256, t: __m256| _mm256_cmp_ps::<_CMP_GT_OQ>(v, t);
        let lt = |v: __m256, t: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(v, t);
        let (a_pos, a_neg) = (gt(va, err_a), lt(va, neg_a));
        let (b_pos, b_neg) = (gt(vb, err_b), lt(vb, neg_b));
        let apart = _mm256_or_ps(_mm256_and_ps(a_pos, b_neg), _mm256_and_ps(a_neg, b_pos));
        let together = _mm256_or_ps(_mm256_and_ps(a_pos, b_pos), _mm256_and_ps(a_neg, b_neg));
        let hit = _mm256_and_ps(_mm256_and_ps(gt(sg, err_n), gt(og, err_o)), apart);
        let reject = _mm256_or_ps(
            _mm256_or_ps(lt(sg, neg_n), lt(og, _mm256_sub_ps(zero, err_o))),
            together,
        );
        (hit, reject)
    }
}

/// The one-edge twin of [`crossings_lanes8`] that the tests compare it with:
/// `edge`'s planes (one lane of [`SweepPlanes8`]) over the samples `lo..hi`
/// of `soa`, `contribution` added to the counter of each sample it certainly
/// crosses and of each unsure one `unsure(i)` says it crosses.
#[cfg(test)]
#[target_feature(enable = "avx")]
#[inline(never)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn crossings8(
    edge: &EdgePlanes8,
    p: [f32; 3],
    soa: [&[f32]; 3],
    lo: usize,
    hi: usize,
    counters: &mut [i32],
    contribution: i32,
    unsure: impl FnMut(usize) -> bool,
) {
    let splat = |x: f32| _mm256_set1_ps(x);
    let test = CrossingTest8::new(
        [edge.nrm, edge.amat, edge.bmat].map(|plane| plane.map(splat)),
        splat(edge.det),
        edge.errs.map(splat),
        splat(flip_unless(edge.want)),
    );
    crossing_blocks(
        &test,
        p.map(splat),
        soa,
        lo..hi,
        counters,
        contribution,
        unsure,
    );
}

/// The per-sample pass of the sweep for the silhouette edges of `planes` in
/// the lanes of `held` (bit `i` for lane `i`), each over its own samples:
/// edge `i` tests the samples of its `ranges[i]` (`(start, end)` each, empty
/// where `start >= end`) with its
/// planes and bounds from lane `i`, adds `contributions[i]` to the counter
/// of each it certainly crosses, and asks `unsure(i, sample)`, the exact
/// test, for each the `f32` signs leave unsure (none is certainly not
/// crossed and some sign is within its bound), adding the contribution
/// where it says crossed. Each sign is taken only beyond the lane's bound on
/// its distance from the exact value ([`silhouette_planes8`]), so a sample
/// said crossed is crossed exactly and one said not is not. Each edge's
/// planes are broadcast from the lanes and its samples read eight contiguous
/// ones at a time, so a batch's sample pass is one call however long its
/// arcs (a large light's hold about three samples, a small light's more).
/// `soa` holds at least seven readable entries past each range's end; it
/// panics otherwise.
#[target_feature(enable = "avx")]
#[inline(never)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn crossings_lanes8(
    planes: &SweepPlanes8,
    p: [f32; 3],
    soa: [&[f32]; 3],
    held: u32,
    ranges: &[[(u32, u32); 3]; 8],
    contributions: &[i32; 8],
    counters: &mut [i32],
    mut unsure: impl FnMut(usize, usize) -> bool,
) {
    let splat = |x: f32| _mm256_set1_ps(x);
    let p = p.map(splat);
    let mut todo = held & 0xFF;
    while todo != 0 {
        let lane = todo.trailing_zeros() as usize;
        todo &= todo - 1;
        // Broadcast from the lanes where they lie (a copy of an axis's
        // eight on the stack first would stall each broadcast on the copy's
        // store).
        let lane_of = |x: &f32| _mm256_broadcast_ss(x);
        let at = |w: &[[f32; 8]; 3]| [0, 1, 2].map(|axis| lane_of(&w[axis][lane]));
        let test = CrossingTest8::new(
            [at(&planes.nrm), at(&planes.amat), at(&planes.bmat)],
            lane_of(&planes.det[lane]),
            [0, 1, 2, 3].map(|k| lane_of(&planes.errs[k][lane])),
            splat(flip_unless(planes.want(lane))),
        );
        let contribution = contributions[lane];
        for &(lo, hi) in &ranges[lane] {
            let range = lo as usize..hi as usize;
            crossing_blocks(&test, p, soa, range, counters, contribution, |i| {
                unsure(lane, i)
            });
        }
    }
}

/// The block loop of [`crossings_lanes8`] (and of its one-edge twin in the
/// tests, `crossings8`): `test` (one edge's planes in every lane) over the
/// samples of `range`, eight at a time from its first, `p` splat per axis.
#[target_feature(enable = "avx")]
#[inline]
fn crossing_blocks(
    test: &CrossingTest8,
    p: [__m256; 3],
    soa: [&[f32]; 3],
    range: core::ops::Range<usize>,
    counters: &mut [i32],
    contribution: i32,
    mut unsure: impl FnMut(usize) -> bool,
) {
    let splat = |x: f32| _mm256_set1_ps(x);
    let lane_index = load(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    let contribution8 = _mm256_castsi256_ps(_mm256_set1_epi32(contribution));
    let (mut base, hi) = (range.start, range.end);
    while base < hi {
        let at = |axis: usize| -> __m256 {
            let eight: &[f32; 8] = soa[axis][base..base + 8]
                .try_into()
                .expect("eight coordinates");
            _mm256_sub_ps(load(eight), p[axis])
        };
        let (hit, reject) = test.classify([at(0), at(1), at(2)]);
        // Lanes of the range only.
        let past = (hi - base).min(8);
        let inside = 0xFFu32 >> (8 - past);
        match counters.get_mut(base..base + 8) {
            Some(eight) => {
                // The hit lanes inside the range get the contribution, the
                // others zero: no branch per sample, nor per block.
                let lanes = _mm256_cmp_ps::<_CMP_LT_OQ>(lane_index, splat(past as f32));
                let add = _mm256_and_ps(_mm256_and_ps(hit, lanes), contribution8);
                add_i32x8(eight.try_into().expect("eight counters"), add);
            }
            None => {
                let mut bits = _mm256_movemask_ps(hit) as u32 & inside;
                while bits != 0 {
                    counters[base + bits.trailing_zeros() as usize] += contribution;
                    bits &= bits - 1;
                }
            }
        }
        let mut open = !(_mm256_movemask_ps(_mm256_or_ps(hit, reject)) as u32) & inside;
        while open != 0 {
            let i = base + open.trailing_zeros() as usize;
            if unsure(i) {
                counters[i] += contribution;
            }
            open &= open - 1;
        }
        base += 8;
    }
}
