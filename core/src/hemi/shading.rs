//! Glossy shading from hemisphere masks: the paper's "mildly glossy" BRDFs
//! (Kautz, Lehtinen and Aila 2004; Lehtinen's thesis §3.3), here the
//! energy-normalised modified Phong lobe of Lafortune and Willems (1994) about the
//! mirror direction `r` of the view vector:
//!
//! ```text
//! f_r(ω) = ρ_s (s + 2)/(2π) max(0, ω·r)^s
//! L_glossy = ∫_H L(ω) V(ω) f_r(ω) cosθ dω = ρ_s Σ_k G_k l_k,
//! G_k = ∫_H V(ω) (s + 2)/(2π) max(0, ω·r)^s y_k(ω) cosθ dω.
//! ```
//!
//! The cosine is kept (it is the BRDF form, and it lets `G` reuse the diffuse cell
//! weights, since `cosθ dω = du dv` on the disk): with `r = n`, unoccluded and unit
//! radiance, `L_glossy = ρ_s` exactly, and less towards grazing views, so `ρ_s ≤ 1`
//! conserves energy. `G`, the "glossy transfer vector" of one view, is computed per
//! receiver from the mask in the local frame,
//!
//! ```text
//! G_k ≈ Σ_{unoccluded valid c} lobe(d_c · r) W_k(c)
//! ```
//!
//! with `W_k(c)` the exact cell integrals of [`TransferTable`] and the lobe taken at
//! the cell's center direction `d_c` ([`PhongLobe`]). Then, like the diffuse
//! transfer, it is rotated to world space and dotted with the lighting. This
//! form takes `N` multiply-adds per cell; evaluating the lighting at every cell
//! (rotate the lighting into the local frame once, then `3N` per cell) would take
//! three times as many.
//!
//! Accuracy: the lobe is sampled at cell centers, so the 32×32 grid (cells about
//! 3.6° wide at the pole, stretched towards the horizon) limits the exponent it
//! resolves; the measured error against a ray-traced evaluation of the same
//! integral is in `tests/tests/hemi_transfer.rs` (see [`PhongLobe`] for figures).
//!
//! Invariants: a [`PhongLobe`] is built once per exponent (a fixed-size table, no
//! allocation); per receiver everything is on the stack.

use glam::Vec3;

use super::mask::{CELL_COORD, CELL_Z, GRID, HemiMask};
use super::transfer::TransferTable;
use crate::sh::{Sh, ShRgb};

/// Samples of the lobe table, over `w = sqrt(1 - cos α)` in `[0, 1]`.
const LOBE_SAMPLES: usize = 1024;

/// Lobe values below this fraction of the peak are dropped, so cells far from the
/// mirror direction are skipped. The dropped tail is at most `LOBE_CUTOFF · peak ·
/// ∫ cosθ dω = LOBE_CUTOFF (s + 2)/2` (in units where the unoccluded lobe at normal
/// incidence integrates to 1): below 2e-4 for `s ≤ 400`.
pub const LOBE_CUTOFF: f32 = 1e-6;

/// The normalised modified Phong lobe `(s + 2)/(2π) max(0, cos α)^s` as a function
/// of `cos α`, tabulated once for an exponent `s`.
///
/// The table is uniform in `w = sqrt(1 - cos α)` (about the angle from the lobe's
/// axis, `w ≈ α/√2`), where `cos^s α ≈ exp(-s w²)` is a Gaussian of width
/// `1/√(2s)`: 1024 samples with linear interpolation keep the relative error below
/// 1e-4 of the peak for `s ≤ 1000`. Lobe values below [`LOBE_CUTOFF`] of the peak
/// are 0.
///
/// Measured on the bunny's vertices facing a viewer (`tests/tests/hemi_transfer.rs`,
/// exact masks, against a lobe-importance-sampled ray-traced evaluation of the same
/// integral): mean error of the glossy transfer vector relative to the unoccluded
/// lobe's, and of the shaded glossy luminance under SH sky lighting,
///
/// | s   | `‖ΔG‖/‖G_unoccluded‖` mean / p90 / max | luminance |
/// |-----|----------------------------------------|-----------|
/// | 4   | 0.40 / 0.78 / 2.4 %                    | 0.16 %    |
/// | 16  | 0.55 / 0.92 / 4.7 %                    | 0.21 %    |
/// | 64  | 1.06 / 2.9 / 9.5 %                     | 0.32 %    |
/// | 256 | 3.9 / 8.0 / 75 %                       | 0.82 %    |
///
/// The error grows with the exponent because the lobe is sampled once per cell (the
/// worst vertices see it at grazing angles, where rim cells are widest): exponents
/// up to about 64 are what the 32×32 grid resolves well.
#[derive(Clone, Debug, PartialEq)]
pub struct PhongLobe {
    exponent: f32,
    /// `(s + 2)/(2π)`.
    scale: f32,
    /// Cosines at or below this give 0 (the cutoff).
    min_cos: f32,
    /// `max(0, 1 - w²)^s` at `w = k / LOBE_SAMPLES`, plus one guard entry.
    table: [f32; LOBE_SAMPLES + 2],
}

