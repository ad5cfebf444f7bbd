//! Ray casting: the [`RayCaster`] trait every algorithm that needs rays goes through,
//! the watertight ray–triangle test, and the brute-force caster that is the
//! obviously-right reference for every accelerated caster.
//!
//! Semantics, shared by every implementation and by the C API: a ray
//! `origin + t * direction` hits a triangle when `t_min < t < t_max`, with `t` in
//! units of the direction's length (directions need not be normalised). Triangles
//! are two-sided. A ray with a zero direction or a non-finite origin, direction or
//! NaN interval end hits nothing.
//!
//! The triangle test is the watertight algorithm of Woop, Benthin and Wald,
//! "Watertight Ray/Triangle Intersection" (JCGT 2013): a ray through a shared edge
//! or vertex hits at least one of the triangles that share it, so closed meshes
//! have no pinholes. Edge functions that round to exactly zero are recomputed in
//! `f64`, as the paper prescribes. When `f32` would overflow or underflow (ray and
//! triangle more than ~1e12 apart, or a triangle smaller than ~1e-13 near the
//! ray), the whole test is redone in `f64`, which covers every finite `f32` input.

#[cfg(feature = "bvh")]
mod bvh;

#[cfg(feature = "bvh")]
pub use bvh::{BuildQuality, BvhError, BvhScene};

/// Largest coordinate magnitude a [`BvhScene`](crate::raycast) accepts (and the C
/// API accepts in every build, so both builds refuse the same meshes). obvhs's
/// builder breaks (index out of bounds) on scenes near 1e17 and beyond; 1e12
/// leaves a wide margin and is far beyond any real scene in any unit.
pub const MAX_COORDINATE: f32 = 1e12;

use glam::{BVec4A, Vec3, Vec4};

use crate::geom::MeshView;

/// A ray segment: the points `origin + t * direction` with `t_min < t < t_max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start of the ray.
    pub origin: Vec3,
    /// Direction; any non-zero length, `t` is measured in units of it.
    pub direction: Vec3,
    /// Hits at or before this parameter are ignored.
    pub t_min: f32,
    /// Hits at or beyond this parameter are ignored (may be `f32::INFINITY`).
    pub t_max: f32,
}

impl Ray {
    /// A ray over the open segment `(0, t_max)`, the C API's convention.
    #[inline]
    pub fn new(origin: Vec3, direction: Vec3, t_max: f32) -> Self {
        Ray {
            origin,
            direction,
            t_min: 0.0,
            t_max,
        }
    }

    /// Whether origin and direction are finite, the direction is not zero, and the
    /// interval is not NaN. Rays that fail this hit nothing.
    #[inline]
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.direction.is_finite()
            && self.direction != Vec3::ZERO
            && !self.t_min.is_nan()
            && !self.t_max.is_nan()
    }
}

/// The closest intersection of a ray with a mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit, in units of the direction's length.
    pub t: f32,
    /// Index of the triangle hit, in the mesh's order.
    pub triangle: u32,
    /// Barycentric weight of the triangle's second corner.
    pub u: f32,
    /// Barycentric weight of the triangle's third corner; the hit point is
    /// `(1 - u - v) * a + u * b + v * c` (Embree's convention).
    pub v: f32,
}

/// Something that answers visibility queries against a fixed set of triangles.
///
/// Implement it to plug an engine's own tracer into Antumbra; the `bvh` feature
/// ships [`BvhScene`]. Implementations must follow the module's semantics, and
/// queries through `&self` must be safe to run from many threads when the type is
/// `Sync`.
pub trait RayCaster {
    /// Whether any triangle is hit with `t_min < t < t_max`.
    fn occluded(&self, ray: &Ray) -> bool;

    /// [`Self::occluded`] of each ray of `rays`, written to the same index of
    /// `occluded`. A caster may trace the rays together (the BVH scene traces
    /// up to 64 rays as one packet, fastest for rays
    /// that start together, such as a bake's from one vertex); each answer is
    /// the one [`Self::occluded`] gives.
    ///
    /// # Panics
    ///
    /// When the two slices differ in length.
    fn occluded_many(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(
            rays.len(),
            occluded.len(),
            "occluded_many: one answer per ray"
        );
        for (ray, out) in rays.iter().zip(occluded.iter_mut()) {
            *out = self.occluded(ray);
        }
    }

    /// The hit with the smallest `t` in `(t_min, t_max)`, if any. Ties between
    /// triangles at the same `t` may resolve to either.
    fn closest_hit(&self, ray: &Ray) -> Option<Hit>;

