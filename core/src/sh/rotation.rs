//! Exact rotation of SH coefficients: the recurrence of Ivanic and Ruedenberg,
//! "Rotation Matrices for Real Spherical Harmonics. Direct Determination by
//! Recursion", J. Phys. Chem. 100 (1996), with the corrections of their 1998
//! addition (J. Phys. Chem. A 102), in the form google/spherical-harmonics uses
//! for the Condon–Shortley basis (its `V` term for `m < 0` fixes a remaining
//! erratum).
//!
//! Band `l` of a rotated vector is a `(2l+1)²` matrix times band `l` of the input.
//! Band 1 is the 3×3 rotation itself, permuted to the basis order `(y, z, x)` with
//! the Condon–Shortley signs; band `l` follows from band 1 and band `l - 1`. The
//! result is exact up to `f32` rounding for every supported band: it is not an
//! approximation by sampling or fitting.
//!
//! Direction: [`ShRotation::new(R)`](ShRotation::new) rotates the *function*,
//! `f'(ω) = f(R⁻¹ω)`: a lobe pointing along `d` points along `R d` afterwards.
//! Improper orthogonal matrices (det = -1) are accepted too: `R = -Q` with `Q` a
//! rotation, and `f(-ω)` has band `l` multiplied by `(-1)^l`.

use glam::Mat3;

use super::basis::const_sqrt;
use super::{MAX_BANDS, Sh, ShRgb};

/// Entries of the band matrices for bands `0..MAX_BANDS`, `Σ (2l+1)²`.
const ROTATION_ENTRIES: usize = band_offset(MAX_BANDS);

/// Where band `l`'s matrix starts in the packed storage:
/// `Σ_{k<l} (2k+1)² = l(2l-1)(2l+1)/3`.
const fn band_offset(l: usize) -> usize {
    if l == 0 { 0 } else { l * (4 * l * l - 1) / 3 }
}

/// The coefficients `(u, v, w)` of Ivanic–Ruedenberg's table 1 (with the errata) for
/// every `(l, m, n)` with `l ≥ 2`, in the same packed layout as the matrices.
const UVW: [[f32; 3]; ROTATION_ENTRIES] = {
    let mut table = [[0.0f32; 3]; ROTATION_ENTRIES];
    let mut l = 2;
    while l < MAX_BANDS {
        let li = l as i64;
        let size = 2 * l + 1;
        let offset = band_offset(l);
        let mut row = 0;
        while row < size {
            let m = row as i64 - li;
            let am = m.abs();
            let delta = if m == 0 { 1.0 } else { 0.0 };
            let mut col = 0;
            while col < size {
                let n = col as i64 - li;
                let denom = if n.abs() == li {
                    (2 * li * (2 * li - 1)) as f64
                } else {
                    ((li + n) * (li - n)) as f64
                };
                let u = const_sqrt(((li + m) * (li - m)) as f64 / denom);
                let v = 0.5
                    * const_sqrt((1.0 + delta) * ((li + am - 1) * (li + am)) as f64 / denom)
                    * (1.0 - 2.0 * delta);
                let w =
                    -0.5 * const_sqrt(((li - am - 1) * (li - am)) as f64 / denom) * (1.0 - delta);
                table[offset + row * size + col] = [u as f32, v as f32, w as f32];
                col += 1;
            }
            row += 1;
        }
        l += 1;
    }
    table
};

/// The per-band rotation matrices for [`Sh<N>`], built once from a 3×3 orthogonal
/// matrix and applied to any number of coefficient vectors.
///
/// Rotates the function: for `g = rotation.apply(&f)`, `g(ω) = f(R⁻¹ω)` (a lobe along
/// `d` ends up along `R d`). `R` must be orthogonal, or orthogonal up to rounding
/// (a rotation, or a rotation times -1): the recurrence assumes it, and band `l`'s
/// matrix of any other `R` is meaningless and grows like `|R|^l`, so a large `R`
/// overflows to infinities and NaN in the higher bands (`|R| ≈ 1e6` does in band
/// `l = 7` in `f32`). Nothing is checked: normalise the columns first when unsure.
/// The matrices live in a fixed array sized for [`MAX_BANDS`] (680 floats); only the
/// first `Sh::<N>::BANDS` bands are computed.
///
/// ```
/// use antumbra_core::sh::{Sh9, ShRotation, sh_index};
/// use antumbra_core::glam::{Mat3, Vec3};
///
/// // Y_1^0 (a lobe along +z), rotated +90° about +x, becomes a lobe along -y,
/// // which is +Y_1^{-1} (Y_1^{-1} = -0.4886 y).
/// let mut f = Sh9::ZERO;
/// f[sh_index(1, 0)] = 1.0;
/// let g = ShRotation::<9>::new(Mat3::from_rotation_x(core::f32::consts::FRAC_PI_2)).apply(&f);
/// assert!((g[sh_index(1, -1)] - 1.0).abs() < 1e-6);
/// assert!(g[sh_index(1, 0)].abs() < 1e-6);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct ShRotation<const N: usize> {
    /// Band `l`'s matrix, row-major, at `band_offset(l)`; entry `(m, n)` at
    /// `(m + l) * (2l + 1) + (n + l)`.
    matrices: [f32; ROTATION_ENTRIES],
}

