//! The sweep of one receiver's silhouette edges: each edge's planes, the
//! samples it separates (an arc in the samples' angular order) and its
//! weight added to their depth-complexity counters.

use super::*;

/// Per-receiver state of the depth-complexity integration. A sample relative
/// to the receiver is `s - p` rounded once in `f64` (computed where it is
/// used, from the shared structure of arrays: nothing per sample is written
/// per receiver).
pub(super) struct Kernel<'a> {
    pub(super) p: Vec3,
    pub(super) pw: DVec3,
    pub(super) sx: &'a [f64],
    pub(super) sy: &'a [f64],
    pub(super) sz: &'a [f64],
    /// Componentwise largest |s - p| (for the error bounds).
    pub(super) smax: DVec3,
    /// Centroid relative to the receiver.
    pub(super) cp: DVec3,
    /// Light vertices relative to the receiver (quick rejection).
    pub(super) lights: [DVec3; MAX_LIGHT_VERTICES],
    /// Their lengths, scaled by `2 NEAR_ANGLE`: how far (seen from p) the
    /// plane of a recorded silhouette may pass beside the light.
    pub(super) light_near: [f64; MAX_LIGHT_VERTICES],
    pub(super) light_count: usize,
    /// The receiver's side of the light plane as a direction: the sweep happens
    /// in front of p along it.
    pub(super) toward: DVec3,
    /// Height of the centroid over the receiver along `toward`.
    pub(super) hc: f64,
    /// `|cp|`, for the projection's rounding bound.
    pub(super) cp_length: f64,
    /// The part of the arc margin due to samples off the light's plane
    /// (receiver-dependent only); `None` when it is too large for arcs.
    pub(super) shift_margin: Option<f64>,
    /// Tests only: every sample (no arc, no bucket range) through the
    /// per-sample [`Kernel::crosses`] (the slow twin of the arc-restricted,
    /// branch-free pass).
    pub(super) slow: bool,
    /// Tests only: samples the fast pass left unsure so far.
    pub(super) unsure: u32,
    /// Tests only: silhouettes swept with the lanes' planes, and of those
    /// the ones with the lanes' arc.
    #[cfg_attr(not(all(target_arch = "x86_64", feature = "std")), allow(dead_code))]
    pub(super) lane_swept: u32,
    #[cfg_attr(not(all(target_arch = "x86_64", feature = "std")), allow(dead_code))]
    pub(super) lane_arcs: u32,
    /// Tests only: silhouettes with samples to sweep that the lanes swept
    /// together ([`Kernel::sweep_held_arcs`]).
    #[cfg_attr(not(all(target_arch = "x86_64", feature = "std")), allow(dead_code))]
    pub(super) held_swept: u32,
    /// Where the silhouette edges met are recorded (for the choice of the
    /// reference sample).
    pub(super) silhouettes: &'a mut Silhouettes,
}

/// What the set-up decided for a silhouette edge (weight not zero) at a
/// receiver ([`Kernel::add_silhouette`]).
#[derive(Clone, Copy)]
pub(super) struct DecidedSilhouette {
    /// The weight, `±1` or `±2`.
    pub(super) weight: i32,
    /// Its plane passes within [`NEAR_ANGLE`] of the light: recorded for the
    /// reference sample.
    pub(super) near: bool,
    /// Its plane cuts the light (grown by its tolerance): swept.
    pub(super) sweep: bool,
}

/// The lane-decided silhouette edges of one lane batch with their sample
/// ranges, gathered for [`Kernel::sweep_held_arcs`] (lane `i` of the batch in
/// entry `i`; empty ranges where lane `i` is not one of them).
#[cfg(all(target_arch = "x86_64", feature = "std"))]
#[derive(Clone, Copy, Default)]
pub(super) struct HeldArcs {
    /// Per lane, the ranges of samples (angular order) its arc may cross:
    /// `(start, end)`, empty where `start >= end`.
    pub(super) ranges: [[(u32, u32); 3]; 8],
    pub(super) contributions: [i32; 8],
    pub(super) edges: [u32; 8],
    pub(super) weights: [i32; 8],
    /// Lanes held with samples to sweep.
    pub(super) held: u32,
}

