//! `weft-capi`: a C ABI over the Weft graph engine, for host applications (Blender, Maya,
//! Houdini, a studio's own tools) that load a graph file, feed it their scene's data, and pull
//! simulated results back, frame by frame.
//!
//! The header, `include/weft.h`, is generated from this crate by cbindgen and checked in; a
//! test regenerates it and fails when the two differ. `tests/c/weft_example.c` uses every
//! call and is compiled with `-Wall -Wextra -Werror` and run by the tests.
//!
//! **Conventions** (the rules every entry point keeps):
//! - Handles are opaque: [`WeftGraph`], [`WeftValue`] (a pulled result), [`WeftError`] and
//!   [`WeftInterrupt`], each freed by its own `*_free` (which accepts NULL).
//! - A call that can fail returns a [`WeftStatus`] (or NULL for a handle) and, when its last
//!   argument `error` is not NULL, stores a new [`WeftError`] there on failure (the caller
//!   frees it); on success `*error` is left untouched.
//! - No Rust type and no panic crosses the boundary: every entry point runs behind
//!   `catch_unwind`; a panic becomes `WEFT_PANIC` with its message, and the graph it happened
//!   in refuses further work (`WEFT_PANIC` again) rather than run in a half-updated state.
//! - Strings in are NUL-terminated UTF-8; NULL or invalid UTF-8 is `WEFT_INVALID_ARGUMENT`.
//!   Strings out are either owned by the graph (`const char *`, valid until the graph is
//!   freed: node ids, types, port and parameter names, which never change after loading) or
//!   copied into a caller's buffer in the manner of `snprintf`: the call returns the string's
//!   length in bytes without the NUL, writes at most `capacity − 1` bytes and a NUL, so a
//!   call with `capacity` 0 asks the size.
//! - Arrays out are copied into caller buffers: the call stores the number of elements
//!   needed in `*len`; with a NULL buffer it only asks the size, and with a buffer smaller
//!   than that it writes nothing and returns `WEFT_BUFFER_TOO_SMALL`.
//! - Geometry is f64 metres, positions as x, y, z triples; indices are u32.
//! - A graph handle is not thread-safe (use it from one thread at a time); a
//!   [`WeftInterrupt`] may be set from any thread to stop a running pull.
#![warn(missing_docs)]
#![allow(clippy::missing_safety_doc)] // each function's doc states its pointer contract

mod graph;
mod value;

pub use graph::*;
pub use value::*;

use std::ffi::{CStr, CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

/// The ABI version this library implements. A host compares `weft_abi_version()` with the
/// `WEFT_ABI_VERSION` of the header it was compiled with and refuses to run on a mismatch;
/// the number changes whenever a signature or a convention changes.
pub const WEFT_ABI_VERSION: u32 = 1;

/// `frame` argument of the feed calls: the value holds for every frame.
pub const WEFT_ALL_FRAMES: i64 = i64::MIN;

/// What a call did.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeftStatus {
    /// Success.
    WeftOk = 0,
    /// A NULL pointer, a string that is not UTF-8, or an argument out of its range.
    WeftInvalidArgument = 1,
    /// The graph file could not be loaded (the error lists every problem found).
    WeftLoadFailed = 2,
    /// No such node, port, parameter, output or element.
    WeftNotFound = 3,
    /// The graph refused a value: a parameter out of its range, data of the wrong type or
    /// shape, a non-finite number.
    WeftRejected = 4,
    /// Evaluating the graph failed (the error names the node and frame).
    WeftEvalFailed = 5,
    /// A pull was stopped through a [`WeftInterrupt`].
    WeftInterrupted = 6,
    /// The caller's buffer is smaller than `*len` elements.
    WeftBufferTooSmall = 7,
    /// An internal error (a bug in Weft); the graph it happened in refuses further work.
    WeftPanic = 8,
}

/// One problem of an error: a graph file's diagnostics each name their node, field and line.
#[derive(Clone, Debug, Default)]
struct Problem {
    node: Option<CString>,
    field: Option<CString>,
    line: i64,
    column: i64,
    message: CString,
}

