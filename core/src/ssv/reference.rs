//! The reference decision of a query: which samples of least depth
//! complexity are blocked, by one `f32` ray away from every silhouette edge
//! it might cross differently from the exact segment, else exactly.

use super::*;

/// Pieces of a segment whose boxes find the triangles of an exact reference
/// decision ([`SoftShadows::exactly_blocked`]); a power of two, so the
/// pieces' parameters are exact.
#[cfg(feature = "bvh")]
pub(super) const SEGMENT_PIECES: usize = 32;

/// Most hits the reference ray re-checks exactly before it calls the segment
/// blocked (each is a hit the `f32` caster reports that the exact test refutes,
/// such as a triangle through a receiver on a surface).
pub(super) const MAX_REFUTED_HITS: usize = 64;

/// Most silhouette edges a query records for [`SoftShadows::reference_sample`];
/// past this every reference decision is exact ([`SoftShadows::exactly_blocked`]).
pub(super) const RECORDED_SILHOUETTES: usize = 1024;

/// Angle (as a sine) within which a reference segment counts as near a
/// silhouette edge, as seen from the receiver. The `f32` ray departs from the
/// exact segment by a few units of `f32` rounding in angle (the rounded
/// direction, the corners moved to the origin and sheared, the edge functions'
/// own rounding: about `20 ε₃₂ ≈ 1.2e-6` in all), so beyond this the ray crosses
/// each silhouette edge on the same side as the segment, with a factor of fifty
/// to spare.
pub(super) const NEAR_ANGLE: f64 = 1.0 / 16384.0;

/// Reference candidates tried before a query decides its reference exactly.
pub(super) const REFERENCE_TRIES: usize = 8;

/// The silhouette edges of one receiver whose plane through it comes within
/// [`NEAR_ANGLE`] of the light (the edges near which an `f32` ray can cross
/// differently from the exact segment), each with that plane's normal.
///
/// The slots are left uninitialised until recorded: a query makes one of
/// these 16 KiB records on its stack, and writing it whole would cost more than
/// the bunny's reference ray.
pub(super) struct Silhouettes {
    /// The first `len` are written.
    pub(super) slots: [MaybeUninit<Recorded>; RECORDED_SILHOUETTES],
    pub(super) len: usize,
    /// More edges were met than fit.
    pub(super) overflow: bool,
    /// The first edge that did not fit (with `overflow`): the edges met
    /// before it that are not recorded are not near.
    pub(super) first_unrecorded: u32,
}

/// A recorded silhouette edge: `a' × b'` scaled by a power of two
/// ([`scaled_normal`]) and rounded to `f32` (the test that reads it allows
/// for that), then the edge; sixteen bytes, so that the lanes read eight of
/// them as rows of four ([`crate::simd::avx::beyond_planes8`]).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct Recorded {
    pub(super) normal: [f32; 3],
    pub(super) edge: u32,
}

impl Recorded {
    /// The normal and the edge's bits as four `f32` (the lanes' rows; the
    /// fourth is only moved, never computed with).
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    fn as_row(&self) -> &[f32; 4] {
        bytemuck::cast_ref(self)
    }
}

impl Silhouettes {
    pub(super) fn new() -> Self {
        Silhouettes {
            slots: [const { MaybeUninit::uninit() }; RECORDED_SILHOUETTES],
            len: 0,
            overflow: false,
            first_unrecorded: 0,
        }
    }

    /// Records edge `edge` with `normal`, the normal of its plane through the
    /// receiver at any length (`a' × b'`: no square root or division per
    /// edge; the test compares squares).
    pub(super) fn record(&mut self, edge: u32, normal: DVec3) {
        self.record_scaled(edge, scaled_normal(normal));
    }

    /// [`Silhouettes::record`] with the normal already scaled and rounded
    /// ([`scaled_normal`]; the lanes make eight at once).
    #[inline]
    pub(super) fn record_scaled(&mut self, edge: u32, scaled: [f32; 3]) {
        match self.slots.get_mut(self.len) {
            Some(slot) => {
                slot.write(Recorded {
                    normal: scaled,
                    edge,
                });
                self.len += 1;
            }
            None => {
                if !self.overflow {
                    self.first_unrecorded = edge;
                }
                self.overflow = true;
            }
        }
    }