#[cfg(all(target_arch = "x86_64", feature = "std"))]
impl HeldArcs {
    /// Holds lane `lane`'s edge `e` (weight `weight`) with its sample
    /// `ranges` and its `contribution`.
    #[inline]
    pub(super) fn hold(
        &mut self,
        lane: usize,
        e: u32,
        weight: i32,
        (ranges, contribution): ([(u32, u32); 3], i32),
    ) {
        self.ranges[lane] = ranges;
        self.contributions[lane] = contribution;
        self.edges[lane] = e;
        self.weights[lane] = weight;
        // No branch per range: whether each is empty varies.
        let [first, second, third] = ranges;
        let any = (first.0 < first.1) | (second.0 < second.1) | (third.0 < third.1);
        self.held |= u32::from(any) << lane;
    }
}

/// An edge seen from the receiver: its endpoints, them relative to the
/// receiver, `a' × b'`, that product's permanent (`|x₁ y₂| + |x₂ y₁|` per
/// component) and its length.
pub(super) struct EdgeAt {
    pub(super) a: Vec3,
    pub(super) b: Vec3,
    pub(super) aw: DVec3,
    pub(super) bw: DVec3,
    pub(super) nrm: DVec3,
    pub(super) nperm: DVec3,
    pub(super) nrm_length: f64,
}

impl EdgeAt {
    /// Edge `a b` seen from `pw`.
    #[inline(always)]
    pub(super) fn new(a: Vec3, b: Vec3, pw: DVec3) -> Self {
        let (aw, bw) = (a.as_dvec3() - pw, b.as_dvec3() - pw);
        let nrm = aw.cross(bw);
        let nperm = cross_permanent(aw, bw);
        EdgeAt {
            a,
            b,
            aw,
            bw,
            nrm,
            nperm,
            nrm_length: crate::geom::length_f64(nrm),
        }
    }
}

/// The permanent of `x × y`: `|x₁ y₂| + |x₂ y₁|` per component, the scale of
/// that product's rounding.
#[inline(always)]
pub(super) fn cross_permanent(x: DVec3, y: DVec3) -> DVec3 {
    DVec3::new(
        (x.y * y.z).abs() + (x.z * y.y).abs(),
        (x.z * y.x).abs() + (x.x * y.z).abs(),
        (x.x * y.y).abs() + (x.y * y.x).abs(),
    )
}

#[inline]
pub(super) fn wide(v: Vec3) -> [f64; 3] {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}

impl<'a> Kernel<'a> {
    pub(super) fn new(ss: &'a SoftShadows, p: Vec3, silhouettes: &'a mut Silhouettes) -> Self {
        let pw = p.as_dvec3();
        // Rounding is monotone, so the largest |fl(s - p)| over the samples is
        // reached at the samples' componentwise bounds: the same value as the
        // maximum over every sample.
        let smax = (ss.sample_lo - pw).abs().max((ss.sample_hi - pw).abs());
        let mut k = Kernel {
            p,
            pw,
            sx: &ss.soa[0],
            sy: &ss.soa[1],
            sz: &ss.soa[2],
            smax,
            cp: ss.centroid.as_dvec3() - pw,
            lights: [DVec3::ZERO; MAX_LIGHT_VERTICES],
            light_near: [0.0; MAX_LIGHT_VERTICES],
            light_count: ss.shape.vertices.len(),
            toward: ss.plane_normal * (ss.plane_point - pw).dot(ss.plane_normal).signum(),
            hc: 0.0,
            cp_length: 0.0,
            shift_margin: None,
            slow: false,
            unsure: 0,
            lane_swept: 0,
            lane_arcs: 0,
            held_swept: 0,
            silhouettes,
        };
        k.hc = k.cp.dot(k.toward);
        k.cp_length = crate::geom::length_f64(k.cp);
        // Samples are on the plane only up to rounding (or the tolerance of
        // user samples): seen from p, a sample at height e off the plane shifts
        // by up to |s - p| e / hc, an angle of that over its distance from the
        // centroid (at least `angle_radius`).
        let sample_shift =
            (k.cp_length + ss.shape_diameter) * ss.sample_offset / k.hc / ss.angle_radius;
        if sample_shift <= 0.25 {
            k.shift_margin = Some(2.0 * sample_shift + 1e-9);
        }
        for (i, v) in ss.shape.vertices.iter().enumerate() {
            k.lights[i] = *v - pw;
            k.light_near[i] = 2.0 * NEAR_ANGLE * crate::geom::length_f64(k.lights[i]);
        }
        k
    }

