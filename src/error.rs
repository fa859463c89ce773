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

/// A vector of `len` copies of `value`, or an error naming `what` if the memory cannot be had:
/// for buffers whose size a user chooses (`-r W H`), where `vec!` would abort the process.
pub fn try_filled_vec<T: Clone>(len: usize, value: T, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    let bytes = len.saturating_mul(std::mem::size_of::<T>());
    v.try_reserve_exact(len).map_err(|_| {
        Error::new(format!("out of memory: cannot allocate {} for {what}", human_bytes(bytes)))
    })?;
    v.resize(len, value);
    Ok(v)
}

/// `1717986918` -> "1.6 GiB".
fn human_bytes(bytes: usize) -> String {
    let units = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < units.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{v:.1} {}", units[unit])
    }
}

/// `bail!("...")` returns early with an [`Error`] built by `format!`.
#[macro_export]
macro_rules! bail {
    ($($arg:tt)*) => { return Err($crate::Error::new(format!($($arg)*))) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_impossible_allocation_is_an_error_naming_it() {
        let e = try_filled_vec(usize::MAX / 2, 0u64, "the test image").unwrap_err();
        assert!(e.message().starts_with("out of memory: cannot allocate"), "{e}");
        assert!(e.message().ends_with("for the test image"), "{e}");
        assert_eq!(try_filled_vec(3, 7u8, "x").unwrap(), vec![7, 7, 7]);
        assert_eq!(human_bytes(1717986918), "1.6 GiB");
        assert_eq!(human_bytes(10), "10 bytes");
    }
}
