//! Spherical harmonics for C callers: projection of an equirectangular RGB map
//! (the lighting the shading entry points take), evaluation of the basis and
//! rotation of coefficient vectors.
//!
//! The basis is core's (`antumbra_core::sh`): real, orthonormal, with the
//! Condon–Shortley phase; coefficient (l, m) at index `l(l+1) + m`; `bands` bands
//! hold `bands²` coefficients; the map convention is core's default
//! `EquirectMapping::Y_UP`.

use alloc::vec::Vec;
use antumbra_core::sh::{self, EquirectMapping, MAX_BANDS, ShRgb};
use glam::Vec3;

use crate::boundary::guard;
use crate::error::Error;
use crate::frame::UNIT_TOLERANCE;
use crate::raw;
use crate::result::*;

/// The most SH bands supported (lmax = 7, 64 coefficients per channel).
pub const ANTUMBRA_SH_MAX_BANDS: u32 = 8;

const _: () = assert!(ANTUMBRA_SH_MAX_BANDS as usize == MAX_BANDS);

const TEXEL_BYTES: usize = 3 * core::mem::size_of::<f32>();

fn check_bands(bands: u32) -> Result<usize, Error> {
    if (1..=ANTUMBRA_SH_MAX_BANDS).contains(&bands) {
        Ok(bands as usize)
    } else {
        Err(Error::invalid(message!(
            "bands is {bands}; expected 1 to {ANTUMBRA_SH_MAX_BANDS}"
        )))
    }
}