    /// The recorded edges and normals (each of any length).
    #[cfg(test)]
    pub(super) fn recorded(&self) -> impl Iterator<Item = (u32, Vec3)> + '_ {
        self.written()
            .iter()
            .map(|r| (r.edge, Vec3::from_array(r.normal)))
    }

    /// The written slots.
    fn written(&self) -> &[Recorded] {
        #[allow(unsafe_code)]
        // SAFETY: `record_scaled` writes slot `len` before it increments
        // `len` (which never passes the slots' number), and nothing else
        // changes either, so every slot below `len` holds a written value (a
        // plain `Copy` struct); `MaybeUninit<Recorded>` has the layout of
        // `Recorded`.
        unsafe {
            core::slice::from_raw_parts(self.slots.as_ptr().cast::<Recorded>(), self.len)
        }
    }

    /// Whether direction `sw` (from the receiver) is clear of every recorded
    /// silhouette's plane by the prefilter, or else of the edge itself by
    /// `near`: for each, `(n · sw)² > bound² |sw|² (n · n)` (in `f64`) or
    /// `!near(sw, edge)`. Where AVX runs the prefilter first takes eight
    /// at a time in `f32` ([`crate::simd::avx::beyond_planes8`]), with a
    /// threshold above `bound² |sw|²` by more than that test's rounding,
    /// so that each edge it clears the `f64` test clears as well: the same
    /// answer, the `f64` test (and `near`) left to the few it does not
    /// clear.
    pub(super) fn clear_of(
        &self,
        sw: DVec3,
        bound: f64,
        near: impl Fn(DVec3, u32) -> bool,
    ) -> bool {
        let length2 = sw.length_squared();
        let bound_squared = bound * bound * length2;
        let clear = |r: &Recorded| {
            let n = Vec3::from_array(r.normal).as_dvec3();
            let along = n.dot(sw);
            along * along > bound_squared * n.length_squared() || !near(sw, r.edge)
        };
        let written = self.written();
        #[cfg(all(target_arch = "x86_64", feature = "std"))]
        if let Some(threshold) = lane_threshold(length2, bound)
            && crate::simd::avx_available()
        {
            let s = sw.as_vec3().to_array();
            let mut chunks = written.chunks_exact(8);
            for chunk in &mut chunks {
                let rows = core::array::from_fn(|i| chunk[i].as_row());
                #[allow(unsafe_code)]
                // SAFETY: the processor runs AVX (checked above).
                let beyond = unsafe { crate::simd::avx::beyond_planes8(rows, s, threshold) };
                let mut open = !beyond & 0xFF;
                while open != 0 {
                    if !clear(&chunk[open.trailing_zeros() as usize]) {
                        return false;
                    }
                    open &= open - 1;
                }
            }
            return chunks.remainder().iter().all(clear);
        }
        written.iter().all(clear)
    }
}

/// The `f32` threshold of [`Silhouettes::clear_of`]'s lanes for a direction
/// `sw` of squared length `length2` and the `f64` test's bound `b`, or
/// `None` where `|sw|²` is outside `[10⁻²⁰, 10³⁰]` (the lanes then take no
/// part).
///
/// The lanes take `s = sw` rounded to `f32` and only normals with
/// `n · n >= 1/4` (every finite non-zero scaled normal: its largest
/// component is at least `1/2`; a zero or non-finite one fails that check
/// or compares false), so `|n| |s|` is far above `f32`'s underflow. Their
/// `n · s` is then within `5u |n| |s|` of the exact `n · sw` (`u = 2⁻²⁴`:
/// `s`'s rounding, three products' and two sums'), and the squares and
/// products of the test within a few `u` relative. So a lane with
/// `(n · s)² > (1.001 b + 8u)² |sw|² (n · n)` has
/// `|n · sw| > (1.001 b + 3u) |n| |sw| (1 - 10u)`, above `b |n| |sw|` by far
/// more than the `f64` test's own rounding: that test clears it too.
#[cfg(all(target_arch = "x86_64", feature = "std"))]
fn lane_threshold(length2: f64, b: f64) -> Option<f32> {
    if !(1e-20..=1e30).contains(&length2) {
        return None;
    }
    let u = f64::from(f32::EPSILON) / 2.0;
    let widened = 1.001 * b + 8.0 * u;
    // Rounded up past `f32`'s rounding.
    let threshold = (widened * widened * length2 * (1.0 + 1e-5)) as f32;
    threshold.is_finite().then_some(threshold)
}

