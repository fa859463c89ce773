//! One error type for the whole crate: a single human-readable line.
//!
//! Every failure a user can cause (bad file, bad flag) ends up here and is printed by the CLI as
//! `error: <message>` with a non-zero exit. The message names the file and the problem.

use std::fmt;

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Error(String);

pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    pub fn new(msg: impl Into<String>) -> Self {
        // Keep it to one line whatever the source text held.
        Error(msg.into().replace('\n', " "))
    }

    /// Prefix the message with context such as a file name: `"scene.dae: <msg>"`.
    pub fn context(self, ctx: impl fmt::Display) -> Self {
        Error(format!("{ctx}: {}", self.0))
    }

    pub fn message(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

/// `bail!("...")` returns early with an [`Error`] built by `format!`.
#[macro_export]
macro_rules! bail {
    ($($arg:tt)*) => { return Err($crate::Error::new(format!($($arg)*))) };
}
