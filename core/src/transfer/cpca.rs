//! How clustered PCA (Sloan, Hall, Hart, Snyder, "Clustered Principal
//! Components for Precomputed Radiance Transfer", 2003) groups the vertices.
//!
//! One global PCA spends its components on what varies most over the mesh, and
//! MRT blocks vary most with the vertex frame, which points every way. Clusters
//! of vertices whose blocks are alike each get their own mean and `K`
//! components, so the same `K` reconstructs far better.
//!
//! The fit aims at the least total squared reconstruction error
//! `Σ_p ‖M_p − μ_c − Σ_k w_pk U_ck‖²` by alternating two steps that each lower
//! it (up to the few subspace iterations of a warm-started fit), as in the
//! paper's iterative PCA (its section 3.2):
//! 1. **Seed**: k-means++ over the blocks (the first block chosen by `seed`, each
//!    next one with probability proportional to its squared distance to the
//!    nearest chosen), then [`KMEANS_ROUNDS`] Lloyd rounds. This is the `K = 0`
//!    clustering, a good start for `K > 0`.
//! 2. **Refine**, at most [`CPCA_ROUNDS`] times: a PCA per cluster (warm-started
//!    from the cluster's previous components), then every vertex moves to the
//!    cluster that reconstructs its block with the least error,
//!    `‖x − μ_c‖² − Σ_k (U_ck · (x − μ_c))²`. It stops early when no vertex
//!    moves.
//!
//! A cluster left empty takes the worst-reconstructed vertex of a cluster that
//! has several, so all `C` clusters stay in use. Everything is deterministic for a
//! seed: ties go to the lower cluster index, sums run in a fixed order.

use alloc::vec;
use alloc::vec::Vec;

use super::pca::{PCA_ITERATIONS, compute};
use super::rng::SplitMix64;

/// Lloyd rounds of the `K = 0` seeding.
pub const KMEANS_ROUNDS: usize = 4;
/// At most this many refit-and-reclassify rounds.
pub const CPCA_ROUNDS: usize = 8;
/// Subspace iterations of a warm-started per-cluster PCA within the rounds
/// (the final fit runs the full [`PCA_ITERATIONS`]).
const WARM_ITERATIONS: usize = 8;

/// A fitted clustered PCA, in the layout of [`Pca`](super::Pca).
pub(crate) struct Fit {
    pub(crate) mean: Vec<f32>,
    pub(crate) basis: Vec<f32>,
    pub(crate) weights: Vec<f32>,
    /// Empty for one cluster.
    pub(crate) cluster_of: Vec<u32>,
}

/// Clustered PCA of `vertices` blocks of `d` values into `clusters` clusters of
/// `k` components (callers check `1 ≤ clusters ≤ vertices`, `1 ≤ k ≤ d`).
pub(crate) fn fit(
    data: &[f32],
    vertices: usize,
    d: usize,
    clusters: usize,
    k: usize,
    seed: u64,
) -> Fit {
    if clusters == 1 {
        let (mean, basis, weights) = compute(data, vertices, d, k, None, PCA_ITERATIONS);
        return Fit {
            mean,
            basis,
            weights,
            cluster_of: Vec::new(),
        };
    }
    let mut cluster_of = kmeans(data, vertices, d, clusters, seed);
    let mut models: Vec<Model> = (0..clusters).map(|_| Model::empty(d, k)).collect();
    let mut errors = vec![0.0f64; vertices];
    for _ in 0..CPCA_ROUNDS {
        for (c, model) in models.iter_mut().enumerate() {
            model.refit(data, d, k, &cluster_of, c as u32, WARM_ITERATIONS);
        }
        let mut moved = 0usize;
        let best = best_clusters(&models, data, d, k);
        for ((c, e), (best, error)) in cluster_of.iter_mut().zip(&mut errors).zip(best) {
            moved += usize::from(*c != best);
            *c = best;
            *e = error;
        }
        moved += fill_empty(&mut cluster_of, &errors, clusters);
        if moved == 0 {
            break;
        }
    }
    // The final fit of each cluster, with the full iteration count.
    let mut mean = Vec::with_capacity(clusters * d);
    let mut basis = Vec::with_capacity(clusters * k * d);
    let mut weights = vec![0.0f32; vertices * k];
    for (c, model) in models.iter_mut().enumerate() {
        let members = model.refit(data, d, k, &cluster_of, c as u32, PCA_ITERATIONS);
        mean.extend_from_slice(&model.mean);
        basis.extend_from_slice(&model.basis);
        for (i, &v) in members.iter().enumerate() {
            weights[v * k..(v + 1) * k].copy_from_slice(&model.weights[i * k..(i + 1) * k]);
        }
    }
    Fit {
        mean,
        basis,
        weights,
        cluster_of,
    }
}