    /// Adds the edge's contribution to the relative depth complexity of every
    /// sample; returns whether its weight at the receiver is non-zero.
    pub(super) fn add_edge(&mut self, ss: &SoftShadows, e: u32, counters: &mut [i32]) -> bool {
        let g = &ss.graph;
        let edge = &g.edges[e as usize];
        let (a, b) = g.endpoints(e);
        let (aw, bw) = (a.as_dvec3() - self.pw, b.as_dvec3() - self.pw);
        // Quick rejections first (conservative, with slack): the edge wholly
        // behind the receiver or beyond the light's plane cannot meet (p, c, s).
        let slack = 1e-9 * (aw.abs().max(bw.abs()).max(self.cp.abs()).max_element());
        let (ha, hb) = (aw.dot(self.toward), bw.dot(self.toward));
        let hc = self.hc;
        if (ha < -slack && hb < -slack) || (ha > hc + slack && hb > hc + slack) {
            return false;
        }
        // Silhouette weight: exact signs, zero counts zero.
        let (a3, b3) = (aw.to_array(), bw.to_array());
        let mut weight = 0;
        for &v in g.third_of(edge) {
            let vp = g.positions[v as usize];
            let vw = (vp.as_dvec3() - self.pw).to_array();
            let (det, perm) = det3_with_permanent(a3, b3, vw);
            // Branch-free in the certain case (the sign is data-dependent, a
            // branch on it mispredicts about half the time).
            let bound = ORIENT_BOUND * perm;
            weight += i32::from(det > bound) - i32::from(det < -bound);
            if det.abs() <= bound {
                weight += orient3d_exact(wide(a), wide(b), wide(vp), wide(self.p));
            }
        }
        if weight == 0 {
            return false;
        }
        let at = EdgeAt::new(a, b, self.pw);
        let (nrm, nperm, nrm_length) = (at.nrm, at.nperm, at.nrm_length);
        // The plane (p, a, b) must cut the light (grown by its tolerance) for
        // the edge to change a counter, and come within [`NEAR_ANGLE`] of it
        // (seen from p) for a reference segment to pass near the edge.
        let reach = nrm_length * ss.shape.tolerance * 2.0;
        let (mut above, mut below) = (false, false);
        let (mut near_above, mut near_below) = (false, false);
        let lights = self.lights[..self.light_count].iter();
        for (l, near) in lights.zip(&self.light_near) {
            let d = nrm.dot(*l);
            let err = ORIENT_BOUND * nperm.dot(l.abs()) + reach;
            above |= d > -err;
            below |= d < err;
            let near = err + near * nrm_length;
            near_above |= d > -near;
            near_below |= d < near;
        }
        let silhouette = DecidedSilhouette {
            weight,
            near: near_above && near_below,
            sweep: above && below,
        };
        self.add_silhouette(ss, e, &at, silhouette, counters);
        true
    }

    /// The rest of [`Kernel::add_edge`] for silhouette edge `e` (weight not
    /// zero), seen from the receiver as `at`, whose set-up is decided:
    /// recorded when near the light, swept over the samples when its plane
    /// cuts the light.
    #[inline(always)]
    pub(super) fn add_silhouette(
        &mut self,
        ss: &SoftShadows,
        e: u32,
        at: &EdgeAt,
        silhouette: DecidedSilhouette,
        counters: &mut [i32],
    ) {
        if silhouette.near {
            self.silhouettes.record(e, at.nrm);
        }
        if silhouette.sweep {
            self.sweep_silhouette(ss, at, silhouette.weight, counters);
        }
    }

    /// The sweep of [`Kernel::add_silhouette`]: silhouette edge `at`
    /// (weight `weight`, its plane cutting the light) over the samples.
    #[inline(always)]
    pub(super) fn sweep_silhouette(
        &mut self,
        ss: &SoftShadows,
        at: &EdgeAt,
        weight: i32,
        counters: &mut [i32],
    ) {
        let planes = self.edge_planes(ss, at, weight);
        // The slow twin tests every sample: it checks the arc and its bucket
        // range as well as the fast pass.
        let arc = if self.slow {
            None
        } else {
            self.arc(ss, at.aw, at.bw)
        };
        let mut unsure = 0;
        for (lo, hi) in ss.arc_ranges(arc) {
            if lo < hi {
                unsure += self.run(ss, &planes, lo as usize, hi as usize, counters);
            }
        }
        self.unsure += unsure;
    }

