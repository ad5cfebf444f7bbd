//! Projection onto the SH basis, `c_i = ∫ f(ω) Y_i(ω) dω`: of an equirectangular
//! (latitude–longitude) image and of an arbitrary function.
//!
//! Images: each texel contributes its value at its centre times its exact solid
//! angle, `(cos θ_top - cos θ_bottom) · 2π/width` (the integral of `sin θ dθ dφ` over
//! the texel), so the weights sum to 4π up to rounding and no `sin θ` factor is
//! approximated. The sum is evaluated separably: per row, Fourier sums of the row
//! against `cos mφ`, `sin mφ`, then the Legendre part once per row, in the map's own
//! frame (its up axis as +z); the result is then turned into world axes with the
//! exact [`ShRotation`]. That is the same quadrature as evaluating every basis
//! function at every texel centre, at a fraction of the cost (`O(W·H·bands)`
//! instead of `O(W·H·bands²)`). The only error is the midpoint rule's within each
//! row, `O((π/height)²)` times the function's second derivative in `θ`. In `φ` the
//! equally spaced sum is exact whenever the image content is a trigonometric
//! polynomial of degree below `width - bands` (so an SH-band-limited function on a
//! map at least `2 · bands` texels wide is integrated exactly around each row).
//!
//! Functions: jittered stratified sampling in `(cos θ, φ)`, where equal rectangles
//! are equal solid angles, with a fixed hash as the random source so results are
//! reproducible bit for bit.

use core::f64::consts::PI;

use glam::{Mat3, Vec2, Vec3};

use super::{MAX_BANDS, Sh, ShError, ShRgb, ShRotation, eval_basis};
use crate::geom::normalize_exponent;
use crate::rng::{splitmix64, unit_f64};

/// How the pixels of an equirectangular image map to directions.
///
/// With `θ = v·π` (from the up axis) and `φ = 2π(u - 0.5)`:
///
/// ```text
/// direction(u, v) = sin θ cos φ · center + sin θ sin φ · right + cos θ · up
/// ```
///
/// so `v = 0` (the top row) looks along `up`, `v = 1` along `-up`, the image centre
/// `u = 0.5` along `center`, `u = 0.75` along `right`, `u = 0.25` along `-right` and
/// the seam `u = 0` (= 1) along `-center`. Texel `(column, row)` of a `w × h` image
/// covers `u ∈ [column/w, (column+1)/w)`, `v ∈ [row/h, (row+1)/h)`; pixels are stored
/// row-major from the top row.
///
/// The default, [`EquirectMapping::Y_UP`] (+Y up, +X at the centre, +Z at
/// `u = 0.75`), is the convention of the `antumbra` command's environment maps:
/// facing -Z with +Y up, +X is on the right, so panoramas are not mirrored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EquirectMapping {
    up: Vec3,
    center: Vec3,
    right: Vec3,
}

impl Default for EquirectMapping {
    fn default() -> Self {
        Self::Y_UP
    }
}

impl EquirectMapping {
    /// +Y up, +X at the image centre, +Z at `u = 0.75`, -Z at `u = 0.25`: the
    /// `antumbra` CLI's environment maps (`v = acos(y)/π`, `u = 0.5 + atan2(z, x)/2π`).
    pub const Y_UP: Self = EquirectMapping {
        up: Vec3::Y,
        center: Vec3::X,
        right: Vec3::Z,
    };

    /// A mapping with the given up axis (`v = 0`) and image-centre direction
    /// (`u = 0.5`), with the same handedness as [`Self::Y_UP`]:
    /// `right = center × up` (so `new(Vec3::Y, Vec3::X)` is `Y_UP`). `center` is
    /// made perpendicular to `up`; neither needs unit length. `None` if either is
    /// zero or not finite, or they are parallel.
    pub fn new(up: Vec3, center: Vec3) -> Option<Self> {
        // Each vector is scaled by a power of two before it is normalised (exact),
        // so that no length of any size, 1e-30 or 1e30, overflows or underflows
        // when squared: `try_normalize` alone refused such axes.
        let up = normalize_exponent(up).try_normalize()?;
        let center = normalize_exponent(center);
        let center = normalize_exponent(center - center.dot(up) * up).try_normalize()?;
        Some(EquirectMapping {
            up,
            center,
            right: center.cross(up),
        })
    }

    /// The same mapping with `u` running the other way around `up` (`right`
    /// negated), for panoramas stored mirrored.
    pub fn mirrored(self) -> Self {
        EquirectMapping {
            right: -self.right,
            ..self
        }
    }