/// Blocks reclassified together: each model vector is read once per tile and
/// dotted with the tile's residuals while they sit in cache (a 1024-value block
/// makes the tile's residuals 64 KiB), instead of once per block.
const TILE: usize = 16;

/// For every block of `data`, the model that reconstructs it best (the lowest
/// index among equals) and its squared error. Spread over rayon's pool with the
/// `parallel` feature; each block's answer is the same either way.
fn best_clusters(models: &[Model], data: &[f32], d: usize, k: usize) -> Vec<(u32, f64)> {
    let tile = |blocks: &[f32], residuals: &mut Vec<f32>| -> Vec<(u32, f64)> {
        let count = blocks.len() / d;
        residuals.resize(count * d, 0.0);
        let mut best = vec![(0u32, f64::INFINITY); count];
        let mut errors = [0.0f64; TILE];
        for (c, model) in models.iter().enumerate() {
            for ((r, x), e) in residuals
                .chunks_exact_mut(d)
                .zip(blocks.chunks_exact(d))
                .zip(&mut errors)
            {
                for ((r, a), m) in r.iter_mut().zip(x).zip(&model.mean) {
                    *r = a - m;
                }
                *e = dot(r, r);
            }
            for u in model.basis.chunks_exact(d).take(k) {
                for (r, e) in residuals.chunks_exact(d).zip(&mut errors) {
                    let w = dot(r, u);
                    *e -= w * w;
                }
            }
            for (b, &e) in best.iter_mut().zip(&errors) {
                let e = e.max(0.0);
                if e < b.1 {
                    *b = (c as u32, e);
                }
            }
        }
        best
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        data.par_chunks(TILE * d)
            .map_init(Vec::new, |residuals, blocks| tile(blocks, residuals))
            .flatten_iter()
            .collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        let mut residuals = Vec::new();
        data.chunks(TILE * d)
            .flat_map(|blocks| tile(blocks, &mut residuals))
            .collect()
    }
}

/// One cluster's mean, components and its members' weights.
struct Model {
    mean: Vec<f32>,
    basis: Vec<f32>,
    weights: Vec<f32>,
}

impl Model {
    fn empty(d: usize, k: usize) -> Model {
        Model {
            mean: vec![0.0; d],
            basis: vec![0.0; k * d],
            weights: Vec::new(),
        }
    }

    /// Fits the PCA of the vertices assigned to `cluster`, warm-started from the
    /// current components; returns those vertices in order (their weights are
    /// `self.weights`, `k` each). An empty cluster keeps its model.
    fn refit(
        &mut self,
        data: &[f32],
        d: usize,
        k: usize,
        cluster_of: &[u32],
        cluster: u32,
        iterations: usize,
    ) -> Vec<usize> {
        let members: Vec<usize> = (0..cluster_of.len())
            .filter(|&v| cluster_of[v] == cluster)
            .collect();
        if members.is_empty() {
            self.weights.clear();
            return members;
        }
        let mut gathered = Vec::with_capacity(members.len() * d);
        for &v in &members {
            gathered.extend_from_slice(&data[v * d..(v + 1) * d]);
        }
        let (mean, basis, weights) = compute(
            &gathered,
            members.len(),
            d,
            k,
            Some(&self.basis),
            iterations,
        );
        *self = Model {
            mean,
            basis,
            weights,
        };
        members
    }
}

/// `a · b` in `f64`, in eight partial sums (so it vectorises): the error
/// `‖r‖² − Σ (U·r)²` subtracts nearly equal numbers when a model fits a block
/// well, so its terms need more than `f32`'s digits.
#[inline]
fn dot(a: &[f32], b: &[f32]) -> f64 {
    let mut lanes = [0.0f64; 8];
    let (ca, ra) = a.as_chunks::<8>();
    let (cb, rb) = b.as_chunks::<8>();
    for (x, y) in ca.iter().zip(cb) {
        for i in 0..8 {
            lanes[i] += f64::from(x[i]) * f64::from(y[i]);
        }
    }
    let tail: f64 = ra
        .iter()
        .zip(rb)
        .map(|(x, y)| f64::from(*x) * f64::from(*y))
        .sum();
    lanes.iter().sum::<f64>() + tail
}