    /// The first part of [`Kernel::sweep_silhouette`] for a silhouette edge
    /// `e` (weight `weight`) whose planes, centroid side and (where
    /// `planes.arc` says so) arc the lanes decided (lane `lane` of `planes`):
    /// the ranges of samples (angular order) its arc may cross and its
    /// contribution, for [`Kernel::sweep_held_arcs`].
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    pub(super) fn lane_silhouette_ranges(
        &mut self,
        ss: &SoftShadows,
        e: u32,
        weight: i32,
        planes: &crate::simd::SweepPlanes8,
        lane: usize,
    ) -> ([(u32, u32); 3], i32) {
        let lane_arc = planes.arc >> lane & 1;
        self.lane_swept += 1;
        self.lane_arcs += lane_arc;
        let ranges = if lane_arc == 1 {
            // An arc lane's buckets are in `[0, ANGLE_BUCKETS)`.
            let [first, last] = planes.buckets.map(|b| b[lane] as usize);
            ss.bucket_ranges(planes.lo[lane] <= planes.hi[lane], first, last)
        } else {
            let (a, b) = ss.graph.endpoints(e);
            ss.arc_ranges(self.arc(ss, a.as_dvec3() - self.pw, b.as_dvec3() - self.pw))
        };
        (ranges, if planes.want(lane) { weight } else { -weight })
    }

    /// Records silhouette edge `e` for the reference sample with lane
    /// `lane` of `normals` ([`recorded_normals8`](crate::simd::avx::recorded_normals8)):
    /// what [`Kernel::add_silhouette`] records for it, bit for bit.
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    #[inline(always)]
    pub(super) fn record_lane_normal(&mut self, e: u32, normals: &[[f32; 8]; 3], lane: usize) {
        let normal = [0, 1, 2].map(|axis| normals[axis][lane]);
        self.silhouettes.record_scaled(e, normal);
    }

    /// The sample pass of a batch's lane-decided silhouette edges, all at
    /// once ([`crossings_lanes8`](crate::simd::avx::crossings_lanes8)): each
    /// edge's `f32` pass over the ranges [`Kernel::lane_silhouette_ranges`]
    /// gave, and the samples it leaves unsure through [`Kernel::crosses`]
    /// with the `f64` planes, so the counts are that test's.
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    pub(super) fn sweep_held_arcs(
        &mut self,
        ss: &SoftShadows,
        planes: &crate::simd::SweepPlanes8,
        arcs: &HeldArcs,
        counters: &mut [i32],
    ) {
        let soa = ss.samples32();
        let mut unsure = 0;
        let this = &*self;
        // The `f64` planes of the lane asked last: the pass asks about one
        // edge's unsure samples before the next edge's.
        let mut exact: Option<(usize, EdgePlanes)> = None;
        let exact_test = |lane: usize, i: usize| {
            unsure += 1;
            let planes = match &exact {
                Some((asked, planes)) if *asked == lane => planes,
                _ => {
                    let (a, b) = ss.graph.endpoints(arcs.edges[lane]);
                    let at = EdgeAt::new(a, b, this.pw);
                    let planes = this.edge_planes(ss, &at, arcs.weights[lane]);
                    &exact.insert((lane, planes)).1
                }
            };
            this.crosses(ss, planes, i)
        };
        #[allow(unsafe_code)]
        // SAFETY: lanes' planes are only made where the processor runs AVX
        // ([`SoftShadows::sweep_receiver`]).
        unsafe {
            crate::simd::avx::crossings_lanes8(
                planes,
                this.p.to_array(),
                soa,
                arcs.held,
                &arcs.ranges,
                &arcs.contributions,
                counters,
                exact_test,
            )
        };
        self.unsure += unsure;
        self.held_swept += arcs.held.count_ones();
    }

