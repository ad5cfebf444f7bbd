//! Real spherical harmonics: evaluation, projection, rotation and zonal convolution.
//!
//! The basis is the real, orthonormal one with the Condon–Shortley phase used by
//! Sloan et al. (PRT, SIGGRAPH 2002; "Stupid SH Tricks", GDC 2008), D3DX and
//! google/spherical-harmonics:
//!
//! ```text
//! Y_l^m  = √2 K_l^m P_l^m(cos θ) cos(mφ)     m > 0
//! Y_l^0  =    K_l^0 P_l^0(cos θ)
//! Y_l^m  = √2 K_l^|m| P_l^|m|(cos θ) sin(|m|φ)  m < 0
//! K_l^m  = √((2l+1)/(4π) · (l-m)!/(l+m)!),  P_l^m with the (-1)^m phase
//! ```
//!
//! with `θ` measured from +z and `φ` from +x towards +y, so `Y_0^0 = 0.282095`,
//! `Y_1^{-1} = -0.488603 y`, `Y_1^0 = 0.488603 z`, `Y_1^1 = -0.488603 x`. Coefficient
//! `(l, m)` is stored at index `l(l+1) + m` ([`sh_index`]); `bands = lmax + 1` and a
//! vector of `bands` bands has `bands²` coefficients. A function is represented as
//! `f(ω) ≈ Σ_i c_i Y_i(ω)` with `c_i = ∫ f Y_i dω`. Directions are unit vectors.
//!
//! Invariants: every operation works on fixed-size arrays on the stack (no
//! allocation), for 1 to [`MAX_BANDS`] = 8 bands (lmax 7). [`Sh<N>`] is generic over
//! the coefficient *count* `N` rather than the band count, because stable Rust
//! cannot size an array `[f32; B * B]` from a const parameter `B`; the band count is
//! the associated constant [`Sh::BANDS`], and a count that is not a square in
//! `1..=64` is a compile-time error the first time it is used. The aliases
//! [`Sh1`] … [`Sh64`] name the useful sizes.
//!
//! What is where:
//! - [`eval_basis`]: closed-form polynomials for bands 0..=4, a normalised Legendre
//!   recurrence above (`basis.rs`).
//! - [`project_equirect`] / [`project_fn`]: projection of an equirectangular image
//!   with exact texel solid angles, and of a function by stratified sampling
//!   (`projection.rs`).
//! - [`ShRotation`]: exact rotation of coefficients by the Ivanic–Ruedenberg
//!   recurrence (`rotation.rs`); it rotates the function, `f'(ω) = f(R⁻¹ω)`.
//! - [`ZonalKernel`]: convolution with rotationally symmetric kernels, the clamped
//!   cosine (irradiance) and normalised Phong lobes (`zonal.rs`).

mod basis;
mod projection;
mod rotation;
mod zonal;

#[cfg(test)]
mod test_support;

use core::fmt;
use core::ops::{Add, AddAssign, Index, IndexMut, Mul, MulAssign, Neg, Sub, SubAssign};

use glam::{Mat3, Vec3};

pub use basis::{POLYNOMIAL_BANDS, eval_basis, eval_basis_into, eval_basis_recurrence};
pub use projection::{
    EquirectMapping, equirect_texel_solid_angle, project_equirect, project_equirect_mono,
    project_fn, project_fn_rgb,
};
pub use rotation::ShRotation;
pub use zonal::{ZonalKernel, clamped_cosine_factor, phong_factor};

/// The most bands supported (lmax = 7).
pub const MAX_BANDS: usize = 8;

/// The most coefficients supported, `MAX_BANDS²`.
pub const MAX_COEFFS: usize = MAX_BANDS * MAX_BANDS;

/// Index of coefficient `(l, m)`, `-l ≤ m ≤ l`: `l(l+1) + m`.
#[inline]
pub const fn sh_index(l: usize, m: isize) -> usize {
    debug_assert!(m.unsigned_abs() <= l);
    (l * (l + 1)).wrapping_add_signed(m)
}

/// The band count for a coefficient count that is a square in `1..=MAX_COEFFS`.
pub(crate) const fn bands_for_len(len: usize) -> Option<usize> {
    let mut bands = 1;
    while bands <= MAX_BANDS {
        if bands * bands == len {
            return Some(bands);
        }
        bands += 1;
    }
    None
}