/// SH coefficients of a linear RGB equirectangular (latitude–longitude) map:
/// `c_i = ∫ L(ω) Y_i(ω) dω` per channel, each texel weighted by its exact solid
/// angle and evaluated at its center (accumulated in double precision).
///
/// Map convention (+Y up, the `antumbra` command's): texel (column, row) of a
/// width × height map covers `u ∈ [column/width, (column+1)/width)`,
/// `v ∈ [row/height, (row+1)/height)`; with `θ = v·π`, `φ = 2π(u - 0.5)` it looks
/// along `(sin θ cos φ, cos θ, sin θ sin φ)`. So row 0 looks up (+Y), the last row
/// down (-Y), the center `u = 0.5` along +X, `u = 0.75` along +Z, `u = 0.25` along
/// -Z and the seam `u = 0` along -X; inversely `u = 0.5 + atan2(z, x)/2π`,
/// `v = acos(y)/π`. Facing -Z with +Y up, +X is on the right: panoramas are not
/// mirrored.
///
/// SH convention: real, orthonormal (`∫ Y_i Y_j dω = δ_ij`), Condon–Shortley phase,
/// coefficient (l, m) at index `l(l+1) + m`: `Y_0 = 0.282095`,
/// `Y_1 = -0.488603 y`, `Y_2 = 0.488603 z`, `Y_3 = -0.488603 x`, ... (as
/// `antumbra_sh_eval`). A constant map of value c gives `c_0 = 2√π · c` and 0
/// elsewhere up to the quadrature error.
///
/// @param rgb texels, 3 floats each (R, G, B, linear), rows from the top; finite
///        (negative values are allowed: projection is linear). 4-byte aligned.
/// @param width texels per row, at least 1.
/// @param height rows, at least 1.
/// @param row_stride_bytes bytes from one row to the next: 0 for packed rows
///        (`12 * width`), otherwise at least `12 * width` and a multiple of 4.
/// @param bands 1 to `ANTUMBRA_SH_MAX_BANDS` (8).
/// @param coefficients receives `3 * bands * bands` floats: the bands² red
///        coefficients, then green, then blue; untouched on failure. Must not
///        overlap `rgb`.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (rgb, coefficients); INVALID_ARGUMENT
///         (bands out of range, zero width or height, stride below the row size
///         or not a multiple of 4, misaligned array, size overflow, or texels so
///         bright that a coefficient exceeds the float range, about 3.4e38: the
///         message names the brightest texel of the channel by column and row);
///         NON_FINITE (a NaN or infinite texel, named by column and row); OUT_OF_MEMORY (a
///         strided map is first copied into a packed temporary of
///         `12 * width * height` bytes, which could not be allocated); PANIC.
///
/// Cost: O(width × height × bands), no allocation for packed maps.
/// Ownership: borrows the arrays for the call only.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `rgb` must be NULL or valid for `(height - 1) * stride + 12 * width` bytes;
/// `coefficients` NULL or valid for `3 * bands * bands` floats.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_sh_project_equirect(
    rgb: *const f32,
    width: u32,
    height: u32,
    row_stride_bytes: usize,
    bands: u32,
    coefficients: *mut f32,
) -> antumbra_result {
    guard("antumbra_sh_project_equirect", || {
        let bands = check_bands(bands)?;
        if width == 0 || height == 0 {
            return Err(Error::invalid(message!(
                "the map is {width}x{height} texels; width and height must be at least 1"
            )));
        }
        let (w, h) = (width as usize, height as usize);
        let row_bytes = raw::element_count(w, TEXEL_BYTES, "width")?;
        let stride = match row_stride_bytes {
            0 => row_bytes,
            s if s < row_bytes => {
                return Err(Error::invalid(message!(
                    "row_stride_bytes is {s}, less than the {row_bytes} bytes of {w} RGB texels"
                )));
            }
            s if s % core::mem::size_of::<f32>() != 0 => {
                return Err(Error::invalid(message!(
                    "row_stride_bytes is {s}, not a multiple of 4 (the size of a float)"
                )));
            }
            s => s,
        };
        let total_bytes = (h - 1)
            .checked_mul(stride)
            .and_then(|b| b.checked_add(row_bytes))
            .ok_or_else(|| {
                Error::invalid(message!(
                    "{h} rows at row_stride_bytes {stride} overflow size_t"
                ))
            })?;
        let stride_floats = stride / core::mem::size_of::<f32>();
        // SAFETY: caller contract on `rgb` for `total_bytes` bytes.
        let floats = unsafe { raw::slice(rgb, total_bytes / 4, "rgb") }?;
        let count = bands * bands;
        // SAFETY: caller contract: valid for 3 * bands² floats, no overlap with `rgb`.
        let out = unsafe { raw::slice_mut(coefficients, 3 * count, "coefficients") }?;
        for row in 0..h {
            let texels = &floats[row * stride_floats..][..3 * w];
            if let Some(column) = texels
                .chunks_exact(3)
                .position(|t| !t.iter().all(|c| c.is_finite()))
            {
                let t = &texels[3 * column..3 * column + 3];
                return Err(Error::new(
                    ANTUMBRA_RESULT_NON_FINITE,
                    message!(
                        "rgb: texel (column {column}, row {row}) is ({}, {}, {}), not finite",
                        t[0],
                        t[1],
                        t[2]
                    ),
                ));
            }
        }
        let packed_copy;
        let pixels: &[[f32; 3]] = if stride == row_bytes {
            bytemuck::cast_slice(floats)
        } else {
            let mut copy = Vec::new();
            copy.try_reserve_exact(w * h).map_err(|e| {
                Error::new(
                    ANTUMBRA_RESULT_OUT_OF_MEMORY,
                    message!(
                        "no memory to pack the {w}x{h} map ({} bytes): {e}",
                        w * h * TEXEL_BYTES
                    ),
                )
            })?;
            for row in 0..h {
                let texels = &floats[row * stride_floats..][..3 * w];
                copy.extend(texels.chunks_exact(3).map(|t| [t[0], t[1], t[2]]));
            }
            packed_copy = copy;
            &packed_copy
        };
        let (r, green_blue) = out.split_at_mut(count);
        let (g, b) = green_blue.split_at_mut(count);
        project(pixels, w, h, bands, [r, g, b]).map_err(|e| match e {
            // The texels are the argument at fault; the others cannot happen
            // here (checked above).
            sh::ShError::CoefficientOverflow { .. } => Error::invalid(message!("rgb: {e}")),
            _ => Error::invalid(message!("{e}")),
        })
    })
}