    /// The `f64` planes of silhouette edge `at` (weight `weight`) for the
    /// per-sample crossing test.
    pub(super) fn edge_planes(&self, ss: &SoftShadows, at: &EdgeAt, weight: i32) -> EdgePlanes {
        let &EdgeAt {
            a,
            b,
            aw,
            bw,
            nrm,
            nperm,
            ..
        } = at;
        let (a3, b3) = (aw.to_array(), bw.to_array());
        // Side of the centroid, its ties broken by the centroid's
        // infinitesimal move (module docs).
        let cw = self.cp.to_array();
        let (det, perm) = det3_with_permanent(a3, b3, cw);
        let c_pos = if det.abs() > ORIENT_BOUND * perm {
            det > 0.0
        } else {
            let (a, b, p) = (wide(a), wide(b), wide(self.p));
            match orient3d_exact(a, b, wide(ss.centroid), p) {
                0 => cross_sign_sequence(a, p, b, p) > 0,
                sign => sign > 0,
            }
        };
        let amat = aw.cross(self.cp);
        let bmat = bw.cross(self.cp);
        let err_n = ORIENT_BOUND * nperm.dot(self.smax);
        let err_a = ORIENT_BOUND * cross_permanent(aw, self.cp).dot(self.smax);
        let err_b = ORIENT_BOUND * cross_permanent(bw, self.cp).dot(self.smax);
        let err_c = ORIENT_BOUND * perm;
        // The crossing test is spelled out at `EdgePlanes`.
        let want = !c_pos;
        EdgePlanes {
            a,
            b,
            nrm,
            amat,
            bmat,
            det,
            errs: [err_n, err_a, err_b, err_c + err_n + err_a + err_b],
            // The wanted side folded into a factor of ±1 (exact).
            g: if want { 1.0 } else { -1.0 },
            want,
            contribution: if want { weight } else { -weight },
        }
    }

    /// Adds the edge's contribution to the samples `lo..hi` (angular order)
    /// that it crosses; returns how many were unsure after the float pass.
    ///
    /// The fast pass: every sample classified branch-free from the certified
    /// float signs ([`Kernel::crosses`]'s float half): certainly crossing
    /// (counted here), certainly not, or unsure (some sign within its bound and
    /// no certain rejection). Unsure samples, rare, then go through
    /// [`Kernel::crosses`] (exact signs where the bounds do not settle them),
    /// so the counts are exactly its counts for every sample.
    #[inline(always)]
    pub(super) fn run(
        &self,
        ss: &SoftShadows,
        planes: &EdgePlanes,
        lo: usize,
        hi: usize,
        counters: &mut [i32],
    ) -> u32 {
        if self.slow {
            for (i, c) in counters.iter_mut().enumerate().take(hi).skip(lo) {
                if self.crosses(ss, planes, i) {
                    *c += planes.contribution;
                }
            }
            return 0;
        }
        let (px, py, pz) = (self.pw.x, self.pw.y, self.pw.z);
        let mut any_unsure = false;
        let range = lo..hi;
        let (xs, ys, zs) = (
            &self.sx[range.clone()],
            &self.sy[range.clone()],
            &self.sz[range.clone()],
        );
        let cs = &mut counters[range];
        for (((c, &x), &y), &z) in cs.iter_mut().zip(xs).zip(ys).zip(zs) {
            let (hit, reject) = planes.classify([x - px, y - py, z - pz]);
            *c += if hit { planes.contribution } else { 0 };
            any_unsure |= !(hit | reject);
        }
        if any_unsure {
            self.settle(ss, planes, lo, hi, counters)
        } else {
            0
        }
    }

    /// The unsure samples of `lo..hi` through the exact test (rare: kept out
    /// of line so that the fast loop stays small).
    #[cold]
    #[inline(never)]
    pub(super) fn settle(
        &self,
        ss: &SoftShadows,
        planes: &EdgePlanes,
        lo: usize,
        hi: usize,
        counters: &mut [i32],
    ) -> u32 {
        let mut unsure = 0;
        for (i, c) in counters.iter_mut().enumerate().take(hi).skip(lo) {
            let v = [
                self.sx[i] - self.pw.x,
                self.sy[i] - self.pw.y,
                self.sz[i] - self.pw.z,
            ];
            let (hit, reject) = planes.classify(v);
            if !(hit | reject) {
                unsure += 1;
                if self.crosses(ss, planes, i) {
                    *c += planes.contribution;
                }
            }
        }
        unsure
    }

