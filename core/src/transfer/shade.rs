//! Run-time shading of transfer sets: per-vertex kernels for the three kinds and
//! the compressed MRT form, and the batch [`TransferSet::shade`].
//!
//! Every kernel takes lighting as `bands²` RGB triples and returns one RGB value;
//! none allocates. Each fast kernel has a slow, obviously right twin it is tested
//! against (`*_reference`).

use alloc::vec;
use core::fmt;

use glam::Vec3;

use super::mrt::{MrtTap, mrt_tap};
use super::{Payload, TransferKind, TransferSet};
use crate::geom::Frame;
use crate::sh::{MAX_COEFFS, ShRgb, ZonalKernel, eval_basis, eval_basis_into};

/// RGB lighting coefficients of an [`ShRgb`], coefficient-major.
pub fn lighting_from_sh_rgb<const N: usize>(sh: &ShRgb<N>) -> [[f32; 3]; N] {
    core::array::from_fn(|i| [sh.r.coeffs[i], sh.g.coeffs[i], sh.b.coeffs[i]])
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
    lighting: &[[f32; 3]],
    r: Vec3,
) -> Vec3 {
    let (Some(matrix), Some(lighting)) = (matrix.get(..N * N), lighting.get(..N)) else {
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
    let mut acc = Vec3::ZERO;
    for (uj, l) in u.iter().zip(lighting) {
        acc += *uj * rgb(l);
    }
    acc
}

/// The obvious form of [`shade_glossy_sh`]: per channel the incident radiance
/// `T l`, convolved with the lobe and evaluated at the mirror direction.
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
/// blended bilinearly and dotted with the lighting, `7n` multiply-adds. `n` is
/// `lighting.len()`, a square from 1 to 64. Zero for a viewer behind the surface,
/// another coefficient count, or a matrix shorter than `grid² · n`.
#[inline]
pub fn shade_mrt(
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
    with_coeff_count!(n, mrt_n, (matrix, lighting, tap))
}

#[inline(always)]
fn mrt_n<const N: usize>(matrix: &[f32], lighting: &[[f32; 3]], tap: MrtTap) -> Vec3 {
    let rows = tap
        .nodes
        .map(|g| matrix.get(g as usize * N..g as usize * N + N));
    let ([Some(ra), Some(rb), Some(rc), Some(rd)], Some(lighting)) = (rows, lighting.get(..N))
    else {
        return Vec3::ZERO;
    };
    let [wa, wb, wc, wd] = tap.weights;
    // Blend the rows first (4N, vectorises), then one row dotted with RGB (3N).
    let mut row = [0.0f32; N];
    for (j, m) in row.iter_mut().enumerate() {
        *m = wa * ra[j] + wb * rb[j] + wc * rc[j] + wd * rd[j];
    }
    let mut acc = Vec3::ZERO;
    for (m, l) in row.iter().zip(lighting) {
        acc += *m * rgb(l);
    }
    acc
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
/// ([`Pca::frame_terms`](super::Pca::frame_terms)) for `components` components,
/// laid out node-major (`grid² × (components + 1)` RGB triples, the mean's first);
/// `weights` the vertex's first `components` PCA weights. Per vertex
/// `4 (components + 1)` RGB multiply-adds. Zero for a viewer behind the surface or
/// slices too short.
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
    let mut out = Vec3::ZERO;
    for (node, w) in tap.nodes.iter().zip(tap.weights) {
        let terms = &frame_terms[*node as usize * stride..(*node as usize + 1) * stride];
        let mut v = rgb(&terms[0]);
        for (c, t) in weights[..components].iter().zip(&terms[1..]) {
            v += *c * rgb(t);
        }
        out += w * v;
    }
    out
}

/// Surface parameters applied at run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Diffuse albedo (diffuse kind: outgoing = albedo/π · irradiance).
    pub diffuse: [f32; 3],
    /// Specular colour multiplying the glossy SH and MRT results.
    pub specular: [f32; 3],
    /// Phong exponent of the glossy SH run time (MRT bakes its BRDF).
    pub phong_exponent: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            diffuse: [1.0; 3],
            specular: [1.0; 3],
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
        }
    }
}

impl core::error::Error for ShadeError {}

/// `out[v] = f(v)` for every vertex, spread over rayon's pool with the `parallel`
/// feature (each vertex is independent, so the result is the same).
fn for_each_vertex(out: &mut [[f32; 3]], f: &(dyn Fn(usize) -> Vec3 + Sync)) {
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

impl TransferSet {
    /// Relights every vertex into `out` (RGB radiance toward the viewer). For an
    /// MRT set compressed with PCA, `components` (clamped to the baked count; `None`
    /// = all) selects how many are used. Allocates one per-frame buffer for the
    /// compressed form, nothing per vertex; vertices run on rayon's pool with the
    /// `parallel` feature. On error `out` is untouched.
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
        let to_eye = |v: usize| -> Vec3 {
            let d = match view {
                View::Eye(e) => Vec3::from_array(e) - Vec3::from_array(self.positions[v]),
                View::Directions(d) => Vec3::from_array(d[v]),
            };
            d.normalize_or_zero()
        };
        let specular = Vec3::from_array(material.specular);
        match (&self.payload, self.kind) {
            (Payload::Dense(data), TransferKind::Diffuse) => {
                let albedo = Vec3::from_array(material.diffuse) / core::f32::consts::PI;
                for_each_vertex(out, &|v| {
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
                for_each_vertex(out, &|v| {
                    let normal = Vec3::from_array(self.normals[v]);
                    let block = &data[v * len..(v + 1) * len];
                    specular * shade_glossy_sh(block, &lobe, lighting, normal, to_eye(v))
                });
            }
            (Payload::Dense(data), TransferKind::Mrt) => {
                let len = self.block_len();
                for_each_vertex(out, &|v| {
                    let frame = Frame::from_normal(Vec3::from_array(self.normals[v]));
                    let block = &data[v * len..(v + 1) * len];
                    specular * shade_mrt(block, self.grid, lighting, &frame, to_eye(v))
                });
            }
            (Payload::Pca(pca), _) => {
                let k = components.unwrap_or(usize::MAX).min(pca.components());
                let mut terms = vec![[0.0f32; 3]; pca.frame_terms_len(k)];
                pca.frame_terms(lighting, k, &mut terms);
                let baked = pca.components();
                for_each_vertex(out, &|v| {
                    let frame = Frame::from_normal(Vec3::from_array(self.normals[v]));
                    let w = &pca.weights()[v * baked..v * baked + k];
                    specular * shade_mrt_pca(w, &terms, k, self.grid, &frame, to_eye(v))
                });
            }
        }
        Ok(())
    }
}