/// `n` times the power of two that brings its largest component into
/// `[0.5, 1)`, rounded to `f32`. The scaling is exact and keeps the direction,
/// so the rounding moves the direction by at most `√3 · 2⁻²⁴ ≈ 1e-7`, as
/// rounding a unit normal would; no component can overflow, and one that
/// falls below `f32`'s normal range is off by under `1e-38`. A zero or
/// non-finite `n` is kept as it is (the test that reads it then decides
/// exactly).
pub(super) fn scaled_normal(n: DVec3) -> [f32; 3] {
    let largest = n.abs().max_element();
    // Biased exponent of `largest`, a normal f64 (a cross product of
    // differences of f32 coordinates is at least 2^-298 when not zero).
    let exponent = (largest.to_bits() >> 52) & 0x7FF;
    if largest == 0.0 || !(1..2045).contains(&exponent) {
        return n.as_vec3().to_array();
    }
    // 2^(1022 - e), e the unbiased exponent: biased, 2045 minus the biased one.
    let scale = f64::from_bits((2045 - exponent) << 52);
    (n * scale).as_vec3().to_array()
}

impl SoftShadows {
    /// Whether the samples of least relative depth complexity `min` (in
    /// `counters`, angular order) are blocked: exactly when the segment to any
    /// one of them meets a triangle (they share the depth complexity).
    ///
    /// An `f32` ray decides it when the segment keeps clear of every
    /// silhouette edge the sweep met ([`Self::reference_sample`]): then the
    /// ray, within a few units of `f32` rounding of the segment, meets the
    /// surfaces the segment meets. Near an edge that is not a silhouette from
    /// `p` the two triangles are on either side of the segment's plane and
    /// the watertight test cannot slip between them; near a silhouette edge
    /// it can (the segment grazing a surface that the ray misses, or a
    /// boundary edge). Without such a sample among the first tries, or when a
    /// hit away from the receiver's own plane is refuted, the decision is
    /// exact ([`Self::exactly_blocked`]).
    pub(super) fn minimum_blocked(
        &self,
        p: Vec3,
        counters: &[i32],
        min: i32,
        silhouettes: &Silhouettes,
    ) -> bool {
        let candidates = counters
            .iter()
            .enumerate()
            .filter(|&(_, &r)| r == min)
            .map(|(k, _)| k);
        match self.reference_sample(p, candidates, silhouettes) {
            Some(s) => self
                .reference_blocked(p, s, true)
                .unwrap_or_else(|| self.exactly_blocked(p, s)),
            None => {
                let first = counters.iter().position(|&r| r == min).unwrap_or(0);
                self.exactly_blocked(p, self.samples[self.order[first] as usize])
            }
        }
    }

    /// The first of the first [`REFERENCE_TRIES`] `candidates` (angular
    /// indices) whose segment from `p` stays more than [`NEAR_ANGLE`] (seen
    /// from `p`) from every silhouette edge at `p`: the recorded ones, or
    /// when the record overflowed the structure's candidates again. The sample
    /// must also lie that far inside the light (projected from `p`), so that
    /// an edge near its segment overlaps the light and is a candidate of every
    /// structure (their culling keeps every edge whose projection overlaps
    /// the light). `None` if no candidate qualifies.
    pub(super) fn reference_sample(
        &self,
        p: Vec3,
        candidates: impl Iterator<Item = usize>,
        silhouettes: &Silhouettes,
    ) -> Option<Vec3> {
        let pw = p.as_dvec3();
        // Height of p over the light's plane: a direction off by an angle α
        // meets the plane α |s'|² / h from s.
        let height = (self.plane_point - pw).dot(self.plane_normal).abs();
        let near = |sw: DVec3, e: u32| {
            let edge = &self.graph.edges[e as usize];
            let [a, b] = [edge.a, edge.b].map(|v| self.graph.positions[v as usize].as_dvec3() - pw);
            direction_near_edge(sw, a, b)
        };
        let chosen = candidates.take(REFERENCE_TRIES).find(|&k| {
            let s = self.samples[self.order[k] as usize];
            let sw = s.as_dvec3() - pw;
            let deep_inside = self.insets[k] > 4.0 * NEAR_ANGLE * sw.length_squared() / height;
            if !deep_inside {
                return false;
            }
            // The recorded normals' directions are within 1e-7 of the exact
            // ones: the prefilter's bound allows for it. `|n·s| > bound |n|`
            // in squares (f64, its rounding far below that allowance).
            let recorded_clear = silhouettes.clear_of(sw, NEAR_ANGLE + 1e-6, near);
            if !recorded_clear || !silhouettes.overflow {
                return recorded_clear;
            }
            // The silhouettes that did not fit, from the structure's
            // candidates (visited in the sweep's order) from the first of
            // them on; every candidate if that one is not met.
            let clear_from = |first: Option<u32>| {
                let mut reached = first.is_none();
                let mut clear = true;
                self.for_each_candidate(p, |e| {
                    reached |= Some(e) == first;
                    // Nothing left to test once one edge is near.
                    if reached && clear && near(sw, e) && self.silhouette_weight(p, e) != 0 {
                        clear = false;
                    }
                });
                (reached, clear)
            };
            match clear_from(Some(silhouettes.first_unrecorded)) {
                (true, clear) => clear,
                (false, _) => clear_from(None).1,
            }
        });
        chosen.map(|k| self.samples[self.order[k] as usize])
    }

