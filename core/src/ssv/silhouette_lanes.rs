//! The sweep's per-edge set-up for eight candidate edges at once, in `f32`
//! lanes ([`crate::simd::avx::silhouette_setup8`]), where the processor runs
//! AVX.
//!
//! A query spends most of its time on the set-up of each candidate: the quick
//! rejection, the silhouette weight from both third vertices, and the plane
//! through the receiver and the edge against each light vertex, in `f64` one
//! edge at a time. The lanes take those decisions for eight candidates at
//! once, each only where the `f32` value is beyond a bound on its distance
//! from the `f64` one (and, for the weight, from the exact sign): so every
//! decision the lanes take is the one [`Kernel::add_edge`] takes. A candidate
//! with any decision left open (a value within its bound, an edge without
//! exactly two adjacent triangles) goes through [`Kernel::add_edge`] whole;
//! a decided silhouette is recorded with the lanes' normal (the bits
//! [`Kernel::add_silhouette`] records) and goes on to
//! [`Kernel::sweep_silhouette`], the same code as the scalar path's, or,
//! where the lanes decide its planes too
//! ([`crate::simd::avx::silhouette_planes8`]: the planes of the per-sample
//! test, the centroid's side and the arc, each with a bound on its rounding),
//! to [`Kernel::lane_silhouette_ranges`] (the arc), then an
//! `f32` sample pass that counts exactly the samples [`Kernel::crosses`]
//! would. Those edges are held with their sample ranges and swept together
//! once the batch is set up ([`Kernel::sweep_held_arcs`]: one call per batch,
//! each edge's samples eight contiguous ones at a time). So the counters, the
//! statistics and the recorded silhouettes are the scalar sweep's, candidate
//! by candidate (the order of a batch's additions aside, which integer sums
//! do not see).

#[cfg(all(target_arch = "x86_64", feature = "std"))]
use super::sweep::{EdgeAt, HeldArcs};
use super::*;
#[cfg(any(test, all(target_arch = "x86_64", feature = "std")))]
use crate::simd::SetupMasks8;

/// Candidates set up at once.
pub(super) const LANES: usize = 8;

/// A receiver as the lanes take it.
#[cfg(all(target_arch = "x86_64", feature = "std"))]
pub(super) type LaneReceiver = crate::simd::SweepReceiver8;
/// No lanes here: never made.
#[cfg(not(all(target_arch = "x86_64", feature = "std")))]
pub(super) type LaneReceiver = core::convert::Infallible;

impl SoftShadows {
    /// Sweeps the candidate `edges` for `kernel`'s receiver as
    /// [`Kernel::add_edge`] would one by one, in order; returns how many are
    /// silhouettes. Without AVX, one by one.
    pub(super) fn sweep_candidates(
        &self,
        kernel: &mut Kernel<'_>,
        receiver: &Option<LaneReceiver>,
        edges: &[u32; LANES],
        counters: &mut [i32],
    ) -> u32 {
        #[cfg(all(target_arch = "x86_64", feature = "std"))]
        if let Some(receiver) = receiver {
            let mut corners = crate::simd::EdgeCorners8::default();
            let irregular = self.lane_corners(edges, &mut corners);
            let masks = lane_masks(receiver, &corners, irregular);
            let decided = !masks.undecided & !masks.idle;
            // The swept silhouettes' planes and arcs in lanes too.
            let swept = masks.sweep & decided;
            #[allow(unsafe_code)]
            // SAFETY: a receiver is only made where the processor runs AVX
            // ([`SoftShadows::sweep_receiver`]).
            let planes = (swept != 0)
                .then(|| unsafe { crate::simd::avx::silhouette_planes8(receiver, &corners) });
            // The normals the decided silhouettes are recorded with where
            // near.
            let normals = if masks.near & decided != 0 {
                #[allow(unsafe_code)]
                // SAFETY: as above.
                unsafe {
                    crate::simd::avx::recorded_normals8(kernel.pw.to_array(), &corners)
                }
            } else {
                Default::default()
            };
            let mut silhouettes = 0;
            let mut held = HeldArcs::default();
            // The lanes in order, idle ones skipped without a branch each.
            let mut todo = (masks.undecided | !masks.idle) & ((1 << LANES) - 1);
            while todo != 0 {
                let i = todo.trailing_zeros() as usize;
                todo &= todo - 1;
                let (bit, e) = (1 << i, edges[i]);
                if masks.undecided & bit != 0 {
                    silhouettes += u32::from(kernel.add_edge(self, e, counters));
                    continue;
                }
                silhouettes += 1;
                // `add_silhouette`'s record, with the lanes' normal (the same
                // bits), then its sweep.
                if masks.near & bit != 0 {
                    kernel.record_lane_normal(e, &normals, i);
                }
                if swept & bit == 0 {
                    continue;
                }
                let weight = if masks.positive & bit != 0 { 2 } else { -2 };
                if let Some(planes) = &planes
                    && planes.decided & bit != 0
                {
                    let arc = kernel.lane_silhouette_ranges(self, e, weight, planes, i);
                    held.hold(i, e, weight, arc);
                } else {
                    let (a, b) = self.graph.endpoints(e);
                    let at = EdgeAt::new(a, b, kernel.pw);
                    kernel.sweep_silhouette(self, &at, weight, counters);
                }
            }
            if let Some(planes) = &planes
                && held.held != 0
            {
                kernel.sweep_held_arcs(self, planes, &held, counters);
            }
            return silhouettes;
        }
        let _ = receiver;
        edges
            .iter()
            .map(|&e| u32::from(kernel.add_edge(self, e, counters)))
            .sum()
    }

