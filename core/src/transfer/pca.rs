//! PCA of per-vertex MRT matrices (P2 §4; Sloan et al., "Clustered Principal
//! Components for PRT", 2003): every vertex's `G² × n` matrix, flattened to `D`
//! values, is approximated by its cluster's mean plus `K` orthonormal components,
//! `M_p ≈ μ_c + Σ_k w_pk U_ck` with `c` the vertex's cluster. A global PCA is the
//! case of one cluster; how vertices are clustered is in [`cpca`](super::cpca).
//!
//! The components are the top `K` eigenvectors of the centred data's covariance,
//! found by subspace iteration (`Q ← orth(Xᵀ X Q)`, fixed iteration count, start
//! vectors from a fixed seed: deterministic) followed by a Rayleigh–Ritz step (the
//! `K × K` projected covariance diagonalised by Jacobi rotations) that orders them
//! by decreasing variance, so that the first `K' < K` are the best `K'` the subspace
//! holds. Sums are in `f64`. Components that come out zero (data of rank below `K`)
//! are kept as zero vectors with zero weights, so `K` always means the same layout;
//! with `K ≥` the data's rank the reconstruction is exact to float rounding.
//!
//! Rendering from the compressed form never rebuilds matrices: per frame
//! [`Pca::frame_terms`] multiplies every cluster's mean and components (as
//! `G² × n` matrices) by the lighting, then [`shade_mrt_pca`](super::shade_mrt_pca)
//! blends `4 (K + 1)` terms of the vertex's cluster per vertex.

use alloc::vec;
use alloc::vec::Vec;
use core::fmt;

use super::rng::SplitMix64;
use super::shade::{ShLighting, row_dot};
use super::{Payload, TransferKind, TransferSet};

/// Subspace iterations of [`TransferSet::compress`].
pub const PCA_ITERATIONS: usize = 32;

/// Per cluster a mean and `K` components over per-vertex blocks of
/// `rows × coeffs` values; per vertex its cluster and `K` weights.
#[derive(Clone, Debug, PartialEq)]
pub struct Pca {
    pub(crate) rows: usize,
    pub(crate) coeffs: usize,
    pub(crate) components: usize,
    pub(crate) vertices: usize,
    /// `C ≥ 1`.
    pub(crate) clusters: usize,
    /// `C × D`, `D = rows · coeffs` values per cluster.
    pub(crate) mean: Vec<f32>,
    /// `C × K × D`, cluster-major, then component-major.
    pub(crate) basis: Vec<f32>,
    /// `vertices × K`.
    pub(crate) weights: Vec<f32>,
    /// Each vertex's cluster (`< C`); empty when `C = 1`.
    pub(crate) cluster_of: Vec<u32>,
}

/// Why a set could not be compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PcaError {
    /// Only dense MRT sets are compressed.
    NotDenseMrt,
    /// `components` is 0 or above the block length or the vertex count.
    Components {
        /// Requested.
        requested: usize,
        /// The most allowed.
        max: usize,
    },
    /// `clusters` is 0 or above the vertex count.
    Clusters {
        /// Requested.
        requested: usize,
        /// The most allowed.
        max: usize,
    },
}

impl fmt::Display for PcaError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            PcaError::NotDenseMrt => f.write_str("only an uncompressed MRT set can be compressed"),
            PcaError::Components { requested, max } => {
                write!(f, "components = {requested} is outside 1..={max}")
            }
            PcaError::Clusters { requested, max } => {
                write!(f, "clusters = {requested} is outside 1..={max}")
            }
        }
    }
}

impl core::error::Error for PcaError {}

/// One point of the error and memory curve of a PCA.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PcaLevel {
    /// Components used.
    pub components: usize,
    /// `sqrt(Σ_p ‖M_p − M̂_p‖² / Σ_p ‖M_p‖²)` over all vertices' matrices.
    pub relative_rms_error: f64,
    /// Bytes of means + components + weights at this `K` (`f32`), and the
    /// vertices' cluster indices (`u32`) when there is more than one cluster.
    pub bytes: usize,
    /// `bytes / vertices`.
    pub bytes_per_vertex: f64,
}

impl Pca {
    /// The baked component count `K` (per cluster).
    pub fn components(&self) -> usize {
        self.components
    }

