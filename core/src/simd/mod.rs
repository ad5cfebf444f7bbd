//! The only place for hand-written intrinsics. Each kernel here computes, lane by
//! lane, exactly the `f32` operations of a portable twin elsewhere in the crate
//! (named in its docs) and is tested against it bit for bit; callers pick a kernel
//! here only after [`avx_available`] said the processor runs it.

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx;

/// Slab planes of the eight child boxes of a wide BVH node: `[axis][side][child]`,
/// side 0 the minima and side 1 the maxima. Aligned so that each row of eight is
/// one 32-byte load that never splits a cache line.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Planes8(pub [[[f32; 8]; 2]; 3]);

/// Per-ray constants of the eight-lane slab test of [`Planes8`] boxes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabRay {
    /// Ray origin per axis.
    pub origin: [f32; 3],
    /// `1 / d` per axis (finite).
    pub inverse: [f32; 3],
    /// Per axis, 1 when the direction is negative (the near plane is the maximum).
    pub negative: [usize; 3],
    /// Lower end of the accepted distances.
    pub t_min: f32,
    /// Relative padding of the far distance.
    pub slack: f32,
}

/// Whether this processor (and operating system) runs the AVX kernels of
/// `avx`: detected once by the standard library and cached there. Always false
/// off x86-64.
#[inline]
pub(crate) fn avx_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Per-ray constants of the watertight triangle test in lanes: the ray after
/// the axis permutation and shear of `raycast::PreparedRay` (whose fields these
/// are).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ShearedRay {
    /// Ray origin per (unpermuted) axis.
    pub origin: [f32; 3],
    /// The permuted axes `[kx, ky, kz]`.
    pub axes: [usize; 3],
    /// `(d[kx] / d[kz], d[ky] / d[kz], 1 / d[kz])`.
    pub shear: [f32; 3],
    /// Lower end of the ray interval.
    pub t_min: f32,
}

/// What an eight-lane triangle test decided, lane `i` the triangle in lane `i`
/// of the first block (`i < 4`) or lane `i - 4` of the second: the layout of
/// `raycast::LaneHits` over eight lanes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LaneHits8 {
    /// Lanes hit at `t[i]` with barycentrics `u[i]`, `v[i]`.
    pub hits: u32,
    /// Lanes only the scalar test decides.
    pub undecided: u32,
    /// Ray parameter per lane.
    pub t: [f32; 8],
    /// Barycentric weight of the second corner per lane.
    pub u: [f32; 8],
    /// Barycentric weight of the third corner per lane.
    pub v: [f32; 8],
}
