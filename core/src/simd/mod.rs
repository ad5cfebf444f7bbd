//! The only place for hand-written intrinsics. Each kernel here computes, lane by
//! lane, exactly the `f32` operations of a portable twin elsewhere in the crate
//! (named in its docs) and is tested against it bit for bit, or (the soft-shadow
//! sweep's kernels) takes only the decisions a bound on its rounding certifies
//! and is tested against the exact path; callers pick a kernel here only after
//! [`avx_available`] said the processor runs it.

#[cfg(all(target_arch = "x86_64", feature = "std"))]
pub(crate) mod avx;

#[cfg(feature = "bvh")]
/// Slab planes of the eight child boxes of a wide BVH node: `[axis][side][child]`,
/// side 0 the minima and side 1 the maxima. Aligned so that each row of eight is
/// one 32-byte load that never splits a cache line.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Planes8(pub [[[f32; 8]; 2]; 3]);

#[cfg(feature = "bvh")]
/// Per-ray constants of the eight-lane slab test of [`Planes8`] boxes.
// Read only by the AVX kernels.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
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
#[cfg(feature = "std")]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
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

/// The builds of [`hemi`](crate::hemi)'s receiver loops: the portable one
/// and two compiled a second and third time for wider x86-64 processors. Each
/// runs the same `f32` operations in the same order (Rust never fuses a
/// multiply and an add by itself), so each gives the same bits and counts;
/// the wider ones take fewer instructions and, with AVX-512, twice the vector
/// registers.
#[cfg_attr(not(all(feature = "std", target_arch = "x86_64")), allow(dead_code))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Build {
    /// As the crate is compiled.
    Portable,
    /// AVX2 with FMA, BMI1, BMI2, LZCNT and POPCNT (x86-64-v3: every x86-64
    /// processor since 2013–2015).
    Avx2,
    /// The above with AVX-512 F, VL, BW, DQ and CD (x86-64-v4).
    Avx512,
}

/// The widest [`Build`] this processor (and operating system) runs, capped
/// by the environment variable `ANTUMBRA_HEMI_BUILD` (see [`build_cap`]):
/// both read once, on the first call. [`Build::Portable`] off x86-64 and
/// without `std`.
#[inline]
pub(crate) fn widest_build() -> Build {
    #[cfg(feature = "std")]
    {
        static CHOSEN: std::sync::OnceLock<Build> = std::sync::OnceLock::new();
        *CHOSEN.get_or_init(|| {
            let cap = std::env::var("ANTUMBRA_HEMI_BUILD").ok();
            detected_build().min(build_cap(cap.as_deref()))
        })
    }
    #[cfg(not(feature = "std"))]
    {
        Build::Portable
    }
}