    /// Whether the edge meets the triangle `(p, c, s)` for sample `i` (angular
    /// order), exactly: the certified float signs, then exact `orient3d`
    /// where they do not settle (the per-sample reference of the fast pass).
    pub(super) fn crosses(&self, ss: &SoftShadows, planes: &EdgePlanes, i: usize) -> bool {
        let sign = |v: f64, err: f64| -> Option<bool> {
            if v > err {
                Some(true)
            } else if v < -err {
                Some(false)
            } else {
                None
            }
        };
        let EdgePlanes {
            a,
            b,
            nrm,
            amat,
            bmat,
            det,
            want,
            ..
        } = *planes;
        let [err_n, err_a, err_b, err_base] = planes.errs;
        let (x, y, z) = (
            self.sx[i] - self.pw.x,
            self.sy[i] - self.pw.y,
            self.sz[i] - self.pw.z,
        );
        let vs = nrm.x * x + nrm.y * y + nrm.z * z;
        let fs = sign(vs, err_n);
        if fs == Some(!want) {
            return false;
        }
        let va = amat.x * x + amat.y * y + amat.z * z;
        let vb = bmat.x * x + bmat.y * y + bmat.z * z;
        let fa = sign(va, err_a);
        let fb = sign(vb, err_b);
        if fa.is_some() && fa == fb {
            return false;
        }
        let vo = det - vs + va - vb;
        let err_o = err_base + SUM_BOUND * (det.abs() + vs.abs() + va.abs() + vb.abs());
        let fo = sign(vo, err_o);
        if fo == Some(!want) {
            return false;
        }
        if fs.is_none() || fa.is_none() || fb.is_none() || fo.is_none() {
            let s = wide(ss.samples[ss.order[i] as usize]);
            let pp = wide(self.p);
            let cc = wide(ss.centroid);
            let (a, b) = (wide(a), wide(b));
            // The sign, exact; where it is zero and the determinant has the
            // centroid in it, the sign of the term the centroid's move adds
            // (`moved`), else negative.
            let exact_pos = |f: Option<bool>, [x, y, z, w]: [[f64; 3]; 4], moved: fn(_) -> i32| {
                f.unwrap_or_else(|| match orient3d_exact(x, y, z, w) {
                    0 => moved([x, y, z, w]) > 0,
                    sign => sign > 0,
                })
            };
            let ps = exact_pos(fs, [a, b, s, pp], |_| 0);
            // det[a - p, c - p, s - p]: the move adds det[a - p, e, s - p].
            let pa = exact_pos(fa, [a, cc, s, pp], |[x, _, z, w]| {
                -cross_sign_sequence(x, w, z, w)
            });
            let pb = exact_pos(fb, [b, cc, s, pp], |[x, _, z, w]| {
                -cross_sign_sequence(x, w, z, w)
            });
            // det[a - s, b - s, c - s]: the move adds det[a - s, b - s, e].
            let po = exact_pos(fo, [a, b, cc, s], |[x, y, _, w]| {
                cross_sign_sequence(x, w, y, w)
            });
            if ps != want || pa == pb || po != want {
                return false;
            }
        }
        true
    }

    /// The pseudo-angle range `[lo, hi]` (cyclic: `lo > hi` wraps past 4) about
    /// the centroid in the light's plane that holds every sample `s` for which
    /// the segment from the centroid to `s` can cross the edge's projection from
    /// the receiver, grown by a margin far above the rounding of the projection;
    /// `None` (test every sample) when the projection is ill-conditioned (an
    /// endpoint nearly level with or behind the receiver, an endpoint projecting
    /// near the centroid, or the edge's projection nearly through it).
    pub(super) fn arc(&self, ss: &SoftShadows, aw: DVec3, bw: DVec3) -> Option<(f64, f64)> {
        let shift_margin = self.shift_margin?;
        let hc = self.hc;
        let (ha, hb) = (aw.dot(self.toward), bw.dot(self.toward));
        if !(ha > 1e-3 * hc && hb > 1e-3 * hc) {
            return None;
        }
        // The 1-norm bounds the length from above (a larger rounding bound).
        let norm1 = |w: DVec3| w.x.abs() + w.y.abs() + w.z.abs();
        let project = |w: DVec3, h: f64| {
            let scale = hc / h;
            let q = w * scale - self.cp;
            let err = 1e-12 * (norm1(w) * scale + self.cp_length);
            (q.dot(ss.u_axis), q.dot(ss.v_axis), err)
        };
        let (xa, ya, ea) = project(aw, ha);
        let (xb, yb, eb) = project(bw, hb);
        // Bounds of the projections' distances from the centroid without a
        // square root: max(|x|, |y|) <= r <= |x| + |y|. The lower bound goes
        // where r divides an error (a wider margin), the upper one where it
        // scales a threshold below which the arc is not used.
        let (ra, rb) = (xa.abs().max(ya.abs()), xb.abs().max(yb.abs()));
        if ra < 1e4 * ea || rb < 1e4 * eb {
            return None;
        }
        let cross = xa * yb - ya * xb;
        if cross.abs() < 1e-6 * (xa.abs() + ya.abs()) * (xb.abs() + yb.abs()) {
            return None;
        }
        let margin = 4.0 * (ea * rb + eb * ra) / (ra * rb) + shift_margin;
        let (pa, pb) = (pseudo_angle(xa, ya), pseudo_angle(xb, yb));
        // Counter-clockwise from the first to the second is the short way.
        let (from, to) = if cross > 0.0 { (pa, pb) } else { (pb, pa) };
        let wrap = |t: f64| {
            if t < 0.0 {
                t + 4.0
            } else if t >= 4.0 {
                t - 4.0
            } else {
                t
            }
        };
        Some((wrap(from - margin), wrap(to + margin)))
    }
}

