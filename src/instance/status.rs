//! What a call of either version returns: its status, and why it failed, with the log
//! category the message goes to. Below the rest of the instance, which all use it.

use crate::plant::AccessError;

/// A function's status, with the numbers FMI 2.0 and 3.0 both give it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
}

/// Log categories, by their position in [`crate::description::LOG_CATEGORIES`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Category {
    Warning = 0,
    Discard = 1,
    Error = 2,
    Fatal = 3,
    Calls = 4,
    Solver = 5,
}

/// Why a call failed: the status to return and the message to log.
#[derive(Debug)]
pub struct Failure {
    pub status: Status,
    pub message: String,
}

impl Failure {
    pub fn error(message: impl Into<String>) -> Self {
        Self {
            status: Status::Error,
            message: message.into(),
        }
    }

    pub fn discard(message: impl Into<String>) -> Self {
        Self {
            status: Status::Discard,
            message: message.into(),
        }
    }
}

impl From<AccessError> for Failure {
    fn from(error: AccessError) -> Self {
        Failure::error(error.to_string())
    }
}

pub type Outcome = Result<(), Failure>;