    /// The unit direction at `v = 0`.
    pub fn up(&self) -> Vec3 {
        self.up
    }

    /// The unit direction at the image centre, `(u, v) = (0.5, 0.5)`.
    pub fn center(&self) -> Vec3 {
        self.center
    }

    /// The unit direction at `(u, v) = (0.75, 0.5)`.
    pub fn right(&self) -> Vec3 {
        self.right
    }

    /// The unit direction at image coordinates `uv ∈ [0, 1]²`.
    pub fn direction(&self, uv: Vec2) -> Vec3 {
        let theta = uv.y * core::f32::consts::PI;
        let phi = (uv.x - 0.5) * core::f32::consts::TAU;
        let (sin_theta, cos_theta) = (libm::sinf(theta), libm::cosf(theta));
        let (sin_phi, cos_phi) = (libm::sinf(phi), libm::cosf(phi));
        sin_theta * (cos_phi * self.center + sin_phi * self.right) + cos_theta * self.up
    }

    /// The image coordinates of a direction (any non-zero length); the inverse of
    /// [`Self::direction`], with `u ∈ [0, 1]`.
    pub fn uv(&self, direction: Vec3) -> Vec2 {
        let d = direction.normalize_or_zero();
        let u = 0.5 + libm::atan2f(d.dot(self.right), d.dot(self.center)) / core::f32::consts::TAU;
        let v = libm::acosf(d.dot(self.up).clamp(-1.0, 1.0)) / core::f32::consts::PI;
        Vec2::new(u, v)
    }

    /// The orthogonal matrix from the map's frame (up = +z, centre = +x, azimuth
    /// `φ_local = -φ` growing towards `-right`) to world axes: columns
    /// `(center, -right, up)`. A rotation for maps of [`Self::Y_UP`]'s handedness,
    /// a reflection for mirrored ones.
    fn local_to_world(&self) -> Mat3 {
        Mat3::from_cols(self.center, -self.right, self.up)
    }
}

/// The solid angle of any texel in row `row` of a `width × height` equirectangular
/// image: `(cos(row·π/h) - cos((row+1)·π/h)) · 2π/w` steradians. Over the whole
/// image these sum to 4π up to rounding (the row terms telescope to 2). 0 for an
/// empty image or a row outside it.
pub fn equirect_texel_solid_angle(row: usize, width: usize, height: usize) -> f64 {
    if width == 0 || row >= height {
        return 0.0;
    }
    let (top, bottom) = row_cosines(row, height);
    (top - bottom) * (2.0 * PI / width as f64)
}

/// `(cos θ_top, cos θ_bottom)` of a row, with the poles exact so the telescoping sum
/// of the rows is exactly 2 before rounding of the differences.
fn row_cosines(row: usize, height: usize) -> (f64, f64) {
    let edge = |k: usize| match k {
        0 => 1.0,
        k if k == height => -1.0,
        k => libm::cos(k as f64 * PI / height as f64),
    };
    (edge(row), edge(row + 1))
}

/// SH coefficients of a linear RGB equirectangular image.
///
/// `pixels` holds `width * height` texels row-major from the top row (`[f32; 3]`,
/// glam `Vec3`, or anything convertible to `[f32; 3]`); `mapping` says which
/// direction each texel looks along. Each texel is weighted by its exact solid
/// angle ([`equirect_texel_solid_angle`]) and evaluated at its centre (see the
/// module docs for the error). Non-finite texels propagate into the result.
/// Accumulates and rotates to world axes in `f64`, rounding to `f32` once at the
/// end; no allocation.
///
/// Errors: [`ShError::EmptyImage`], [`ShError::ImageSizeMismatch`], and
/// [`ShError::CoefficientOverflow`] when finite texels give a coefficient beyond
/// the `f32` range (texels of about `1e37` and more can; the error names the
/// brightest texel of the channel).
///
/// ```
/// use antumbra_core::sh::{EquirectMapping, Sh9, project_equirect};
///
/// // A uniformly white sky: radiance 1 everywhere projects to c_0 = √(4π).
/// let pixels = vec![[1.0f32; 3]; 64 * 32];
/// let sh = project_equirect::<9, _>(&pixels, 64, 32, &EquirectMapping::Y_UP)?;
/// assert!((sh.g[0] - 2.0 * core::f32::consts::PI.sqrt()).abs() < 1e-4);
/// # Ok::<(), antumbra_core::sh::ShError>(())
/// ```
pub fn project_equirect<const N: usize, P>(
    pixels: &[P],
    width: usize,
    height: usize,
    mapping: &EquirectMapping,
) -> Result<ShRgb<N>, ShError>
where
    P: Copy + Into<[f32; 3]>,
{
    check_image(pixels.len(), width, height)?;
    let channels = project_rows::<N, 3>(width, height, mapping, |i| pixels[i].into())?;
    Ok(ShRgb::from_channels(channels))
}

