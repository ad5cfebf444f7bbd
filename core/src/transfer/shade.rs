//! Run-time shading of transfer sets: per-vertex kernels for the three kinds and
//! the compressed MRT form, and the batch [`TransferSet::shade`].
//!
//! Every kernel takes lighting as `bands²` RGB coefficients and returns one RGB
//! value; none allocates. The glossy SH and MRT kernels take it split per channel
//! ([`ShLighting`], built once per frame) so that their dot products vectorise;
//! each fast kernel has a slow, obviously right twin it is tested against
//! (`*_reference`, coefficient-major `[[f32; 3]]` lighting, serial sums).

use core::fmt;

use glam::{Vec3, Vec4};

use super::mrt::{MrtTap, mrt_tap};
use super::{Payload, TransferKind, TransferSet};
use crate::geom::{Frame, unit_or_zero};
use crate::prefetch::prefetch;
use crate::sh::{MAX_COEFFS, ShRgb, ZonalKernel, eval_basis, eval_basis_into};

/// RGB lighting coefficients of an [`ShRgb`], coefficient-major.
pub fn lighting_from_sh_rgb<const N: usize>(sh: &ShRgb<N>) -> [[f32; 3]; N] {
    core::array::from_fn(|i| [sh.r.coeffs[i], sh.g.coeffs[i], sh.b.coeffs[i]])
}

/// RGB lighting coefficients split into one plane per channel and zero-padded to
/// [`MAX_COEFFS`], built once per frame: the layout in which the glossy SH and MRT
/// kernels' final dot products vectorise (each channel is a contiguous row, where
/// the coefficient-major `[[f32; 3]]` form interleaves them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShLighting {
    coeffs: usize,
    planes: [[f32; MAX_COEFFS]; 3],
}

impl ShLighting {
    /// Splits coefficient-major RGB lighting (`bands²` triples); `None` for more
    /// than [`MAX_COEFFS`] coefficients.
    pub fn new(lighting: &[[f32; 3]]) -> Option<Self> {
        if lighting.len() > MAX_COEFFS {
            return None;
        }
        let mut planes = [[0.0; MAX_COEFFS]; 3];
        for (j, l) in lighting.iter().enumerate() {
            for (plane, c) in planes.iter_mut().zip(l) {
                plane[j] = *c;
            }
        }
        Some(ShLighting {
            coeffs: lighting.len(),
            planes,
        })
    }

    /// Number of coefficients (the `lighting.len()` it was built from).
    pub fn coeff_count(&self) -> usize {
        self.coeffs
    }

    /// Coefficient `j` as RGB (zero past [`coeff_count`](Self::coeff_count)).
    pub fn get(&self, j: usize) -> [f32; 3] {
        if j >= self.coeffs {
            return [0.0; 3];
        }
        [self.planes[0][j], self.planes[1][j], self.planes[2][j]]
    }
}

/// Four consecutive values of `s` from `i` as a [`Vec4`] (SSE2 / NEON / simd128
/// under glam, four scalars elsewhere).
#[inline(always)]
fn vec4_at(s: &[f32], i: usize) -> Vec4 {
    Vec4::new(s[i], s[i + 1], s[i + 2], s[i + 3])
}