/// Why an SH operation rejected its input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShError {
    /// An image with no pixels.
    EmptyImage {
        /// Width given, in pixels.
        width: usize,
        /// Height given, in pixels.
        height: usize,
    },
    /// The pixel slice does not hold exactly `width * height` pixels (or that product
    /// overflows).
    ImageSizeMismatch {
        /// Width given, in pixels.
        width: usize,
        /// Height given, in pixels.
        height: usize,
        /// Number of pixels in the slice.
        pixels: usize,
    },
    /// A coefficient slice whose length is not `bands²` for 1 to [`MAX_BANDS`] bands.
    CoefficientCount {
        /// The length given.
        len: usize,
    },
    /// Finite texels project to a coefficient beyond the `f32` range (about
    /// `3.4e38`): the image is too bright to be represented, for instance texels
    /// near `f32::MAX`.
    CoefficientOverflow {
        /// The channel (0 red, 1 green, 2 blue; 0 for a single-channel image).
        channel: usize,
        /// The coefficient, `l(l+1) + m`.
        index: usize,
        /// Column of the texel with the largest magnitude in that channel.
        column: usize,
        /// Row of that texel (from the top).
        row: usize,
    },
}

impl fmt::Display for ShError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ShError::EmptyImage { width, height } => {
                write!(f, "the image is {width}x{height} pixels, which is empty")
            }
            ShError::ImageSizeMismatch {
                width,
                height,
                pixels,
            } => write!(
                f,
                "the image holds {pixels} pixels but is declared {width}x{height}"
            ),
            ShError::CoefficientCount { len } => write!(
                f,
                "{len} coefficients is not a square count between 1 and {MAX_COEFFS}"
            ),
            ShError::CoefficientOverflow {
                channel,
                index,
                column,
                row,
            } => write!(
                f,
                "coefficient {index} of channel {channel} exceeds the float range: the \
                 texels are too bright (the brightest of that channel is at column \
                 {column}, row {row})"
            ),
        }
    }
}

impl core::error::Error for ShError {}

/// Coefficients of a real function on the sphere in the first `N = bands²` real SH
/// (convention in the [module docs](self)): `f(ω) ≈ Σ_i coeffs[i] Y_i(ω)`,
/// `coeffs[l(l+1) + m]` for band `l`, order `m`.
///
/// `N` must be a square between 1 and 64; use the aliases [`Sh4`] (2 bands),
/// [`Sh9`] (3), [`Sh16`], [`Sh25`], [`Sh36`], [`Sh49`], [`Sh64`] (8). Layout is
/// exactly `[f32; N]`. Any other `N` is rejected when the type is used:
///
/// ```compile_fail
/// let not_square = antumbra_core::sh::Sh::<10>::new([0.0; 10]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(transparent)]
pub struct Sh<const N: usize> {
    /// The coefficients, `coeffs[l(l+1) + m]`.
    pub coeffs: [f32; N],
}

impl<const N: usize> From<Sh<N>> for [f32; N] {
    /// The coefficients.
    #[inline]
    fn from(sh: Sh<N>) -> Self {
        sh.coeffs
    }
}

impl<const N: usize> From<[f32; N]> for Sh<N> {
    /// Wraps the coefficients ([`Sh::new`]).
    #[inline]
    fn from(coeffs: [f32; N]) -> Self {
        Sh { coeffs }
    }
}

/// One band (a constant function).
pub type Sh1 = Sh<1>;
/// Two bands (lmax 1).
pub type Sh4 = Sh<4>;
/// Three bands (lmax 2), the classic irradiance size.
pub type Sh9 = Sh<9>;
/// Four bands (lmax 3).
pub type Sh16 = Sh<16>;
/// Five bands (lmax 4), the size the transfer papers use for glossy work.
pub type Sh25 = Sh<25>;
/// Six bands (lmax 5).
pub type Sh36 = Sh<36>;
/// Seven bands (lmax 6).
pub type Sh49 = Sh<49>;
/// Eight bands (lmax 7), the most supported.
pub type Sh64 = Sh<64>;

impl<const N: usize> Sh<N> {
    /// The number of bands, `√N`. Naming it with an unsupported `N` fails to compile.
    pub const BANDS: usize = match bands_for_len(N) {
        Some(bands) => bands,
        None => panic!("Sh<N>: N must be bands² for 1 to 8 bands (1, 4, 9, ..., 64)"),
    };

    /// All coefficients zero.
    pub const ZERO: Self = Sh { coeffs: [0.0; N] };

    /// Wraps coefficients in the documented order.
    #[inline]
    pub const fn new(coeffs: [f32; N]) -> Self {
        let _ = Self::BANDS;
        Sh { coeffs }
    }

    /// The number of bands, `√N`.
    #[inline]
    pub const fn bands(&self) -> usize {
        Self::BANDS
    }

