//! Error detail: the thread-local last error message and the optional process-wide
//! error callback (in the bare-metal build, one message for the program).
//!
//! Every fallible export clears this thread's message on entry and sets it on
//! failure, so after any call the message describes that call ("" on success).

use core::ffi::{c_char, c_void};

use crate::result::*;

/// The text of an error: a `String` in the hosted build; in the bare-metal build a
/// fixed buffer on the stack, so that reporting an error never allocates (and so
/// never fails for want of memory). Longer messages are cut at a character
/// boundary.
#[cfg(feature = "std")]
pub(crate) type Message = String;
/// The text of an error (see the hosted build's definition).
#[cfg(not(feature = "std"))]
pub(crate) type Message = FixedMessage;

/// `format!` into a [`Message`]: every message of the library is made with this.
macro_rules! message {
    ($($arguments:tt)*) => {
        $crate::error::make_message(format_args!($($arguments)*))
    };
}

/// What `message!` expands to.
#[cfg(feature = "std")]
pub(crate) fn make_message(arguments: core::fmt::Arguments<'_>) -> Message {
    alloc::fmt::format(arguments)
}

/// What `message!` expands to.
#[cfg(not(feature = "std"))]
pub(crate) fn make_message(arguments: core::fmt::Arguments<'_>) -> Message {
    FixedMessage::from_arguments(arguments)
}

/// Bytes of message text the bare-metal build keeps (the longest message the
/// library makes is about 200 bytes; anything longer is cut).
#[cfg(not(feature = "std"))]
const MESSAGE_CAPACITY: usize = 240;

/// A message of at most [`MESSAGE_CAPACITY`] bytes of UTF-8, held inline.
#[cfg(not(feature = "std"))]
#[derive(Clone)]
pub(crate) struct FixedMessage {
    bytes: [u8; MESSAGE_CAPACITY],
    len: usize,
}

#[cfg(not(feature = "std"))]
impl FixedMessage {
    pub(crate) const fn new() -> Self {
        FixedMessage {
            bytes: [0; MESSAGE_CAPACITY],
            len: 0,
        }
    }

    pub(crate) fn from_arguments(arguments: core::fmt::Arguments<'_>) -> Self {
        let mut message = FixedMessage::new();
        // Writing into a FixedMessage never fails: excess text is dropped.
        let _ = core::fmt::Write::write_fmt(&mut message, arguments);
        message
    }

    pub(crate) fn as_str(&self) -> &str {
        // Only whole characters are ever copied in (see `write_str`).
        core::str::from_utf8(&self.bytes[..self.len]).unwrap_or("")
    }
}

#[cfg(not(feature = "std"))]
impl core::fmt::Write for FixedMessage {
    fn write_str(&mut self, text: &str) -> core::fmt::Result {
        let room = MESSAGE_CAPACITY - self.len;
        let mut take = text.len().min(room);
        while !text.is_char_boundary(take) {
            take -= 1;
        }
        self.bytes[self.len..self.len + take].copy_from_slice(&text.as_bytes()[..take]);
        self.len += take;
        Ok(())
    }
}

#[cfg(not(feature = "std"))]
impl core::ops::Deref for FixedMessage {
    type Target = str;
    fn deref(&self) -> &str {
        self.as_str()
    }
}

#[cfg(not(feature = "std"))]
impl core::fmt::Display for FixedMessage {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(not(feature = "std"))]
impl core::fmt::Debug for FixedMessage {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Debug::fmt(self.as_str(), f)
    }
}

#[cfg(not(feature = "std"))]
impl From<&str> for FixedMessage {
    fn from(text: &str) -> Self {
        FixedMessage::from_arguments(format_args!("{text}"))
    }
}

/// A failure inside an export: a result code and a message naming the argument.
#[derive(Debug)]
pub(crate) struct Error {
    pub(crate) code: antumbra_result,
    pub(crate) message: Message,
}

impl Error {
    pub(crate) fn new(code: antumbra_result, message: impl Into<Message>) -> Self {
        debug_assert_ne!(code, ANTUMBRA_RESULT_OK);
        Error {
            code,
            message: message.into(),
        }
    }