/// `Σ_j (Σ_k w_k rows_k[j]) · planes[c][j]` for the three channels, rows of length
/// `N`: blend the rows four coefficients at a time (`4N`), then three dot products
/// (`3N`) with four-lane partial sums (a reassociation of the serial sum). With
/// one row of weight 1 it is a plain dot product with the planes.
#[inline(always)]
fn blend_dot<const N: usize, const R: usize>(
    rows: [&[f32; N]; R],
    weights: [f32; R],
    planes: &[[f32; MAX_COEFFS]; 3],
) -> Vec3 {
    let (mut r, mut g, mut b) = (Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
    let full = N / 4 * 4;
    let mut j = 0;
    while j < full {
        let mut m = Vec4::ZERO;
        for (row, w) in rows.iter().zip(weights) {
            m += w * vec4_at(&row[..], j);
        }
        r += m * vec4_at(&planes[0], j);
        g += m * vec4_at(&planes[1], j);
        b += m * vec4_at(&planes[2], j);
        j += 4;
    }
    let mut tail = Vec3::ZERO;
    for j in full..N {
        let mut m = 0.0;
        for (row, w) in rows.iter().zip(weights) {
            m += w * row[j];
        }
        tail += m * Vec3::new(planes[0][j], planes[1][j], planes[2][j]);
    }
    Vec3::new(r.element_sum(), g.element_sum(), b.element_sum()) + tail
}

/// `grid² · per_node`, saturating (a huge `grid` then fails every length check).
#[inline(always)]
fn node_values(grid: u32, per_node: usize) -> usize {
    (grid as usize)
        .saturating_mul(grid as usize)
        .saturating_mul(per_node)
}

#[inline(always)]
fn rgb(c: &[f32; 3]) -> Vec3 {
    Vec3::from_array(*c)
}

/// Diffuse transfer dotted with the lighting: the irradiance `Σ_j t_j l_j` per
/// channel (outgoing radiance is `albedo/π` times it). Extra values on either side
/// are ignored.
#[inline]
pub fn shade_diffuse(transfer: &[f32], lighting: &[[f32; 3]]) -> Vec3 {
    let mut acc = Vec3::ZERO;
    for (t, l) in transfer.iter().zip(lighting) {
        acc += *t * rgb(l);
    }
    acc
}

/// The Phong lobe's zonal factors spread over coefficients: `A_l(i)` for the
/// normalised lobe `((s+1)/2π) max(0, cos)^s` ([`ZonalKernel::phong`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlossyLobe {
    coeffs: usize,
    factors: [f32; MAX_COEFFS],
}

impl GlossyLobe {
    /// The lobe of exponent `exponent` for `bands` bands; `None` for an exponent that
    /// is not finite and `≥ 0`, or bands outside `1..=8`.
    pub fn phong(bands: u32, exponent: f32) -> Option<Self> {
        let kernel = ZonalKernel::phong(exponent)?;
        if !(1..=8).contains(&bands) {
            return None;
        }
        let mut factors = [0.0; MAX_COEFFS];
        for l in 0..bands as usize {
            for f in &mut factors[l * l..(l + 1) * (l + 1)] {
                *f = kernel.factor(l);
            }
        }
        Some(GlossyLobe {
            coeffs: (bands * bands) as usize,
            factors,
        })
    }

    /// Coefficient count the lobe was built for.
    pub fn coeff_count(&self) -> usize {
        self.coeffs
    }
}

/// The mirror direction of `to_eye` about `normal`, or `None` for a viewer behind
/// the surface (or a non-finite view).
#[inline]
fn mirror(normal: Vec3, to_eye: Vec3) -> Option<Vec3> {
    let c = normal.dot(to_eye);
    (c > 0.0).then(|| 2.0 * c * normal - to_eye)
}

/// Glossy SH transfer (Kautz, Sloan & Snyder 2002 with the Sloan et al. 2002 transfer
/// matrix): `L_o = Σ_i A_l(i) Y_i(r) (T l)_i` per channel with `T` the world-frame
/// `n × n` matrix (row-major), `r` the mirror of the unit `to_eye` about the unit
/// `normal`. Computed view-first, `u = Tᵀ w`, `w_i = A_l(i) Y_i(r)`, then `u · l`:
/// `n² + 3n` multiply-adds. Zero for a viewer behind the surface, or when `matrix`
/// or `lighting` is shorter than the lobe's coefficient count requires.
#[inline]
pub fn shade_glossy_sh(
    matrix: &[f32],
    lobe: &GlossyLobe,
    lighting: &ShLighting,
    normal: Vec3,
    to_eye: Vec3,
) -> Vec3 {
    let n = lobe.coeffs;
    if matrix.len() < n * n || lighting.coeffs < n {
        return Vec3::ZERO;
    }
    let Some(r) = mirror(normal, to_eye) else {
        return Vec3::ZERO;
    };
    with_coeff_count!(n, glossy_n, (matrix, lobe, lighting, r))
}

/// Calls `$f::<N>($args)` for the square coefficient count `$n`, so each kernel is
/// compiled with fixed-size, unrolled loops; zero for other counts.
macro_rules! with_coeff_count {
    ($n:expr, $f:ident, ($($arg:expr),*)) => {
        match $n {
            1 => $f::<1>($($arg),*),
            4 => $f::<4>($($arg),*),
            9 => $f::<9>($($arg),*),
            16 => $f::<16>($($arg),*),
            25 => $f::<25>($($arg),*),
            36 => $f::<36>($($arg),*),
            49 => $f::<49>($($arg),*),
            64 => $f::<64>($($arg),*),
            _ => Vec3::ZERO,
        }
    };
}
use with_coeff_count;

