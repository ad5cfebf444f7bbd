//! Soft shadow visibility (`antumbra_core::ssv`) against Embree occlusion rays,
//! shared by the `embree_ssv` test and `antumbra verify ssv`.
//!
//! For every receiver `p` and light sample `s` the library's bit is compared with
//! Embree's occlusion ray from `p` along `s - p` with `t` in the open interval
//! `(0, 1)` (the oracle's contract: hits at `t = 0`, e.g. a receiver lying on the
//! floor, are not occlusions), that is, the same open segment the library claims
//! to decide. Each mismatch is then decided by the exact segment test
//! ([`segment_meets_triangle`] against every occluder): where the library agrees
//! with the exact test, Embree's `f32` rounding decided, and the mismatch is a
//! grazing case when the segment passes within [`GRAZING_OF_SCENE`] of the scene
//! size from an edge of the deciding triangle (the distance is reported); where
//! the library disagrees with the exact test, it is a library bug.

use antumbra_core::Ray;
use antumbra_core::ssv::{SoftShadows, segment_meets_triangle};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::data::Mesh;
use crate::oracle::{OracleOptions, try_cast};

/// A mismatch whose segment passes within this fraction of the scene's largest
/// coordinate from a triangle edge is a grazing case (Embree decides such rays in
/// `f32` after translating to the ray origin: its error is a few ulps of the
/// coordinates; this leaves two orders of magnitude of margin).
pub const GRAZING_OF_SCENE: f64 = 1e-5;

/// The agreement the acceptance asks for: mismatches at most this fraction of
/// all bits.
pub const MAX_MISMATCH_FRACTION: f64 = 1e-5;

/// One bit on which the library and Embree disagree.
#[derive(Clone, Debug)]
pub struct Mismatch {
    /// Receiver index.
    pub receiver: usize,
    /// Sample index.
    pub sample: usize,
    /// The receiver.
    pub point: Vec3,
    /// The sample.
    pub target: Vec3,
    /// The library's answer (visible).
    pub library: bool,
    /// The exact segment test's answer (visible).
    pub exact: bool,
    /// Distance from the segment's crossing of the deciding triangle's plane to
    /// the nearest edge of that triangle (the triangles the exact test finds, or
    /// Embree's hit); infinite when no triangle could be named.
    pub edge_distance: f64,
    /// The deciding triangle.
    pub triangle: Option<usize>,
}

impl Mismatch {
    /// Explained: the library agrees with the exact test, and the segment grazes
    /// an edge within `GRAZING_OF_SCENE * scale`.
    pub fn is_grazing(&self, scale: f64) -> bool {
        self.library == self.exact && self.edge_distance <= GRAZING_OF_SCENE * scale
    }
}

/// The outcome of one comparison.
#[derive(Clone, Debug, Default)]
pub struct Comparison {
    /// Receivers compared.
    pub receivers: usize,
    /// Bits compared (receivers × samples).
    pub bits: u64,
    /// Bits set (visible) by the library.
    pub visible_bits: u64,
    /// Every mismatch.
    pub mismatches: Vec<Mismatch>,
    /// The scene's largest absolute coordinate (the grazing scale).
    pub scale: f64,
}

impl Comparison {
    /// Fraction of bits that agree.
    pub fn agreement(&self) -> f64 {
        1.0 - self.mismatches.len() as f64 / self.bits.max(1) as f64
    }

    /// Mismatches where the library disagrees with the exact test.
    pub fn library_errors(&self) -> impl Iterator<Item = &Mismatch> {
        self.mismatches.iter().filter(|m| m.library != m.exact)
    }

    /// Mismatches that are neither grazing nor library errors... or grazing too
    /// far from an edge to be rounding: anything not explained.
    pub fn unexplained(&self) -> impl Iterator<Item = &Mismatch> {
        self.mismatches.iter().filter(|m| !m.is_grazing(self.scale))
    }

    /// Largest edge distance among the mismatches, as a fraction of the scale.
    pub fn worst_edge_distance(&self) -> f64 {
        self.mismatches
            .iter()
            .map(|m| m.edge_distance / self.scale)
            .fold(0.0, f64::max)
    }