    /// [`Self::closest_hit`] of each ray of `rays`, written to the same index
    /// of `hits`, traced together as [`Self::occluded_many`] traces them. Each
    /// hit has the `t` of [`Self::closest_hit`]; ties between triangles at the
    /// same `t` may resolve to either, not always as one ray alone does.
    ///
    /// # Panics
    ///
    /// When the two slices differ in length.
    fn closest_hit_many(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(
            rays.len(),
            hits.len(),
            "closest_hit_many: one answer per ray"
        );
        for (ray, out) in rays.iter().zip(hits.iter_mut()) {
            *out = self.closest_hit(ray);
        }
    }
}

/// A ray prepared for many watertight triangle tests: the axis permutation and
/// shear of Woop et al. that make the ray the +z axis.
#[derive(Clone, Copy, Debug)]
pub struct PreparedRay {
    origin: Vec3,
    direction: Vec3,
    axes: [usize; 3],
    shear: Vec3,
    t_min: f32,
    t_max: f32,
}

/// Below this |det| (or with a non-finite intermediate) the f32 test may have lost
/// precision to underflow: far above the subnormal range, so f32 results that pass
/// are fully precise.
const WIDE_DETERMINANT: f32 = 1e-30;
/// Sheared corner coordinates all below this: their products would underflow.
const WIDE_EXTENT: f32 = 1e-15;

/// Where a ray crosses one triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter.
    pub t: f32,
    /// Barycentric weight of the second corner.
    pub u: f32,
    /// Barycentric weight of the third corner.
    pub v: f32,
}