/// [`project_equirect`] for a single-channel image (`width * height` values,
/// row-major from the top row), with the same errors (channel 0).
pub fn project_equirect_mono<const N: usize>(
    pixels: &[f32],
    width: usize,
    height: usize,
    mapping: &EquirectMapping,
) -> Result<Sh<N>, ShError> {
    check_image(pixels.len(), width, height)?;
    let [sh] = project_rows::<N, 1>(width, height, mapping, |i| [pixels[i]])?;
    Ok(sh)
}

fn check_image(len: usize, width: usize, height: usize) -> Result<(), ShError> {
    if width == 0 || height == 0 {
        return Err(ShError::EmptyImage { width, height });
    }
    if width.checked_mul(height) != Some(len) {
        return Err(ShError::ImageSizeMismatch {
            width,
            height,
            pixels: len,
        });
    }
    Ok(())
}

/// The separable quadrature for `C` channels; `texel(i)` reads pixel `i` (in range).
fn project_rows<const N: usize, const C: usize>(
    width: usize,
    height: usize,
    mapping: &EquirectMapping,
    texel: impl Fn(usize) -> [f32; C],
) -> Result<[Sh<N>; C], ShError> {
    let bands = Sh::<N>::BANDS;
    let mut local = [[0.0f64; N]; C];
    // In the map's frame the texel centre of column j has azimuth
    // φ_j = -2π((j + 0.5)/w - 0.5) = φ_0 - jΔ: step e^{iφ} by e^{-iΔ} across the row
    // (in f64, the drift over a row is far below f32 resolution).
    let delta = 2.0 * PI / width as f64;
    let phi_0 = PI - 0.5 * delta;
    let start = (libm::cos(phi_0), libm::sin(phi_0));
    let step = (libm::cos(delta), -libm::sin(delta));
    for row in 0..height {
        // Σ_j f_j e^{imφ_j} for m < bands: the row's Fourier sums.
        let mut cos_sums = [[0.0f64; MAX_BANDS]; C];
        let mut sin_sums = [[0.0f64; MAX_BANDS]; C];
        let mut e = start;
        for column in 0..width {
            let value = texel(row * width + column);
            let mut power = (1.0f64, 0.0f64);
            for m in 0..bands {
                for ch in 0..C {
                    let v = f64::from(value[ch]);
                    cos_sums[ch][m] += v * power.0;
                    sin_sums[ch][m] += v * power.1;
                }
                power = complex_mul(power, e);
            }
            e = complex_mul(e, step);
        }
        // The θ part: the basis at azimuth 0 is √2 K P_l^m(cos θ) sin^m θ for m ≥ 0
        // (and K P_l^0 for m = 0); the sin(|m|φ) harmonics share it.
        let (top, bottom) = row_cosines(row, height);
        let weight = (top - bottom) * delta;
        let theta = (row as f64 + 0.5) * PI / height as f64;
        let polar = eval_basis::<N>(Vec3::new(
            libm::sin(theta) as f32,
            0.0,
            libm::cos(theta) as f32,
        ));
        for l in 0..bands {
            let centre = l * (l + 1);
            for m in 0..=l {
                let p = weight * f64::from(polar[centre + m]);
                for ch in 0..C {
                    local[ch][centre + m] += p * cos_sums[ch][m];
                    if m > 0 {
                        local[ch][centre - m] += p * sin_sums[ch][m];
                    }
                }
            }
        }
    }
    // Rotated in f64 and rounded last: a local sum beyond the f32 range became
    // infinite before the rotation, where inf * 0 gave NaN in every coefficient.
    let to_world = ShRotation::<N>::new(mapping.local_to_world());
    let world = local.map(|c| to_world.apply_f64(&c));
    for (channel, coeffs) in world.iter().enumerate() {
        // Finite in f64 (finite texels) but not in f32: too bright. Non-finite
        // sums come from non-finite texels and propagate, as documented.
        if let Some(index) = coeffs
            .iter()
            .position(|&x| x.is_finite() && !(x as f32).is_finite())
        {
            let brightest = (0..width * height)
                .max_by(|&i, &j| {
                    let (a, b) = (texel(i)[channel].abs(), texel(j)[channel].abs());
                    a.total_cmp(&b).then(j.cmp(&i))
                })
                .unwrap_or(0);
            return Err(ShError::CoefficientOverflow {
                channel,
                index,
                column: brightest % width,
                row: brightest / width,
            });
        }
    }
    Ok(world.map(|c| Sh {
        coeffs: c.map(|x| x as f32),
    }))
}