    /// The reference ray over the open segment `p → s`, through the caster.
    ///
    /// The `f32` watertight test may report a triangle the segment only touches
    /// at `p` (a receiver on a surface: the triangle's plane holds `p` and
    /// rounding puts the hit at `t ≈ 1e-17`). So an occlusion is confirmed:
    /// the first hit found is checked with the exact segment test, which
    /// settles most occluded segments without a second search; otherwise the
    /// nearest hit is, and if refuted the search goes on beyond it. With
    /// `certified`, a refuted nearest hit whose plane does not hold `p`
    /// returns `None` instead: the ray then passes within rounding of that
    /// triangle's edge, where it may also have skipped the neighbour the
    /// segment does cross.
    pub(super) fn reference_blocked(&self, p: Vec3, s: Vec3, certified: bool) -> Option<bool> {
        let mut ray = Ray::new(p, s - p, 1.0);
        let Some(found) = self.caster.occluding_triangle(&ray) else {
            return Some(false);
        };
        // A triangle the segment meets, exactly: blocked, whatever the ray
        // may have missed nearer.
        let [a, b, c] = self.graph.corners(found);
        if segment_meets_triangle(p, s, a, b, c) {
            return Some(true);
        }
        for _ in 0..MAX_REFUTED_HITS {
            let Some((t, triangle)) = self.caster.closest_hit(&ray) else {
                return Some(false);
            };
            let [a, b, c] = self.graph.corners(triangle);
            if segment_meets_triangle(p, s, a, b, c) || t <= ray.t_min || t.is_nan() {
                return Some(true);
            }
            if certified && orient3d(a, b, c, p) != 0 {
                return None;
            }
            ray.t_min = t;
        }
        Some(true)
    }

    /// Whether the open segment `p → s` meets an occluder triangle, exactly
    /// ([`segment_meets_triangle`] on every triangle whose box meets the box of
    /// one of [`SEGMENT_PIECES`] consecutive pieces of the segment, found
    /// through the reference caster's hierarchy; without `bvh`, every triangle
    /// whose box meets the segment's), for the rare references
    /// [`Self::minimum_blocked`] cannot leave to a ray.
    #[cold]
    #[inline(never)]
    pub(super) fn exactly_blocked(&self, p: Vec3, s: Vec3) -> bool {
        let meets = |t: usize| {
            let [a, b, c] = self.graph.corners(t);
            segment_meets_triangle(p, s, a, b, c)
        };
        #[cfg(feature = "bvh")]
        {
            let Caster::Bvh(scene) = &self.caster;
            let (pw, sw) = (p.as_dvec3(), s.as_dvec3());
            let d = sw - pw;
            // Every point of a piece is in the box of its ends; the ends are
            // off by the rounding of `p + t d` (t is exact: a power of two
            // divides it), far below this pad.
            let pad = 4.0 * f64::EPSILON * (pw.abs() + sw.abs());
            (0..SEGMENT_PIECES).any(|k| {
                let t = |k: usize| k as f64 / SEGMENT_PIECES as f64;
                let (x0, x1) = (pw + d * t(k), pw + d * t(k + 1));
                let lo = (x0.min(x1) - pad).to_array().map(crate::geom::f32_down);
                let hi = (x0.max(x1) + pad).to_array().map(crate::geom::f32_up);
                scene.any_in_box(Vec3::from(lo), Vec3::from(hi), meets)
            })
        }
        #[cfg(not(feature = "bvh"))]
        {
            let (lo, hi) = (p.min(s), p.max(s));
            (0..self.graph.triangles.len()).any(|t| {
                let [a, b, c] = self.graph.corners(t);
                let (tlo, thi) = (a.min(b).min(c), a.max(b).max(c));
                tlo.cmple(hi).all() && thi.cmpge(lo).all() && meets(t)
            })
        }
    }