    /// The cluster count `C` (1 for a global PCA).
    pub fn clusters(&self) -> usize {
        self.clusters
    }

    /// Values per vertex block, `D`.
    pub fn block_len(&self) -> usize {
        self.rows * self.coeffs
    }

    /// The mean block of `cluster`; `None` for `cluster ≥ C`.
    pub fn mean(&self, cluster: usize) -> Option<&[f32]> {
        if cluster >= self.clusters {
            return None;
        }
        let d = self.block_len();
        self.mean.get(cluster * d..(cluster + 1) * d)
    }

    /// Component `k` of `cluster` (a block of `D` values); `None` for `k ≥ K` or
    /// `cluster ≥ C`.
    pub fn component(&self, cluster: usize, k: usize) -> Option<&[f32]> {
        let d = self.block_len();
        if k >= self.components || cluster >= self.clusters {
            return None;
        }
        let start = (cluster * self.components + k) * d;
        self.basis.get(start..start + d)
    }

    /// All weights, `K` per vertex.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// The cluster of `vertex` (0 for a global PCA or a vertex out of range).
    #[inline]
    pub fn cluster_of(&self, vertex: usize) -> usize {
        self.cluster_of.get(vertex).map_or(0, |&c| c as usize)
    }

    /// Stored values: means, components, weights and (when `C > 1`) the
    /// vertices' clusters, 4 bytes each.
    pub fn value_count(&self) -> usize {
        self.mean.len() + self.basis.len() + self.weights.len() + self.cluster_of.len()
    }

    /// Bytes of the means + `k` components per cluster + `k` weights per vertex,
    /// and the vertices' clusters when `C > 1`.
    pub fn bytes_at(&self, k: usize) -> usize {
        let indices = if self.clusters > 1 { self.vertices } else { 0 };
        4 * (self.clusters * self.block_len() * (k + 1) + self.vertices * k + indices)
    }

    /// Length of the [`frame_terms`](Self::frame_terms) buffer for `k` components:
    /// [`cluster_terms_len`](Self::cluster_terms_len) per cluster.
    pub fn frame_terms_len(&self, k: usize) -> usize {
        self.clusters * self.cluster_terms_len(k)
    }

    /// Length of one cluster's part of the [`frame_terms`](Self::frame_terms)
    /// buffer, `rows · (k + 1)` (`k` clamped to the baked count).
    pub fn cluster_terms_len(&self, k: usize) -> usize {
        self.rows * (k.min(self.components) + 1)
    }

    /// The per-frame products `r_ck = U_ck · l` for each cluster's mean (`k = 0`)
    /// and first `k` components, cluster-major then node-major: cluster `c`'s part
    /// starts at `c · cluster_terms_len(k)`, and within it `[g (k + 1) + j]` is node
    /// `g` of term `j`. `k` is clamped to the baked count; does nothing unless
    /// `lighting` has `coeffs` entries and `out` at least
    /// [`frame_terms_len`](Self::frame_terms_len).
    pub fn frame_terms(&self, lighting: &[[f32; 3]], k: usize, out: &mut [[f32; 3]]) {
        self.frame_terms_where(lighting, k, |_, _| true, out);
    }

    /// [`frame_terms`](Self::frame_terms) for the `(cluster, node)` pairs
    /// `wanted` accepts only; the others are left as they are. Shading reads
    /// only the nodes around each vertex's view, so with many clusters most
    /// pairs are never read (the nodes a cluster's vertices look through).
    pub fn frame_terms_where(
        &self,
        lighting: &[[f32; 3]],
        k: usize,
        wanted: impl Fn(usize, usize) -> bool,
        out: &mut [[f32; 3]],
    ) {
        let k = k.min(self.components);
        let n = self.coeffs;
        if lighting.len() != n || out.len() < self.frame_terms_len(k) {
            return;
        }
        // Split per channel once, so each row's product vectorises.
        let Some(planar) = ShLighting::new(lighting) else {
            return;
        };
        let stride = k + 1;
        let d = self.block_len();
        for (cluster, part) in out
            .chunks_exact_mut(self.cluster_terms_len(k))
            .take(self.clusters)
            .enumerate()
        {
            for c in 0..stride {
                let block = if c == 0 {
                    &self.mean[cluster * d..(cluster + 1) * d]
                } else {
                    let start = (cluster * self.components + c - 1) * d;
                    &self.basis[start..start + d]
                };
                for g in (0..self.rows).filter(|&g| wanted(cluster, g)) {
                    let row = &block[g * n..(g + 1) * n];
                    part[g * stride + c] = row_dot(row, &planar).to_array();
                }
            }
        }
    }