#[inline]
fn complex_mul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

/// SH coefficients of `f` by jittered stratified sampling over the sphere.
///
/// The sphere is cut into `k_z × k_φ` cells of equal solid angle, equal steps in
/// `cos θ` and in `φ` (`k_z = max(1, round(√(count/π)))`, `k_φ = max(1, count / k_z)`,
/// so cells are roughly square and at most `sample_count` samples are taken, at
/// least one), with one sample per cell at a jittered position. The jitter comes from
/// a fixed hash of the cell index: the same call gives the same bits every time.
/// Each sample weighs `4π / (k_z k_φ)`; sums are kept in `f64`. `f` receives unit
/// directions.
///
/// ```
/// use antumbra_core::sh::{Sh4, project_fn};
///
/// // Projecting Y_1^0 = 0.488603 z recovers the unit vector of index 2.
/// let sh: Sh4 = project_fn(20_000, |d| 0.488603 * d.z);
/// assert!((sh[2] - 1.0).abs() < 1e-3 && sh[0].abs() < 1e-3);
/// ```
pub fn project_fn<const N: usize>(sample_count: usize, mut f: impl FnMut(Vec3) -> f32) -> Sh<N> {
    let [sh] = project_samples::<N, 1>(sample_count, |d| [f(d)]);
    sh
}

/// [`project_fn`] for an RGB function (the basis is evaluated once per sample).
pub fn project_fn_rgb<const N: usize>(
    sample_count: usize,
    mut f: impl FnMut(Vec3) -> Vec3,
) -> ShRgb<N> {
    ShRgb::from_channels(project_samples::<N, 3>(sample_count, |d| f(d).to_array()))
}

fn project_samples<const N: usize, const C: usize>(
    sample_count: usize,
    mut f: impl FnMut(Vec3) -> [f32; C],
) -> [Sh<N>; C] {
    let (rows, columns) = strata(sample_count);
    let mut sums = [[0.0f64; N]; C];
    for row in 0..rows {
        for column in 0..columns {
            let cell = (row * columns + column) as u64;
            let jitter_z = unit_f64(splitmix64(2 * cell));
            let jitter_phi = unit_f64(splitmix64(2 * cell + 1));
            let z = 1.0 - 2.0 * (row as f64 + jitter_z) / rows as f64;
            let phi = 2.0 * PI * (column as f64 + jitter_phi) / columns as f64;
            let r = crate::geom::sqrt((1.0 - z * z).max(0.0));
            let dir = Vec3::new(
                (r * libm::cos(phi)) as f32,
                (r * libm::sin(phi)) as f32,
                z as f32,
            );
            let value = f(dir);
            let y = eval_basis::<N>(dir);
            for (sum, v) in sums.iter_mut().zip(value) {
                for (s, yi) in sum.iter_mut().zip(y) {
                    *s += f64::from(v) * f64::from(yi);
                }
            }
        }
    }
    let weight = 4.0 * PI / (rows * columns) as f64;
    sums.map(|s| Sh {
        coeffs: s.map(|x| (x * weight) as f32),
    })
}

