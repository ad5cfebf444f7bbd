//! Answering a receiver: the structure's candidate edges, the sweep of their
//! silhouette weights into depth complexity, the reference decision, and the
//! batch of receivers on or off the pool.

use super::silhouette_lanes::LANES;
use super::*;

/// Points per rayon task of [`SoftShadows::query_batch`]: one query costs tens
/// of microseconds (hundreds of candidate edges times N samples), so small
/// tasks balance well.
pub const PARALLEL_GRAIN: usize = 16;

/// Sets the first `n` bits of `bits` (bit `i` of word `i / 64`), clears the
/// rest of the words given.
pub(super) fn set_first(bits: &mut [u64], n: usize) {
    for (k, w) in bits.iter_mut().enumerate() {
        let left = n.saturating_sub(64 * k);
        *w = if left >= 64 { !0 } else { (1u64 << left) - 1 };
    }
}

impl SoftShadows {
    /// The visibility bits of receiver `p` into `bits[..words_per_receiver()]`
    /// (bit `i` of word `i / 64` set = sample `i` visible; unused high bits of the
    /// last word cleared; words beyond untouched). Returns the visible count.
    pub fn query(&self, p: Vec3, bits: &mut [u64]) -> Result<u32, SsvError> {
        self.query_detailed(p, bits).map(|info| info.visible)
    }

    /// [`SoftShadows::query`] with the work it did.
    pub fn query_detailed(&self, p: Vec3, bits: &mut [u64]) -> Result<QueryInfo, SsvError> {
        let info = self.query_uncounted(p, bits)?;
        self.queries.fetch_add(1, Ordering::Relaxed);
        self.candidates
            .fetch_add(info.candidates as usize, Ordering::Relaxed);
        Ok(info)
    }

    pub(super) fn query_uncounted(&self, p: Vec3, bits: &mut [u64]) -> Result<QueryInfo, SsvError> {
        let words = self.words_per_receiver();
        if bits.len() < words {
            return Err(SsvError::BitsTooShort {
                needed: words,
                got: bits.len(),
            });
        }
        if !p.is_finite() {
            return Err(SsvError::NonFiniteReceiver);
        }
        let bits = &mut bits[..words];
        bits.fill(0);
        let n = self.samples.len();
        let mut info = QueryInfo::default();
        let height = (p.as_dvec3() - self.plane_point).dot(self.plane_normal);
        if height.abs() <= self.band_half_width {
            // Inside the band around the light's plane only band triangles can
            // meet a segment (module docs).
            for (k, w) in bits.iter_mut().enumerate() {
                let left = n - 64 * k;
                *w = if left >= 64 { !0 } else { (1 << left) - 1 };
            }
            self.clear_blocked(&self.band, &self.band_sides, &self.band_planes, p, bits);
            info.visible = bits.iter().map(|w| w.count_ones()).sum();
            return Ok(info);
        }
        if self.structure != Structure::RayTrace && self.pyramid_misses_occluders(p.as_dvec3()) {
            // No segment to a sample can meet a triangle.
            set_first(bits, n);
            info.visible = n as u32;
            return Ok(info);
        }
        if self.structure == Structure::RayTrace {
            for (i, &s) in self.samples.iter().enumerate() {
                info.rays += 1;
                let blocked = self.reference_blocked(p, s, false).unwrap_or(true);
                if !blocked && !self.near_blocked(p, s) {
                    bits[i / 64] |= 1 << (i % 64);
                    info.visible += 1;
                }
            }
            return Ok(info);
        }
        let mut silhouettes = Silhouettes::new();
        let lit = with_counters(n, |counters| {
            self.sweep(p, counters, &mut info, &mut silhouettes);
            let min = counters.iter().copied().min().expect("at least one sample");
            if self.minimum_blocked(p, counters, min, &silhouettes) {
                return false;
            }
            if info.silhouettes == 0 {
                // No edge changed a counter: every sample shares the minimum.
                set_first(bits, n);
                return true;
            }
            // Counters are in angular order, bits in the caller's: gathered
            // branch-free through the inverse order (a scattered, branchy
            // store per sample costs far more on a lit receiver).
            for (w, word) in bits.iter_mut().enumerate() {
                let rank = &self.rank[64 * w..(64 * w + 64).min(n)];
                *word = rank.iter().enumerate().fold(0u64, |acc, (j, &k)| {
                    acc | u64::from(counters[k as usize] == min) << j
                });
            }
            true
        });
        info.rays = 1;
        if !lit {
            return Ok(info);
        }
        // The near-light triangles take away the samples they block.
        self.clear_blocked(
            &self.near_light,
            &self.near_sides,
            &self.near_planes,
            p,
            bits,
        );
        info.visible = bits.iter().map(|w| w.count_ones()).sum();
        Ok(info)
    }