impl PreparedRay {
    /// Prepares `ray`; `None` when the ray is not [`Ray::is_valid`].
    #[inline]
    pub fn new(ray: &Ray) -> Option<Self> {
        if !ray.is_valid() {
            return None;
        }
        // Arrays indexed by a run-time axis are loads; `Vec3` indexed so is a chain
        // of branches, unpredictable here as directions vary from ray to ray.
        let d = ray.direction.to_array();
        let abs = d.map(f32::abs);
        let kz = if abs[0] > abs[1] {
            if abs[0] > abs[2] { 0 } else { 2 }
        } else if abs[1] > abs[2] {
            1
        } else {
            2
        };
        const NEXT: [usize; 3] = [1, 2, 0];
        let kx = NEXT[kz];
        let ky = NEXT[kx];
        // Keep the winding of the permuted axes when looking down -z.
        let (kx, ky) = if d[kz] < 0.0 { (ky, kx) } else { (kx, ky) };
        let shear = Vec3::new(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
        Some(PreparedRay {
            origin: ray.origin,
            direction: ray.direction,
            axes: [kx, ky, kz],
            shear,
            t_min: ray.t_min,
            t_max: ray.t_max,
        })
    }

    /// The constants of the eight-lane triangle test ([`crate::simd::avx`]).
    #[cfg(all(feature = "bvh", target_arch = "x86_64"))]
    #[inline(always)]
    pub(crate) fn sheared(&self) -> crate::simd::ShearedRay {
        crate::simd::ShearedRay {
            origin: self.origin.to_array(),
            axes: self.axes,
            shear: self.shear.to_array(),
            t_min: self.t_min,
        }
    }

    /// Upper end of the ray interval.
    #[inline]
    pub fn t_max(&self) -> f32 {
        self.t_max
    }

    /// Shortens the interval to `(t_min, t_max)`; used for closest-hit search.
    #[inline]
    pub fn set_t_max(&mut self, t_max: f32) {
        self.t_max = t_max;
    }

    /// The watertight test against triangle `(a, b, c)`, two-sided.
    #[inline]
    pub fn intersect(&self, a: Vec3, b: Vec3, c: Vec3) -> Option<TriangleHit> {
        self.intersect_in(a, b, c, self.axes)
    }

    /// [`Self::intersect`] with the permuted axes `[kx, ky, kz]` (`self.axes`).
    /// The corners are indexed as arrays: an array indexed by a run-time axis is a
    /// load, a `Vec3` so indexed a chain of branches per coordinate (and one copy
    /// of the test per permutation would still pay an unpredictable branch per
    /// ray).
    #[inline(always)]
    fn intersect_in(
        &self,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        [kx, ky, kz]: [usize; 3],
    ) -> Option<TriangleHit> {
        let s = self.shear;
        let corners = (a, b, c);
        let a = (a - self.origin).to_array();
        let b = (b - self.origin).to_array();
        let c = (c - self.origin).to_array();
        let ax = a[kx] - s.x * a[kz];
        let ay = a[ky] - s.y * a[kz];
        let bx = b[kx] - s.x * b[kz];
        let by = b[ky] - s.y * b[kz];
        let cx = c[kx] - s.x * c[kz];
        let cy = c[ky] - s.y * c[kz];

        // Below this lateral extent the f32 edge products would underflow. The
        // common case, some coordinate at least `WIDE_EXTENT` (a comparison that
        // is false for NaN), is decided by six plain comparisons; only otherwise
        // is the extent itself (NaN-ignoring `max`, several instructions each)
        // computed. Same outcome as testing the extent directly: it is below
        // `WIDE_EXTENT` exactly when no coordinate reaches it and one is a number.
        let reaches = |v: f32| v.abs() >= WIDE_EXTENT;
        let wide_enough =
            reaches(ax) | reaches(ay) | reaches(bx) | reaches(by) | reaches(cx) | reaches(cy);
        if !wide_enough {
            let extent = ax
                .abs()
                .max(ay.abs())
                .max(bx.abs())
                .max(by.abs())
                .max(cx.abs())
                .max(cy.abs());
            if extent < WIDE_EXTENT {
                // Zero extent: every corner on the ray's line, a degenerate miss.
                return (extent > 0.0)
                    .then(|| self.intersect_wide(corners.0, corners.1, corners.2))?;
            }
        }
        let mut eu = cx * by - cy * bx;
        let mut ev = ax * cy - ay * cx;
        let mut ew = bx * ay - by * ax;
        if eu == 0.0 || ev == 0.0 || ew == 0.0 {
            // Exactly-zero edge functions decide edge ownership: redo them in f64.
            let (ax, ay, bx, by, cx, cy) = (
                f64::from(ax),
                f64::from(ay),
                f64::from(bx),
                f64::from(by),
                f64::from(cx),
                f64::from(cy),
            );
            eu = (cx * by - cy * bx) as f32;
            ev = (ax * cy - ay * cx) as f32;
            ew = (bx * ay - by * ax) as f32;
        }
        if !(eu.is_finite() && ev.is_finite() && ew.is_finite()) {
            return self.intersect_wide(corners.0, corners.1, corners.2);
        }
        if (eu < 0.0 || ev < 0.0 || ew < 0.0) && (eu > 0.0 || ev > 0.0 || ew > 0.0) {
            return None;
        }
        let det = eu + ev + ew;
        if det == 0.0 {
            return None;
        }
        let az = s.z * a[kz];
        let bz = s.z * b[kz];
        let cz = s.z * c[kz];
        let scaled_t = eu * az + ev * bz + ew * cz;
        if !scaled_t.is_finite()
            || det.abs() < WIDE_DETERMINANT
            || scaled_t.abs() < WIDE_DETERMINANT
        {
            return self.intersect_wide(corners.0, corners.1, corners.2);
        }
        let inv_det = 1.0 / det;
        let t = scaled_t * inv_det;
        self.accept(t, ev * inv_det, ew * inv_det)
    }

    #[inline]
    fn accept(&self, t: f32, u: f32, v: f32) -> Option<TriangleHit> {
        (t > self.t_min && t < self.t_max).then_some(TriangleHit { t, u, v })
    }

    /// The same test entirely in `f64`, for inputs whose `f32` products overflow or
    /// underflow. `a`, `b`, `c` are the original corners.
    #[cold]
    fn intersect_wide(&self, a: Vec3, b: Vec3, c: Vec3) -> Option<TriangleHit> {
        let [kx, ky, kz] = self.axes;
        let wide = |v: Vec3| [f64::from(v.x), f64::from(v.y), f64::from(v.z)];
        let (o, d) = (wide(self.origin), wide(self.direction));
        let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
        let shear = |p: Vec3| {
            let p = wide(p);
            let q = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
            (q[kx] - sx * q[kz], q[ky] - sy * q[kz], sz * q[kz])
        };
        let (ax, ay, az) = shear(a);
        let (bx, by, bz) = shear(b);
        let (cx, cy, cz) = shear(c);
        let eu = cx * by - cy * bx;
        let ev = ax * cy - ay * cx;
        let ew = bx * ay - by * ax;
        if (eu < 0.0 || ev < 0.0 || ew < 0.0) && (eu > 0.0 || ev > 0.0 || ew > 0.0) {
            return None;
        }
        let det = eu + ev + ew;
        if det == 0.0 {
            return None;
        }
        let t = (eu * az + ev * bz + ew * cz) / det;
        self.accept(t as f32, (ev / det) as f32, (ew / det) as f32)
    }
}

/// Up to four triangles with their coordinates in lanes, for
/// [`PreparedRay::intersect_lanes`]: `corners[corner][axis]` holds that
/// coordinate of each lane's triangle. Lanes beyond a block's triangle count
/// repeat one of its triangles, so they hold ordinary numbers.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(not(feature = "bvh"), allow(dead_code))]
pub(crate) struct TriangleLanes {
    pub(crate) corners: [[Vec4; 3]; 3],
}

#[cfg_attr(not(feature = "bvh"), allow(dead_code))]
impl TriangleLanes {
    /// Triangles `triangles[..]` (one to four) in lanes, the last repeated into
    /// the lanes beyond them.
    pub(crate) fn new(triangles: &[[Vec3; 3]]) -> Self {
        let lane = |i: usize| triangles[i.min(triangles.len() - 1)];
        TriangleLanes {
            corners: core::array::from_fn(|corner| {
                core::array::from_fn(|axis| {
                    Vec4::from_array(core::array::from_fn(|i| lane(i)[corner][axis]))
                })
            }),
        }
    }