/// Projects with the const coefficient count for `bands` and writes the channels.
fn project(
    pixels: &[[f32; 3]],
    width: usize,
    height: usize,
    bands: usize,
    out: [&mut [f32]; 3],
) -> Result<(), sh::ShError> {
    fn write<const N: usize>(
        pixels: &[[f32; 3]],
        width: usize,
        height: usize,
        out: [&mut [f32]; 3],
    ) -> Result<(), sh::ShError> {
        let sh: ShRgb<N> =
            sh::project_equirect::<N, _>(pixels, width, height, &EquirectMapping::Y_UP)?;
        for (channel, coeffs) in out.into_iter().zip(sh.channels()) {
            channel.copy_from_slice(&coeffs.coeffs);
        }
        Ok(())
    }
    match bands {
        1 => write::<1>(pixels, width, height, out),
        2 => write::<4>(pixels, width, height, out),
        3 => write::<9>(pixels, width, height, out),
        4 => write::<16>(pixels, width, height, out),
        5 => write::<25>(pixels, width, height, out),
        6 => write::<36>(pixels, width, height, out),
        7 => write::<49>(pixels, width, height, out),
        8 => write::<64>(pixels, width, height, out),
        _ => unreachable!("bands checked to be 1..=8"),
    }
}

/// The real SH basis functions at a direction: `values[l(l+1) + m] = Y_l^m(direction)`
/// for `l < bands`, real, orthonormal, with the Condon–Shortley phase (the
/// convention of `antumbra_sh_project_equirect`): `values[0] = 0.282095`,
/// `values[1] = -0.488603 y`, `values[2] = 0.488603 z`, `values[3] = -0.488603 x`,
/// `values[6] = 0.315392 (3z² - 1)`, ...; θ is measured from +Z and φ from +X
/// towards +Y.
///
/// @param direction 3 floats, finite, unit length within 1e-3 (used as given).
/// @param bands 1 to `ANTUMBRA_SH_MAX_BANDS` (8).
/// @param values receives `bands * bands` floats; untouched on failure. May be the
///        same array as `direction` (it is read first).
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (direction, values); INVALID_ARGUMENT
///         (bands out of range, a direction whose length is not 1 within 1e-3,
///         misaligned array); NON_FINITE (direction).
///
/// Thread safety: safe from any thread.
///
/// # Safety
/// `direction` must be NULL or valid for reading 3 floats; `values` NULL or valid
/// for writing `bands * bands` floats.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_sh_eval(
    direction: *const f32,
    bands: u32,
    values: *mut f32,
) -> antumbra_result {
    guard("antumbra_sh_eval", || {
        // Read the direction into a local first: `values` may alias it.
        // SAFETY: caller contract on `direction`.
        let d = unsafe { raw::slice(direction, 3, "direction") }?;
        let d = Vec3::from_slice(d);
        let bands = check_bands(bands)?;
        let count = bands * bands;
        let out = raw::writable(values, count, "values")?;
        if !d.is_finite() {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!("direction ({}, {}, {}) is not finite", d.x, d.y, d.z),
            ));
        }
        let length = d.length();
        if (length - 1.0).abs() > UNIT_TOLERANCE {
            return Err(Error::invalid(message!(
                "direction has length {length}, not 1 (tolerance {UNIT_TOLERANCE})"
            )));
        }
        let mut basis = [0.0f32; sh::MAX_COEFFS];
        sh::eval_basis_into(d, &mut basis[..count]).map_err(|e| Error::invalid(message!("{e}")))?;
        // SAFETY: `out` checked non-NULL and aligned for `count` floats; written
        // through the raw pointer only, so aliasing `direction` is fine.
        unsafe { core::ptr::copy_nonoverlapping(basis.as_ptr(), out, count) };
        Ok(())
    })
}