impl<const N: usize> ShRotation<N> {
    /// The band matrices of the orthogonal matrix `rotation` (glam column-major, so
    /// `rotation * v` rotates `v`).
    pub fn new(rotation: Mat3) -> Self {
        let bands = Sh::<N>::BANDS;
        let mut matrices = [0.0f32; ROTATION_ENTRIES];
        matrices[0] = 1.0;
        if bands == 1 {
            return ShRotation { matrices };
        }
        // A reflection -Q is Q followed by ω → -ω, which is (-1)^l on band l.
        let (proper, reflected) = if rotation.determinant() < 0.0 {
            (-rotation, true)
        } else {
            (rotation, false)
        };
        // r(i, j) = row i, column j.
        let r = |i: usize, j: usize| proper.col(j)[i];
        // Band 1 in the order (Y_1^{-1}, Y_1^0, Y_1^1) ∝ (-y, z, -x): the rotation
        // permuted to (y, z, x), with the sign of each entry that pairs a ±1 index
        // with index 0 flipped by the Condon–Shortley phase.
        matrices[1..10].copy_from_slice(&[
            r(1, 1),
            -r(1, 2),
            r(1, 0),
            -r(2, 1),
            r(2, 2),
            -r(2, 0),
            r(0, 1),
            -r(0, 2),
            r(0, 0),
        ]);
        // Bands 2 and 3 (the sizes shading uses) with the band a constant, so
        // the indices and trip counts fold; the same operations in the same
        // order as the general loop, so the same bits.
        for l in 2..bands {
            match l {
                2 => fill_band(&mut matrices, 2),
                3 => fill_band(&mut matrices, 3),
                _ => fill_band_general(&mut matrices, l),
            }
        }
        if reflected {
            for l in (1..bands).step_by(2) {
                let size = 2 * l + 1;
                for e in &mut matrices[band_offset(l)..band_offset(l) + size * size] {
                    *e = -*e;
                }
            }
        }
        ShRotation { matrices }
    }

    /// The matrix of band `l` (`l < Sh::<N>::BANDS`), row-major `(2l+1)²`: rotated
    /// `c'_{l,m} = Σ_n M[(m+l)(2l+1) + (n+l)] c_{l,n}`. Empty for other `l`.
    pub fn band_matrix(&self, l: usize) -> &[f32] {
        if l >= Sh::<N>::BANDS {
            return &[];
        }
        let size = 2 * l + 1;
        &self.matrices[band_offset(l)..band_offset(l) + size * size]
    }

    /// The rotated coefficients of `sh`.
    #[inline]
    pub fn apply(&self, sh: &Sh<N>) -> Sh<N> {
        let mut out = [0.0f32; N];
        for l in 0..Sh::<N>::BANDS {
            let size = 2 * l + 1;
            let matrix = &self.matrices[band_offset(l)..band_offset(l) + size * size];
            let input = &sh.coeffs[l * l..l * l + size];
            let output = &mut out[l * l..l * l + size];
            for (row, o) in matrix.chunks_exact(size).zip(output) {
                *o = row.iter().zip(input).map(|(a, b)| a * b).sum();
            }
        }
        Sh { coeffs: out }
    }

    /// [`ShRotation::apply`] in `f64` on `f64` coefficients (the matrices
    /// widened), for sums that may exceed the `f32` range before the rotation
    /// brings them back, and so that projections round once, at the end.
    pub(crate) fn apply_f64(&self, coeffs: &[f64; N]) -> [f64; N] {
        let mut out = [0.0f64; N];
        for l in 0..Sh::<N>::BANDS {
            let size = 2 * l + 1;
            let matrix = &self.matrices[band_offset(l)..band_offset(l) + size * size];
            let input = &coeffs[l * l..l * l + size];
            let output = &mut out[l * l..l * l + size];
            for (row, o) in matrix.chunks_exact(size).zip(output) {
                *o = row.iter().zip(input).map(|(&a, b)| f64::from(a) * b).sum();
            }
        }
        out
    }

    /// The rotated coefficients of each channel of `sh`.
    #[inline]
    pub fn apply_rgb(&self, sh: &ShRgb<N>) -> ShRgb<N> {
        sh.map(|c| self.apply(c))
    }
}