#[inline(always)]
fn glossy_n<const N: usize>(
    matrix: &[f32],
    lobe: &GlossyLobe,
    lighting: &ShLighting,
    r: Vec3,
) -> Vec3 {
    let Some(matrix) = matrix.get(..N * N) else {
        return Vec3::ZERO;
    };
    let y = eval_basis::<N>(r);
    let mut u = [0.0f32; N];
    for (i, row) in matrix.chunks_exact(N).enumerate() {
        let w = lobe.factors[i] * y[i];
        for (uj, t) in u.iter_mut().zip(row) {
            *uj += w * t;
        }
    }
    blend_dot([&u], [1.0], &lighting.planes)
}

/// Glossy SH transfer in the published order (Sloan, Kautz & Snyder 2002; Kautz,
/// Sloan & Snyder 2002): per channel the transferred incident radiance `T l`
/// (`3n²` multiply-adds), then convolved with the lobe and evaluated at the mirror
/// direction, `Σ_i A_l(i) Y_i(r) (T l)_i` (`3n` more). The same value as
/// [`shade_glossy_sh`] and [`shade_glossy_sh_reference`] (the latter is its serial
/// twin), written in the same fixed-size, four-lane style as [`shade_mrt`] so that
/// benchmarks compare MRT with an equally optimised form of the 2002 baseline:
/// per row, four-lane partial sums of `T_i · l` per channel, weighted by
/// `A_l(i) Y_i(r)` while still in lanes and reduced once at the end (a
/// reassociation of the serial sums). Zero in the cases [`shade_glossy_sh`] is.
#[inline]
pub fn shade_glossy_sh_2002(
    matrix: &[f32],
    lobe: &GlossyLobe,
    lighting: &ShLighting,
    normal: Vec3,
    to_eye: Vec3,
) -> Vec3 {
    let n = lobe.coeffs;
    if matrix.len() < n * n || lighting.coeffs < n {
        return Vec3::ZERO;
    }
    let Some(r) = mirror(normal, to_eye) else {
        return Vec3::ZERO;
    };
    with_coeff_count!(n, glossy_2002_n, (matrix, lobe, lighting, r))
}

