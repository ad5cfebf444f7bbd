//! The piecewise-bilinear hemispherical basis of matrix radiance transfer (P2 §3)
//! and the BRDFs that turn incident radiance into its node values.
//!
//! Parameterisation: the hemi-octahedral map. A local direction `d` (z up, the
//! vertex frame of [`Frame::from_normal`](crate::Frame::from_normal)) with `d.z ≥ 0`
//! goes to the diamond `p = (d.x, d.y) / (|d.x| + |d.y| + d.z)`, which is rotated 45°
//! onto the square: `(a, b) = (p.x + p.y, p.x - p.y) ∈ [-1, 1]²`. Nodes sit on a
//! `G × G` grid that includes the square's edges, `a_i = -1 + 2i/(G-1)`, node index
//! `j·G + i`; the square's edges are the horizon. A direction lies in one cell and
//! exactly four hat functions are nonzero there ([`MrtTap`]). The map is continuous
//! and its Jacobian is bounded on the whole hemisphere (unlike the concentric map's
//! center), so bilinear interpolation error falls as `O(1/G²)` everywhere.
//!
//! A BRDF is given as a function ([`Brdf`]) returning the *reflection kernel*
//! `k(ω_i, ω_o) = f_r(ω_i, ω_o) · cos θ_i` in local coordinates, so that outgoing
//! radiance is `L_o(ω_o) = ∫ L_in(ω_i) k(ω_i, ω_o) dω_i` over the sphere. Node `g`'s
//! row of the BRDF matrix is `B_g,i = ∫ k(ω, v_g) Y_i(ω) dω` (P2's `P · B` in one
//! step), computed once per bake by Gauss–Legendre × uniform-φ quadrature; the MRT
//! matrix of a vertex is then `B · T_local` with `T_local` its local incident
//! radiance transfer matrix.

use alloc::vec;
use alloc::vec::Vec;
use core::f64::consts::PI;

use glam::Vec3;

use crate::sh::eval_basis_into;

/// The reflection kernel of a BRDF in the local frame (z = normal):
/// `k(ω_i, ω_o) = f_r(ω_i, ω_o) · max(0, cos θ_i)` or any other kernel with
/// `L_o(ω_o) = ∫_sphere L_in(ω_i) k(ω_i, ω_o) dω_i`. Unit vectors, `ω_o.z ≥ 0`.
pub trait Brdf {
    /// The kernel value; must be finite.
    fn kernel(&self, wi: Vec3, wo: Vec3) -> f32;
    /// What the file records about this BRDF ([`BrdfInfo::CUSTOM`] by default).
    fn info(&self) -> BrdfInfo {
        BrdfInfo::CUSTOM
    }
}

/// A description of the BRDF baked into an MRT set, stored in bake files. Run time
/// does not need it (the BRDF is in the matrices); it tells tools what was baked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrdfInfo {
    /// 0: none or custom, 1: [`PhongBrdf`] (`params[0]` = exponent), 2: [`WardBrdf`]
    /// (`params` = `α_x`, `α_y`).
    pub kind: u32,
    /// Parameters of the kind.
    pub params: [f32; 2],
}

impl BrdfInfo {
    /// No BRDF or one not described.
    pub const CUSTOM: Self = BrdfInfo {
        kind: 0,
        params: [0.0; 2],
    };
    /// The largest kind value understood.
    pub const MAX_KIND: u32 = 2;
}

/// The reflected Phong lobe of Kautz, Sloan and Snyder (EGWR 2002), the kernel their
/// SH glossy runtime uses: `k(ω_i, ω_o) = (s+1)/(2π) max(0, ω_i·r)^s` with
/// `r = (-ω_o.x, -ω_o.y, ω_o.z)` the mirror direction. The cosine is folded into
/// the lobe (the lobe integrates to 1 over the sphere), and the lobe is not cut at
/// the horizon, which makes it exactly the zonal kernel
/// [`ZonalKernel::phong`](crate::sh::ZonalKernel::phong): MRT nodes then equal the
/// glossy SH path at their view directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhongBrdf {
    exponent: f32,
}