    /// The function at the unit direction `dir`: `Σ_i c_i Y_i(dir)`.
    #[inline]
    pub fn eval(&self, dir: Vec3) -> f32 {
        dot(&self.coeffs, &eval_basis::<N>(dir))
    }

    /// `∫ f g dω` of the two represented functions (orthonormality makes it the
    /// coefficient dot product).
    #[inline]
    pub fn dot(&self, other: &Self) -> f32 {
        dot(&self.coeffs, &other.coeffs)
    }

    /// The `2l + 1` coefficients of band `l`, `m = -l..=l`; empty if `l ≥ bands`.
    #[inline]
    pub fn band(&self, l: usize) -> &[f32] {
        if l >= Self::BANDS {
            return &[];
        }
        &self.coeffs[l * l..(l + 1) * (l + 1)]
    }

    /// The energy `Σ_m c_{l,m}²` of band `l` (0 if `l ≥ bands`); rotations keep it.
    #[inline]
    pub fn band_energy(&self, l: usize) -> f32 {
        self.band(l).iter().map(|c| c * c).sum()
    }

    /// The function rotated by `rotation`: `f'(ω) = f(R⁻¹ω)`. Builds an
    /// [`ShRotation`]; build one yourself to rotate several vectors by the same `R`.
    #[inline]
    pub fn rotated(&self, rotation: Mat3) -> Self {
        ShRotation::<N>::new(rotation).apply(self)
    }

    /// The convolution with a zonal kernel: band `l` scaled by `kernel.factor(l)`.
    #[inline]
    pub fn convolved(&self, kernel: &ZonalKernel) -> Self {
        let mut out = *self;
        for l in 0..Self::BANDS {
            let factor = kernel.factor(l);
            for c in &mut out.coeffs[l * l..(l + 1) * (l + 1)] {
                *c *= factor;
            }
        }
        out
    }
}

impl<const N: usize> Default for Sh<N> {
    fn default() -> Self {
        Self::ZERO
    }
}

impl<const N: usize> Index<usize> for Sh<N> {
    type Output = f32;
    #[inline]
    fn index(&self, i: usize) -> &f32 {
        &self.coeffs[i]
    }
}

impl<const N: usize> IndexMut<usize> for Sh<N> {
    #[inline]
    fn index_mut(&mut self, i: usize) -> &mut f32 {
        &mut self.coeffs[i]
    }
}

impl<const N: usize> Add for Sh<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, rhs: Self) -> Self {
        self += rhs;
        self
    }
}

impl<const N: usize> AddAssign for Sh<N> {
    #[inline]
    fn add_assign(&mut self, rhs: Self) {
        for (a, b) in self.coeffs.iter_mut().zip(rhs.coeffs) {
            *a += b;
        }
    }
}

impl<const N: usize> Sub for Sh<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, rhs: Self) -> Self {
        self -= rhs;
        self
    }
}

impl<const N: usize> SubAssign for Sh<N> {
    #[inline]
    fn sub_assign(&mut self, rhs: Self) {
        for (a, b) in self.coeffs.iter_mut().zip(rhs.coeffs) {
            *a -= b;
        }
    }
}

impl<const N: usize> Mul<f32> for Sh<N> {
    type Output = Self;
    #[inline]
    fn mul(mut self, rhs: f32) -> Self {
        self *= rhs;
        self
    }
}

impl<const N: usize> MulAssign<f32> for Sh<N> {
    #[inline]
    fn mul_assign(&mut self, rhs: f32) {
        for a in &mut self.coeffs {
            *a *= rhs;
        }
    }
}

impl<const N: usize> Neg for Sh<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        self * -1.0
    }
}

/// Three [`Sh<N>`], one per colour channel (linear RGB radiance, typically).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[repr(C)]
pub struct ShRgb<const N: usize> {
    /// Red channel.
    pub r: Sh<N>,
    /// Green channel.
    pub g: Sh<N>,
    /// Blue channel.
    pub b: Sh<N>,
}

impl<const N: usize> ShRgb<N> {
    /// All channels zero.
    pub const ZERO: Self = ShRgb {
        r: Sh::ZERO,
        g: Sh::ZERO,
        b: Sh::ZERO,
    };

    /// From `[r, g, b]`.
    #[inline]
    pub const fn from_channels([r, g, b]: [Sh<N>; 3]) -> Self {
        ShRgb { r, g, b }
    }

    /// `[r, g, b]`.
    #[inline]
    pub const fn channels(&self) -> [Sh<N>; 3] {
        [self.r, self.g, self.b]
    }

    /// The number of bands, `√N`.
    #[inline]
    pub const fn bands(&self) -> usize {
        Sh::<N>::BANDS
    }