#[inline(always)]
fn glossy_2002_n<const N: usize>(
    matrix: &[f32],
    lobe: &GlossyLobe,
    lighting: &ShLighting,
    r: Vec3,
) -> Vec3 {
    let Some(matrix) = matrix.get(..N * N) else {
        return Vec3::ZERO;
    };
    let planes = &lighting.planes;
    let y = eval_basis::<N>(r);
    let full = N / 4 * 4;
    let (mut out_r, mut out_g, mut out_b) = (Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
    let mut out_tail = Vec3::ZERO;
    for (i, row) in matrix.chunks_exact(N).enumerate() {
        // (T l)_i per channel, in four-lane partial sums.
        let (mut tr, mut tg, mut tb) = (Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
        let mut j = 0;
        while j < full {
            let t = vec4_at(row, j);
            tr += t * vec4_at(&planes[0], j);
            tg += t * vec4_at(&planes[1], j);
            tb += t * vec4_at(&planes[2], j);
            j += 4;
        }
        let mut tail = Vec3::ZERO;
        for (j, t) in row.iter().enumerate().skip(full) {
            tail += *t * Vec3::new(planes[0][j], planes[1][j], planes[2][j]);
        }
        // The lobe evaluated at the mirror direction.
        let w = lobe.factors[i] * y[i];
        out_r += w * tr;
        out_g += w * tg;
        out_b += w * tb;
        out_tail += w * tail;
    }
    Vec3::new(
        out_r.element_sum(),
        out_g.element_sum(),
        out_b.element_sum(),
    ) + out_tail
}

/// The obvious form of [`shade_glossy_sh`] and [`shade_glossy_sh_2002`]: per
/// channel the incident radiance `T l`, convolved with the lobe and evaluated at
/// the mirror direction.
pub fn shade_glossy_sh_reference(
    matrix: &[f32],
    lobe: &GlossyLobe,
    lighting: &[[f32; 3]],
    normal: Vec3,
    to_eye: Vec3,
) -> Vec3 {
    let n = lobe.coeffs;
    if matrix.len() < n * n || lighting.len() < n {
        return Vec3::ZERO;
    }
    let Some(r) = mirror(normal, to_eye) else {
        return Vec3::ZERO;
    };
    let mut y = [0.0f32; MAX_COEFFS];
    let _ = eval_basis_into(r, &mut y[..n]);
    let mut out = Vec3::ZERO;
    for i in 0..n {
        let mut incident = Vec3::ZERO;
        for j in 0..n {
            incident += matrix[i * n + j] * rgb(&lighting[j]);
        }
        out += lobe.factors[i] * y[i] * incident;
    }
    out
}

/// MRT (P2 §3): the view in the vertex frame selects four nodes of the `grid × grid`
/// hemi-octahedral basis; their rows of `matrix` (`grid² × n`, row-major) are
/// blended bilinearly (`4n`) and the blended row dotted with each channel of the
/// lighting (`3n`), `7n` multiply-adds. `n` is the lighting's coefficient count, a
/// square from 1 to 64. `to_eye` need not be unit (the hemi-octahedral map is
/// scale-invariant). Zero for a viewer behind the surface, another coefficient
/// count, or a matrix shorter than `grid² · n`.
#[inline]
pub fn shade_mrt(
    matrix: &[f32],
    grid: u32,
    lighting: &ShLighting,
    frame: &Frame,
    to_eye: Vec3,
) -> Vec3 {
    let n = lighting.coeffs;
    if grid < 2 || matrix.len() < node_values(grid, n) {
        return Vec3::ZERO;
    }
    let Some(tap) = mrt_tap(grid, frame.to_local(to_eye)) else {
        return Vec3::ZERO;
    };
    with_coeff_count!(n, mrt_n, (matrix, lighting, tap))
}

/// `row · lighting` per channel for a row of a supported square length (the
/// vectorised form of [`shade_diffuse`]); zero for another length.
#[inline]
pub(crate) fn row_dot(row: &[f32], lighting: &ShLighting) -> Vec3 {
    with_coeff_count!(row.len(), row_dot_n, (row, lighting))
}

#[inline(always)]
fn row_dot_n<const N: usize>(row: &[f32], lighting: &ShLighting) -> Vec3 {
    match row.first_chunk::<N>() {
        Some(r) => blend_dot([r], [1.0], &lighting.planes),
        None => Vec3::ZERO,
    }
}

/// The PCA weights of one vertex blended at a tap: `Σ_nodes w (r_0 + Σ_k c_k r_k)`
/// (the second half of [`shade_mrt_pca`]); zero for a node past `frame_terms`.
#[inline(always)]
fn pca_at_tap(weights: &[f32], frame_terms: &[[f32; 3]], stride: usize, tap: MrtTap) -> Vec3 {
    let mut out = Vec3::ZERO;
    for (node, w) in tap.nodes.iter().zip(tap.weights) {
        let start = *node as usize * stride;
        let Some(terms) = frame_terms.get(start..start + stride) else {
            return Vec3::ZERO;
        };
        let mut v = rgb(&terms[0]);
        for (c, t) in weights.iter().zip(&terms[1..]) {
            v += *c * rgb(t);
        }
        out += w * v;
    }
    out
}

#[inline(always)]
fn mrt_n<const N: usize>(matrix: &[f32], lighting: &ShLighting, tap: MrtTap) -> Vec3 {
    // Fixed-size rows: one bounds check each, then unchecked, unrolled loops.
    let rows = tap.nodes.map(|g| {
        matrix
            .get(g as usize * N..)
            .and_then(|r| r.first_chunk::<N>())
    });
    let [Some(ra), Some(rb), Some(rc), Some(rd)] = rows else {
        return Vec3::ZERO;
    };
    blend_dot([ra, rb, rc, rd], tap.weights, &lighting.planes)
}

/// The paper's order of [`shade_mrt`]: each of the four rows dotted with the
/// lighting, then the four colours blended.
pub fn shade_mrt_reference(
    matrix: &[f32],
    grid: u32,
    lighting: &[[f32; 3]],
    frame: &Frame,
    to_eye: Vec3,
) -> Vec3 {
    let n = lighting.len();
    if grid < 2 || n > MAX_COEFFS || matrix.len() < node_values(grid, n) {
        return Vec3::ZERO;
    }
    let Some(tap) = mrt_tap(grid, frame.to_local(to_eye)) else {
        return Vec3::ZERO;
    };
    let mut out = Vec3::ZERO;
    for (node, w) in tap.nodes.iter().zip(tap.weights) {
        let row = &matrix[*node as usize * n..(*node as usize + 1) * n];
        out += w * shade_diffuse(row, lighting);
    }
    out
}

/// MRT from its PCA (P2 §4): `frame_terms` are the per-frame products
/// ([`Pca::frame_terms`](super::Pca::frame_terms)) of the vertex's cluster (its
/// part of the buffer) for `components` components,
/// laid out node-major (`grid² × (components + 1)` RGB triples, the mean's first);
/// `weights` the vertex's first `components` PCA weights; `to_eye` of any length.
/// Per vertex `4 (components + 1)` RGB multiply-adds. Zero for a viewer behind the
/// surface or slices too short.
#[inline]
pub fn shade_mrt_pca(
    weights: &[f32],
    frame_terms: &[[f32; 3]],
    components: usize,
    grid: u32,
    frame: &Frame,
    to_eye: Vec3,
) -> Vec3 {
    let stride = components.saturating_add(1);
    if grid < 2 || weights.len() < components || frame_terms.len() < node_values(grid, stride) {
        return Vec3::ZERO;
    }
    let Some(tap) = mrt_tap(grid, frame.to_local(to_eye)) else {
        return Vec3::ZERO;
    };
    pca_at_tap(&weights[..components], frame_terms, stride, tap)
}

/// Surface parameters applied at run time, in the vocabulary of the
/// hemispherical material (`antumbra_hemi_material` in the C API): `albedo`,
/// `specular`, `phong_exponent`, with the same defaults, a white Lambertian
/// surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Diffuse albedo per channel (diffuse kind: outgoing = albedo/π ·
    /// irradiance). Default (1, 1, 1).
    pub albedo: [f32; 3],
    /// Specular reflectance `ρ_s` per channel, multiplying the glossy SH and MRT
    /// results. (0, 0, 0), the default, turns the glossy term off as in the
    /// hemispherical material, so glossy SH and MRT sets (which hold only a
    /// glossy term) shade to black until it is set; (1, 1, 1) shows the baked
    /// lobe as it is.
    pub specular: [f32; 3],
    /// Phong exponent of the glossy SH run time (MRT bakes its BRDF). Default 16.
    pub phong_exponent: f32,
}

impl Material {
    /// The default material with specular reflectance `specular` in every
    /// channel: `Material::glossy(1.0)` shows a glossy SH or MRT set's baked lobe
    /// as it is.
    pub fn glossy(specular: f32) -> Self {
        Material {
            specular: [specular; 3],
            ..Material::default()
        }
    }
}

impl Default for Material {
    fn default() -> Self {
        Material {
            albedo: [1.0; 3],
            specular: [0.0; 3],
            phong_exponent: 16.0,
        }
    }
}

/// Where the viewer is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum View<'a> {
    /// An eye position (world); each vertex looks towards it.
    Eye([f32; 3]),
    /// One direction per vertex, from the vertex towards the viewer (any length).
    Directions(&'a [[f32; 3]]),
}

/// Why [`TransferSet::shade`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadeError {
    /// The lighting does not have `bands²` coefficients.
    LightingLength {
        /// Required.
        expected: usize,
        /// Given.
        found: usize,
    },
    /// The output does not have one entry per vertex.
    OutputLength {
        /// Required.
        expected: usize,
        /// Given.
        found: usize,
    },
    /// The view directions do not have one entry per vertex.
    ViewLength {
        /// Required.
        expected: usize,
        /// Given.
        found: usize,
    },
    /// The eye position or the Phong exponent is not finite (or the exponent is
    /// negative).
    NonFinite {
        /// Which argument.
        argument: &'static str,
    },
    /// The per-frame products of a PCA set (`C × grid² × (K + 1)` RGB values) could
    /// not be allocated (only allocators that can run out get here).
    OutOfMemory {
        /// Bytes asked for.
        bytes: usize,
    },
}