    /// Clears in `bits` every sample `s` for which one of `triangles` meets the
    /// open segment `p → s`, exactly as [`segment_meets_triangle`] decides, with
    /// the samples' sides of each plane taken from `sides` (see
    /// [`plane_sides`]).
    ///
    /// [`segment_meets_triangle`] needs `p` and `s` strictly on opposite sides
    /// of the triangle's plane (an open segment with an endpoint on the plane,
    /// or both on one side, touches the plane at most at that endpoint, which it
    /// excludes; a segment in the plane is declared not to meet the triangle).
    /// Both signs are the same exact `orient3d(a, b, c, ·)`, so with the side of
    /// `p` computed once per triangle only the samples strictly on the other
    /// side go on to the edge tests, and the result is the same bit for bit.
    /// This matters most for receivers on a near-light triangle's plane (a
    /// floor crossing the light's plane): there the sign of `p` needs the exact
    /// expansion, once per triangle instead of once per sample.
    pub(super) fn clear_blocked(
        &self,
        triangles: &[[Vec3; 3]],
        sides: &[u64],
        planes: &[Option<AxisPlane>],
        p: Vec3,
        bits: &mut [u64],
    ) {
        let words = bits.len();
        for ((&[a, b, c], side), plane) in triangles
            .iter()
            .zip(sides.chunks_exact(2 * words))
            .zip(planes)
        {
            let p_side = match plane {
                Some(plane) => plane.side(p),
                None => orient3d(a, b, c, p),
            };
            let opposite = match p_side {
                1 => &side[words..],
                -1 => &side[..words],
                _ => continue,
            };
            for (k, (w, &o)) in bits.iter_mut().zip(opposite).enumerate() {
                let mut todo = *w & o;
                while todo != 0 {
                    let j = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    if crossing_in_triangle(p, self.samples[64 * k + j], a, b, c) {
                        *w &= !(1 << j);
                    }
                }
            }
        }
    }

    pub(super) fn near_blocked(&self, p: Vec3, s: Vec3) -> bool {
        self.near_light
            .iter()
            .any(|&[a, b, c]| segment_meets_triangle(p, s, a, b, c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The recorded normal keeps the direction within the prefilter's
    /// allowance for every magnitude a cross product of `f32` differences can
    /// have, with no component overflowing or lost; zero stays zero (so the
    /// prefilter passes the edge to the exact test).
    #[test]
    fn scaled_normals_keep_the_direction_at_every_magnitude() {
        let mut rng = SplitMix64::new(11);
        let mut worst = 0.0f64;
        for k in -298..=258 {
            for _ in 0..20 {
                let mut n = DVec3::new(
                    rng.next_f64() - 0.5,
                    rng.next_f64() - 0.5,
                    rng.next_f64() - 0.5,
                );
                // Some normals along an axis, some with a tiny component.
                if rng.next_f64() < 0.2 {
                    n.y *= 1e-30;
                }
                let n = n * 2f64.powi(k);
                let m = DVec3::from(scaled_normal(n).map(f64::from));
                let largest = m.abs().max_element();
                assert!((0.5..=1.0).contains(&largest), "{n:?} -> {m:?}");
                let angle = n.normalize().cross(m.normalize()).length();
                worst = worst.max(angle);
            }
        }
        // The prefilter allows 1e-6; rounding to f32 alone gives about 1e-7.
        assert!(worst < 1.5e-7, "worst angle {worst:e}");
        assert_eq!(scaled_normal(DVec3::ZERO), [0.0; 3]);
    }
}