    /// Whether the acceptance holds: at most [`MAX_MISMATCH_FRACTION`] of the
    /// bits differ and every mismatch is explained.
    pub fn passes(&self) -> bool {
        (self.mismatches.len() as f64) <= MAX_MISMATCH_FRACTION * self.bits as f64
            && self.unexplained().next().is_none()
    }

    /// Adds another comparison's counts.
    pub fn merge(&mut self, other: Comparison) {
        self.receivers += other.receivers;
        self.bits += other.bits;
        self.visible_bits += other.visible_bits;
        self.mismatches.extend(other.mismatches);
        self.scale = self.scale.max(other.scale);
    }
}

/// The library's bits for every receiver (in parallel), `words_per_receiver`
/// words each.
pub fn library_bits(ssv: &SoftShadows, receivers: &[Vec3]) -> Result<Vec<u64>, String> {
    let words = ssv.words_per_receiver();
    let mut bits = vec![0u64; receivers.len() * words];
    bits.par_chunks_mut(words)
        .zip(receivers.par_iter())
        .try_for_each(|(out, &p)| ssv.query(p, out).map(|_| ()))
        .map_err(|e| format!("soft shadow query failed: {e}"))?;
    Ok(bits)
}

/// The shadow rays of every (receiver, sample) pair, receiver-major:
/// origin `p`, direction `s - p`, `t` in `(0, 1)`.
pub fn shadow_rays(receivers: &[Vec3], samples: &[Vec3]) -> Vec<Ray> {
    receivers
        .iter()
        .flat_map(|&p| samples.iter().map(move |&s| Ray::new(p, s - p, 1.0)))
        .collect()
}

fn bit(bits: &[u64], words: usize, receiver: usize, sample: usize) -> bool {
    bits[receiver * words + sample / 64] >> (sample % 64) & 1 == 1
}