impl fmt::Display for ShadeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ShadeError::LightingLength { expected, found } => {
                write!(
                    f,
                    "lighting has {found} coefficients, the set needs {expected}"
                )
            }
            ShadeError::OutputLength { expected, found } => {
                write!(f, "output has {found} entries for {expected} vertices")
            }
            ShadeError::ViewLength { expected, found } => {
                write!(f, "view has {found} directions for {expected} vertices")
            }
            ShadeError::NonFinite { argument } => write!(f, "{argument} is not valid"),
            ShadeError::OutOfMemory { bytes } => {
                write!(
                    f,
                    "no memory for the per-frame PCA products ({bytes} bytes)"
                )
            }
        }
    }
}

impl core::error::Error for ShadeError {}

/// `out[v] = f(v)` for every vertex, spread over rayon's pool with the `parallel`
/// feature (each vertex is independent, so the result is the same). Generic, not
/// `dyn`, so that the kernel inlines into the loop.
fn for_each_vertex<F: Fn(usize) -> Vec3 + Sync>(out: &mut [[f32; 3]], f: F) {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        out.par_iter_mut()
            .with_min_len(256)
            .enumerate()
            .for_each(|(v, o)| *o = f(v).to_array());
    }
    #[cfg(not(feature = "parallel"))]
    for (v, o) in out.iter_mut().enumerate() {
        *o = f(v).to_array();
    }
}