    /// The relative depth complexity `R(s)` of every sample, in angular order
    /// (`counters[k]` belongs to sample `order[k]`), from the structure's
    /// candidates (every potential edge for [`Structure::RayTrace`]).
    /// Also records the silhouette edges the sweep meets in `silhouettes`.
    pub(super) fn sweep(
        &self,
        p: Vec3,
        counters: &mut [i32],
        info: &mut QueryInfo,
        silhouettes: &mut Silhouettes,
    ) {
        self.sweep_with(Kernel::new(self, p, silhouettes), counters, info);
    }

    pub(super) fn sweep_with(
        &self,
        mut kernel: Kernel<'_>,
        counters: &mut [i32],
        info: &mut QueryInfo,
    ) {
        // Candidates in groups of LANES through the set-up in lanes (one by
        // one where there are none); the rest one by one.
        let receiver = self.sweep_receiver(&kernel);
        let mut batch = [0u32; LANES];
        let mut held = 0;
        self.for_each_candidate(kernel.p, |e: u32| {
            info.candidates += 1;
            batch[held] = e;
            held += 1;
            if held == LANES {
                held = 0;
                info.silhouettes += self.sweep_candidates(&mut kernel, &receiver, &batch, counters);
            }
        });
        for &e in &batch[..held] {
            if kernel.add_edge(self, e, counters) {
                info.silhouettes += 1;
            }
        }
    }

    /// The structure's candidate edges for receiver `p`.
    pub(super) fn for_each_candidate(&self, p: Vec3, mut visit: impl FnMut(u32)) {
        match (&self.hierarchy, &self.hemicube) {
            (Some(h), _) => {
                h.for_each_candidate(&self.graph, &self.shape, p.as_dvec3(), &mut visit)
            }
            (_, Some(c)) => c.for_each_candidate(p.as_dvec3(), &mut visit),
            _ => self.potential.iter().for_each(|&e| visit(e)),
        }
    }