    /// Vertex `v`'s block rebuilt from its cluster's mean and first `k`
    /// components into `out` (`D` values).
    pub fn reconstruct(&self, v: usize, k: usize, out: &mut [f32]) {
        let d = self.block_len();
        let k = k.min(self.components);
        if v >= self.vertices || out.len() != d {
            return;
        }
        let cluster = self.cluster_of(v);
        out.copy_from_slice(&self.mean[cluster * d..(cluster + 1) * d]);
        for c in 0..k {
            let w = self.weights[v * self.components + c];
            let start = (cluster * self.components + c) * d;
            for (o, u) in out.iter_mut().zip(&self.basis[start..start + d]) {
                *o += w * u;
            }
        }
    }
}

/// Orthonormalises the rows of `q` (`k × d`) in place by modified Gram–Schmidt run
/// twice; rows that are numerically dependent on the earlier ones become zero.
fn orthonormalize(q: &mut [f64], d: usize) {
    let k = q.len() / d;
    let norm = |v: &[f64]| crate::geom::sqrt(v.iter().map(|x| x * x).sum::<f64>());
    for a in 0..k {
        let before = norm(&q[a * d..(a + 1) * d]);
        for _ in 0..2 {
            for b in 0..a {
                let (head, tail) = q.split_at_mut(a * d);
                let qb = &head[b * d..(b + 1) * d];
                let qa = &mut tail[..d];
                let dot: f64 = qa.iter().zip(qb).map(|(x, y)| x * y).sum();
                for (x, y) in qa.iter_mut().zip(qb) {
                    *x -= dot * y;
                }
            }
        }
        let qa = &mut q[a * d..(a + 1) * d];
        let after = norm(qa);
        // A column is dependent on the earlier ones when projecting them out
        // leaves only rounding of its own size: judged against the column
        // itself, not the data's overall scale, so that a real direction of
        // tiny variance (a rank the data does have) is kept.
        if after > DEPENDENT * before && after > 0.0 {
            qa.iter_mut().for_each(|x| *x /= after);
        } else {
            qa.iter_mut().for_each(|x| *x = 0.0);
        }
    }
}

/// What is left of a column after two Gram–Schmidt passes, relative to its
/// norm before, below which it is numerically dependent on the earlier columns
/// (far above the `f64` rounding of those passes, about `1e-16 · √d`).
const DEPENDENT: f64 = 1e-10;

/// Eigen-decomposition of a symmetric `k × k` matrix by cyclic Jacobi rotations:
/// returns eigenvalues and the eigenvectors as columns of a `k × k` matrix.
fn jacobi_eigen(mut a: Vec<f64>, k: usize) -> (Vec<f64>, Vec<f64>) {
    let mut v = vec![0.0f64; k * k];
    for i in 0..k {
        v[i * k + i] = 1.0;
    }
    for _sweep in 0..64 {
        let off: f64 = (0..k)
            .flat_map(|i| (0..k).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i * k + j] * a[i * k + j])
            .sum();
        let total: f64 = a.iter().map(|x| x * x).sum();
        if off <= 1e-30 * total.max(1e-300) {
            break;
        }
        for p in 0..k {
            for q in p + 1..k {
                let apq = a[p * k + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q * k + q] - a[p * k + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + crate::geom::sqrt(theta * theta + 1.0));
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / crate::geom::sqrt(t * t + 1.0);
                let s = t * c;
                for r in 0..k {
                    let (arp, arq) = (a[r * k + p], a[r * k + q]);
                    a[r * k + p] = c * arp - s * arq;
                    a[r * k + q] = s * arp + c * arq;
                }
                for r in 0..k {
                    let (apr, aqr) = (a[p * k + r], a[q * k + r]);
                    a[p * k + r] = c * apr - s * aqr;
                    a[q * k + r] = s * apr + c * aqr;
                }
                for r in 0..k {
                    let (vrp, vrq) = (v[r * k + p], v[r * k + q]);
                    v[r * k + p] = c * vrp - s * vrq;
                    v[r * k + q] = s * vrp + c * vrq;
                }
            }
        }
    }
    ((0..k).map(|i| a[i * k + i]).collect(), v)
}