    pub(crate) fn null(argument: impl core::fmt::Display) -> Self {
        Error::new(
            ANTUMBRA_RESULT_NULL_ARGUMENT,
            message!("{argument} is NULL"),
        )
    }

    pub(crate) fn invalid(message: impl Into<Message>) -> Self {
        Error::new(ANTUMBRA_RESULT_INVALID_ARGUMENT, message)
    }
}

/// Optional function called on every failed call, from the failing thread, with the
/// result code, the message (valid only during the call) and the `user_data` given
/// to `antumbra_set_error_callback`. It must return normally (no longjmp, no C++
/// exception) and must not call back into Antumbra.
pub type antumbra_error_callback = Option<
    unsafe extern "C" fn(code: antumbra_result, message: *const c_char, user_data: *mut c_void),
>;

#[cfg(feature = "std")]
pub(crate) use hosted::{clear_last_error, record};
#[cfg(feature = "std")]
use hosted::{last_message, set_callback, with_last_message};

#[cfg(not(feature = "std"))]
pub(crate) use bare_metal::{clear_last_error, record};
#[cfg(not(feature = "std"))]
use bare_metal::{last_message, set_callback, with_last_message};

/// Hosted: one message per thread, the callback behind a lock.
#[cfg(feature = "std")]
mod hosted {
    use core::ffi::{c_char, c_void};
    use std::cell::RefCell;
    use std::ffi::CString;
    use std::sync::RwLock;

    use super::{Error, antumbra_error_callback};
    use crate::result::antumbra_result;

    thread_local! {
        static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
    }

    struct Callback {
        function: antumbra_error_callback,
        user_data: usize,
    }

    static CALLBACK: RwLock<Callback> = RwLock::new(Callback {
        function: None,
        user_data: 0,
    });

    pub(crate) fn clear_last_error() {
        // `try_with`: during thread teardown the slot may be gone; there is nothing
        // to clear then, and `with` would abort the process.
        let _ = LAST_ERROR.try_with(|last| {
            if let Ok(mut last) = last.try_borrow_mut()
                && !last.as_bytes().is_empty()
            {
                *last = CString::default();
            }
        });
    }

    /// Records `error` as this thread's last error, calls the callback, and returns
    /// the code for the export to return.
    pub(crate) fn record(function: &str, error: Error) -> antumbra_result {
        let text = message!("{function}: {}", error.message).replace('\0', "\\0");
        let message = CString::new(text).unwrap_or_default();
        let callback = CALLBACK.read().map(|c| (c.function, c.user_data));
        if let Ok((Some(function), user_data)) = callback {
            // SAFETY: the caller registered this function and promised it is
            // callable with these arguments from any thread; `message` outlives
            // the call.
            unsafe { function(error.code, message.as_ptr(), user_data as *mut c_void) };
        }
        let _ = LAST_ERROR.try_with(|last| {
            if let Ok(mut last) = last.try_borrow_mut() {
                *last = message;
            }
        });
        error.code
    }

    pub(super) fn last_message() -> *const c_char {
        LAST_ERROR
            .try_with(|last| last.try_borrow().map_or(c"".as_ptr(), |m| m.as_ptr()))
            .unwrap_or(c"".as_ptr())
    }

    /// Runs `read` on the message's bytes, NUL included.
    pub(super) fn with_last_message<R>(read: impl FnOnce(&[u8]) -> R) -> Option<R> {
        std::panic::catch_unwind(core::panic::AssertUnwindSafe(|| {
            LAST_ERROR.with(|last| read(last.borrow().as_bytes_with_nul()))
        }))
        .ok()
    }

    pub(super) fn set_callback(function: antumbra_error_callback, user_data: *mut c_void) {
        let mut slot = match CALLBACK.write() {
            Ok(slot) => slot,
            // A poisoned lock only means a callback panicked; the data is plain.
            Err(poisoned) => poisoned.into_inner(),
        };
        *slot = Callback {
            function,
            user_data: user_data as usize,
        };
    }
}

/// Bare metal: no threads to keep apart, so one message and one callback for the
/// program, in static memory (the calls are documented as single-threaded there).
#[cfg(not(feature = "std"))]
mod bare_metal {
    use core::cell::UnsafeCell;
    use core::ffi::{c_char, c_void};

