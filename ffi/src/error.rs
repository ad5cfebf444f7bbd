//! Error detail: the thread-local last error message and the optional process-wide
//! error callback.
//!
//! Every fallible export clears this thread's message on entry and sets it on
//! failure, so after any call the message describes that call ("" on success).

use core::ffi::{c_char, c_void};
use std::cell::RefCell;
use std::ffi::CString;
use std::sync::RwLock;

use crate::result::*;

/// A failure inside an export: a result code and a message naming the argument.
#[derive(Debug)]
pub(crate) struct Error {
    pub(crate) code: antumbra_result,
    pub(crate) message: String,
}

impl Error {
    pub(crate) fn new(code: antumbra_result, message: impl Into<String>) -> Self {
        debug_assert_ne!(code, ANTUMBRA_RESULT_OK);
        Error {
            code,
            message: message.into(),
        }
    }

    pub(crate) fn null(argument: impl core::fmt::Display) -> Self {
        Error::new(ANTUMBRA_RESULT_NULL_ARGUMENT, format!("{argument} is NULL"))
    }

    pub(crate) fn invalid(message: impl Into<String>) -> Self {
        Error::new(ANTUMBRA_RESULT_INVALID_ARGUMENT, message)
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// Optional function called on every failed call, from the failing thread, with the
/// result code, the message (valid only during the call) and the `user_data` given
/// to `antumbra_set_error_callback`. It must return normally (no longjmp, no C++
/// exception) and must not call back into Antumbra.
pub type antumbra_error_callback = Option<
    unsafe extern "C" fn(code: antumbra_result, message: *const c_char, user_data: *mut c_void),
>;

struct Callback {
    function: antumbra_error_callback,
    user_data: usize,
}

static CALLBACK: RwLock<Callback> = RwLock::new(Callback {
    function: None,
    user_data: 0,
});

pub(crate) fn clear_last_error() {
    // `try_with`: during thread teardown the slot may be gone; there is nothing to
    // clear then, and `with` would abort the process.
    let _ = LAST_ERROR.try_with(|last| {
        if let Ok(mut last) = last.try_borrow_mut()
            && !last.as_bytes().is_empty()
        {
            *last = CString::default();
        }
    });
}

/// Records `error` as this thread's last error, calls the callback, and returns the
/// code for the export to return.
pub(crate) fn record(function: &str, error: Error) -> antumbra_result {
    let text = format!("{function}: {}", error.message).replace('\0', "\\0");
    let message = CString::new(text).unwrap_or_default();
    let callback = CALLBACK.read().map(|c| (c.function, c.user_data));
    if let Ok((Some(function), user_data)) = callback {
        // SAFETY: the caller registered this function and promised it is callable
        // with these arguments from any thread; `message` outlives the call.
        unsafe { function(error.code, message.as_ptr(), user_data as *mut c_void) };
    }
    let _ = LAST_ERROR.try_with(|last| {
        if let Ok(mut last) = last.try_borrow_mut() {
            *last = message;
        }
    });
    error.code
}

/// The message of the last call on this thread: "" when it succeeded, otherwise
/// `"<function>: <what was wrong, naming the argument>"`.
///
/// Returns a NUL-terminated UTF-8 string owned by the library, never NULL, valid
/// until the next Antumbra call on the same thread; copy it to keep it (or use
/// `antumbra_last_error_message_copy`).
/// Thread safety: each thread has its own message.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_last_error_message() -> *const c_char {
    LAST_ERROR
        .try_with(|last| last.try_borrow().map_or(c"".as_ptr(), |m| m.as_ptr()))
        .unwrap_or(c"".as_ptr())
}

/// Copies this thread's last error message, NUL included, into `buffer`.
///
/// @param buffer destination of `capacity` bytes; may be NULL when `capacity` is 0.
/// @param capacity size of `buffer` in bytes.
/// @param required_size if not NULL, receives the bytes needed including the NUL,
///        on success and on ANTUMBRA_RESULT_BUFFER_TOO_SMALL (only then).
/// @return ANTUMBRA_RESULT_OK; ANTUMBRA_RESULT_NULL_ARGUMENT when `buffer` is NULL
///         and `capacity` > 0; ANTUMBRA_RESULT_INVALID_ARGUMENT when
///         `required_size` is misaligned; ANTUMBRA_RESULT_BUFFER_TOO_SMALL when
///         `capacity` is less than the size needed (nothing is written to `buffer`).
///
/// Unlike other calls this one does not replace the last error message with its
/// own outcome, so it can be called repeatedly (to size, then to copy).
/// Thread safety: reads only the calling thread's message.
///
/// # Safety
/// `buffer` must be NULL or valid for `capacity` bytes of writes.
#[must_use]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn antumbra_last_error_message_copy(
    buffer: *mut c_char,
    capacity: usize,
    required_size: *mut usize,
) -> antumbra_result {
    let copy = std::panic::catch_unwind(|| {
        LAST_ERROR.with(|last| {
            let last = last.borrow();
            let bytes = last.as_bytes_with_nul();
            if buffer.is_null() && capacity > 0 {
                return ANTUMBRA_RESULT_NULL_ARGUMENT;
            }
            if !required_size.is_null() && !required_size.is_aligned() {
                return ANTUMBRA_RESULT_INVALID_ARGUMENT;
            }
            let report_size = || {
                if !required_size.is_null() {
                    // SAFETY: non-NULL, aligned (checked), a `size_t*` by contract.
                    unsafe { required_size.write(bytes.len()) };
                }
            };
            if capacity < bytes.len() {
                report_size();
                return ANTUMBRA_RESULT_BUFFER_TOO_SMALL;
            }
            report_size();
            // SAFETY: `buffer` is valid for `capacity >= bytes.len()` bytes and
            // cannot overlap the library-owned message.
            unsafe {
                core::ptr::copy_nonoverlapping(bytes.as_ptr(), buffer.cast::<u8>(), bytes.len())
            };
            ANTUMBRA_RESULT_OK
        })
    });
    copy.unwrap_or(ANTUMBRA_RESULT_PANIC)
}

/// Installs (or, with NULL, removes) the process-wide error callback.
///
/// @param callback called on every failed call from then on, on the failing
///        thread, before the call returns; NULL removes it.
/// @param user_data passed back to `callback` untouched.
///
/// Thread safety: may be called from any thread; calls already in flight may
/// still report to the previous callback.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_set_error_callback(
    callback: antumbra_error_callback,
    user_data: *mut c_void,
) {
    let mut slot = match CALLBACK.write() {
        Ok(slot) => slot,
        // A poisoned lock only means a callback panicked; the data is plain.
        Err(poisoned) => poisoned.into_inner(),
    };
    *slot = Callback {
        function: callback,
        user_data: user_data as usize,
    };
}