/// Band `l`'s matrix from band 1's and band `l - 1`'s (Ivanic–Ruedenberg),
/// inlined so that a constant `l` folds its indices.
#[inline(always)]
fn fill_band(matrices: &mut [f32; ROTATION_ENTRIES], l: usize) {
    let (done, rest) = matrices.split_at_mut(band_offset(l));
    let size = 2 * l + 1;
    let current = &mut rest[..size * size];
    let uvw = &UVW[band_offset(l)..band_offset(l) + size * size];
    let li = l as isize;
    for m in -li..=li {
        for n in -li..=li {
            let at = (m + li) as usize * size + (n + li) as usize;
            let [u, v, w] = uvw[at];
            // Zero coefficients guard terms whose indices leave band l - 1.
            let mut value = 0.0;
            if u != 0.0 {
                value += u * term_u(done, l, m, n);
            }
            if v != 0.0 {
                value += v * term_v(done, l, m, n);
            }
            if w != 0.0 {
                value += w * term_w(done, l, m, n);
            }
            current[at] = value;
        }
    }
}

/// [`fill_band`] for any band, not inlined.
#[inline(never)]
fn fill_band_general(matrices: &mut [f32; ROTATION_ENTRIES], l: usize) {
    fill_band(matrices, l);
}

/// Element `(m, n)` of band `l` in the packed storage.
#[inline(always)]
fn element(matrices: &[f32], l: usize, m: isize, n: isize) -> f32 {
    let li = l as isize;
    let size = 2 * l + 1;
    matrices[band_offset(l) + (m + li) as usize * size + (n + li) as usize]
}

/// Ivanic–Ruedenberg's `P_i^{a,b}` for band `l`, from band 1 and band `l - 1`.
#[inline(always)]
fn term_p(done: &[f32], l: usize, i: isize, a: isize, b: isize) -> f32 {
    let li = l as isize;
    let r1 = |n: isize| element(done, 1, i, n);
    let prev = |n: isize| element(done, l - 1, a, n);
    if b == li {
        r1(1) * prev(li - 1) - r1(-1) * prev(-li + 1)
    } else if b == -li {
        r1(1) * prev(-li + 1) + r1(-1) * prev(li - 1)
    } else {
        r1(0) * prev(b)
    }
}

#[inline(always)]
fn term_u(done: &[f32], l: usize, m: isize, n: isize) -> f32 {
    term_p(done, l, 0, m, n)
}

#[inline(always)]
fn term_v(done: &[f32], l: usize, m: isize, n: isize) -> f32 {
    const SQRT_2: f32 = core::f32::consts::SQRT_2;
    match m {
        0 => term_p(done, l, 1, 1, n) + term_p(done, l, -1, -1, n),
        1 => term_p(done, l, 1, 0, n) * SQRT_2,
        m if m > 1 => term_p(done, l, 1, m - 1, n) - term_p(done, l, -1, -m + 1, n),
        -1 => term_p(done, l, -1, 0, n) * SQRT_2,
        // The published paper has (1 + δ) and (1 - δ)^½ here; the algebra (and the
        // m > 0 case it mirrors) needs (1 - δ) and (1 + δ)^½, which for m < -1 are 1.
        m => term_p(done, l, 1, m + 1, n) + term_p(done, l, -1, -m - 1, n),
    }
}