impl PhongBrdf {
    /// The lobe of exponent `exponent` (finite, `≥ 0`).
    pub fn new(exponent: f32) -> Option<Self> {
        (exponent.is_finite() && exponent >= 0.0).then_some(PhongBrdf { exponent })
    }

    /// The exponent `s`.
    pub fn exponent(&self) -> f32 {
        self.exponent
    }
}

impl Brdf for PhongBrdf {
    fn kernel(&self, wi: Vec3, wo: Vec3) -> f32 {
        let r = Vec3::new(-wo.x, -wo.y, wo.z);
        let c = wi.dot(r);
        if c <= 0.0 {
            return 0.0;
        }
        let s = self.exponent;
        (s + 1.0) / (2.0 * core::f32::consts::PI) * libm::powf(c, s)
    }

    fn info(&self) -> BrdfInfo {
        BrdfInfo {
            kind: 1,
            params: [self.exponent, 0.0],
        }
    }
}

/// Ward's anisotropic BRDF (Ward, "Measuring and Modeling Anisotropic Reflection",
/// SIGGRAPH 1992), specular term with unit reflectance, roughness `α_x` along the
/// tangent and `α_y` along the bitangent:
///
/// ```text
/// f_r = exp(-tan²θ_h (cos²φ_h/α_x² + sin²φ_h/α_y²)) / (4π α_x α_y √(cos θ_i cos θ_o))
/// k   = f_r cos θ_i   for cos θ_i, cos θ_o > 0, else 0.
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WardBrdf {
    alpha_x: f32,
    alpha_y: f32,
}

impl WardBrdf {
    /// Roughnesses in `(0, 1]`.
    pub fn new(alpha_x: f32, alpha_y: f32) -> Option<Self> {
        let ok = |a: f32| a.is_finite() && a > 0.0 && a <= 1.0;
        (ok(alpha_x) && ok(alpha_y)).then_some(WardBrdf { alpha_x, alpha_y })
    }
}

impl Brdf for WardBrdf {
    fn kernel(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let h = wi + wo;
        if h.z <= 0.0 {
            return 0.0;
        }
        let (hx, hy, hz) = (h.x / self.alpha_x, h.y / self.alpha_y, h.z);
        // tan²θ_h (cos²φ_h/α_x² + sin²φ_h/α_y²) = (h_x²/α_x² + h_y²/α_y²) / h_z².
        let e = (hx * hx + hy * hy) / (hz * hz);
        let f = libm::expf(-e)
            / (4.0
                * core::f32::consts::PI
                * self.alpha_x
                * self.alpha_y
                * crate::geom::sqrtf(wi.z * wo.z));
        f * wi.z
    }

    fn info(&self) -> BrdfInfo {
        BrdfInfo {
            kind: 2,
            params: [self.alpha_x, self.alpha_y],
        }
    }
}

/// The four nonzero hat functions at a direction: node indices and bilinear weights
/// (summing to 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MrtTap {
    /// Node indices `j·G + i`.
    pub nodes: [u32; 4],
    /// Weights of the nodes.
    pub weights: [f32; 4],
}

/// The square coordinates `(a, b) ∈ [-1, 1]²` of a local direction with `z ≥ 0`
/// (below the horizon, `z` is taken as 0); any finite length (the map is
/// scale-invariant). `None` for a zero or non-finite vector.
#[inline]
pub fn hemi_oct_encode(local: Vec3) -> Option<(f32, f32)> {
    // Only instructions on the hot path: `abs`, `max` and `clamp` are core's
    // intrinsics (no libm call), and one division instead of two.
    let mut local = local;
    let mut sum = local.x.abs() + local.y.abs() + local.z.max(0.0);
    if !(sum >= f32::MIN_POSITIVE && sum.is_finite()) {
        // A sum that overflows f32 or falls below its normal range (where
        // `1 / sum` overflows and the coordinates would be NaN): the same
        // direction scaled by a power of two, exactly.
        if !local.is_finite() {
            return None;
        }
        local = crate::geom::normalize_exponent(local);
        sum = local.x.abs() + local.y.abs() + local.z.max(0.0);
        if sum < f32::MIN_POSITIVE {
            return None;
        }
    }
    let inv = 1.0 / sum;
    let (px, py) = (local.x * inv, local.y * inv);
    Some(((px + py).clamp(-1.0, 1.0), (px - py).clamp(-1.0, 1.0)))
}

