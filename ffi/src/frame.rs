//! The receiver frame for C callers, so external tools rebuild exactly the
//! directions Antumbra uses.

use antumbra_core::Frame;
use glam::Vec3;

use crate::boundary::guard;
use crate::error::Error;
use crate::raw;
use crate::result::*;

/// How far |normal| may be from 1: the frame formula assumes a unit normal, and a
/// normal this far off is a caller bug, not rounding.
const UNIT_TOLERANCE: f32 = 1e-3;

/// The orthonormal frame (tangent, bitangent, normal) of Duff et al. 2017 around a
/// unit normal, exactly as Antumbra's hemisphere algorithms use it:
/// `s = n.z >= 0 ? 1 : -1; a = -1/(s + n.z); c = n.x*n.y*a;
/// tangent = (1 + s*n.x*n.x*a, s*c, -s*n.x); bitangent = (c, s + n.y*n.y*a, -n.y)`.
///
/// @param normal unit normal (|normal| within 1e-3 of 1), used as given.
/// @param tangent receives the first tangent axis.
/// @param bitangent receives the second tangent axis; tangent x bitangent = normal.
///
/// On a NULL pointer, a non-finite normal or one that is not unit length, nothing
/// is written, and the thread's last error message and the error callback report
/// ANTUMBRA_RESULT_NULL_ARGUMENT, ANTUMBRA_RESULT_NON_FINITE or
/// ANTUMBRA_RESULT_INVALID_ARGUMENT.
/// Thread safety: safe from any thread.
///
/// # Safety
/// Non-NULL pointers must point to 3 floats each (readable for `normal`, writable
/// for the others).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_frame_from_normal(
    normal: *const f32,
    tangent: *mut f32,
    bitangent: *mut f32,
) {
    let _ = guard("antumbra_frame_from_normal", || {
        // SAFETY: pointer contracts forwarded from the caller.
        let n = unsafe { raw::slice(normal, 3, "normal") }?;
        // SAFETY: as above.
        let t = unsafe { raw::slice_mut(tangent, 3, "tangent") }?;
        // SAFETY: as above.
        let b = unsafe { raw::slice_mut(bitangent, 3, "bitangent") }?;
        let n = Vec3::new(n[0], n[1], n[2]);
        if !n.is_finite() {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                format!("normal ({}, {}, {}) is not finite", n.x, n.y, n.z),
            ));
        }
        if (n.length() - 1.0).abs() > UNIT_TOLERANCE {
            return Err(Error::invalid(format!(
                "normal has length {}, not 1",
                n.length()
            )));
        }
        let frame = Frame::from_normal(n);
        t.copy_from_slice(&frame.tangent.to_array());
        b.copy_from_slice(&frame.bitangent.to_array());
        Ok(())
    });
}