impl SoftShadows {
    /// The sample ranges (angular order, some possibly empty) an edge's arc
    /// asks to test: the samples whose pseudo-angle is in the arc (a cyclic
    /// range), then those too close to the centroid for an angle (always
    /// tested); every sample without an arc. The buckets holding the arc's
    /// ends (exact: the scale is a power of two) widen the range to whole
    /// buckets: extra samples only get tested, none is left out.
    pub(super) fn arc_ranges(&self, arc: Option<(f64, f64)>) -> [(u32, u32); 3] {
        let Some((lo, hi)) = arc else {
            // At most `MAX_SAMPLES`: fits `u32`.
            return [(0, self.samples.len() as u32), (0, 0), (0, 0)];
        };
        let bucket = |t: f64| ((t * ANGLE_SCALE) as usize).min(ANGLE_BUCKETS - 1);
        self.bucket_ranges(lo <= hi, bucket(lo), bucket(hi))
    }

    /// [`SoftShadows::arc_ranges`] for an arc from bucket `first` to bucket
    /// `last` of the sample table, `straight` when it does not wrap past the
    /// pseudo-angle 4 (its ends in order).
    #[inline]
    pub(super) fn bucket_ranges(
        &self,
        straight: bool,
        first: usize,
        last: usize,
    ) -> [(u32, u32); 3] {
        // At most `MAX_SAMPLES`: both fit `u32`.
        let (n, angled) = (self.samples.len() as u32, self.angles.len() as u32);
        let first = self.angle_starts[first];
        let last = self.angle_starts[last + 1];
        let central = (angled, n);
        if straight {
            [(first, last), central, (0, 0)]
        } else if first < last {
            // A wrapped range whose widened ends overlap: every sample (once).
            [(0, angled), central, (0, 0)]
        } else {
            [(first, angled), (0, last), central]
        }
    }
}

/// Rounding of the four-term sum `det(a',b',c') - det(a',b',s') + det(a',c',s')
/// - det(b',c',s')`, on top of each term's own bound.
pub(super) const SUM_BOUND: f64 = 4.0 * f64::EPSILON;

/// One edge's planes at one receiver, for the per-sample crossing test: the
/// edge meets the triangle `(p, c, s)` when `(a, b)` crosses the plane
/// `(p, c, s)` (`det(a', c', s')` and `det(b', c', s')` differ in sign) and the
/// three orientations `orient(a, b, p, c) = -det(a', b', c')`,
/// `orient(a, b, s, p) = det(a', b', s')` and `orient(a, b, c, s) =
/// det(a',b',c') - det(a',b',s') + det(a',c',s') - det(b',c',s')` share one
/// sign (the line `ab` passes through the closed triangle).
pub(super) struct EdgePlanes {
    pub(super) a: Vec3,
    pub(super) b: Vec3,
    /// `a' × b'`: `det(a', b', s') = nrm · s'`.
    pub(super) nrm: DVec3,
    /// `a' × c'`.
    pub(super) amat: DVec3,
    /// `b' × c'`.
    pub(super) bmat: DVec3,
    /// `det(a', b', c')`.
    pub(super) det: f64,
    /// Error bounds of `nrm · s'`, `amat · s'`, `bmat · s'`, and the sum of
    /// those three and `det`'s.
    pub(super) errs: [f64; 4],
    /// `1` when the wanted side (`want`) is positive, else `-1`.
    pub(super) g: f64,
    /// The side of `p`'s plane through the edge opposite the centroid's.
    pub(super) want: bool,
    /// `±weight`: what a crossed sample's counter gets.
    pub(super) contribution: i32,
}