/// An error: its status, a message, and its problems (several for a graph file that failed
/// to load, one otherwise).
pub struct WeftError {
    status: WeftStatus,
    message: CString,
    problems: Vec<Problem>,
}

/// A failure inside the library, before it becomes a [`WeftError`].
pub(crate) struct Failure {
    status: WeftStatus,
    message: String,
    problems: Vec<Problem>,
}

/// A C string from Rust text: interior NULs (never expected) become U+FFFD.
pub(crate) fn c_string(s: &str) -> CString {
    CString::new(s.replace('\0', "\u{fffd}")).expect("NULs replaced")
}

impl Failure {
    pub(crate) fn new(status: WeftStatus, message: impl Into<String>) -> Self {
        Failure {
            status,
            message: message.into(),
            problems: Vec::new(),
        }
    }

    /// A failure carrying graph diagnostics (node, field, line) as its problems.
    pub(crate) fn with_diagnostics<'d>(
        status: WeftStatus,
        message: impl Into<String>,
        diagnostics: impl IntoIterator<Item = &'d weft_graph::Diagnostic>,
    ) -> Self {
        let problems = diagnostics
            .into_iter()
            .map(|d| Problem {
                node: d.node.as_deref().map(c_string),
                field: d.field.as_deref().map(c_string),
                line: d.line.map_or(0, |l| l as i64),
                column: d.column.map_or(0, |c| c as i64),
                message: c_string(&match &d.help {
                    Some(h) => format!("{} ({h})", d.message),
                    None => d.message.clone(),
                }),
            })
            .collect();
        Failure {
            status,
            message: message.into(),
            problems,
        }
    }

    fn into_error(self) -> Box<WeftError> {
        let mut problems = self.problems;
        if problems.is_empty() {
            problems.push(Problem {
                message: c_string(&self.message),
                ..Problem::default()
            });
        }
        Box::new(WeftError {
            status: self.status,
            message: c_string(&self.message),
            problems,
        })
    }
}

/// The message of a caught panic.
fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    let what = p
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "an internal error".into());
    format!("internal error in Weft (please report it): {what}")
}

/// Runs `f` behind `catch_unwind`; on a failure (or panic) stores it in `*error` when
/// `error` is not NULL and gives its status.
fn run<T>(
    error: *mut *mut WeftError,
    f: impl FnOnce() -> Result<T, Failure>,
) -> Result<T, WeftStatus> {
    let failure = match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => return Ok(v),
        Ok(Err(e)) => e,
        Err(p) => Failure::new(WeftStatus::WeftPanic, panic_message(&*p)),
    };
    let status = failure.status;
    if !error.is_null() {
        // SAFETY: the caller passes NULL or a valid pointer to a `WeftError *`.
        unsafe { *error = Box::into_raw(failure.into_error()) };
    }
    Err(status)
}

/// [`run`] for calls that return a value or handle: `fail` on a failure.
pub(crate) fn guard<T>(
    error: *mut *mut WeftError,
    fail: T,
    f: impl FnOnce() -> Result<T, Failure>,
) -> T {
    run(error, f).unwrap_or(fail)
}

/// [`run`] for calls that return a status: the failure's status on a failure.
pub(crate) fn status(
    error: *mut *mut WeftError,
    f: impl FnOnce() -> Result<WeftStatus, Failure>,
) -> WeftStatus {
    run(error, f).unwrap_or_else(|s| s)
}

/// Runs `f` behind `catch_unwind` for calls that cannot report an error: a panic gives
/// `fail`.
pub(crate) fn quiet<T>(fail: T, f: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(fail)
}

/// A string argument: NULL or invalid UTF-8 is `WEFT_INVALID_ARGUMENT` naming `what`.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string that outlives the call.
pub(crate) unsafe fn str_arg<'a>(p: *const c_char, what: &str) -> Result<&'a str, Failure> {
    if p.is_null() {
        return Err(Failure::new(
            WeftStatus::WeftInvalidArgument,
            format!("{what} is NULL"),
        ));
    }
    // SAFETY: non-NULL and NUL-terminated by the caller's contract.
    unsafe { CStr::from_ptr(p) }.to_str().map_err(|_| {
        Failure::new(
            WeftStatus::WeftInvalidArgument,
            format!("{what} is not UTF-8"),
        )
    })
}