impl PhongLobe {
    /// The lobe of exponent `exponent`; `None` unless it is finite and `≥ 0`.
    pub fn new(exponent: f32) -> Option<Self> {
        if !(exponent.is_finite() && exponent >= 0.0) {
            return None;
        }
        let s = f64::from(exponent);
        let mut table = [0.0f32; LOBE_SAMPLES + 2];
        for (k, value) in table.iter_mut().enumerate().take(LOBE_SAMPLES + 1) {
            let w = k as f64 / LOBE_SAMPLES as f64;
            let c = (1.0 - w * w).max(0.0);
            let v = libm::pow(c, s);
            *value = if v < f64::from(LOBE_CUTOFF) {
                0.0
            } else {
                v as f32
            };
        }
        table[LOBE_SAMPLES + 1] = table[LOBE_SAMPLES];
        // cos^s = cutoff at cos = cutoff^(1/s); below 0 for s = 0 (every cosine >= 0
        // counts).
        let min_cos = if exponent > 0.0 {
            libm::pow(f64::from(LOBE_CUTOFF), 1.0 / s) as f32
        } else {
            0.0
        };
        Some(PhongLobe {
            exponent,
            scale: ((s + 2.0) / (2.0 * core::f64::consts::PI)) as f32,
            min_cos,
            table,
        })
    }

    /// The exponent `s`.
    #[inline]
    pub fn exponent(&self) -> f32 {
        self.exponent
    }

    /// The lobe at `cos_angle = ω·r`: `(s + 2)/(2π) cos^s α` from the table for
    /// positive cosines, 0 at and below `cos α = 0` (also for `s = 0`) and below the
    /// cutoff.
    #[inline]
    pub fn eval(&self, cos_angle: f32) -> f32 {
        if cos_angle.is_nan() || cos_angle <= self.min_cos {
            return 0.0;
        }
        self.scale * self.shape(cos_angle)
    }

    /// `(s + 2)/(2π)`, the lobe's peak.
    #[inline]
    pub fn peak(&self) -> f32 {
        self.scale
    }

    /// `cos^s` by table, for `cos_angle` in `(0, 1]` (clamped).
    #[inline(always)]
    fn shape(&self, cos_angle: f32) -> f32 {
        let w = crate::geom::sqrtf((1.0 - cos_angle).max(0.0));
        let x = (w * LOBE_SAMPLES as f32).min(LOBE_SAMPLES as f32);
        let k = x as usize;
        let f = x - k as f32;
        let (a, b) = (self.table[k], self.table[k + 1]);
        a + (b - a) * f
    }
}

/// The mirror direction of the unit vector `to_eye` (from the surface point towards
/// the viewer) about the unit `normal`: `r = 2 (n·v) n - v`. Below the horizon
/// (`r·n < 0`) exactly when the viewer is behind the surface.
#[inline]
pub fn mirror_direction(normal: Vec3, to_eye: Vec3) -> Vec3 {
    2.0 * normal.dot(to_eye) * normal - to_eye
}

/// The local glossy transfer vector of `mask` for a lobe about the local mirror
/// direction `mirror_local` (unit): `G_k = Σ_{unoccluded valid c} lobe(d_c · r)
/// W_k(c)` (see the module docs). Zero when `mirror_local` is below the horizon
/// (`z < 0`, the viewer behind the surface).
pub fn glossy_transfer<const N: usize>(
    table: &TransferTable<N>,
    mask: &HemiMask,
    lobe: &PhongLobe,
    mirror_local: Vec3,
) -> Sh<N> {
    let mut acc = [0.0f32; N];
    // Non-finite directions (a viewer at the vertex) count as behind the surface,
    // and leave the per-cell test below free of NaN.
    if !mirror_local.is_finite() || mirror_local.z < 0.0 {
        return Sh::new(acc);
    }
    let r = mirror_local;
    let free = mask.complement();
    for (j, &row) in free.rows.iter().enumerate() {
        if row == 0 {
            continue;
        }
        let v = CELL_COORD[j];
        let row_dot = r.y * v;
        let mut row_sum = [0.0f32; N];
        let mut bits = row;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let c = r.x * CELL_COORD[i] + row_dot + r.z * CELL_Z[j][i];
            if c <= lobe.min_cos {
                continue;
            }
            let weight = lobe.shape(c);
            let w = table.cell_weights(j * GRID + i);
            for k in 0..N {
                row_sum[k] += weight * w[k];
            }
        }
        for k in 0..N {
            acc[k] += lobe.scale * row_sum[k];
        }
    }
    Sh::new(acc)
}