    use super::{Error, FixedMessage, MESSAGE_CAPACITY, antumbra_error_callback};
    use crate::result::antumbra_result;

    /// The message, NUL-terminated, and the callback.
    struct State {
        message: [u8; MESSAGE_CAPACITY + 1],
        callback: antumbra_error_callback,
        user_data: *mut c_void,
    }

    struct Program(UnsafeCell<State>);

    // SAFETY: the bare-metal build documents its error state as the program's
    // single-threaded state (calls from interrupt handlers or other cores must be
    // serialised by the application), so there is no concurrent access.
    unsafe impl Sync for Program {}

    static STATE: Program = Program(UnsafeCell::new(State {
        message: [0; MESSAGE_CAPACITY + 1],
        callback: None,
        user_data: core::ptr::null_mut(),
    }));

    fn state() -> *mut State {
        STATE.0.get()
    }

    pub(crate) fn clear_last_error() {
        // SAFETY: single-threaded by the build's contract (see `Program`).
        unsafe { (*state()).message[0] = 0 };
    }

    /// Records `error` as the program's last error, calls the callback, and returns
    /// the code for the export to return.
    pub(crate) fn record(function: &str, error: Error) -> antumbra_result {
        let mut text = FixedMessage::new();
        let _ =
            core::fmt::Write::write_fmt(&mut text, format_args!("{function}: {}", error.message));
        // SAFETY: single-threaded by the build's contract (see `Program`).
        let state = unsafe { &mut *state() };
        let bytes = text.as_str().as_bytes();
        let len = bytes.len().min(state.message.len() - 1);
        for (slot, &byte) in state.message.iter_mut().zip(&bytes[..len]) {
            // An interior NUL would cut the C string short; show it instead.
            *slot = if byte == 0 { b'?' } else { byte };
        }
        state.message[len] = 0;
        if let Some(function) = state.callback {
            // SAFETY: the caller registered this function and promised it is
            // callable with these arguments; the message outlives the call.
            unsafe { function(error.code, state.message.as_ptr().cast(), state.user_data) };
        }
        error.code
    }

    pub(super) fn last_message() -> *const c_char {
        // SAFETY: only the address is taken.
        unsafe { (*state()).message.as_ptr().cast() }
    }

    /// Runs `read` on the message's bytes, NUL included.
    pub(super) fn with_last_message<R>(read: impl FnOnce(&[u8]) -> R) -> Option<R> {
        // SAFETY: single-threaded by the build's contract (see `Program`).
        let message = unsafe { &(*state()).message };
        let len = message.iter().position(|&b| b == 0).unwrap_or(0);
        Some(read(&message[..=len]))
    }

    pub(super) fn set_callback(function: antumbra_error_callback, user_data: *mut c_void) {
        // SAFETY: single-threaded by the build's contract (see `Program`).
        let state = unsafe { &mut *state() };
        state.callback = function;
        state.user_data = user_data;
    }
}

/// The message of the last call on this thread: "" when it succeeded, otherwise
/// `"<function>: <what was wrong, naming the argument>"`.
///
/// Returns a NUL-terminated UTF-8 string owned by the library, never NULL, valid
/// until the next Antumbra call on the same thread; copy it to keep it (or use
/// `antumbra_last_error_message_copy`).
/// Thread safety: each thread has its own message. Without ANTUMBRA_HAS_STD (the
/// bare-metal build) there is one message for the program, kept in static memory
/// and cut at 240 bytes; call the library from one thread of execution there.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_last_error_message() -> *const c_char {
    last_message()
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
    let copy = with_last_message(|bytes| {
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
        // SAFETY: `buffer` is valid for `capacity >= bytes.len()` bytes and cannot
        // overlap the library-owned message.
        unsafe { core::ptr::copy_nonoverlapping(bytes.as_ptr(), buffer.cast::<u8>(), bytes.len()) };
        ANTUMBRA_RESULT_OK
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
/// still report to the previous callback. Without ANTUMBRA_HAS_STD, call it while
/// no other Antumbra call runs.
#[unsafe(no_mangle)]
pub extern "C" fn antumbra_set_error_callback(
    callback: antumbra_error_callback,
    user_data: *mut c_void,
) {
    set_callback(callback, user_data);
}