/// Copies `s` into `buf` as `snprintf` would; its length in bytes (without the NUL).
///
/// # Safety
/// `buf` is NULL or writable for `capacity` bytes.
pub(crate) unsafe fn write_str(s: &CStr, buf: *mut c_char, capacity: usize) -> usize {
    let bytes = s.to_bytes();
    if !buf.is_null() && capacity > 0 {
        let n = bytes.len().min(capacity - 1);
        // SAFETY: `buf` holds `capacity` > n bytes; the regions cannot overlap (ours is owned).
        unsafe {
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), buf.cast::<u8>(), n);
            *buf.add(n) = 0;
        }
    }
    bytes.len()
}

/// Copies `src` into `buf` (see the crate doc's array convention).
///
/// # Safety
/// `buf` is NULL or writable for `capacity` elements; `len` is NULL or writable.
pub(crate) unsafe fn write_slice<T: Copy>(
    src: &[T],
    buf: *mut T,
    capacity: usize,
    len: *mut usize,
) -> Result<WeftStatus, Failure> {
    if !len.is_null() {
        // SAFETY: non-NULL by the check, writable by contract.
        unsafe { *len = src.len() };
    }
    if buf.is_null() {
        return Ok(WeftStatus::WeftOk);
    }
    if capacity < src.len() {
        return Err(Failure::new(
            WeftStatus::WeftBufferTooSmall,
            format!(
                "the buffer holds {capacity} elements; {} are needed",
                src.len()
            ),
        ));
    }
    // SAFETY: `buf` holds at least `src.len()` elements; ours is a separate allocation.
    unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), buf, src.len()) };
    Ok(WeftStatus::WeftOk)
}

/// The ABI version of this library (see [`WEFT_ABI_VERSION`]).
#[unsafe(no_mangle)]
pub extern "C" fn weft_abi_version() -> u32 {
    WEFT_ABI_VERSION
}

/// Weft's version as a NUL-terminated string owned by the library (never freed).
#[unsafe(no_mangle)]
pub extern "C" fn weft_version() -> *const c_char {
    static VERSION: &CStr =
        match CStr::from_bytes_with_nul(concat!(env!("CARGO_PKG_VERSION"), "\0").as_bytes()) {
            Ok(v) => v,
            Err(_) => c"unknown",
        };
    VERSION.as_ptr()
}

/// The status of `error` (`WEFT_INVALID_ARGUMENT` for NULL).
///
/// # Safety
/// `error` is NULL or a live error.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_error_status(error: *const WeftError) -> WeftStatus {
    // SAFETY: NULL or live, by contract.
    match unsafe { error.as_ref() } {
        Some(e) => e.status,
        None => WeftStatus::WeftInvalidArgument,
    }
}

/// Copies the error's message into `buf` (snprintf convention; see the crate doc); its
/// length. For a graph file that failed to load, the message summarizes and each problem
/// has its own message, node, field and line.
///
/// # Safety
/// `error` is NULL or a live error; `buf` is NULL or writable for `capacity` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_error_message(
    error: *const WeftError,
    buf: *mut c_char,
    capacity: usize,
) -> usize {
    quiet(0, || {
        // SAFETY: NULL or live, by contract.
        let Some(e) = (unsafe { error.as_ref() }) else {
            return 0;
        };
        // SAFETY: buffer contract passed through.
        unsafe { write_str(&e.message, buf, capacity) }
    })
}

/// The number of problems the error holds (at least 1 for a live error).
///
/// # Safety
/// `error` is NULL or a live error.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_error_problem_count(error: *const WeftError) -> usize {
    // SAFETY: NULL or live, by contract.
    unsafe { error.as_ref() }.map_or(0, |e| e.problems.len())
}