    /// The corners of lane `lane`'s triangle.
    #[inline(always)]
    pub(crate) fn triangle(&self, lane: usize) -> [Vec3; 3] {
        self.corners
            .map(|[x, y, z]| Vec3::new(x[lane], y[lane], z[lane]))
    }
}

/// What [`PreparedRay::intersect_lanes`] decided for four triangles.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(not(feature = "bvh"), allow(dead_code))]
pub(crate) struct LaneHits {
    /// Bit `i` set when lane `i`'s triangle is hit at `t[i]` with barycentrics
    /// `u[i]`, `v[i]`: exactly what [`PreparedRay::intersect`] returns for it.
    pub(crate) hits: u32,
    /// Bit `i` set when lane `i` left the common `f32` path (an edge function
    /// exactly zero, a possible overflow or underflow): only
    /// [`PreparedRay::intersect`] on that triangle decides it. Lanes in neither
    /// mask are misses.
    pub(crate) undecided: u32,
    /// Ray parameter per lane (meaningful for hits only).
    pub(crate) t: Vec4,
    /// Barycentric weight of the second corner per lane.
    pub(crate) u: Vec4,
    /// Barycentric weight of the third corner per lane.
    pub(crate) v: Vec4,
}

#[cfg_attr(not(feature = "bvh"), allow(dead_code))]
impl PreparedRay {
    /// [`Self::intersect`] on four triangles at once, in glam's `Vec4` lanes
    /// (SSE on x86-64, NEON on aarch64, plain arrays elsewhere): each lane does the `f32` operations of the
    /// common path of [`Self::intersect`], in the same order with the same
    /// operands, so a lane it decides gets the same answer bit for bit; a lane
    /// that would leave that path (to the `f64` edge functions or the wide test)
    /// is reported undecided instead, for the caller to hand to
    /// [`Self::intersect`]. Tested lane by lane against it.
    #[inline(always)]
    pub(crate) fn intersect_lanes(&self, lanes: &TriangleLanes) -> LaneHits {
        let [kx, ky, kz] = self.axes;
        let origin = self.origin.to_array();
        let s = self.shear;
        let (sx, sy, sz) = (Vec4::splat(s.x), Vec4::splat(s.y), Vec4::splat(s.z));
        let relative =
            |corner: usize, axis: usize| lanes.corners[corner][axis] - Vec4::splat(origin[axis]);
        let sheared = |corner: usize| {
            let depth = relative(corner, kz);
            (
                relative(corner, kx) - sx * depth,
                relative(corner, ky) - sy * depth,
                depth,
            )
        };
        let (ax, ay, a_depth) = sheared(0);
        let (bx, by, b_depth) = sheared(1);
        let (cx, cy, c_depth) = sheared(2);
        let reaches = |v: Vec4| v.abs().cmpge(Vec4::splat(WIDE_EXTENT));
        let wide_enough =
            reaches(ax) | reaches(ay) | reaches(bx) | reaches(by) | reaches(cx) | reaches(cy);
        let eu = cx * by - cy * bx;
        let ev = ax * cy - ay * cx;
        let ew = bx * ay - by * ax;
        let zero = Vec4::ZERO;
        let some_zero = eu.cmpeq(zero) | ev.cmpeq(zero) | ew.cmpeq(zero);
        let finite = eu.is_finite_mask() & ev.is_finite_mask() & ew.is_finite_mask();
        let negative = eu.cmplt(zero) | ev.cmplt(zero) | ew.cmplt(zero);
        let positive = eu.cmpgt(zero) | ev.cmpgt(zero) | ew.cmpgt(zero);
        let inside = !(negative & positive);
        let det = eu + ev + ew;
        let crossed = inside & det.cmpne(zero);
        let scaled_t = eu * (sz * a_depth) + ev * (sz * b_depth) + ew * (sz * c_depth);
        let threshold = Vec4::splat(WIDE_DETERMINANT);
        let imprecise = !scaled_t.is_finite_mask()
            | det.abs().cmplt(threshold)
            | scaled_t.abs().cmplt(threshold);
        let undecided: BVec4A = !wide_enough | some_zero | !finite | (crossed & imprecise);
        let inv_det = Vec4::ONE / det;
        let t = scaled_t * inv_det;
        let accepted = t.cmpgt(Vec4::splat(self.t_min)) & t.cmplt(Vec4::splat(self.t_max));
        LaneHits {
            hits: (crossed & accepted & !undecided).bitmask(),
            undecided: undecided.bitmask(),
            t,
            u: ev * inv_det,
            v: ew * inv_det,
        }
    }
}

/// The reference caster: tests every triangle of a mesh for every ray.
///
/// `O(triangles)` per ray and allocation-free; use it to check faster casters and
/// for tiny scenes.
#[derive(Clone, Copy, Debug)]
pub struct BruteForceCaster<'a> {
    mesh: MeshView<'a>,
}