/// Vertices per block of the two-phase MRT loops in [`TransferSet::shade`].
const BLOCK: usize = 32;

/// `f(first_vertex, out_block)` over blocks of [`BLOCK`] vertices, on rayon's pool
/// with the `parallel` feature.
fn for_each_block<T: Send, F: Fn(usize, &mut [T]) + Sync>(out: &mut [T], f: F) {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        out.par_chunks_mut(BLOCK)
            .with_min_len(256 / BLOCK)
            .enumerate()
            .for_each(|(b, o)| f(b * BLOCK, o));
    }
    #[cfg(not(feature = "parallel"))]
    for (b, o) in out.chunks_mut(BLOCK).enumerate() {
        f(b * BLOCK, o);
    }
}

/// The taps of a block of vertices, computed before any row is read: each tap is
/// a long dependent chain (frame, division, conversions, row address) but taps of
/// different vertices are independent, so computed together they overlap instead
/// of each vertex's row loads waiting on its own chain.
#[inline(always)]
fn block_taps(
    grid: u32,
    first: usize,
    count: usize,
    local: impl Fn(usize) -> Vec3,
) -> [Option<MrtTap>; BLOCK] {
    let mut taps = [None; BLOCK];
    for (i, t) in taps.iter_mut().take(count).enumerate() {
        *t = mrt_tap(grid, local(first + i));
    }
    taps
}

/// Multiply-adds of the per-frame products that listing every vertex's tap
/// costs, per vertex (writing the list, marking the nodes read and reading it
/// back): about what a vertex's shading from the products costs.
const TAP_LIST_COST: usize = 100;

/// Whether computing a clustered PCA's per-frame products only at the nodes
/// the vertices read beats computing them all: when all of them (`clusters ·
/// rows · (k + 1)` dot products of `3 · coeffs` multiply-adds) cost more than
/// listing the taps. Small meshes with many clusters gain (the bunny's 16
/// clusters of 8 components); large meshes amortise the products anyway.
fn lazy_terms_pay(pca: &super::Pca, k: usize, vertices: usize) -> bool {
    let all = pca.clusters() * pca.rows * (k.min(pca.components()) + 1) * 3 * pca.coeffs;
    pca.clusters() > 1 && all > TAP_LIST_COST * vertices
}

/// The tap of every vertex (`local` gives its view in its frame), on rayon's
/// pool with the `parallel` feature; an error when the list cannot be
/// allocated.
fn all_taps(
    grid: u32,
    vertices: usize,
    local: &(impl Fn(usize) -> Vec3 + Sync),
) -> Result<alloc::vec::Vec<Option<MrtTap>>, ShadeError> {
    let bytes = vertices.saturating_mul(core::mem::size_of::<Option<MrtTap>>());
    let mut taps =
        crate::fallible::filled(None, vertices).map_err(|_| ShadeError::OutOfMemory { bytes })?;
    for_each_block(&mut taps, |first, block| {
        let own = block_taps(grid, first, block.len(), local);
        block.copy_from_slice(&own[..block.len()]);
    });
    Ok(taps)
}

/// Vertices ahead of the one being shaded whose rows [`mrt_blocks`] has already
/// requested: enough that a row requested from memory (hundreds of cycles) has
/// arrived by the time its vertex is shaded (tens of cycles each).
const PREFETCH_AHEAD: usize = 8;