#[inline(always)]
fn term_w(done: &[f32], l: usize, m: isize, n: isize) -> f32 {
    // w = 0 whenever m = 0, so W's value there never matters.
    match m {
        0 => 0.0,
        m if m > 0 => term_p(done, l, 1, m + 1, n) + term_p(done, l, -1, -m - 1, n),
        m => term_p(done, l, 1, m - 1, n) - term_p(done, l, -1, -m + 1, n),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::test_support::{coefficients, rotation, unit_vector};
    use crate::sh::{Sh9, Sh64, sh_index};
    use glam::{Quat, Vec3};
    use proptest::prelude::*;

    #[test]
    fn storage_covers_every_band() {
        assert_eq!(ROTATION_ENTRIES, 680);
        for l in 0..=MAX_BANDS {
            let sum: usize = (0..l).map(|k| (2 * k + 1) * (2 * k + 1)).sum();
            assert_eq!(band_offset(l), sum);
        }
    }

    #[test]
    fn identity_leaves_coefficients_alone() {
        let rot = ShRotation::<64>::new(Mat3::IDENTITY);
        for l in 0..8 {
            let size = 2 * l + 1;
            for (i, e) in rot.band_matrix(l).iter().enumerate() {
                let want = if i / size == i % size { 1.0 } else { 0.0 };
                assert!((e - want).abs() < 1e-6, "band {l} entry {i}: {e}");
            }
        }
    }

    #[test]
    fn quarter_turn_about_x_sends_z_lobe_to_minus_y() {
        let mut f = Sh9::ZERO;
        f[sh_index(1, 0)] = 1.0;
        let g = f.rotated(Mat3::from_rotation_x(core::f32::consts::FRAC_PI_2));
        let mut want = Sh9::ZERO;
        want[sh_index(1, -1)] = 1.0;
        for i in 0..9 {
            assert!((g[i] - want[i]).abs() < 1e-6, "{i}: {g:?}");
        }
    }

    #[test]
    fn zonal_lobe_follows_the_rotated_axis() {
        // A band-limited lobe about +z turned by R is the same lobe about R·z.
        let axis = Vec3::new(0.3, -0.4, 0.866).normalize();
        let r = Mat3::from_quat(Quat::from_rotation_arc(Vec3::Z, axis));
        let mut zonal = Sh64::ZERO;
        for l in 0..8 {
            zonal[sh_index(l, 0)] = 1.0 / (1.0 + l as f32);
        }
        let turned = zonal.rotated(r);
        // Direct construction: c_lm = z_l √(4π/(2l+1)) Y_lm(axis).
        let y = crate::sh::eval_basis::<64>(axis);
        for l in 0..8usize {
            let scale = libm::sqrtf(4.0 * core::f32::consts::PI / (2 * l + 1) as f32);
            for m in -(l as isize)..=(l as isize) {
                let i = sh_index(l, m);
                let want = zonal[sh_index(l, 0)] * scale * y[i];
                assert!(
                    (turned[i] - want).abs() < 2e-5,
                    "{l} {m}: {} {want}",
                    turned[i]
                );
            }
        }
    }

    proptest! {
        #[test]
        fn rotating_then_evaluating_is_evaluating_at_the_inverse_direction(
            r in rotation(), c in coefficients(), dir in unit_vector(),
        ) {
            let f = Sh64::new(c);
            let g = f.rotated(r);
            let want = f.eval(r.transpose() * dir);
            let got = g.eval(dir);
            let scale = c.iter().map(|x| x.abs()).sum::<f32>();
            prop_assert!((got - want).abs() <= 2e-6 * scale, "{} vs {}", got, want);
        }

        #[test]
        fn reflections_rotate_the_function_too(
            r in rotation(), c in coefficients(), dir in unit_vector(),
        ) {
            let reflection = -r;
            let f = Sh64::new(c);
            let g = f.rotated(reflection);
            let want = f.eval(reflection.transpose() * dir);
            let got = g.eval(dir);
            let scale = c.iter().map(|x| x.abs()).sum::<f32>();
            prop_assert!((got - want).abs() <= 2e-6 * scale, "{} vs {}", got, want);
        }

        #[test]
        fn per_band_energy_is_preserved(r in rotation(), c in coefficients()) {
            let f = Sh64::new(c);
            let g = f.rotated(r);
            for l in 0..8 {
                let (before, after) = (f.band_energy(l), g.band_energy(l));
                prop_assert!((before - after).abs() <= 1e-5 * before.max(1e-3), "band {}: {} {}", l, before, after);
            }
        }

        #[test]
        fn band_matrices_are_orthogonal(r in rotation()) {
            let rot = ShRotation::<64>::new(r);
            for l in 0..8 {
                let size = 2 * l + 1;
                let m = rot.band_matrix(l);
                for i in 0..size {
                    for j in 0..size {
                        let d: f32 = (0..size).map(|k| m[i * size + k] * m[j * size + k]).sum();
                        let want = if i == j { 1.0 } else { 0.0 };
                        prop_assert!((d - want).abs() < 1e-5, "band {} ({}, {}): {}", l, i, j, d);
                    }
                }
            }
        }

        #[test]
        fn composition_matches_the_product(a in rotation(), b in rotation(), c in coefficients()) {
            let f = Sh64::new(c);
            // Rotating by B, then by A, is rotating by A·B.
            let twice = f.rotated(b).rotated(a);
            let once = f.rotated(a * b);
            let scale = c.iter().map(|x| x.abs()).fold(0.0f32, f32::max);
            for i in 0..64 {
                prop_assert!((twice[i] - once[i]).abs() <= 1e-5 * scale, "{}: {} {}", i, twice[i], once[i]);
            }
        }

        #[test]
        fn smaller_vectors_rotate_like_the_prefix(r in rotation(), c in coefficients()) {
            let big = Sh64::new(c).rotated(r);
            let mut small = Sh9::ZERO;
            small.coeffs.copy_from_slice(&c[..9]);
            let small = small.rotated(r);
            for i in 0..9 {
                prop_assert!((small[i] - big[i]).abs() < 1e-6);
            }
        }
    }
}