/// Squared distance of two blocks, in eight partial sums (so it vectorises).
fn distance2(a: &[f32], b: &[f32]) -> f64 {
    let mut lanes = [0.0f32; 8];
    let (ca, ra) = a.as_chunks::<8>();
    let (cb, rb) = b.as_chunks::<8>();
    for (x, y) in ca.iter().zip(cb) {
        for i in 0..8 {
            let e = x[i] - y[i];
            lanes[i] += e * e;
        }
    }
    let tail: f32 = ra.iter().zip(rb).map(|(x, y)| (x - y) * (x - y)).sum();
    lanes.iter().map(|&l| f64::from(l)).sum::<f64>() + f64::from(tail)
}

/// The `K = 0` clustering: k-means++ seeds from `seed`, then Lloyd rounds.
fn kmeans(data: &[f32], vertices: usize, d: usize, clusters: usize, seed: u64) -> Vec<u32> {
    let block = |v: usize| &data[v * d..(v + 1) * d];
    let mut rng = SplitMix64::new(seed ^ 0x4350_4341_5345_4544);
    let mut centres: Vec<f32> = Vec::with_capacity(clusters * d);
    let first = (rng.next_u64() % vertices as u64) as usize;
    centres.extend_from_slice(block(first));
    let mut nearest: Vec<f64> = (0..vertices)
        .map(|v| distance2(block(v), block(first)))
        .collect();
    for _ in 1..clusters {
        let total: f64 = nearest.iter().sum();
        // Identical blocks all around: any vertex will do; take the farthest
        // (the first of them), which is also the choice when total is zero.
        let pick = if total > 0.0 {
            let mut target = f64::from(rng.next_f32()) * total;
            let mut pick = vertices - 1;
            for (v, &w) in nearest.iter().enumerate() {
                if target < w {
                    pick = v;
                    break;
                }
                target -= w;
            }
            pick
        } else {
            0
        };
        let chosen = block(pick).to_vec();
        for (v, n) in nearest.iter_mut().enumerate() {
            *n = n.min(distance2(block(v), &chosen));
        }
        centres.extend_from_slice(&chosen);
    }
    let mut cluster_of = vec![0u32; vertices];
    let mut errors = vec![0.0f64; vertices];
    for _ in 0..KMEANS_ROUNDS {
        // The K = 0 models: a mean each, so the error is the squared distance.
        let models: Vec<Model> = centres
            .chunks_exact(d)
            .map(|centre| Model {
                mean: centre.to_vec(),
                basis: Vec::new(),
                weights: Vec::new(),
            })
            .collect();
        let best = best_clusters(&models, data, d, 0);
        for ((c, e), (best, error)) in cluster_of.iter_mut().zip(&mut errors).zip(best) {
            *c = best;
            *e = error;
        }
        fill_empty(&mut cluster_of, &errors, clusters);
        let mut sums = vec![0.0f64; clusters * d];
        let mut counts = vec![0usize; clusters];
        for (&c, x) in cluster_of.iter().zip(data.chunks_exact(d)) {
            let c = c as usize;
            counts[c] += 1;
            for (s, x) in sums[c * d..(c + 1) * d].iter_mut().zip(x) {
                *s += f64::from(*x);
            }
        }
        for (c, centre) in centres.chunks_exact_mut(d).enumerate() {
            if counts[c] > 0 {
                let n = counts[c] as f64;
                for (o, s) in centre.iter_mut().zip(&sums[c * d..(c + 1) * d]) {
                    *o = (s / n) as f32;
                }
            }
        }
    }
    cluster_of
}

/// Gives every empty cluster the worst-fitted vertex (largest `errors`) among
/// clusters of two or more; returns how many vertices moved.
fn fill_empty(cluster_of: &mut [u32], errors: &[f64], clusters: usize) -> usize {
    let mut counts = vec![0usize; clusters];
    for &c in cluster_of.iter() {
        counts[c as usize] += 1;
    }
    let mut moved = 0;
    let mut taken = vec![false; cluster_of.len()];
    for empty in 0..clusters {
        if counts[empty] != 0 {
            continue;
        }
        let worst = (0..cluster_of.len())
            .filter(|&v| !taken[v] && counts[cluster_of[v] as usize] > 1)
            .fold(None, |best: Option<usize>, v| match best {
                Some(b) if errors[b] >= errors[v] => Some(b),
                _ => Some(v),
            });
        let Some(v) = worst else {
            break;
        };
        counts[cluster_of[v] as usize] -= 1;
        counts[empty] = 1;
        cluster_of[v] = empty as u32;
        taken[v] = true;
        moved += 1;
    }
    moved
}