/// Requests the four rows of vertex `v`'s tap (two pairs of adjacent rows, `2N`
/// values each, starting anywhere in a cache line).
#[inline(always)]
fn prefetch_tap<const N: usize>(data: &[f32], v: usize, len: usize, tap: &Option<MrtTap>) {
    if let Some(tap) = tap {
        for pair in [tap.nodes[0], tap.nodes[2]] {
            // Wrapping: an address only, checked nowhere (a hint cannot fault).
            let start = v.wrapping_mul(len).wrapping_add(pair as usize * N);
            // One request per 16 floats (64-byte lines) and one for the last value.
            let mut k = 0;
            while k < 2 * N {
                prefetch(data, start.wrapping_add(k));
                k += 16;
            }
            prefetch(data, start.wrapping_add(2 * N - 1));
        }
    }
}

/// Dense MRT over blocks, compiled for `N` coefficients. Each vertex's matrix is
/// kilobytes and the four rows it reads depend on the view, so they are cache
/// misses the hardware prefetcher cannot foresee: the block's taps are computed
/// first, then each vertex's rows are requested [`PREFETCH_AHEAD`] vertices
/// before it is shaded.
fn mrt_blocks<const N: usize>(
    data: &[f32],
    grid: u32,
    lighting: &ShLighting,
    specular: Vec3,
    local: impl Fn(usize) -> Vec3 + Sync,
    out: &mut [[f32; 3]],
) {
    let len = node_values(grid, N);
    for_each_block(out, |first, block| {
        let taps = block_taps(grid, first, block.len(), &local);
        for (i, tap) in taps.iter().enumerate().take(PREFETCH_AHEAD) {
            prefetch_tap::<N>(data, first + i, len, tap);
        }
        for (i, (o, tap)) in block.iter_mut().zip(taps).enumerate() {
            // Past the block's end the taps are `None`: nothing is requested.
            if let Some(ahead) = taps.get(i + PREFETCH_AHEAD) {
                prefetch_tap::<N>(data, first + i + PREFETCH_AHEAD, len, ahead);
            }
            let v = first + i;
            let c = match (tap, data.get(v * len..(v + 1) * len)) {
                (Some(tap), Some(m)) => specular * mrt_n::<N>(m, lighting, tap),
                _ => Vec3::ZERO,
            };
            *o = c.to_array();
        }
    });
}

