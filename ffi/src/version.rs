//! Library version, for checking the header against the linked library.

use core::ffi::c_char;

use crate::crate_version;

/// The version of the linked library, packed as `major << 16 | minor << 8 | patch`;
/// compare with `ANTUMBRA_VERSION` from the header to detect a mismatch.
/// Thread safety: safe from any thread.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_version() -> u32 {
    crate_version::PACKED
}

/// The version of the linked library as a static string, e.g. `"0.1.0"`.
/// Never NULL; must not be freed. Thread safety: safe from any thread.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_version_string() -> *const c_char {
    const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "\0");
    VERSION.as_ptr().cast()
}