    /// The RGB value at the unit direction `dir` (the basis is evaluated once).
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        let y = eval_basis::<N>(dir);
        Vec3::new(
            dot(&self.r.coeffs, &y),
            dot(&self.g.coeffs, &y),
            dot(&self.b.coeffs, &y),
        )
    }

    /// Each channel rotated by `rotation` (`f'(ω) = f(R⁻¹ω)`), building the rotation
    /// once.
    #[inline]
    pub fn rotated(&self, rotation: Mat3) -> Self {
        ShRotation::<N>::new(rotation).apply_rgb(self)
    }

    /// Each channel convolved with `kernel`.
    #[inline]
    pub fn convolved(&self, kernel: &ZonalKernel) -> Self {
        self.map(|c| c.convolved(kernel))
    }

    /// Applies `f` to each channel.
    #[inline]
    pub fn map(&self, mut f: impl FnMut(&Sh<N>) -> Sh<N>) -> Self {
        ShRgb {
            r: f(&self.r),
            g: f(&self.g),
            b: f(&self.b),
        }
    }
}

impl<const N: usize> Add for ShRgb<N> {
    type Output = Self;
    #[inline]
    fn add(self, rhs: Self) -> Self {
        ShRgb {
            r: self.r + rhs.r,
            g: self.g + rhs.g,
            b: self.b + rhs.b,
        }
    }
}

impl<const N: usize> Sub for ShRgb<N> {
    type Output = Self;
    #[inline]
    fn sub(self, rhs: Self) -> Self {
        ShRgb {
            r: self.r - rhs.r,
            g: self.g - rhs.g,
            b: self.b - rhs.b,
        }
    }
}

impl<const N: usize> Mul<f32> for ShRgb<N> {
    type Output = Self;
    #[inline]
    fn mul(self, rhs: f32) -> Self {
        self.map(|c| *c * rhs)
    }
}

#[inline]
fn dot<const N: usize>(a: &[f32; N], b: &[f32; N]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_and_band_layout() {
        assert_eq!(sh_index(0, 0), 0);
        assert_eq!(sh_index(1, -1), 1);
        assert_eq!(sh_index(1, 1), 3);
        assert_eq!(sh_index(2, -2), 4);
        assert_eq!(sh_index(7, 7), 63);
        assert_eq!(Sh9::BANDS, 3);
        assert_eq!(Sh64::ZERO.bands(), 8);
        assert_eq!(bands_for_len(49), Some(7));
        assert_eq!(bands_for_len(50), None);
        assert_eq!(bands_for_len(0), None);
        let mut sh = Sh9::ZERO;
        sh[sh_index(2, 1)] = 3.0;
        assert_eq!(sh.band(2), &[0.0, 0.0, 0.0, 3.0, 0.0]);
        assert_eq!(sh.band(3), &[] as &[f32]);
        assert_eq!(sh.band_energy(2), 9.0);
    }

    #[test]
    fn arithmetic_is_per_coefficient() {
        let a = Sh4::new([1.0, 2.0, 3.0, 4.0]);
        let b = Sh4::new([0.5, 0.5, 0.5, 0.5]);
        assert_eq!((a + b).coeffs, [1.5, 2.5, 3.5, 4.5]);
        assert_eq!((a - b).coeffs, [0.5, 1.5, 2.5, 3.5]);
        assert_eq!((a * 2.0).coeffs, [2.0, 4.0, 6.0, 8.0]);
        assert_eq!((-a).coeffs, [-1.0, -2.0, -3.0, -4.0]);
        assert_eq!(a.dot(&b), 5.0);
        let rgb = ShRgb::from_channels([a, b, a]);
        assert_eq!(rgb.channels(), [a, b, a]);
        assert_eq!((rgb + rgb).g, b * 2.0);
    }

    #[test]
    fn rgb_eval_matches_channels() {
        let r = Sh9::new([1.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]);
        let rgb = ShRgb::from_channels([r, r * 2.0, -r]);
        let d = Vec3::new(0.2, 0.3, -0.9).normalize();
        let v = rgb.eval(d);
        assert!((v.x - r.eval(d)).abs() < 1e-6);
        assert!((v.y - 2.0 * r.eval(d)).abs() < 1e-5);
        assert!((v.z + r.eval(d)).abs() < 1e-6);
    }

    #[test]
    fn error_messages_name_the_numbers() {
        let e = ShError::ImageSizeMismatch {
            width: 4,
            height: 2,
            pixels: 7,
        };
        assert_eq!(
            alloc::format!("{e}"),
            "the image holds 7 pixels but is declared 4x2"
        );
    }
}