impl TransferSet {
    /// Relights every vertex into `out` (RGB radiance toward the viewer). For an
    /// MRT set compressed with PCA, `components` (clamped to the baked count; `None`
    /// = all) selects how many are used. Allocates one per-frame buffer for the
    /// compressed form, nothing per vertex; vertices run on rayon's pool with the
    /// `parallel` feature. Per call the lighting is split per channel; per vertex
    /// the set's cached frame is used, and MRT takes the raw view vector (its map
    /// is scale-invariant), computes the taps of a block of vertices first and
    /// requests each vertex's rows from memory a few vertices before shading it
    /// (a cache hint: no effect on the values). Each vertex's value is that of the kernels given
    /// [`Frame::from_normal`] of its normal. On error `out` is untouched.
    pub fn shade(
        &self,
        lighting: &[[f32; 3]],
        view: View<'_>,
        material: &Material,
        components: Option<usize>,
        out: &mut [[f32; 3]],
    ) -> Result<(), ShadeError> {
        let n = self.coeff_count();
        let vertices = self.vertex_count();
        if lighting.len() != n {
            return Err(ShadeError::LightingLength {
                expected: n,
                found: lighting.len(),
            });
        }
        if out.len() != vertices {
            return Err(ShadeError::OutputLength {
                expected: vertices,
                found: out.len(),
            });
        }
        match view {
            View::Eye(e) if !Vec3::from_array(e).is_finite() => {
                return Err(ShadeError::NonFinite { argument: "eye" });
            }
            View::Directions(d) if d.len() != vertices => {
                return Err(ShadeError::ViewLength {
                    expected: vertices,
                    found: d.len(),
                });
            }
            _ => {}
        }
        // Per call: the lighting split per channel. Per vertex: the cached frame
        // (`TransferSet::frames`) and the raw view vector; MRT needs no unit view
        // (the hemi-octahedral map is scale-invariant), glossy SH normalises it.
        let planar = ShLighting::new(lighting).ok_or(ShadeError::LightingLength {
            expected: n,
            found: lighting.len(),
        })?;
        let view_vector = |v: usize| -> Vec3 {
            match view {
                View::Eye(e) => Vec3::from_array(e) - Vec3::from_array(self.positions[v]),
                View::Directions(d) => Vec3::from_array(d[v]),
            }
        };
        let specular = Vec3::from_array(material.specular);
        match (&self.payload, self.kind) {
            (Payload::Dense(data), TransferKind::Diffuse) => {
                let albedo = Vec3::from_array(material.albedo) / core::f32::consts::PI;
                for_each_vertex(out, |v| {
                    albedo * shade_diffuse(&data[v * n..(v + 1) * n], lighting)
                });
            }
            (Payload::Dense(data), TransferKind::GlossySh) => {
                let lobe = GlossyLobe::phong(self.bands, material.phong_exponent).ok_or(
                    ShadeError::NonFinite {
                        argument: "phong_exponent",
                    },
                )?;
                let len = n * n;
                for_each_vertex(out, |v| {
                    let normal = self.frames[v].normal;
                    let block = &data[v * len..(v + 1) * len];
                    let to_eye = unit_or_zero(view_vector(v));
                    specular * shade_glossy_sh(block, &lobe, &planar, normal, to_eye)
                });
            }
            (Payload::Dense(data), TransferKind::Mrt) => {
                let local = |v: usize| self.frames[v].to_local(view_vector(v));
                let args = (data, self.grid, &planar, specular, local, out);
                match n {
                    1 => mrt_blocks::<1>(args.0, args.1, args.2, args.3, args.4, args.5),
                    4 => mrt_blocks::<4>(args.0, args.1, args.2, args.3, args.4, args.5),
                    9 => mrt_blocks::<9>(args.0, args.1, args.2, args.3, args.4, args.5),
                    16 => mrt_blocks::<16>(args.0, args.1, args.2, args.3, args.4, args.5),
                    25 => mrt_blocks::<25>(args.0, args.1, args.2, args.3, args.4, args.5),
                    36 => mrt_blocks::<36>(args.0, args.1, args.2, args.3, args.4, args.5),
                    49 => mrt_blocks::<49>(args.0, args.1, args.2, args.3, args.4, args.5),
                    _ => mrt_blocks::<64>(args.0, args.1, args.2, args.3, args.4, args.5),
                }
            }
            (Payload::Pca(pca), _) => {
                let k = components.unwrap_or(usize::MAX).min(pca.components());
                let len = pca.frame_terms_len(k);
                let mut terms = crate::fallible::filled([0.0f32; 3], len)
                    .map_err(|_| ShadeError::OutOfMemory { bytes: 12 * len })?;
                let grid = self.grid;
                let local = |v: usize| self.frames[v].to_local(view_vector(v));
                // With many clusters for few vertices, every vertex's tap
                // first, then each cluster's terms only at the nodes its
                // vertices read (a cluster's vertices face alike and look
                // through a few of the grid's nodes), then the shading from
                // the same taps.
                let taps = if lazy_terms_pay(pca, k, self.vertex_count()) {
                    let taps = all_taps(grid, self.vertex_count(), &local)?;
                    let rows = pca.rows;
                    let pairs = pca.clusters() * rows;
                    let mut read = crate::fallible::filled(false, pairs)
                        .map_err(|_| ShadeError::OutOfMemory { bytes: pairs })?;
                    for (v, tap) in taps.iter().enumerate() {
                        if let Some(tap) = tap {
                            let base = pca.cluster_of(v) * rows;
                            for node in tap.nodes {
                                read[base + node as usize] = true;
                            }
                        }
                    }
                    pca.frame_terms_where(
                        lighting,
                        k,
                        |cluster, node| read[cluster * rows + node],
                        &mut terms,
                    );
                    Some(taps)
                } else {
                    pca.frame_terms(lighting, k, &mut terms);
                    None
                };
                let baked = pca.components();
                let part = pca.cluster_terms_len(k);
                for_each_block(out, |first, block| {
                    let taps = match &taps {
                        Some(all) => {
                            let mut own = [None; BLOCK];
                            own[..block.len()].copy_from_slice(&all[first..first + block.len()]);
                            own
                        }
                        None => block_taps(grid, first, block.len(), local),
                    };
                    for (i, (o, tap)) in block.iter_mut().zip(taps).enumerate() {
                        let v = first + i;
                        let w = &pca.weights()[v * baked..v * baked + k];
                        let cluster = pca.cluster_of(v) * part;
                        let terms = &terms[cluster..cluster + part];
                        let c = match tap {
                            Some(tap) => specular * pca_at_tap(w, terms, k + 1, tap),
                            None => Vec3::ZERO,
                        };
                        *o = c.to_array();
                    }
                });
            }
        }
        Ok(())
    }
}
