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
pub(crate) const UNIT_TOLERANCE: f32 = 1e-3;

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
/// `normal` may be the same array as `tangent` or `bitangent` (it is read before
/// anything is written); `tangent` and `bitangent` must not overlap.
/// Thread safety: safe from any thread.
///
/// # Safety
/// Non-NULL pointers must point to 3 floats each (readable for `normal`, writable
/// for the others), aligned to 4 bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_frame_from_normal(
    normal: *const f32,
    tangent: *mut f32,
    bitangent: *mut f32,
) {
    let _ = guard("antumbra_frame_from_normal", || {
        // Read the normal into a local before touching outputs: it may alias them.
        // SAFETY: pointer contract forwarded from the caller.
        let n = unsafe { raw::slice(normal, 3, "normal") }?;
        let n = Vec3::new(n[0], n[1], n[2]);
        let t = raw::writable(tangent, 3, "tangent")?;
        let b = raw::writable(bitangent, 3, "bitangent")?;
        if !n.is_finite() {
            return Err(Error::new(
                ANTUMBRA_RESULT_NON_FINITE,
                message!("normal ({}, {}, {}) is not finite", n.x, n.y, n.z),
            ));
        }
        if (n.length() - 1.0).abs() > UNIT_TOLERANCE {
            return Err(Error::invalid(message!(
                "normal has length {}, not 1",
                n.length()
            )));
        }
        let frame = Frame::from_normal(n);
        // SAFETY: both checked non-NULL, aligned, 3 floats; written through raw
        // pointers only, so aliasing with `normal` creates no conflicting reference.
        unsafe {
            core::ptr::copy_nonoverlapping(frame.tangent.to_array().as_ptr(), t, 3);
            core::ptr::copy_nonoverlapping(frame.bitangent.to_array().as_ptr(), b, 3);
        }
        Ok(())
    });
}