/// `a · b` in four partial sums, so that it vectorises (a fixed order: the
/// same result on every run).
#[inline]
fn dot_f64(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0f64; 4];
    let (ca, ra) = a.as_chunks::<4>();
    let (cb, rb) = b.as_chunks::<4>();
    for (x, y) in ca.iter().zip(cb) {
        for i in 0..4 {
            lanes[i] += x[i] * y[i];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

/// PCA of `vertices` blocks of `d` values: the mean, `k` components and
/// `vertices × k` weights. The subspace iteration starts from `start` (`k × d`,
/// e.g. the previous round's components of a clustered PCA) where given, its zero
/// rows and every row otherwise from a fixed seed, and runs `iterations` times.
pub(crate) fn compute(
    data: &[f32],
    vertices: usize,
    d: usize,
    k: usize,
    start: Option<&[f32]>,
    iterations: usize,
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    // Mean and centred data.
    let mut mean = vec![0.0f64; d];
    for block in data.chunks_exact(d) {
        for (m, x) in mean.iter_mut().zip(block) {
            *m += f64::from(*x);
        }
    }
    mean.iter_mut().for_each(|m| *m /= vertices as f64);
    let centred: Vec<f64> = data
        .chunks_exact(d)
        .flat_map(|b| b.iter().zip(&mean).map(|(x, m)| f64::from(*x) - m))
        .collect();
    let project = |q: &[f64]| -> Vec<f64> {
        // Y = X Qᵀ, vertices × k.
        let mut y = vec![0.0f64; vertices * k];
        for (p, x) in centred.chunks_exact(d).enumerate() {
            for c in 0..k {
                y[p * k + c] = dot_f64(x, &q[c * d..(c + 1) * d]);
            }
        }
        y
    };
    let mut rng = SplitMix64::new(0x5043_415F_4D52_5421);
    let mut q: Vec<f64> = (0..k * d)
        .map(|_| f64::from(rng.next_f32()) * 2.0 - 1.0)
        .collect();
    if let Some(start) = start.filter(|s| s.len() == k * d) {
        for (row, from) in q.chunks_exact_mut(d).zip(start.chunks_exact(d)) {
            if from.iter().any(|&x| x != 0.0) {
                row.iter_mut()
                    .zip(from)
                    .for_each(|(q, &x)| *q = f64::from(x));
            }
        }
    }
    orthonormalize(&mut q, d);
    for _ in 0..iterations {
        let y = project(&q);
        // Z = Xᵀ Y, as k rows of d.
        let mut z = vec![0.0f64; k * d];
        for (p, x) in centred.chunks_exact(d).enumerate() {
            for c in 0..k {
                let w = y[p * k + c];
                if w == 0.0 {
                    continue;
                }
                for (zz, xx) in z[c * d..(c + 1) * d].iter_mut().zip(x) {
                    *zz += w * xx;
                }
            }
        }
        orthonormalize(&mut z, d);
        q = z;
    }
    // Rayleigh–Ritz: order the subspace by variance.
    let y = project(&q);
    let mut s = vec![0.0f64; k * k];
    for row in y.chunks_exact(k) {
        for a in 0..k {
            for b in 0..k {
                s[a * k + b] += row[a] * row[b];
            }
        }
    }
    let (values, vectors) = jacobi_eigen(s, k);
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| values[b].total_cmp(&values[a]).then(a.cmp(&b)));
    let mut basis = vec![0.0f64; k * d];
    for (new, &old) in order.iter().enumerate() {
        for c in 0..k {
            let e = vectors[c * k + old];
            for (o, x) in basis[new * d..(new + 1) * d]
                .iter_mut()
                .zip(&q[c * d..(c + 1) * d])
            {
                *o += e * x;
            }
        }
    }
    // Rotations of zero rows leave tiny values: clean up to exact zeros / unit rows.
    orthonormalize(&mut basis, d);
    let weights_f64 = project(&basis);
    (
        mean.iter().map(|&m| m as f32).collect(),
        basis.iter().map(|&b| b as f32).collect(),
        weights_f64.iter().map(|&w| w as f32).collect(),
    )
}

impl TransferSet {
    /// PCA-compresses a dense MRT set to `components` components (1 ..= min(block
    /// length, vertex count)): one global mean and basis. Deterministic. Cost
    /// about `2 · PCA_ITERATIONS · vertices · D · K` multiply-adds.
    pub fn compress(&self, components: usize) -> Result<TransferSet, PcaError> {
        self.compress_clustered(1, components, 0)
    }

    /// Clustered-PCA-compresses a dense MRT set ([`cpca`](super::cpca)):
    /// `clusters` (1 ..= vertex count) clusters of `components` (1 ..= min(block
    /// length, vertex count)) components each, the clustering seeded from `seed`.
    /// Deterministic for a seed (and the same on rayon's pool, with the
    /// `parallel` feature, as off it); one cluster is
    /// [`compress`](Self::compress) whatever the seed. Cost: about three
    /// global PCAs (the rounds' warm-started fits and the final one), plus
    /// `vertices · clusters · D` per k-means round and
    /// `vertices · clusters · (K + 1) · D` multiply-adds per reclassification,
    /// for at most [`KMEANS_ROUNDS`](super::cpca::KMEANS_ROUNDS) and
    /// [`CPCA_ROUNDS`](super::cpca::CPCA_ROUNDS) rounds.
    pub fn compress_clustered(
        &self,
        clusters: usize,
        components: usize,
        seed: u64,
    ) -> Result<TransferSet, PcaError> {
        let (Payload::Dense(data), TransferKind::Mrt) = (&self.payload, self.kind) else {
            return Err(PcaError::NotDenseMrt);
        };
        let d = self.block_len();
        let vertices = self.vertex_count();
        let max = d.min(vertices);
        if components == 0 || components > max {
            return Err(PcaError::Components {
                requested: components,
                max,
            });
        }
        if clusters == 0 || clusters > vertices {
            return Err(PcaError::Clusters {
                requested: clusters,
                max: vertices,
            });
        }
        let fit = super::cpca::fit(data, vertices, d, clusters, components, seed);
        Ok(TransferSet {
            payload: Payload::Pca(Pca {
                rows: (self.grid * self.grid) as usize,
                coeffs: self.coeff_count(),
                components,
                vertices,
                clusters,
                mean: fit.mean,
                basis: fit.basis,
                weights: fit.weights,
                cluster_of: fit.cluster_of,
            }),
            ..self.clone_header()
        })
    }

    /// Error and memory of the compressed set `compressed` against this dense set,
    /// for each component count in `ks` (clamped to the baked count). `None` unless
    /// `self` is dense and `compressed` is its PCA (same kind, sizes and vertices).
    pub fn pca_levels(&self, compressed: &TransferSet, ks: &[usize]) -> Option<Vec<PcaLevel>> {
        let (Payload::Dense(data), Some(pca)) = (&self.payload, compressed.pca()) else {
            return None;
        };
        let d = self.block_len();
        if pca.block_len() != d || pca.vertices != self.vertex_count() {
            return None;
        }
        let total: f64 = data.iter().map(|&x| f64::from(x) * f64::from(x)).sum();
        let mut block = vec![0.0f32; d];
        Some(
            ks.iter()
                .map(|&k| {
                    let k = k.min(pca.components);
                    let mut err = 0.0f64;
                    for (v, orig) in data.chunks_exact(d).enumerate() {
                        pca.reconstruct(v, k, &mut block);
                        err += orig
                            .iter()
                            .zip(&block)
                            .map(|(a, b)| {
                                let e = f64::from(*a) - f64::from(*b);
                                e * e
                            })
                            .sum::<f64>();
                    }
                    let bytes = pca.bytes_at(k);
                    PcaLevel {
                        components: k,
                        relative_rms_error: crate::geom::sqrt(err / total.max(f64::MIN_POSITIVE)),
                        bytes,
                        bytes_per_vertex: bytes as f64 / pca.vertices.max(1) as f64,
                    }
                })
                .collect(),
        )
    }

    /// A copy without the payload (filled in by the caller).
    fn clone_header(&self) -> TransferSet {
        TransferSet {
            kind: self.kind,
            bands: self.bands,
            grid: self.grid,
            info: self.info,
            positions: self.positions.clone(),
            normals: self.normals.clone(),
            frames: self.frames.clone(),
            payload: Payload::Dense(Vec::new()),
            texels: self.texels.clone(),
        }
    }
}