    /// The lanes' decisions for `edges` at `receiver` (with edges not
    /// bordered by exactly two triangles undecided), or `None` without a
    /// receiver (no AVX).
    #[cfg(test)]
    pub(super) fn setup_masks(
        &self,
        receiver: &Option<LaneReceiver>,
        edges: &[u32; LANES],
    ) -> Option<SetupMasks8> {
        #[cfg(all(target_arch = "x86_64", feature = "std"))]
        if let Some(receiver) = receiver {
            let mut corners = crate::simd::EdgeCorners8::default();
            let irregular = self.lane_corners(edges, &mut corners);
            return Some(lane_masks(receiver, &corners, irregular));
        }
        let _ = (receiver, edges);
        None
    }

    /// The corners of `edges` by lane, into `corners` (written in place: a
    /// returned copy of its 384 bytes cost a `memcpy` per batch), from
    /// [`EdgeGraph::lane_records`]; returns the lanes whose edge has not
    /// exactly two adjacent triangles (their third vertices are NaN).
    #[cfg(all(target_arch = "x86_64", feature = "std"))]
    pub(super) fn lane_corners(
        &self,
        edges: &[u32; LANES],
        corners: &mut crate::simd::EdgeCorners8,
    ) -> u32 {
        let records = edges.map(|e| &self.graph.lane_records[e as usize]);
        #[allow(unsafe_code)]
        // SAFETY: the records are made only where the processor runs AVX
        // (creation checks it); without them the indexing above panics
        // before any AVX runs.
        unsafe {
            crate::simd::avx::edge_corners8(records, corners)
        }
    }

    /// `kernel`'s receiver for the lanes, or `None` where they do not run (no
    /// AVX, the slow twin, or values beyond the lanes' range).
    pub(super) fn sweep_receiver(&self, kernel: &Kernel<'_>) -> Option<LaneReceiver> {
        #[cfg(all(target_arch = "x86_64", feature = "std"))]
        {
            if kernel.slow || !crate::simd::avx_available() {
                return None;
            }
            let f = |v: DVec3| v.as_vec3().to_array();
            let mut lights = [[0.0; 3]; MAX_LIGHT_VERTICES];
            let mut light_near = [0.0; MAX_LIGHT_VERTICES];
            for i in 0..kernel.light_count {
                lights[i] = f(kernel.lights[i]);
                light_near[i] = kernel.light_near[i] as f32;
            }
            let receiver = crate::simd::SweepReceiver8 {
                p: kernel.p.to_array(),
                toward: f(kernel.toward),
                hc: kernel.hc as f32,
                cp_max: kernel.cp.abs().max_element() as f32,
                lights,
                light_near,
                light_count: kernel.light_count,
                tolerance2: (self.shape.tolerance * 2.0) as f32,
                centroid: self.centroid.to_array(),
                cp: f(kernel.cp),
                u_axis: f(self.u_axis),
                v_axis: f(self.v_axis),
                // Rounding is monotone: the largest rounded difference is at
                // the samples' bounds.
                smax: {
                    let (lo, hi) = (self.sample_lo.as_vec3(), self.sample_hi.as_vec3());
                    ((lo - kernel.p).abs().max((hi - kernel.p).abs())).to_array()
                },
                // Rounded up past the `f64` margin.
                shift_margin: kernel.shift_margin.map(|m| m as f32 * (1.0 + 1e-6)),
            };
            // Everything finite in f32 (the bounds need it).
            let finite = receiver.hc.is_finite()
                && receiver.cp_max.is_finite()
                && receiver.tolerance2.is_finite()
                && receiver.lights.iter().flatten().all(|x| x.is_finite())
                && receiver.light_near.iter().all(|x| x.is_finite())
                && [receiver.cp, receiver.smax]
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite());
            finite.then_some(receiver)
        }
        #[cfg(not(all(target_arch = "x86_64", feature = "std")))]
        {
            let _ = kernel;
            None
        }
    }
}

/// The set-up's decisions in lanes for `corners` (with its irregular lanes
/// undecided).
#[cfg(all(target_arch = "x86_64", feature = "std"))]
fn lane_masks(
    receiver: &LaneReceiver,
    corners: &crate::simd::EdgeCorners8,
    irregular: u32,
) -> SetupMasks8 {
    #[allow(unsafe_code)]
    // SAFETY: a receiver is only made where the processor runs AVX
    // ([`SoftShadows::sweep_receiver`]).
    let masks = unsafe { crate::simd::avx::silhouette_setup8(receiver, corners) };
    let idle = masks.idle & !irregular;
    SetupMasks8 {
        undecided: (masks.undecided | irregular) & !idle,
        idle,
        ..masks
    }
}