impl<'a> BruteForceCaster<'a> {
    /// A caster over `mesh`.
    pub fn new(mesh: MeshView<'a>) -> Self {
        BruteForceCaster { mesh }
    }
}

impl RayCaster for BruteForceCaster<'_> {
    fn occluded(&self, ray: &Ray) -> bool {
        let Some(prepared) = PreparedRay::new(ray) else {
            return false;
        };
        self.mesh
            .triangles()
            .any(|[a, b, c]| prepared.intersect(a, b, c).is_some())
    }

    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        let mut prepared = PreparedRay::new(ray)?;
        let mut best = None;
        for (triangle, [a, b, c]) in self.mesh.triangles().enumerate() {
            if let Some(hit) = prepared.intersect(a, b, c) {
                prepared.set_t_max(hit.t);
                best = Some(Hit {
                    t: hit.t,
                    triangle: triangle as u32,
                    u: hit.u,
                    v: hit.v,
                });
            }
        }
        best
    }
}

/// Occlusion for many rays: `out[i] = caster.occluded(&rays[i])`, through
/// [`RayCaster::occluded_many`] (so neighbouring rays that start together are
/// traced as packets).
///
/// With the `parallel` feature the rays are split across rayon's thread pool;
/// results are identical either way. Panics if `out` and `rays` differ in length.
pub fn occluded_batch<C: RayCaster + Sync + ?Sized>(caster: &C, rays: &[Ray], out: &mut [bool]) {
    assert_eq!(rays.len(), out.len(), "one output per ray");
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        out.par_chunks_mut(BATCH_GRAIN)
            .zip(rays.par_chunks(BATCH_GRAIN))
            .for_each(|(o, r)| caster.occluded_many(r, o));
    }
    #[cfg(not(feature = "parallel"))]
    caster.occluded_many(rays, out);
}

/// Closest hits for many rays: `out[i] = caster.closest_hit(&rays[i])`, in
/// parallel with the `parallel` feature. Panics if the lengths differ.
pub fn closest_hit_batch<C: RayCaster + Sync + ?Sized>(
    caster: &C,
    rays: &[Ray],
    out: &mut [Option<Hit>],
) {
    assert_eq!(rays.len(), out.len(), "one output per ray");
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        out.par_iter_mut()
            .zip(rays.par_iter())
            .with_min_len(BATCH_GRAIN)
            .for_each(|(o, r)| *o = caster.closest_hit(r));
    }
    #[cfg(not(feature = "parallel"))]
    for (o, r) in out.iter_mut().zip(rays) {
        *o = caster.closest_hit(r);
    }
}

/// Rays per rayon task: enough that scheduling costs little against the casts.
#[cfg(feature = "parallel")]
const BATCH_GRAIN: usize = 256;

#[cfg(test)]
mod tests;
