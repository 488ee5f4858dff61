//! [`EmbreeError`]: what Embree reported through the device's error callback, or input the wrapper refused.

use std::fmt;

use super::ffi::*;

/// The kind of an [`EmbreeError`]: Embree's `RTCError` codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorCode {
    /// `RTC_ERROR_UNKNOWN` (also used for codes this wrapper does not know).
    Unknown,
    /// `RTC_ERROR_INVALID_ARGUMENT`; also used by this wrapper for input it rejects before calling Embree.
    InvalidArgument,
    /// `RTC_ERROR_INVALID_OPERATION`.
    InvalidOperation,
    /// `RTC_ERROR_OUT_OF_MEMORY`.
    OutOfMemory,
    /// `RTC_ERROR_UNSUPPORTED_CPU`.
    UnsupportedCpu,
    /// `RTC_ERROR_CANCELLED`.
    Cancelled,
}

impl ErrorCode {
    pub(super) fn from_raw(code: RTCError) -> Self {
        match code {
            RTC_ERROR_INVALID_ARGUMENT => ErrorCode::InvalidArgument,
            RTC_ERROR_INVALID_OPERATION => ErrorCode::InvalidOperation,
            RTC_ERROR_OUT_OF_MEMORY => ErrorCode::OutOfMemory,
            RTC_ERROR_UNSUPPORTED_CPU => ErrorCode::UnsupportedCpu,
            RTC_ERROR_CANCELLED => ErrorCode::Cancelled,
            _ => ErrorCode::Unknown,
        }
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ErrorCode::Unknown => "unknown error",
            ErrorCode::InvalidArgument => "invalid argument",
            ErrorCode::InvalidOperation => "invalid operation",
            ErrorCode::OutOfMemory => "out of memory",
            ErrorCode::UnsupportedCpu => "unsupported cpu",
            ErrorCode::Cancelled => "cancelled",
        })
    }
}

/// An error reported by Embree (through the device's error callback), or input this wrapper refused to pass on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("embree: {code}: {message}")]
pub struct EmbreeError {
    /// What kind of error.
    pub code: ErrorCode,
    /// What failed, then what Embree said.
    pub message: String,
}

impl EmbreeError {
    pub(super) fn invalid_argument(message: impl Into<String>) -> Self {
        EmbreeError {
            code: ErrorCode::InvalidArgument,
            message: message.into(),
        }
    }
}