/// The `(k_z, k_φ)` grid of [`project_fn`] for a sample budget.
fn strata(sample_count: usize) -> (usize, usize) {
    let count = sample_count.max(1);
    let rows = (libm::round(crate::geom::sqrt(count as f64 / PI)) as usize).max(1);
    let columns = (count / rows).max(1);
    (rows, columns)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::{Sh9, Sh16, Sh25, Sh64, ZonalKernel, sh_index};
    use alloc::vec;
    use alloc::vec::Vec;

    /// The CLI's `uv_to_direction`, copied from cli/src/envmap/equirect.rs.
    fn cli_uv_to_direction(uv: Vec2) -> Vec3 {
        let phi = (uv.x - 0.5) * core::f32::consts::TAU;
        let theta = uv.y * core::f32::consts::PI;
        let (sin_theta, cos_theta) = (libm::sinf(theta), libm::cosf(theta));
        let (sin_phi, cos_phi) = (libm::sinf(phi), libm::cosf(phi));
        Vec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi)
    }

    #[test]
    fn default_mapping_is_the_clis() {
        let m = EquirectMapping::default();
        assert_eq!(m, EquirectMapping::new(Vec3::Y, Vec3::X).unwrap());
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
        assert!(close(m.direction(Vec2::new(0.5, 0.5)), Vec3::X));
        assert!(close(m.direction(Vec2::new(0.75, 0.5)), Vec3::Z));
        assert!(close(m.direction(Vec2::new(0.25, 0.5)), -Vec3::Z));
        assert!(close(m.direction(Vec2::new(0.0, 0.5)), -Vec3::X));
        assert!(close(m.direction(Vec2::new(0.3, 0.0)), Vec3::Y));
        assert!(close(m.direction(Vec2::new(0.3, 1.0)), -Vec3::Y));
        for i in 1..40 {
            for j in 1..20 {
                let uv = Vec2::new(i as f32 / 40.0, j as f32 / 20.0);
                assert!(close(m.direction(uv), cli_uv_to_direction(uv)), "{uv}");
                assert!((m.uv(m.direction(uv)) - uv).length() < 1e-5, "{uv}");
            }
        }
    }

    #[test]
    fn custom_and_mirrored_mappings() {
        let z_up =
            EquirectMapping::new(Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 0.5)).unwrap();
        assert_eq!(z_up.up(), Vec3::Z);
        assert_eq!(z_up.center(), Vec3::X);
        assert_eq!(z_up.right(), Vec3::X.cross(Vec3::Z));
        let mirrored = EquirectMapping::Y_UP.mirrored();
        assert!((mirrored.direction(Vec2::new(0.75, 0.5)) + Vec3::Z).length() < 1e-6);
        assert_eq!(EquirectMapping::new(Vec3::Y, Vec3::Y * 3.0), None);
        assert_eq!(EquirectMapping::new(Vec3::ZERO, Vec3::X), None);
        assert_eq!(EquirectMapping::new(Vec3::NAN, Vec3::X), None);
    }

    #[test]
    fn bright_maps_rotate_in_f64_and_report_overflow() {
        // One texel looking along (1, 1, 1)/√3: in the map's frame it looks along
        // +x, where 6e37 projects beyond the f32 range in bands 1 and 2 (about
        // 3.7e38 and 4.1e38), though no world coefficient does (at most 2.8e38).
        // The sums were rounded to f32 (infinite) before the rotation to world
        // axes, where inf * 0 gave NaN.
        let mapping = EquirectMapping::new(Vec3::new(1.0, -1.0, 0.0), Vec3::ONE).unwrap();
        let unit = project_equirect_mono::<9>(&[1.0], 1, 1, &mapping).unwrap();
        let bright = project_equirect_mono::<9>(&[6e37], 1, 1, &mapping).unwrap();
        for (i, (&b, &u)) in bright.coeffs.iter().zip(&unit.coeffs).enumerate() {
            assert!(
                (b - 6e37 * u).abs() <= 1e-6 * 6e37 * u.abs().max(1e-3),
                "{i}: {b} vs {u}"
            );
        }
        // A coefficient beyond the f32 range is an error naming the brightest
        // texel, instead of NaN (1e38 projects to c_0 = 3.5e38).
        assert_eq!(
            project_equirect::<9, _>(&[[1e38f32; 3]], 1, 1, &EquirectMapping::Y_UP),
            Err(ShError::CoefficientOverflow {
                channel: 0,
                index: 0,
                column: 0,
                row: 0
            })
        );
        // Green: 3e38 in the two middle rows, -3.3e38 (the brightest) at
        // column 5 of row 2.
        let mut pixels = vec![[1.0f32, 2.0, 3.0]; 8 * 4];
        for pixel in &mut pixels[8..3 * 8] {
            pixel[1] = 3e38;
        }
        pixels[2 * 8 + 5][1] = -3.3e38;
        let error = project_equirect::<4, _>(&pixels, 8, 4, &EquirectMapping::Y_UP).unwrap_err();
        assert!(
            matches!(
                error,
                ShError::CoefficientOverflow {
                    channel: 1,
                    column: 5,
                    row: 2,
                    ..
                }
            ),
            "{error:?}"
        );
        assert!(
            alloc::format!("{error}").contains("column 5, row 2"),
            "{error}"
        );
        // Non-finite texels still propagate (documented), they are no overflow.
        let nan = project_equirect::<9, _>(&[[f32::NAN, 1.0, 1.0]], 1, 1, &EquirectMapping::Y_UP);
        assert!(nan.unwrap().r.coeffs.iter().all(|c| c.is_nan()));
    }

    #[test]
    fn mappings_accept_axes_of_any_finite_length() {
        // try_normalize refused axes whose squared length overflows or
        // underflows (1e20 squares to infinity, 1e-30 to zero).
        for s in [1e20f32, 3e38, 1e-30, 1e-40] {
            let z_up = EquirectMapping::new(Vec3::new(0.0, 0.0, s), Vec3::new(s, 0.0, 0.5 * s));
            assert_eq!(
                z_up,
                EquirectMapping::new(Vec3::Z, Vec3::new(1.0, 0.0, 0.5)),
                "{s}"
            );
            assert_eq!(
                EquirectMapping::new(Vec3::Y * s, Vec3::X),
                Some(EquirectMapping::Y_UP),
                "{s}"
            );
            assert_eq!(
                EquirectMapping::new(Vec3::Y, Vec3::X * s),
                Some(EquirectMapping::Y_UP),
                "{s}"
            );
        }
        assert!(EquirectMapping::new(Vec3::Y, Vec3::new(1e20, 0.0, 0.0)).is_some());
        assert!(EquirectMapping::new(Vec3::new(0.0, 1e-30, 0.0), Vec3::X).is_some());
        assert_eq!(EquirectMapping::new(Vec3::INFINITY, Vec3::X), None);
        assert_eq!(EquirectMapping::new(Vec3::Y, Vec3::Y * 1e30), None);
    }

    #[test]
    fn texel_solid_angles_sum_to_four_pi() {
        for (w, h) in [
            (1, 1),
            (2, 1),
            (3, 7),
            (64, 32),
            (1000, 500),
            (4096, 2048),
            (17, 1023),
        ] {
            let total: f64 = (0..h)
                .map(|row| equirect_texel_solid_angle(row, w, h) * w as f64)
                .sum();
            assert!((total - 4.0 * PI).abs() < 1e-12, "{w}x{h}: {total}");
        }
        // Symmetric about the equator, and the exact band integral.
        let (w, h) = (8, 6);
        assert!(
            (equirect_texel_solid_angle(0, w, h) - equirect_texel_solid_angle(5, w, h)).abs()
                < 1e-15
        );
        let want = (1.0 - libm::cos(PI / 6.0)) * 2.0 * PI / 8.0;
        assert!((equirect_texel_solid_angle(0, w, h) - want).abs() < 1e-15);
        assert_eq!(equirect_texel_solid_angle(6, w, h), 0.0);
        assert_eq!(equirect_texel_solid_angle(0, 0, h), 0.0);
    }

    /// The obvious quadrature: every basis function at every texel centre, each
    /// texel weighted by its solid angle, in world directions from the mapping.
    fn brute_force<const N: usize>(
        pixels: &[[f32; 3]],
        width: usize,
        height: usize,
        mapping: &EquirectMapping,
    ) -> [[f64; N]; 3] {
        let mut out = [[0.0f64; N]; 3];
        for row in 0..height {
            let weight = equirect_texel_solid_angle(row, width, height);
            for column in 0..width {
                let uv = Vec2::new(
                    (column as f32 + 0.5) / width as f32,
                    (row as f32 + 0.5) / height as f32,
                );
                let y = eval_basis::<N>(mapping.direction(uv));
                let value = pixels[row * width + column];
                for ch in 0..3 {
                    for i in 0..N {
                        out[ch][i] += weight * f64::from(value[ch]) * f64::from(y[i]);
                    }
                }
            }
        }
        out
    }

    /// A deterministic, rough test image with positive values.
    fn noise_image(width: usize, height: usize, seed: u64) -> Vec<[f32; 3]> {
        (0..width * height)
            .map(|i| {
                let h = splitmix64(seed ^ (i as u64));
                [
                    (h & 0xffff) as f32 / 65535.0,
                    ((h >> 16) & 0xffff) as f32 / 65535.0,
                    ((h >> 32) & 0xffff) as f32 / 65535.0 * 4.0,
                ]
            })
            .collect()
    }

    #[test]
    fn separable_projection_equals_per_texel_evaluation() {
        let mappings = [
            EquirectMapping::Y_UP,
            EquirectMapping::new(Vec3::new(0.2, -0.3, 0.9), Vec3::new(0.5, 1.0, 0.1)).unwrap(),
            EquirectMapping::Y_UP.mirrored(),
            EquirectMapping::new(Vec3::Z, -Vec3::Y).unwrap().mirrored(),
        ];
        for (k, mapping) in mappings.iter().enumerate() {
            let (w, h) = (48, 20);
            let pixels = noise_image(w, h, k as u64);
            let fast = project_equirect::<64, _>(&pixels, w, h, mapping)
                .unwrap()
                .channels();
            let slow = brute_force::<64>(&pixels, w, h, mapping);
            for ch in 0..3 {
                for i in 0..64 {
                    let (a, b) = (f64::from(fast[ch][i]), slow[ch][i]);
                    assert!(
                        (a - b).abs() < 2e-5 * (1.0 + b.abs()),
                        "map {k} ch {ch} i {i}: {a} {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn glam_vectors_and_mono_images_project_like_arrays() {
        let (w, h) = (16, 8);
        let pixels = noise_image(w, h, 9);
        let vectors: Vec<Vec3> = pixels.iter().map(|&p| Vec3::from_array(p)).collect();
        let mono: Vec<f32> = pixels.iter().map(|p| p[1]).collect();
        let mapping = EquirectMapping::Y_UP;
        let a = project_equirect::<16, _>(&pixels, w, h, &mapping).unwrap();
        let b = project_equirect::<16, _>(&vectors, w, h, &mapping).unwrap();
        let c = project_equirect_mono::<16>(&mono, w, h, &mapping).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.g, c);
    }

    #[test]
    fn bad_images_are_rejected() {
        let m = EquirectMapping::Y_UP;
        let px = vec![[0.0f32; 3]; 8];
        assert_eq!(
            project_equirect::<4, _>(&px, 4, 3, &m),
            Err(ShError::ImageSizeMismatch {
                width: 4,
                height: 3,
                pixels: 8
            })
        );
        assert_eq!(
            project_equirect::<4, _>(&px[..0], 0, 3, &m),
            Err(ShError::EmptyImage {
                width: 0,
                height: 3
            })
        );
        assert!(project_equirect_mono::<4>(&[1.0; 4], usize::MAX, 2, &m).is_err());
    }

    #[test]
    fn constant_map_projects_to_band_zero() {
        let (w, h) = (32, 16);
        let sh = project_equirect::<64, _>(&vec![[1.0f32; 3]; w * h], w, h, &EquirectMapping::Y_UP)
            .unwrap();
        let c0 = 2.0 * libm::sqrtf(core::f32::consts::PI);
        assert!((sh.r[0] - c0).abs() < 1e-5);
        // Other zonal terms carry only the midpoint rule's error, O((π/h)²).
        for i in 1..64 {
            assert!(sh.r[i].abs() < 0.05, "{i}: {}", sh.r[i]);
        }
    }

    /// Largest coefficient error when an image sampled from a known band-limited
    /// function at texel centres is projected back.
    fn round_trip_error(f: &Sh64, mapping: &EquirectMapping, height: usize) -> f32 {
        let width = 2 * height;
        let mut pixels = Vec::with_capacity(width * height);
        for row in 0..height {
            for column in 0..width {
                let uv = Vec2::new(
                    (column as f32 + 0.5) / width as f32,
                    (row as f32 + 0.5) / height as f32,
                );
                let v = f.eval(mapping.direction(uv));
                pixels.push([v, 2.0 * v, -v]);
            }
        }
        let sh = project_equirect::<64, _>(&pixels, width, height, mapping).unwrap();
        let mut worst = 0.0f32;
        for i in 0..64 {
            worst = worst.max((sh.r[i] - f[i]).abs());
            worst = worst.max((sh.g[i] - 2.0 * f[i]).abs() / 2.0);
            worst = worst.max((sh.b[i] + f[i]).abs());
        }
        worst
    }

    #[test]
    fn equirect_round_trip_converges_at_the_midpoint_rate() {
        // The midpoint rule in θ over a row of height Δθ = π/h errs by about
        // Δθ²/24 times the second θ-derivative of the integrand f·Y_i, which for
        // bands < 8 is at most ~(2·7)² times its size: so the error per unit of
        // coefficient magnitude is bounded by (π/h)² · 14² / 24 ≈ 8 (π/h)². The test
        // asserts that bound and the quadratic rate (×4 per doubling of h).
        let mut f = Sh64::ZERO;
        for (i, c) in f.coeffs.iter_mut().enumerate() {
            *c = libm::sinf(1.7 * i as f32 + 0.3);
        }
        let mapping =
            EquirectMapping::new(Vec3::new(0.1, 1.0, -0.2), Vec3::new(1.0, 0.0, 0.3)).unwrap();
        let scale = f.coeffs.iter().map(|c| c.abs()).sum::<f32>();
        let errors: Vec<f32> = [32, 64, 128]
            .iter()
            .map(|&h| round_trip_error(&f, &mapping, h))
            .collect();
        for (&h, &e) in [32usize, 64, 128].iter().zip(&errors) {
            let bound = 8.0 * (core::f32::consts::PI / h as f32).powi(2) * scale;
            assert!(e < bound, "h={h}: error {e}, bound {bound}");
        }
        assert!(
            errors[0] / errors[1] > 3.5 && errors[1] / errors[2] > 3.5,
            "{errors:?}"
        );
    }

    #[test]
    fn low_bands_of_a_low_band_map_are_nearly_exact_at_moderate_resolution() {
        // A 3-band function on a 256×128 map: integrands of degree ≤ 4 in cos θ,
        // error ≈ (π/128)²·4²/24 ≈ 4e-4 relative at worst.
        let f = Sh9::new([1.0, -0.5, 0.25, 0.7, 0.1, -0.2, 0.3, 0.05, -0.4]);
        let mut big = Sh64::ZERO;
        big.coeffs[..9].copy_from_slice(&f.coeffs);
        assert!(round_trip_error(&big, &EquirectMapping::Y_UP, 128) < 1e-3);
    }

    #[test]
    fn function_projection_of_a_constant() {
        let sh: Sh16 = project_fn(1000, |_| 1.0);
        assert!((sh[0] - 2.0 * libm::sqrtf(core::f32::consts::PI)).abs() < 1e-5);
        for i in 1..16 {
            assert!(sh[i].abs() < 0.02, "{i}: {}", sh[i]);
        }
    }

    #[test]
    fn function_projection_of_each_basis_function_is_a_unit_vector() {
        // Jittered stratification errs like 1/count for smooth integrands; the worst
        // coefficient over all 64 × 64 pairs measured 1.6e-2, 5.8e-3 and 6.3e-4 at
        // 10k, 40k and 160k samples. Projection is linear, so this also bounds the
        // error for any band-limited function by Σ|c_i| times the tolerance.
        for i in 0..64 {
            let sh: Sh64 = project_fn(160_000, |d| eval_basis::<64>(d)[i]);
            for j in 0..64 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!(
                    (sh[j] - want).abs() < 2e-3,
                    "Y_{i} -> coefficient {j}: {}",
                    sh[j]
                );
            }
        }
    }

    #[test]
    fn function_projection_of_a_clamped_cosine_matches_the_convolution_formula() {
        let kernel = ZonalKernel::clamped_cosine();
        for axis in [
            Vec3::Z,
            Vec3::new(0.48, 0.6, -0.64),
            Vec3::new(-2.0, 1.0, 2.0) / 3.0,
        ] {
            let projected: Sh64 = project_fn(100_000, |d| axis.dot(d).max(0.0));
            let formula = kernel.along::<64>(axis);
            for i in 0..64 {
                assert!(
                    (projected[i] - formula[i]).abs() < 2e-3,
                    "{axis} {i}: {} vs {}",
                    projected[i],
                    formula[i]
                );
            }
        }
    }

    #[test]
    fn function_projection_is_deterministic_and_rgb_matches_mono() {
        let f = |d: Vec3| libm::expf(2.0 * d.x) * (1.0 + d.y);
        let a: Sh25 = project_fn(5000, f);
        let b: Sh25 = project_fn(5000, f);
        assert_eq!(a, b);
        let rgb = project_fn_rgb::<25>(5000, |d| Vec3::new(f(d), 0.0, -f(d)));
        assert_eq!(rgb.r, a);
        assert_eq!(rgb.b, -a);
        assert_eq!(strata(0), (1, 1));
        assert_eq!(strata(1), (1, 1));
        let (rows, columns) = strata(10_000);
        assert!(rows * columns <= 10_000 && rows * columns > 9_900);
    }

    #[test]
    fn single_harmonic_in_an_image_lands_on_its_index() {
        // Y_2^1 drawn into a Y-up map projects onto index 7 only (up to the midpoint
        // rule), which ties the map's axes to the SH axes.
        let mut f = Sh64::ZERO;
        f[sh_index(2, 1)] = 1.0;
        let err = round_trip_error(&f, &EquirectMapping::Y_UP, 64);
        assert!(err < 2e-3, "{err}");
    }
}