/// Distance from where the line `p → s` crosses the plane of `(a, b, c)` to the
/// nearest of the triangle's edges (infinite when the line is parallel to it).
pub fn edge_distance(p: Vec3, s: Vec3, [a, b, c]: [Vec3; 3]) -> f64 {
    let [p, s, a, b, c] = [p, s, a, b, c].map(|v| v.as_dvec3());
    let n = (b - a).cross(c - a);
    let d = s - p;
    let denominator = n.dot(d);
    if denominator == 0.0 {
        return f64::INFINITY;
    }
    let x = p + d * (n.dot(a - p) / denominator);
    let to_segment = |u: DVec3, v: DVec3| {
        let e = v - u;
        let t = ((x - u).dot(e) / e.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        (u + e * t - x).length()
    };
    to_segment(a, b).min(to_segment(b, c)).min(to_segment(c, a))
}

/// Compares the library's bits for `receivers` with Embree on `occluders` (the
/// same triangles the soft shadows were built from). Errors when the oracle or a
/// query fails.
pub fn compare_with_embree(
    occluders: &Mesh,
    ssv: &SoftShadows,
    receivers: &[Vec3],
) -> Result<Comparison, String> {
    let samples = ssv.samples();
    let bits = library_bits(ssv, receivers)?;
    let rays = shadow_rays(receivers, samples);
    let embree = try_cast(
        &occluders.positions,
        &occluders.indices,
        &rays,
        OracleOptions::default(),
    )?;
    let n = samples.len();
    let embree_visible = pack(receivers.len(), n, |k| !embree.hits[k].occluded);
    let hit = |k: usize| embree.hits[k].triangle;
    Ok(classify(
        occluders,
        receivers,
        samples,
        (&bits, &embree_visible),
        &hit,
    ))
}

/// Bits `visible(r * samples + i)` packed as the library packs them,
/// `ceil(samples / 64)` words per receiver.
pub fn pack(receivers: usize, samples: usize, visible: impl Fn(usize) -> bool) -> Vec<u64> {
    let words = samples.div_ceil(64);
    let mut bits = vec![0u64; receivers * words];
    for r in 0..receivers {
        for i in 0..samples {
            if visible(r * samples + i) {
                bits[r * words + i / 64] |= 1 << (i % 64);
            }
        }
    }
    bits
}

/// Compares the library's bits with Embree's from a frame
/// ([`crate::oracle::try_frame`]: visible bits, no hit triangles): the
/// mismatches are decided by the exact segment test, and the rays of those the
/// exact test finds unblocked are cast again through the oracle for the
/// triangle Embree hit.
pub fn compare_frame(
    occluders: &Mesh,
    receivers: &[Vec3],
    samples: &[Vec3],
    library: &[u64],
    embree_visible: &[u64],
) -> Result<Comparison, String> {
    let words = samples.len().div_ceil(64);
    let n = samples.len();
    let differing: Vec<usize> = (0..receivers.len() * n)
        .filter(|&k| bit(library, words, k / n, k % n) != bit(embree_visible, words, k / n, k % n))
        .collect();
    let rays: Vec<Ray> = differing
        .iter()
        .map(|&k| Ray::new(receivers[k / n], samples[k % n] - receivers[k / n], 1.0))
        .collect();
    let hits = if rays.is_empty() {
        Vec::new()
    } else {
        try_cast(
            &occluders.positions,
            &occluders.indices,
            &rays,
            OracleOptions::default(),
        )?
        .hits
    };
    let hit = |k: usize| {
        differing
            .binary_search(&k)
            .map_or(u32::MAX, |at| hits[at].triangle)
    };
    Ok(classify(
        occluders,
        receivers,
        samples,
        (library, embree_visible),
        &hit,
    ))
}

/// The mismatches between the library's and Embree's bits, each decided by
/// the exact segment test against every occluder; `hit(k)` names the triangle
/// Embree's ray `k` (`r * samples + i`) hit, if known.
fn classify(
    occluders: &Mesh,
    receivers: &[Vec3],
    samples: &[Vec3],
    (bits, embree_visible): (&[u64], &[u64]),
    hit: &(dyn Fn(usize) -> u32 + Sync),
) -> Comparison {
    let words = samples.len().div_ceil(64);
    let view = occluders.view();
    let triangles: Vec<[Vec3; 3]> = (0..view.triangle_count())
        .map(|t| view.triangle(t))
        .collect();
    let scale = occluders
        .positions
        .iter()
        .chain(receivers.iter().map(|p| p.as_ref()))
        .chain(samples.iter().map(|s| s.as_ref()))
        .flatten()
        .fold(1e-30f64, |m, &c| m.max(f64::from(c).abs()));
    let n = samples.len();
    let differing: Vec<usize> = (0..receivers.len() * n)
        .filter(|&k| bit(bits, words, k / n, k % n) != bit(embree_visible, words, k / n, k % n))
        .collect();
    let mismatches = differing
        .par_iter()
        .map(|&k| {
            let (r, i) = (k / n, k % n);
            let (p, s) = (receivers[r], samples[i]);
            let blocking: Vec<usize> = (0..triangles.len())
                .filter(|&t| {
                    let [a, b, c] = triangles[t];
                    segment_meets_triangle(p, s, a, b, c)
                })
                .collect();
            let embree_hit = hit(k);
            let candidates: Vec<usize> = if blocking.is_empty() && embree_hit != u32::MAX {
                vec![embree_hit as usize]
            } else {
                blocking.clone()
            };
            let (edge_distance, triangle) = candidates
                .iter()
                .map(|&t| (edge_distance(p, s, triangles[t]), Some(t)))
                .fold(
                    (f64::INFINITY, None),
                    |best, x| {
                        if x.0 < best.0 { x } else { best }
                    },
                );
            Mismatch {
                receiver: r,
                sample: i,
                point: p,
                target: s,
                library: bit(bits, words, r, i),
                exact: blocking.is_empty(),
                edge_distance,
                triangle,
            }
        })
        .collect();
    let visible_bits = bits.iter().map(|w| u64::from(w.count_ones())).sum();
    Comparison {
        receivers: receivers.len(),
        bits: (receivers.len() * n) as u64,
        visible_bits,
        mismatches,
        scale,
    }
}