/// The unit local direction of square coordinates `(a, b) ∈ [-1, 1]²`.
#[inline]
pub fn hemi_oct_decode(a: f32, b: f32) -> Vec3 {
    let (px, py) = ((a + b) * 0.5, (a - b) * 0.5);
    let z = (1.0 - px.abs() - py.abs()).max(0.0);
    Vec3::new(px, py, z).normalize()
}

/// The local direction of node `(i, j)` of a `grid × grid` basis.
#[inline]
pub fn node_direction(grid: u32, i: u32, j: u32) -> Vec3 {
    // grid < 2 has no nodes to speak of; max(1) keeps the division finite.
    let step = 2.0 / grid.saturating_sub(1).max(1) as f32;
    hemi_oct_decode(-1.0 + step * i as f32, -1.0 + step * j as f32)
}

/// The hat functions of a `grid × grid` basis (`grid ≥ 2`) at the local direction
/// `local` (any length); `None` when `local.z ≤ 0` (a viewer behind the surface),
/// the vector is not finite, or `grid` is outside `2..=65,535` (node indices
/// must fit `u32`).
#[inline]
pub fn mrt_tap(grid: u32, local: Vec3) -> Option<MrtTap> {
    if !(2..=0xFFFF).contains(&grid) || local.z.is_nan() || local.z <= 0.0 {
        return None;
    }
    let (a, b) = hemi_oct_encode(local)?;
    let half = 0.5 * (grid - 1) as f32;
    let s = (a + 1.0) * half;
    let t = (b + 1.0) * half;
    // s, t ∈ [0, G-1]: truncation is the floor, no libm `floorf` needed.
    let i = (s as u32).min(grid - 2);
    let j = (t as u32).min(grid - 2);
    let fx = s - i as f32;
    let fy = t - j as f32;
    let n = j * grid + i;
    Some(MrtTap {
        nodes: [n, n + 1, n + grid, n + grid + 1],
        weights: [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ],
    })
}

/// Quadrature points in `cos θ` (Gauss–Legendre) for the BRDF matrix.
pub(crate) const BRDF_QUADRATURE_Z: usize = 128;
/// Quadrature points in `φ` (uniform, exact for trigonometric polynomials of degree
/// below it).
pub(crate) const BRDF_QUADRATURE_PHI: usize = 256;