    /// Whether the pyramid from `p` to the light (grown by its tolerance)
    /// provably misses the box of every occluder: a plane of the pyramid (one
    /// through `p` and a light edge, the light's plane, the plane through `p`
    /// parallel to it) with the box beyond it by more than the tolerance and
    /// the rounding of these few `f64` operations. Then every sample is
    /// visible, with no structure walked and no ray cast: most of a ground
    /// outside the shadows.
    pub(super) fn pyramid_misses_occluders(&self, p: DVec3) -> bool {
        let Some((lo, hi)) = self.occluder_box else {
            return true;
        };
        let (centre, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
        let light = &self.shape.vertices;
        let scale = light
            .iter()
            .fold(p.abs().max(centre.abs() + half).max_element(), |m, v| {
                m.max(v.abs().max_element())
            });
        let slack = self.shape.tolerance + 1e-9 * scale;
        // The box beyond the plane through `point` with unit normal `n`
        // (pointing away from the pyramid) by more than the slack.
        let beyond = |n: DVec3, point: DVec3| n.dot(centre - point) - n.abs().dot(half) > slack;
        let toward = self.plane_normal * (self.plane_point - p).dot(self.plane_normal).signum();
        if beyond(toward, self.plane_point) || beyond(-toward, p) {
            return true;
        }
        let inside = self.centroid.as_dvec3();
        let k = light.len();
        (0..k).any(|j| {
            let (a, b) = (light[j], light[(j + 1) % k]);
            let n = (a - p).cross(b - p);
            let side = n.dot(inside - p);
            let n = -n * side.signum();
            let length = crate::geom::length_f64(n);
            // A plane nearly through the light's centroid (p near the light's
            // plane) decides nothing.
            side.abs() > 1e-6 * length * crate::geom::length_f64(inside - p)
                && length.is_finite()
                && length > 0.0
                && beyond(n / length, p)
        })
    }

    /// The silhouette weight of edge `e` at `p` (exact signs, as the sweep
    /// takes them).
    pub(super) fn silhouette_weight(&self, p: Vec3, e: u32) -> i32 {
        let edge = &self.graph.edges[e as usize];
        let [a, b] = [edge.a, edge.b].map(|v| self.graph.positions[v as usize]);
        let thirds = self.graph.third_of(edge).iter();
        thirds
            .map(|&v| orient3d(a, b, self.graph.positions[v as usize], p))
            .sum()
    }

    /// The depth complexity of every sample relative to the least:
    /// `out[i] = D(p, s_i) - min_j D(p, s_j)`, where `D` counts the triangles
    /// meeting the open segment (as [`segment_meets_triangle`] decides), from
    /// the silhouette sweep (no ray). This is what an any-hit tracer counting
    /// every hit along each segment gives, up to one constant per receiver.
    /// `out` needs [`SoftShadows::sample_count`] entries (more are untouched).
    pub fn relative_depth_complexity(&self, p: Vec3, out: &mut [i32]) -> Result<(), SsvError> {
        let n = self.samples.len();
        if out.len() < n {
            return Err(SsvError::BitsTooShort {
                needed: n,
                got: out.len(),
            });
        }
        if !p.is_finite() {
            return Err(SsvError::NonFiniteReceiver);
        }
        let out = &mut out[..n];
        let count = |tris: &[[Vec3; 3]], s: Vec3| {
            tris.iter()
                .filter(|&&[a, b, c]| segment_meets_triangle(p, s, a, b, c))
                .count() as i32
        };
        let height = (p.as_dvec3() - self.plane_point).dot(self.plane_normal);
        if height.abs() <= self.band_half_width {
            for (o, &s) in out.iter_mut().zip(&self.samples) {
                *o = count(&self.band, s);
            }
        } else {
            let mut silhouettes = Silhouettes::new();
            with_counters(n, |counters| {
                self.sweep(p, counters, &mut QueryInfo::default(), &mut silhouettes);
                for (k, &r) in counters.iter().enumerate() {
                    let i = self.order[k] as usize;
                    out[i] = r + count(&self.near_light, self.samples[i]);
                }
            });
        }
        let min = out.iter().copied().min().unwrap_or(0);
        out.iter_mut().for_each(|o| *o -= min);
        Ok(())
    }

    /// Builds ahead what queries of `points` will need of the structure (the
    /// hierarchy's nodes, split where enough of the receivers fall to pay for
    /// it; nothing for the other structures), so that a batch of receivers
    /// queried next pays neither coarse nodes nor nodes it does not need.
    /// [`SoftShadows::query_batch`] does this itself; call it before
    /// querying a batch one point at a time. With `parallel` (and the
    /// `parallel` feature) the work is spread over rayon's pool. Non-finite
    /// points are skipped. Never changes a query's bits.
    pub fn prepare<P: Copy + Into<Vec3>>(&self, points: &[P], parallel: bool) {
        if let Some(h) = &self.hierarchy {
            // Preparing only saves the queries work: without memory, skip it.
            let Ok(points) = fallible::collect(
                points
                    .iter()
                    .map(|&p| p.into())
                    .filter(|p: &Vec3| p.is_finite())
                    .map(|p| p.as_dvec3()),
            ) else {
                return;
            };
            h.prepare(&self.graph, &self.shape, &points, parallel);
        }
    }

    /// Queries every point: receiver `r`'s bits go to
    /// `bits[r * words_per_receiver()..][..words_per_receiver()]`, its visible
    /// count to `visible[r]` when given; returns the work of all the queries,
    /// summed. Every point is checked before any is computed, and the
    /// hierarchy is prepared for the batch first ([`SoftShadows::prepare`]).
    /// With `parallel` (and the `parallel` feature) the points are spread
    /// over rayon's pool, [`PARALLEL_GRAIN`] at least per task; the results
    /// are the same either way. Points are anything that converts to a
    /// `Vec3` (`[f32; 3]` too, so a caller's flat array need not be copied).
    pub fn query_batch<P: Copy + Into<Vec3> + Sync>(
        &self,
        points: &[P],
        bits: &mut [u64],
        visible: Option<&mut [u32]>,
        parallel: bool,
    ) -> Result<QueryWork, SsvError> {
        let words = self.words_per_receiver();
        let needed = points.len() * words;
        if bits.len() < needed {
            return Err(SsvError::BitsTooShort {
                needed,
                got: bits.len(),
            });
        }
        if let Some(v) = &visible
            && v.len() < points.len()
        {
            return Err(SsvError::BitsTooShort {
                needed: points.len(),
                got: v.len(),
            });
        }
        if points.iter().any(|&p| !p.into().is_finite()) {
            return Err(SsvError::NonFiniteReceiver);
        }
        if points.is_empty() {
            return Ok(QueryWork::default());
        }
        let bits = &mut bits[..needed];
        self.prepare(points, parallel);
        let one = |p: P, out: &mut [u64]| {
            self.query_detailed(p.into(), out)
                .expect("the point is finite and its words are there")
        };
        #[cfg(feature = "parallel")]
        if parallel && points.len() > 1 {
            use rayon::prelude::*;
            let chunks = bits.par_chunks_mut(words.max(1)).zip(points.par_iter());
            let work = match visible {
                Some(v) => chunks
                    .zip(v[..points.len()].par_iter_mut())
                    .with_min_len(PARALLEL_GRAIN)
                    .fold(QueryWork::default, |work, ((out, &p), v)| {
                        let info = one(p, out);
                        *v = info.visible;
                        work.with(&info)
                    })
                    .reduce(QueryWork::default, QueryWork::merge),
                None => chunks
                    .with_min_len(PARALLEL_GRAIN)
                    .fold(QueryWork::default, |work, (out, &p)| {
                        work.with(&one(p, out))
                    })
                    .reduce(QueryWork::default, QueryWork::merge),
            };
            return Ok(work);
        }
        let mut visible = visible;
        let mut work = QueryWork::default();
        for (r, (out, &p)) in bits.chunks_mut(words.max(1)).zip(points).enumerate() {
            let info = one(p, out);
            if let Some(v) = visible.as_deref_mut() {
                v[r] = info.visible;
            }
            work = work.with(&info);
        }
        Ok(work)
    }

    /// The Monte Carlo estimate, from a receiver's bits, of
    /// `∫_L V(p, s) cos θ_p cos θ_s / |s - p|² dA(s)` (thesis Eq. 1.16 per unit
    /// emitted radiance: multiply by the light's radiance for irradiance):
    /// `area / N · Σ_visible max(0, n·d) |n_L·d| / |d|⁴` with `d = s - p`, the
    /// receiver's unit normal `n` and the light's normal `n_L` (two-sided light).
    pub fn irradiance(&self, p: Vec3, normal: Vec3, bits: &[u64]) -> f32 {
        let light_normal = self.light.normal();
        let mut any_visible = false;
        let mut sum = 0.0f64;
        for (i, &s) in self.samples.iter().enumerate() {
            if bits.get(i / 64).is_some_and(|w| w >> (i % 64) & 1 == 1) {
                let d = (s - p).as_dvec3();
                let r2 = d.length_squared();
                if r2 > 0.0 {
                    let cos_p = normal.as_dvec3().dot(d).max(0.0);
                    let cos_l = light_normal.as_dvec3().dot(d).abs();
                    sum += cos_p * cos_l / (r2 * r2);
                    any_visible = true;
                }
            }
        }
        if !any_visible || sum == 0.0 {
            // No light arrives (and a light whose area overflows f32 would
            // make it 0 · ∞).
            return 0.0;
        }
        (sum * f64::from(self.light.area()) / self.samples.len() as f64) as f32
    }
}