/// Defines `unsafe fn $name(build: Build, args) -> ret` that evaluates
/// `body` (an expression of the arguments, inlining what it calls) as
/// compiled for `build`: the one place that lists each [`Build`]'s features.
/// Its safety contract: the processor runs `build` (any build up to
/// [`widest_build`] does). Without `std`, or off x86-64, only the portable
/// build exists.
macro_rules! in_builds {
    ($(#[$doc:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty $body:block) => {
        $(#[$doc])*
        ///
        /// # Safety
        /// The processor runs `build` (any build up to `simd::widest_build()` does).
        #[allow(unsafe_code)]
        $vis unsafe fn $name(build: $crate::simd::Build, $($arg: $ty),*) -> $ret {
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            {
                #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
                fn avx2($($arg: $ty),*) -> $ret $body
                #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
                #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx512cd")]
                fn avx512($($arg: $ty),*) -> $ret $body
                match build {
                    // SAFETY: the caller's contract.
                    $crate::simd::Build::Avx512 => return unsafe { avx512($($arg),*) },
                    // SAFETY: the caller's contract.
                    $crate::simd::Build::Avx2 => return unsafe { avx2($($arg),*) },
                    $crate::simd::Build::Portable => {}
                }
            }
            let _ = build;
            $body
        }
    };
}
pub(crate) use in_builds;

/// The widest build the processor runs.
#[cfg(feature = "std")]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn detected_build() -> Build {
    #[cfg(target_arch = "x86_64")]
    {
        use std::is_x86_feature_detected as has;
        let v3 = has!("avx2")
            && has!("fma")
            && has!("bmi1")
            && has!("bmi2")
            && has!("lzcnt")
            && has!("popcnt");
        let v4 = has!("avx512f")
            && has!("avx512vl")
            && has!("avx512bw")
            && has!("avx512dq")
            && has!("avx512cd");
        match (v3, v4) {
            (true, true) => Build::Avx512,
            (true, false) => Build::Avx2,
            _ => Build::Portable,
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Build::Portable
    }
}

/// The widest build the value of `ANTUMBRA_HEMI_BUILD` allows: `portable`
/// or `avx2` cap it there (valgrind 3.19, for one, stops at an AVX2 register
/// move the compiler emits; `portable` runs there); unset, or anything else,
/// leaves the processor's widest.
#[cfg(feature = "std")]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn build_cap(value: Option<&str>) -> Build {
    match value.map(str::trim) {
        Some(v) if v.eq_ignore_ascii_case("portable") => Build::Portable,
        Some(v) if v.eq_ignore_ascii_case("avx2") => Build::Avx2,
        _ => Build::Avx512,
    }
}

#[cfg(feature = "bvh")]
/// Per-ray constants of the watertight triangle test in lanes: the ray after
/// the axis permutation and shear of `raycast::PreparedRay` (whose fields these
/// are).
// Read only by the AVX kernels.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
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

#[cfg(feature = "bvh")]
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

#[cfg(all(target_arch = "x86_64", feature = "std"))]
/// Eight candidate edges of a soft-shadow sweep, by coordinate (`[axis][lane]`):
/// each edge's endpoints `a`, `b` and the third vertices `u`, `v` of its two
/// adjacent triangles, as [`avx::silhouette_setup8`] takes them.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub(crate) struct EdgeCorners8 {
    pub a: [[f32; 8]; 3],
    pub b: [[f32; 8]; 3],
    pub u: [[f32; 8]; 3],
    pub v: [[f32; 8]; 3],
}

#[cfg(all(target_arch = "x86_64", feature = "std"))]
/// What [`avx::silhouette_setup8`] needs of a soft-shadow receiver, in `f32`
/// (each value rounded once from the sweep's `f64` one).
#[derive(Clone, Copy, Debug)]
pub(crate) struct SweepReceiver8 {
    /// The receiver.
    pub p: [f32; 3],
    /// The receiver's side of the light's plane, a unit direction.
    pub toward: [f32; 3],
    /// The light's centroid's height over the receiver along `toward`.
    pub hc: f32,
    /// The largest coordinate of the centroid relative to the receiver.
    pub cp_max: f32,
    /// The light's vertices relative to the receiver (the first
    /// `light_count`).
    pub lights: [[f32; 3]; crate::ssv::MAX_LIGHT_VERTICES],
    /// Per light vertex, its distance from the receiver times `2 NEAR_ANGLE`.
    pub light_near: [f32; crate::ssv::MAX_LIGHT_VERTICES],
    pub light_count: usize,
    /// Twice the light's tolerance.
    pub tolerance2: f32,
    /// The light's centroid (the sweep's `f32` one, exactly).
    pub centroid: [f32; 3],
    /// The centroid relative to the receiver.
    pub cp: [f32; 3],
    /// The light plane's in-plane axes (pseudo-angles are taken in them).
    pub u_axis: [f32; 3],
    pub v_axis: [f32; 3],
    /// Per axis, the largest `|s - p|` over the samples, each difference
    /// rounded to `f32` (so a bound on every rounded difference).
    pub smax: [f32; 3],
    /// The arc's margin for samples off the light's plane (at least the
    /// sweep's `f64` one), or `None` where the sweep uses no arcs.
    pub shift_margin: Option<f32>,
}