/// Gauss–Legendre nodes and weights on `[-1, 1]` by Newton's method on `P_n`.
pub(crate) fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let mut x = libm::cos(PI * (k as f64 + 0.75) / (n as f64 + 0.5));
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for m in 2..=n {
                let p2 = ((2 * m - 1) as f64 * x * p1 - (m - 1) as f64 * p0) / m as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

/// The BRDF matrix `B` (`grid² × coeffs`, row-major): `B_g,i = ∫ k(ω, v_g) Y_i(ω) dω`
/// over the sphere, with `v_g` the node directions.
pub(crate) fn brdf_matrix(brdf: &dyn Brdf, grid: u32, coeffs: usize) -> Vec<f32> {
    let nodes = (grid * grid) as usize;
    let gl = gauss_legendre(BRDF_QUADRATURE_Z);
    // Quadrature points with their weights and basis values, shared by every node.
    let mut points = Vec::with_capacity(gl.len() * BRDF_QUADRATURE_PHI);
    let mut basis = vec![0.0f32; gl.len() * BRDF_QUADRATURE_PHI * coeffs];
    for &(z, w) in &gl {
        let r = crate::geom::sqrt((1.0 - z * z).max(0.0));
        for k in 0..BRDF_QUADRATURE_PHI {
            let phi = 2.0 * PI * (k as f64 + 0.5) / BRDF_QUADRATURE_PHI as f64;
            let d = Vec3::new(
                (r * libm::cos(phi)) as f32,
                (r * libm::sin(phi)) as f32,
                z as f32,
            );
            let idx = points.len();
            // The coefficient count is validated by the caller.
            let _ = eval_basis_into(d, &mut basis[idx * coeffs..(idx + 1) * coeffs]);
            points.push((d, w * 2.0 * PI / BRDF_QUADRATURE_PHI as f64));
        }
    }
    let mut out = vec![0.0f32; nodes * coeffs];
    let mut acc = vec![0.0f64; coeffs];
    for j in 0..grid {
        for i in 0..grid {
            let v = node_direction(grid, i, j);
            acc.iter_mut().for_each(|a| *a = 0.0);
            for (p, &(d, w)) in points.iter().enumerate() {
                let k = brdf.kernel(d, v);
                if k == 0.0 {
                    continue;
                }
                let kw = f64::from(k) * w;
                for (a, y) in acc.iter_mut().zip(&basis[p * coeffs..(p + 1) * coeffs]) {
                    *a += kw * f64::from(*y);
                }
            }
            let g = (j * grid + i) as usize;
            for (o, a) in out[g * coeffs..(g + 1) * coeffs].iter_mut().zip(&acc) {
                *o = *a as f32;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::ZonalKernel;

    #[test]
    fn taps_are_scale_invariant_and_finite_for_every_finite_view() {
        // A view whose |x| + |y| + z overflows f32 gave no tap (zero radiance),
        // and one shorter than the smallest normal float NaN weights (1/|v|
        // overflowed, and 0 · ∞ is NaN): both take the f64 map.
        let unit = mrt_tap(8, Vec3::new(1.0, 0.25, 1.0)).unwrap();
        // Powers of two, so the direction is exact (2^-147 · 0.25 is the
        // smallest subnormal); 2^127 overflows the sum.
        for k in [127, 100, -100, -130, -147] {
            // 2^k from its bits (powi goes through 2^-k, which overflows).
            let two_k = if k >= -126 {
                f32::from_bits(((k + 127) as u32) << 23)
            } else {
                f32::from_bits(1 << (k + 149))
            };
            let v = Vec3::new(1.0, 0.25, 1.0) * two_k;
            let tap = mrt_tap(8, v).unwrap();
            assert_eq!(tap.nodes, unit.nodes, "2^{k}");
            for (w, u) in tap.weights.iter().zip(unit.weights) {
                assert!((w - u).abs() <= 1e-6, "2^{k}: {tap:?} vs {unit:?}");
            }
        }
        assert_eq!(
            mrt_tap(8, Vec3::new(3e38, 0.0, 3e38)),
            mrt_tap(8, Vec3::new(1.0, 0.0, 1.0))
        );
        let pole = mrt_tap(3, Vec3::new(0.0, 0.0, 1e-45)).unwrap();
        assert_eq!((pole.nodes[0], pole.weights), (4, [1.0, 0.0, 0.0, 0.0]));
        let mut rng = crate::rng::SplitMix64::new(5);
        for _ in 0..20_000 {
            let bits = |r: &mut crate::rng::SplitMix64| f32::from_bits(r.next_u64() as u32);
            let v = Vec3::new(bits(&mut rng), bits(&mut rng), bits(&mut rng).abs());
            if let Some(tap) = mrt_tap(8, v) {
                let sum: f32 = tap.weights.iter().sum();
                assert!(
                    tap.weights.iter().all(|w| (0.0..=1.0).contains(w)) && (sum - 1.0).abs() < 1e-5,
                    "{v:?}: {tap:?}"
                );
            } else {
                assert!(!v.is_finite() || v.z == 0.0, "{v:?} has no tap");
            }
        }
    }

    #[test]
    fn hemi_oct_round_trips_and_nodes_cover_the_hemisphere() {
        for k in 0..500 {
            let t = k as f32 * 0.618;
            let d = Vec3::new(
                libm::cosf(t * 7.0),
                libm::sinf(t * 7.0),
                0.2 + (k % 9) as f32,
            )
            .normalize();
            let (a, b) = hemi_oct_encode(d).unwrap();
            let back = hemi_oct_decode(a, b);
            assert!((back - d).length() < 1e-5, "{d} {back}");
        }
        // Corner and edge nodes are on the horizon, the center node is the normal.
        assert!((node_direction(9, 4, 4) - Vec3::Z).length() < 1e-6);
        for i in 0..9 {
            assert!(node_direction(9, i, 0).z.abs() < 1e-6);
            assert!(node_direction(9, 8, i).z.abs() < 1e-6);
        }
    }

    #[test]
    fn taps_interpolate_positions_exactly() {
        // Bilinear interpolation reproduces the (a, b) coordinates themselves.
        let grid = 7;
        for k in 1..200 {
            let t = k as f32 * 0.37;
            let d = Vec3::new(
                libm::cosf(t),
                libm::sinf(t * 1.3),
                0.05 + (k % 5) as f32 * 0.3,
            )
            .normalize();
            let tap = mrt_tap(grid, d).unwrap();
            assert!((tap.weights.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            let mut a = 0.0;
            for (n, w) in tap.nodes.iter().zip(tap.weights) {
                let i = n % grid;
                a += w * (-1.0 + 2.0 * i as f32 / (grid - 1) as f32);
            }
            assert!((a - hemi_oct_encode(d).unwrap().0).abs() < 1e-5);
        }
        assert!(mrt_tap(grid, Vec3::new(0.0, 0.3, -0.1)).is_none());
        assert!(mrt_tap(1, Vec3::Z).is_none() && mrt_tap(0, Vec3::Z).is_none());
        assert!(mrt_tap(u32::MAX, Vec3::Z).is_none());
        assert!(mrt_tap(0xFFFF, Vec3::new(0.3, 0.2, 0.9).normalize()).is_some());
        assert!(mrt_tap(grid, Vec3::new(f32::INFINITY, 0.0, 1.0)).is_none());
    }

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let gl = gauss_legendre(16);
        let w: f64 = gl.iter().map(|p| p.1).sum();
        assert!((w - 2.0).abs() < 1e-13);
        let x6: f64 = gl.iter().map(|&(x, w)| w * x.powi(6)).sum();
        assert!((x6 - 2.0 / 7.0).abs() < 1e-13);
    }

    #[test]
    fn phong_brdf_matrix_is_the_zonal_kernel_at_the_mirror_direction() {
        // Funk–Hecke: ∫ lobe(ω·r) Y_i(ω) dω = A_l Y_i(r).
        let s = 12.0;
        let brdf = PhongBrdf::new(s).unwrap();
        let grid = 5;
        let b = brdf_matrix(&brdf, grid, 25);
        let kernel = ZonalKernel::phong(s).unwrap();
        for j in 0..grid {
            for i in 0..grid {
                let v = node_direction(grid, i, j);
                let r = Vec3::new(-v.x, -v.y, v.z);
                let want = kernel.along::<25>(r);
                let g = (j * grid + i) as usize;
                for c in 0..25 {
                    assert!(
                        (b[g * 25 + c] - want.coeffs[c]).abs() < 2e-4,
                        "node {i},{j} coeff {c}: {} vs {}",
                        b[g * 25 + c],
                        want.coeffs[c]
                    );
                }
            }
        }
    }

    #[test]
    fn ward_is_reciprocal_and_anisotropic() {
        let w = WardBrdf::new(0.1, 0.4).unwrap();
        let a = Vec3::new(0.3, 0.1, 0.9).normalize();
        let b = Vec3::new(-0.2, 0.2, 0.8).normalize();
        // f_r symmetric: k(a, b)/a.z == k(b, a)/b.z.
        assert!((w.kernel(a, b) / a.z - w.kernel(b, a) / b.z).abs() < 1e-5);
        let wo = Vec3::new(0.5, 0.0, 0.866).normalize();
        let along_x = w.kernel(Vec3::new(-0.45, 0.05, 0.89).normalize(), wo);
        let along_y = w.kernel(
            Vec3::new(-0.5, 0.05, 0.86).normalize(),
            Vec3::new(0.0, 0.5, 0.866),
        );
        assert!(along_x.is_finite() && along_y.is_finite());
        assert!(w.kernel(Vec3::new(0.0, 0.0, -1.0), wo) == 0.0);
    }
}