/// Which text of a problem [`weft_error_problem_text`] copies.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeftProblemText {
    /// What is wrong (with a hint when there is one).
    WeftProblemMessage = 0,
    /// The node id ("" when the problem is not about one node).
    WeftProblemNode = 1,
    /// The port or parameter, as `param 'name'` or `input 'name'` ("" when none).
    WeftProblemField = 2,
}

/// Copies a text of problem `index` (`which`: a [`WeftProblemText`]) into `buf` (snprintf
/// convention); its length, 0 when `index` or `which` is out of range or the problem has no
/// such text.
///
/// # Safety
/// `error` is NULL or a live error; `buf` is NULL or writable for `capacity` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_error_problem_text(
    error: *const WeftError,
    index: usize,
    which: u32,
    buf: *mut c_char,
    capacity: usize,
) -> usize {
    quiet(0, || {
        // SAFETY: NULL or live, by contract.
        let Some(p) = (unsafe { error.as_ref() }).and_then(|e| e.problems.get(index)) else {
            return 0;
        };
        let empty = CString::default();
        // An integer, not the enum: C may pass any value (an invalid Rust enum is UB).
        let text = match which {
            w if w == WeftProblemText::WeftProblemMessage as u32 => &p.message,
            w if w == WeftProblemText::WeftProblemNode as u32 => p.node.as_ref().unwrap_or(&empty),
            w if w == WeftProblemText::WeftProblemField as u32 => {
                p.field.as_ref().unwrap_or(&empty)
            }
            _ => return 0,
        };
        // SAFETY: buffer contract passed through.
        unsafe { write_str(text, buf, capacity) }
    })
}

/// The line (1-based) in the graph file of problem `index`, 0 when unknown or out of range;
/// its column in `*column` when `column` is not NULL (0 when unknown).
///
/// # Safety
/// `error` is NULL or a live error; `column` is NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_error_problem_line(
    error: *const WeftError,
    index: usize,
    column: *mut i64,
) -> i64 {
    // SAFETY: NULL or live, by contract.
    let p = unsafe { error.as_ref() }.and_then(|e| e.problems.get(index));
    if !column.is_null() {
        // SAFETY: non-NULL, writable by contract.
        unsafe { *column = p.map_or(0, |p| p.column) };
    }
    p.map_or(0, |p| p.line)
}

/// Frees an error (NULL is ignored).
///
/// # Safety
/// `error` is NULL or an error from this library not yet freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn weft_error_free(error: *mut WeftError) {
    if !error.is_null() {
        // SAFETY: made by `Box::into_raw` in `guard`, freed once by contract.
        drop(unsafe { Box::from_raw(error) });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A panic inside an entry point becomes `WEFT_PANIC` with its message; nothing unwinds
    /// into the caller.
    #[test]
    fn a_panic_becomes_a_status_and_a_message() {
        let mut err: *mut WeftError = std::ptr::null_mut();
        let s = status(&mut err, || panic!("boom"));
        assert_eq!(s, WeftStatus::WeftPanic);
        let mut buf = [0 as c_char; 128];
        // SAFETY: `err` was just made; `buf` holds 128 bytes.
        let n = unsafe { weft_error_message(err, buf.as_mut_ptr(), buf.len()) };
        // SAFETY: NUL-terminated by `write_str`.
        let text = unsafe { CStr::from_ptr(buf.as_ptr()) }.to_str().unwrap();
        assert!(n > 0 && text.contains("boom"), "{text}");
        // SAFETY: freed once.
        unsafe { weft_error_free(err) };
    }

    /// Strings out follow snprintf: the full length back, a NUL-terminated prefix written.
    #[test]
    fn strings_out_truncate_like_snprintf() {
        let s = c_string("hello");
        let mut buf = [1 as c_char; 4];
        // SAFETY: `buf` holds 4 bytes.
        assert_eq!(unsafe { write_str(&s, buf.as_mut_ptr(), 4) }, 5);
        assert_eq!(buf.map(|c| c as u8), *b"hel\0");
        // SAFETY: NULL with capacity 0 is a size query.
        assert_eq!(unsafe { write_str(&s, std::ptr::null_mut(), 0) }, 5);
    }
}