/// Rotates SH coefficient vectors: for each vector, the coefficients of
/// `g(ω) = f(R⁻¹ω)`, so a lobe along `d` ends up along `R d` (exact per band, by
/// the Ivanic–Ruedenberg recurrence; band energies are preserved).
///
/// @param rotation 9 floats, row-major: `rotation[3 * i + j]` is row i, column j
///        of R, so `(R d)_i = Σ_j rotation[3 i + j] d_j`. Finite and orthogonal
///        (`R Rᵀ = I` within 1e-3 per entry); a reflection (det -1) is allowed.
/// @param bands 1 to `ANTUMBRA_SH_MAX_BANDS` (8).
/// @param coefficients `vector_count * bands²` floats, finite: the vectors one
///        after another (e.g. 3 for the channel-planar RGB lighting of
///        `antumbra_sh_project_equirect`).
/// @param vector_count the number of vectors; 0 is a valid empty batch.
/// @param rotated receives `vector_count * bands²` floats; untouched on failure.
///        May be the same array as `coefficients` (each vector is read before it
///        is written), but must not partly overlap it.
/// @return ANTUMBRA_RESULT_OK; NULL_ARGUMENT (rotation, or an array with
///         vector_count > 0); INVALID_ARGUMENT (bands out of range, a matrix that
///         is not orthogonal, misaligned array, size overflow); NON_FINITE
///         (rotation, coefficients, naming the index).
///
/// Cost: building the band matrices (about 700 multiply-adds at 8 bands), then
/// `Σ_l (2l+1)²` multiply-adds per vector; no allocation.
/// Thread safety: safe from any thread.
///
/// # Safety
/// `rotation` must be NULL or valid for 9 floats; the arrays NULL or valid for
/// `vector_count * bands * bands` floats.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_sh_rotate(
    rotation: *const f32,
    bands: u32,
    coefficients: *const f32,
    vector_count: usize,
    rotated: *mut f32,
) -> antumbra_result {
    guard("antumbra_sh_rotate", || {
        // SAFETY: caller contract on `rotation`.
        let r = unsafe { raw::slice(rotation, 9, "rotation") }?;
        let r: [f32; 9] = core::array::from_fn(|i| r[i]);
        if let Some(i) = r.iter().position(|c| !c.is_finite()) {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!("rotation[{i}] is {}; it must be finite", r[i]),
            ));
        }
        let bands = check_bands(bands)?;
        // glam is column-major: column j holds row entries (r[j], r[3+j], r[6+j]).
        let matrix = glam::Mat3::from_cols_array(&r).transpose();
        let error = (matrix * matrix.transpose() - glam::Mat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f32, |m, e| m.max(e.abs()));
        if error > UNIT_TOLERANCE {
            return Err(Error::invalid(message!(
                "rotation is not orthogonal: R Rᵀ differs from the identity by {error} \
                 (tolerance {UNIT_TOLERANCE})"
            )));
        }
        let count = bands * bands;
        let total = raw::element_count(vector_count, count, "vector_count")?;
        // Raw pointers: `rotated` may be `coefficients` itself.
        let input = if total == 0 {
            coefficients
        } else {
            // Checked like a slice, but read through the pointer only.
            raw::writable(coefficients.cast_mut(), total, "coefficients")?.cast_const()
        };
        let output = raw::writable(rotated, total, "rotated")?;
        for i in 0..total {
            // SAFETY: checked non-NULL, aligned and in bounds above.
            let c = unsafe { input.add(i).read() };
            if !c.is_finite() {
                return Err(Error::new(
                    ANTUMBRA_RESULT_NON_FINITE,
                    message!(
                        "coefficients[{i}] (vector {}, coefficient {}) is {c}; it must be finite",
                        i / count,
                        i % count
                    ),
                ));
            }
        }
        rotate(matrix, bands, vector_count, input, output);
        Ok(())
    })
}

/// Rotates `vectors` vectors of `bands²` floats from `input` to `output` (which may
/// be equal), one vector at a time through a stack copy.
fn rotate(matrix: glam::Mat3, bands: usize, vectors: usize, input: *const f32, output: *mut f32) {
    fn run<const N: usize>(
        matrix: glam::Mat3,
        vectors: usize,
        input: *const f32,
        output: *mut f32,
    ) {
        let rotation = sh::ShRotation::<N>::new(matrix);
        for v in 0..vectors {
            let mut coeffs = [0.0f32; N];
            // SAFETY: the export checked `vectors * N` floats at both pointers; the
            // vector is copied out before its slot is written.
            unsafe {
                core::ptr::copy(input.add(v * N), coeffs.as_mut_ptr(), N);
                let out = rotation.apply(&sh::Sh::new(coeffs));
                core::ptr::copy(out.coeffs.as_ptr(), output.add(v * N), N);
            }
        }
    }
    match bands {
        1 => run::<1>(matrix, vectors, input, output),
        2 => run::<4>(matrix, vectors, input, output),
        3 => run::<9>(matrix, vectors, input, output),
        4 => run::<16>(matrix, vectors, input, output),
        5 => run::<25>(matrix, vectors, input, output),
        6 => run::<36>(matrix, vectors, input, output),
        7 => run::<49>(matrix, vectors, input, output),
        8 => run::<64>(matrix, vectors, input, output),
        _ => unreachable!("bands checked to be 1..=8"),
    }
}
