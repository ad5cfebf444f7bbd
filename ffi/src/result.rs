//! Result codes. Values are explicit and append-only: a code, once published,
//! never changes meaning.

use core::ffi::c_char;

/// The result of every fallible Antumbra call. `ANTUMBRA_RESULT_OK` (0) is
/// success; every other value is an error, detailed by
/// `antumbra_last_error_message()`.
pub type antumbra_result = i32;

/// Success.
pub const ANTUMBRA_RESULT_OK: antumbra_result = 0;
/// A required pointer argument is NULL (or NULL with a non-zero count).
pub const ANTUMBRA_RESULT_NULL_ARGUMENT: antumbra_result = 1;
/// An argument is out of its documented domain (zero count, small stride,
/// misaligned pointer, unknown mode, zero direction, ...).
pub const ANTUMBRA_RESULT_INVALID_ARGUMENT: antumbra_result = 2;
/// A coordinate or parameter is NaN or infinite where a finite value is needed.
pub const ANTUMBRA_RESULT_NON_FINITE: antumbra_result = 3;
/// An index refers past the end of its array (e.g. a vertex index >= vertex_count).
pub const ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE: antumbra_result = 4;
/// An output buffer is too small; the required size is reported through an
/// out-parameter.
pub const ANTUMBRA_RESULT_BUFFER_TOO_SMALL: antumbra_result = 5;
/// Memory for a structure could not be reserved.
pub const ANTUMBRA_RESULT_OUT_OF_MEMORY: antumbra_result = 6;
/// The capability was compiled out of this build of the library.
pub const ANTUMBRA_RESULT_UNSUPPORTED: antumbra_result = 7;
/// The library panicked: an internal bug. The handle involved is poisoned.
pub const ANTUMBRA_RESULT_PANIC: antumbra_result = 8;
/// The handle was poisoned by an earlier panic; destroy it and build another.
pub const ANTUMBRA_RESULT_POISONED: antumbra_result = 9;
/// Bytes given as a file (a bake file) are not valid: truncated, corrupted
/// (checksum mismatch), of an unsupported version, or holding out-of-range fields
/// or values. The message names the field.
pub const ANTUMBRA_RESULT_INVALID_DATA: antumbra_result = 10;

/// A static, NUL-terminated name for a result code, e.g.
/// `"ANTUMBRA_RESULT_NULL_ARGUMENT"`; `"ANTUMBRA_RESULT_UNKNOWN"` for values this
/// version does not define. Never NULL; the string must not be freed.
/// Thread safety: safe from any thread.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_result_str(code: antumbra_result) -> *const c_char {
    result_name(code).as_ptr()
}

pub(crate) fn result_name(code: antumbra_result) -> &'static core::ffi::CStr {
    match code {
        ANTUMBRA_RESULT_OK => c"ANTUMBRA_RESULT_OK",
        ANTUMBRA_RESULT_NULL_ARGUMENT => c"ANTUMBRA_RESULT_NULL_ARGUMENT",
        ANTUMBRA_RESULT_INVALID_ARGUMENT => c"ANTUMBRA_RESULT_INVALID_ARGUMENT",
        ANTUMBRA_RESULT_NON_FINITE => c"ANTUMBRA_RESULT_NON_FINITE",
        ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE => c"ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE",
        ANTUMBRA_RESULT_BUFFER_TOO_SMALL => c"ANTUMBRA_RESULT_BUFFER_TOO_SMALL",
        ANTUMBRA_RESULT_OUT_OF_MEMORY => c"ANTUMBRA_RESULT_OUT_OF_MEMORY",
        ANTUMBRA_RESULT_UNSUPPORTED => c"ANTUMBRA_RESULT_UNSUPPORTED",
        ANTUMBRA_RESULT_PANIC => c"ANTUMBRA_RESULT_PANIC",
        ANTUMBRA_RESULT_POISONED => c"ANTUMBRA_RESULT_POISONED",
        ANTUMBRA_RESULT_INVALID_DATA => c"ANTUMBRA_RESULT_INVALID_DATA",
        _ => c"ANTUMBRA_RESULT_UNKNOWN",
    }
}
