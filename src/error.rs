//! One error type for the whole crate: an enum a caller can match on, whose `Display` is a
//! single human-readable line.
//!
//! Every failure a user can cause (bad file, bad flag) ends up here and is printed by the CLI as
//! `error: <message>` with exit code 2. The message names the file and the problem.

use std::fmt;
use std::path::{Path, PathBuf};

/// What went wrong. Match on the variant to react (a missing file, a scene to fix, a bad
/// argument); print it (`Display`) for the one-line message.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written; `message` is what failed and the system's reason
    /// (`cannot read: No such file or directory`).
    Io {
        /// The file.
        path: PathBuf,
        /// What failed and why, one line.
        message: String,
    },
    /// A scene file was read but is not a scene we can render (malformed XML, not COLLADA, a
    /// dangling reference, a non-finite number, too many triangles...). `path` is `None` for
    /// scene text parsed without a file.
    Scene {
        /// The scene file, if there is one.
        path: Option<PathBuf>,
        /// What is wrong with it, one line.
        message: String,
    },
    /// Anything else a caller passed in: an out-of-range option, an image of the wrong size, a
    /// BVH path off the tree, a failed print.
    Invalid(String),
}

/// The crate's result type: every fallible function fails with an [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An [`Error::Invalid`] with `msg` kept to one line.
    pub fn new(msg: impl Into<String>) -> Self {
        Error::Invalid(one_line(msg))
    }

    /// An [`Error::Io`]: `action` on `path` failed (`"cannot read"`, and the reason).
    pub fn io(path: &Path, action: &str, reason: impl fmt::Display) -> Self {
        Error::Io { path: path.to_path_buf(), message: one_line(format!("{action}: {reason}")) }
    }

    /// This error as a problem with the scene at `path` (`None`: scene text without a file);
    /// an I/O error stays one.
    pub fn in_scene(self, path: Option<&Path>) -> Self {
        let path = path.map(Path::to_path_buf);
        match self {
            Error::Invalid(message) => Error::Scene { path, message },
            Error::Scene { path: None, message } => Error::Scene { path, message },
            other => other,
        }
    }

    /// Prefix the message with context such as a flag: `"--csv: <msg>"`. The variant is kept.
    pub fn context(self, ctx: impl fmt::Display) -> Self {
        match self {
            Error::Invalid(m) => Error::Invalid(format!("{ctx}: {m}")),
            Error::Io { path, message } => Error::Io { path, message: format!("{ctx}: {message}") },
            Error::Scene { path, message } => {
                Error::Scene { path, message: format!("{ctx}: {message}") }
            }
        }
    }

    /// The one-line message (what `Display` prints).
    pub fn message(&self) -> String {
        self.to_string()
    }
}

fn one_line(msg: impl Into<String>) -> String {
    // Keep it to one line whatever the source text held.
    msg.into().replace('\n', " ")
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io { path, message } => write!(f, "{}: {message}", path.display()),
            Error::Scene { path: Some(path), message } => {
                write!(f, "{}: {message}", path.display())
            }
            Error::Scene { path: None, message } | Error::Invalid(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for Error {}

/// A vector of `len` copies of `value`, or an error naming `what` if the memory cannot be had:
/// for buffers whose size a user chooses (`-r W H`), where `vec!` would abort the process.
pub(crate) fn try_filled_vec<T: Clone>(len: usize, value: T, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    let bytes = len.saturating_mul(std::mem::size_of::<T>());
    v.try_reserve_exact(len).map_err(|_| {
        Error::new(format!("out of memory: cannot allocate {} for {what}", human_bytes(bytes)))
    })?;
    v.resize(len, value);
    Ok(v)
}

/// The bytes of the file at `path`, refusing it (with `too_large()`) once it holds more than
/// `max_bytes`: a regular file is judged by its size before reading, anything else (a pipe, a
/// device such as `/dev/zero`) is read only up to the limit, and memory that cannot be had is
/// an error, never an abort.
pub(crate) fn read_capped(
    path: &Path,
    max_bytes: u64,
    too_large: impl Fn() -> Error,
) -> Result<Vec<u8>> {
    use std::io::Read;
    let cannot_read = |e: std::io::Error| Error::io(path, "cannot read", e);
    let file = std::fs::File::open(path).map_err(cannot_read)?;
    if file.metadata().is_ok_and(|m| m.is_file() && m.len() > max_bytes) {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    let mut reader = file.take(max_bytes.saturating_add(1));
    let mut chunk = vec![0u8; 1 << 16];
    loop {
        let n = match reader.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(cannot_read(e)),
        };
        bytes.try_reserve(n).map_err(|_| {
            let reason = format!("out of memory after {} bytes", bytes.len());
            Error::io(path, "cannot read", reason)
        })?;
        bytes.extend_from_slice(&chunk[..n]);
    }
    if bytes.len() as u64 > max_bytes {
        return Err(too_large());
    }
    Ok(bytes)
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

/// `bail!("...")` returns early with an [`Error::Invalid`] built by `format!`.
#[macro_export]
macro_rules! bail {
    ($($arg:tt)*) => { return Err($crate::Error::new(format!($($arg)*))) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_prints_one_line_naming_the_file() {
        let io = Error::io(Path::new("a.dae"), "cannot read", "No such file\nor directory");
        assert_eq!(io.to_string(), "a.dae: cannot read: No such file or directory");
        let scene = Error::new("not valid XML").in_scene(Some(Path::new("b.dae")));
        assert!(matches!(&scene, Error::Scene { path: Some(p), .. } if p == Path::new("b.dae")));
        assert_eq!(scene.to_string(), "b.dae: not valid XML");
        assert!(matches!(io.clone().in_scene(Some(Path::new("x"))), Error::Io { .. }));
        assert_eq!(Error::new("bad").context("-r").to_string(), "-r: bad");
        assert_eq!(
            io.context("--csv").message(),
            "a.dae: --csv: cannot read: No such file or directory"
        );
    }

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