impl EdgePlanes {
    /// Certainly crossing, certainly not (both false: unsure), from the
    /// certified float signs, branch-free.
    #[inline(always)]
    pub(super) fn classify(&self, v: [f64; 3]) -> (bool, bool) {
        let (nrm, amat, bmat) = (self.nrm, self.amat, self.bmat);
        let [err_n, err_a, err_b, err_base] = self.errs;
        let [x, y, z] = v;
        let vs = nrm.x * x + nrm.y * y + nrm.z * z;
        let va = amat.x * x + amat.y * y + amat.z * z;
        let vb = bmat.x * x + bmat.y * y + bmat.z * z;
        let vo = self.det - vs + va - vb;
        let err_o = err_base + SUM_BOUND * (self.det.abs() + vs.abs() + va.abs() + vb.abs());
        let (sg, og) = (vs * self.g, vo * self.g);
        let (a_pos, a_neg) = (va > err_a, va < -err_a);
        let (b_pos, b_neg) = (vb > err_b, vb < -err_b);
        let hit = (sg > err_n) & (og > err_o) & ((a_pos & b_neg) | (a_neg & b_pos));
        let reject = (sg < -err_n) | (og < -err_o) | (a_pos & b_pos) | (a_neg & b_neg);
        (hit, reject)
    }
}

/// How far the point `d` (relative to the light's centroid) lies inside the
/// convex polygon `uv` (the light's vertices in the plane's `(u, v)`
/// coordinates), measured in the plane: the least distance to an edge's line,
/// negative outside. `orientation` is 1 for a counter-clockwise `uv`, -1 for a
/// clockwise one.
pub(super) fn inset(
    uv: &[(f64, f64)],
    orientation: f64,
    d: DVec3,
    u_axis: DVec3,
    v_axis: DVec3,
) -> f64 {
    let (x, y) = (d.dot(u_axis), d.dot(v_axis));
    (0..uv.len())
        .map(|i| {
            let ((x0, y0), (x1, y1)) = (uv[i], uv[(i + 1) % uv.len()]);
            let (ex, ey) = (x1 - x0, y1 - y0);
            orientation * (ex * (y - y0) - ey * (x - x0)) / libm::hypot(ex, ey)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Whether the direction `s` (from the receiver) is within [`NEAR_ANGLE`] of
/// the edge from `a` to `b` (relative to the receiver) as seen from the
/// receiver: within that angle of the plane through the receiver and the edge,
/// and, in that plane, within that angle of the arc of directions from `a` to
/// `b` (a superset of the directions within that angle of the edge's points).
/// An edge seen end-on (its plane undefined) is near a direction near either
/// endpoint. `f64` from `f32` coordinates: far more precise than the angle.
pub(super) fn direction_near_edge(s: DVec3, a: DVec3, b: DVec3) -> bool {
    let n = a.cross(b);
    let (ls2, la2, lb2, ln2) = (
        s.length_squared(),
        a.length_squared(),
        b.length_squared(),
        n.length_squared(),
    );
    // Most directions are far from the edge's plane: decided in squares,
    // before any square root (the same comparisons as below, squared).
    let along = n.dot(s);
    let plane_defined = ln2 > 1e-18 * la2 * lb2;
    if plane_defined && along * along > NEAR_ANGLE * NEAR_ANGLE * ln2 * ls2 {
        return false;
    }
    let [ls, la, lb, ln] = [ls2, la2, lb2, ln2].map(crate::geom::sqrt);
    let near_endpoint = |e: DVec3, le: f64| {
        crate::geom::length_f64(e.cross(s)) <= NEAR_ANGLE * le * ls && e.dot(s) > 0.0
    };
    if !plane_defined {
        return near_endpoint(a, la) || near_endpoint(b, lb);
    }
    // In the plane, `a → b` turns counter-clockwise about `n` through less
    // than a half turn: `s` is inside the arc when it is on the inner side of
    // both ends, allowing the angle.
    let inside_a = a.cross(s).dot(n) >= -NEAR_ANGLE * la * ls * ln;
    let inside_b = s.cross(b).dot(n) >= -NEAR_ANGLE * ls * lb * ln;
    (inside_a && inside_b) || near_endpoint(a, la) || near_endpoint(b, lb)
}

/// A cheap angle substitute, monotone in the angle of `(x, y)` about the origin,
/// in `[0, 4)`, changing by at most one unit per radian (so an angle margin is
/// also a pseudo-angle margin).
#[inline]
pub(super) fn pseudo_angle(x: f64, y: f64) -> f64 {
    let t = y / (x.abs() + y.abs());
    if x >= 0.0 {
        if t >= 0.0 { t } else { 4.0 + t }
    } else {
        2.0 - t
    }
}