#[cfg(all(target_arch = "x86_64", feature = "std"))]
/// What [`avx::silhouette_planes8`] found for eight silhouette edges: the
/// planes of each edge's per-sample crossing test in `f32` with bounds on
/// their distance from the exact values, and the arc of samples to test.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub(crate) struct SweepPlanes8 {
    /// `(a - p) × (b - p)`, `(a - p) × (c - p)`, `(b - p) × (c - p)` per
    /// axis and lane.
    pub nrm: [[f32; 8]; 3],
    pub amat: [[f32; 8]; 3],
    pub bmat: [[f32; 8]; 3],
    /// `det[a - p, b - p, c - p]` per lane.
    pub det: [f32; 8],
    /// Bounds on the distance of `nrm · s'`, `amat · s'`, `bmat · s'` (any
    /// sample's rounded `s' = s - p`) from their exact values, and the sum
    /// of those three and `det`'s (as the per-sample test takes them).
    pub errs: [[f32; 8]; 4],
    /// The arc's pseudo-angle range `[lo, hi]` (cyclic), where `arc` says so.
    pub lo: [f32; 8],
    pub hi: [f32; 8],
    /// The sample-table buckets of `lo` and `hi` where `arc` says so
    /// (`min(⌊t · ANGLE_SCALE⌋, ANGLE_BUCKETS - 1)`, as the sweep buckets
    /// a pseudo-angle `t`).
    pub buckets: [[i32; 8]; 2],
    /// Lanes whose planes are finite and whose centroid side is certain.
    pub decided: u32,
    /// Of those, the centroid is on the positive side of the plane `(p, a, b)`.
    pub centroid_positive: u32,
    /// Lanes whose arc is certain to hold every sample the edge may cross.
    pub arc: u32,
}

#[cfg(all(test, target_arch = "x86_64", feature = "std"))]
/// One silhouette edge's planes from [`SweepPlanes8`], as the one-edge
/// sample pass `avx::crossings8` (the tests' twin) takes them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct EdgePlanes8 {
    pub nrm: [f32; 3],
    pub amat: [f32; 3],
    pub bmat: [f32; 3],
    pub det: f32,
    /// The bounds of `nrm · s'`, `amat · s'`, `bmat · s'`, and the sum of
    /// those three and `det`'s.
    pub errs: [f32; 4],
    /// The wanted side (opposite the centroid's) is the positive one.
    pub want: bool,
}

#[cfg(all(target_arch = "x86_64", feature = "std"))]
impl SweepPlanes8 {
    /// Lane `i`'s planes.
    #[cfg(test)]
    pub(crate) fn lane(&self, i: usize) -> EdgePlanes8 {
        EdgePlanes8 {
            nrm: self.nrm.map(|v| v[i]),
            amat: self.amat.map(|v| v[i]),
            bmat: self.bmat.map(|v| v[i]),
            det: self.det[i],
            errs: self.errs.map(|e| e[i]),
            want: self.want(i),
        }
    }

    /// Whether lane `i`'s wanted side (the one away from the centroid) is
    /// the positive one.
    #[inline]
    pub(crate) fn want(&self, i: usize) -> bool {
        self.centroid_positive >> i & 1 == 0
    }
}

/// Per candidate (bit `i` for lane `i`), what the soft-shadow sweep's
/// set-up in lanes decided (`avx::silhouette_setup8`, where AVX runs).
#[cfg_attr(not(all(target_arch = "x86_64", feature = "std")), allow(dead_code))]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SetupMasks8 {
    /// Left to the scalar set-up (a sign or comparison within its bound, or
    /// an edge without exactly two adjacent triangles).
    pub undecided: u32,
    /// Certainly no silhouette at the receiver, or out of reach.
    pub idle: u32,
    /// Of the others (silhouettes, weight ±2): the weight is positive.
    pub positive: u32,
    /// Of the silhouettes: recorded as near the light.
    pub near: u32,
    /// Of the silhouettes: their plane cuts the light, so they are swept.
    pub sweep: u32,
}