/// Glossy outgoing radiance `ρ_s Σ_k G_k l_k` per channel, for a world-space glossy
/// transfer vector and world-space SH coefficients of incident radiance.
#[inline]
pub fn shade_glossy<const N: usize>(
    glossy_world: &Sh<N>,
    lighting: &ShRgb<N>,
    specular: Vec3,
) -> Vec3 {
    specular
        * Vec3::new(
            glossy_world.dot(&lighting.r),
            glossy_world.dot(&lighting.g),
            glossy_world.dot(&lighting.b),
        )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemi::{TransferRotation, cell_directions};
    use crate::sh::Sh9;

    #[test]
    fn lobe_table_matches_the_formula() {
        for s in [0.0f32, 1.0, 8.0, 32.5, 100.0, 1000.0] {
            let lobe = PhongLobe::new(s).unwrap();
            let peak = lobe.peak();
            assert!((peak - (s + 2.0) / core::f32::consts::TAU).abs() < 1e-5 * peak);
            // Positive cosines only: the lobe is 0 at and below cos α = 0, also for s = 0.
            for k in 1..=2000 {
                let c = k as f32 / 2000.0;
                let exact = peak * libm::powf(c, s);
                let exact = if exact < LOBE_CUTOFF * peak * 1.01 {
                    0.0
                } else {
                    exact
                };
                let got = lobe.eval(c);
                assert!(
                    (got - exact).abs() <= 1e-4 * peak + 1e-6 * peak,
                    "s {s} c {c}: {got} vs {exact}"
                );
            }
            assert_eq!(lobe.eval(-0.5), 0.0);
            assert_eq!(lobe.eval(f32::NAN), 0.0);
        }
        assert!(PhongLobe::new(-1.0).is_none() && PhongLobe::new(f32::INFINITY).is_none());
    }

    #[test]
    fn unoccluded_normal_incidence_under_unit_radiance_gives_rho() {
        let table = TransferTable::<9>::new();
        let mut unit = Sh9::ZERO;
        unit[0] = 2.0 * core::f32::consts::PI.sqrt();
        let light = ShRgb::from_channels([unit, unit, unit]);
        for s in [1.0f32, 4.0, 16.0] {
            let lobe = PhongLobe::new(s).unwrap();
            let g = glossy_transfer(&table, &HemiMask::EMPTY, &lobe, Vec3::Z);
            let out = shade_glossy(&g, &light, Vec3::ONE);
            // The lobe is sampled at cell centers: a fraction of a percent off.
            assert!((out.x - 1.0).abs() < 0.01, "s {s}: {}", out.x);
        }
        // The viewer behind the surface sees nothing.
        let lobe = PhongLobe::new(8.0).unwrap();
        let g = glossy_transfer(&table, &HemiMask::EMPTY, &lobe, Vec3::new(0.6, 0.0, -0.8));
        assert_eq!(g, Sh9::ZERO);
        // Occluding every cell blocks everything.
        let g = glossy_transfer(&table, &HemiMask::VALID, &lobe, Vec3::Z);
        assert_eq!(g, Sh9::ZERO);
    }

    #[test]
    fn glossy_transfer_is_the_per_cell_sum() {
        let table = TransferTable::<9>::new();
        let lobe = PhongLobe::new(12.0).unwrap();
        let r = Vec3::new(0.3, -0.2, 0.9).normalize();
        let mut mask = HemiMask::EMPTY;
        for (i, j, d) in cell_directions() {
            mask.set(i, j, d.x + 0.2 * d.y > 0.25);
        }
        let g = glossy_transfer(&table, &mask, &lobe, r);
        let mut expected = [0.0f64; 9];
        for (i, j, d) in cell_directions() {
            if !mask.get(i, j) {
                let f = f64::from(lobe.eval(d.dot(r)));
                for (e, w) in expected.iter_mut().zip(table.cell(i, j).coeffs) {
                    *e += f * f64::from(w);
                }
            }
        }
        for (k, (&got, e)) in g.coeffs.iter().zip(expected).enumerate() {
            assert!((f64::from(got) - e).abs() < 1e-5, "{k}");
        }
        // Rotating it to world space and shading is linear in the specular colour.
        let rotation = TransferRotation::<9>::new(&crate::Frame::from_normal(Vec3::Y));
        let world = rotation.to_world(&g);
        let light = ShRgb::from_channels([Sh9::new([1.0; 9]); 3]);
        let a = shade_glossy(&world, &light, Vec3::new(1.0, 0.5, 0.0));
        assert!((a.y - 0.5 * a.x).abs() < 1e-6 && a.z == 0.0);
        assert_eq!(
            mirror_direction(Vec3::Z, Vec3::new(0.6, 0.0, 0.8)),
            Vec3::new(-0.6, 0.0, 0.8)
        );
    }
}