/// The eight octants of a soft-shadow hierarchy node, as the eight-lane edge
/// tests of `ssv::edge_bounds` (portable) and [`avx::edge_octants8`] take
/// them: lane `i` is octant `i` (bit 0 of `i`: upper half in x, 1: in y, 2:
/// in z).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Octants8 {
    /// Per axis, each octant's centre coordinate.
    pub axis_mid: [[f32; 8]; 3],
    /// Per octant, its highest point above the light's plane (0 if none).
    pub above: [f32; 8],
    /// Per octant, its lowest point below the light's plane, as a height.
    pub below: [f32; 8],
    /// The parent's centre.
    pub centre: [f32; 3],
    /// Half an octant's extent per axis.
    pub quarter: [f32; 3],
    /// Margin of every comparison.
    pub margin: f32,
}

/// `±1` per octant and axis: the side of each octant's centre from its
/// parent's.
pub(crate) const OCTANT_SIGN: [[f32; 8]; 3] = {
    let mut s = [[0.0; 8]; 3];
    let mut i = 0;
    while i < 8 {
        let mut axis = 0;
        while axis < 3 {
            s[axis][i] = if i >> axis & 1 == 1 { 1.0 } else { -1.0 };
            axis += 1;
        }
        i += 1;
    }
    s
};

/// Layout of one edge record of `ssv::edge_bounds`, in `f32`s: the side of the
/// light's plane the edge is on (`±1`, 0 across it), the inverse of its
/// smallest height, the number of directions; per axis `[min, max, climb,
/// fall]`; the two adjacent triangles' planes `[nx, ny, nz, d]`; then the
/// directions `[nx, ny, nz, min, max, climb, fall]` in groups of
/// [`GROUP_LANES`](edge_record::GROUP_LANES), each field of a group's
/// directions contiguous (lanes over directions: the octant tests take eight
/// directions per operation). Lanes past the directions used hold a zero
/// normal, NaN min and max, and zero climb and fall: every comparison with
/// the NaN bounds is false, so they separate nothing.
pub(crate) mod edge_record {
    /// `±1` or 0.
    pub const SIDE: usize = 0;
    /// `1 / smallest height` above (or below) the light's plane.
    pub const INVERSE: usize = 1;
    /// Directions used.
    pub const COUNT: usize = 2;
    /// Axis bounds, four per axis.
    pub const AXES: usize = 3;
    /// Triangle planes, four each.
    pub const PLANES: usize = AXES + 12;
    /// First group of directions.
    pub const DIRECTIONS: usize = PLANES + 8;
    /// Fields per direction.
    pub const DIRECTION: usize = 7;
    /// Directions per group.
    pub const GROUP_LANES: usize = 8;
    /// `f32`s per group: field `f` of the group's direction `l` at
    /// `f * GROUP_LANES + l`.
    pub const GROUP: usize = DIRECTION * GROUP_LANES;
}

#[cfg(all(test, feature = "std"))]
mod tests {
    use super::{Build, build_cap};

    #[test]
    fn the_environment_caps_the_build() {
        assert_eq!(build_cap(None), Build::Avx512);
        assert_eq!(build_cap(Some("portable")), Build::Portable);
        assert_eq!(build_cap(Some(" Portable\n")), Build::Portable);
        assert_eq!(build_cap(Some("AVX2")), Build::Avx2);
        assert_eq!(build_cap(Some("avx512")), Build::Avx512);
        assert_eq!(build_cap(Some("")), Build::Avx512);
        assert_eq!(build_cap(Some("sse")), Build::Avx512);
    }
}
