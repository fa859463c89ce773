//! The command line: clap parses the arguments (`command.rs` holds the definition and maps
//! clap's errors to ours; each subcommand's module its flags), then the subcommands call the
//! library. Every user error is one line on stderr and exit code 2.
//!
//! All printing goes through [`write_stdout`] and [`write_stderr`] (the `outln!`, `out!` and
//! `errln!` macros), never `println!`, which panics when stdout is full or closed. A failed
//! write to stdout is an [`Error`] like any other (`writing to standard output: No space left
//! on device`, exit 2), except a closed pipe (`| head -1`), which ends the program quietly
//! with exit 0; [`exit_code`] decides. Commands that write files print through a [`Report`],
//! so a failed print never stops the file from being written.

/// `outln!("...")`: one line on stdout; `Err` (one line) if it cannot be written.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `out!("...")`: text on stdout without a line break; `Err` if it cannot be written.
macro_rules! out {
    ($($arg:tt)*) => { $crate::cli::write_stdout(format_args!($($arg)*)) };
}

/// `errln!("...")`: one line on stderr (warnings, notes); never panics (see [`write_stderr`]).
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::cli::write_stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub mod bench;
pub mod chart;
pub mod command;
pub mod compare;
pub mod converge;
pub mod cpu;
pub mod gen;
pub mod launch;
pub mod merge;
pub mod render;
pub mod render_args;
pub mod signals;

use std::fmt;
use std::io::{self, ErrorKind, Write};
use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

use pathtracer::{bail, Error, Result};

/// The first failed write to stdout: later writes fail the same way without trying again
/// (so a closed pipe gives one error, not one per line).
static STDOUT_FAILED: OnceLock<(ErrorKind, Error)> = OnceLock::new();
/// Set when a command's check failed (`bench --baseline` found a regression): exit code 1.
static CHECK_FAILED: AtomicBool = AtomicBool::new(false);

/// Makes the exit code 1 (a check that ran and failed, unlike an error's 2).
pub fn fail_check() {
    CHECK_FAILED.store(true, Ordering::Relaxed);
}

/// Set when a write to stderr failed with anything but a closed pipe: the exit code is then 2.
static STDERR_FAILED: AtomicBool = AtomicBool::new(false);

/// Writes `args` to stdout and flushes it. A failure is a one-line [`Error`], and sticks: every
/// later call returns the same error.
pub fn write_stdout(args: fmt::Arguments) -> Result<()> {
    if let Some((_, e)) = STDOUT_FAILED.get() {
        return Err(e.clone());
    }
    let mut stdout = io::stdout().lock();
    match stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        Ok(()) => Ok(()),
        Err(e) => {
            let error = Error::new(format!("writing to standard output: {}", io_message(&e)));
            Err(STDOUT_FAILED.get_or_init(|| (e.kind(), error)).1.clone())
        }
    }
}

/// Writes `args` to stderr. Stderr is where errors go, so a failure cannot be reported; it
/// is remembered instead and makes the exit code 2 (a closed pipe is ignored, as on stdout).
pub fn write_stderr(args: fmt::Arguments) {
    let mut stderr = io::stderr().lock();
    if let Err(e) = stderr.write_fmt(args).and_then(|()| stderr.flush()) {
        if e.kind() != ErrorKind::BrokenPipe {
            STDERR_FAILED.store(true, Ordering::Relaxed);
        }
    }
}

/// An I/O error's text without the `(os error N)` suffix: "No space left on device".
fn io_message(e: &io::Error) -> String {
    let text = e.to_string();
    match text.find(" (os error ") {
        Some(i) => text[..i].to_string(),
        None => text,
    }
}

/// The end of every command: success is exit 0; an error is one line on stderr and exit 2,
/// except that a closed stdout (the reader went away: `| head -1`) ends quietly with exit 0.
pub fn exit_code(result: Result<()>) -> ExitCode {
    let error = match result {
        Ok(()) => None,
        Err(e) => match STDOUT_FAILED.get() {
            Some((ErrorKind::BrokenPipe, closed)) if *closed == e => None,
            _ => Some(e),
        },
    };
    if let Some(e) = error {
        errln!("error: {e}");
        return ExitCode::from(2);
    }
    if STDERR_FAILED.load(Ordering::Relaxed) {
        ExitCode::from(2)
    } else if CHECK_FAILED.load(Ordering::Relaxed) {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

/// Stdout for a command that writes files: a failed print does not stop the work (the file is
/// written all the same); the first failure is kept, later lines are skipped, and [`finish`]
/// returns it once the files are written.
///
/// [`finish`]: Report::finish
#[derive(Default)]
pub struct Report {
    failed: Option<Error>,
}

impl Report {
    /// Prints `args` unless an earlier print failed.
    pub fn print(&mut self, args: fmt::Arguments) {
        if self.failed.is_none() {
            self.failed = write_stdout(args).err();
        }
    }

    /// The first failed print, if any.
    pub fn finish(self) -> Result<()> {
        self.failed.map_or(Ok(()), Err)
    }
}

pub fn parse_number<T: std::str::FromStr>(flag: &str, text: &str) -> Result<T> {
    text.parse().map_err(|_| Error::new(format!("{flag}: '{text}' is not a valid number")))
}

pub fn parse_in_range(flag: &str, text: &str, lo: u32, hi: u32) -> Result<u32> {
    let v: i64 = parse_number(flag, text)?;
    if v < lo as i64 || v > hi as i64 {
        bail!("{flag}: {v} is out of range (expected {lo} to {hi})");
    }
    Ok(v as u32)
}

/// Refuses, before any work, an output path that cannot safely be replaced: an existing
/// directory, device or other non-regular file, a symbolic link (the rename that writes the
/// file would replace the link itself, not its target), or the same file as one of `inputs`
/// (the output would destroy it). `what` names the flag, e.g. "-f" or "--csv".
pub fn check_output(what: &str, output: &Path, inputs: &[&Path]) -> Result<()> {
    // Most file systems' NAME_MAX: a longer name cannot be created, so say so before the work.
    if output.file_name().is_some_and(|n| n.len() > 255) {
        bail!("{what} {}: the file name is longer than 255 bytes", output.display());
    }
    let Ok(meta) = std::fs::symlink_metadata(output) else {
        return Ok(()); // Nothing there yet: nothing to destroy.
    };
    let out = output.display();
    if meta.file_type().is_symlink() {
        bail!("{what} {out}: is a symbolic link; give the path of a regular file instead");
    }
    if !meta.is_file() {
        bail!("{what} {out}: exists and is not a regular file (a directory or device)");
    }
    for input in inputs {
        if same_file(output, &meta, input) {
            bail!(
                "{what} {out}: is the same file as the input {} (writing would destroy it)",
                input.display()
            );
        }
    }
    Ok(())
}

fn same_file(output: &Path, meta: &std::fs::Metadata, input: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let _ = output;
        if let Ok(m) = std::fs::metadata(input) {
            return m.dev() == meta.dev() && m.ino() == meta.ino();
        }
        false
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        match (std::fs::canonicalize(output), std::fs::canonicalize(input)) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        }
    }
}

/// A positive number of bytes for `flag` (`--max-scene-bytes`).
pub(crate) fn parse_byte_count(flag: &str, text: &str) -> Result<u64> {
    match parse_number::<u64>(flag, text)? {
        0 => bail!("{flag}: expected a positive number of bytes, got 0"),
        n => Ok(n),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn io_errors_read_without_the_os_error_number() {
        let full = io::Error::from_raw_os_error(28); // ENOSPC
        assert_eq!(io_message(&full), "No space left on device");
        let custom = io::Error::other("disk on fire");
        assert_eq!(io_message(&custom), "disk on fire");
    }

    #[test]
    fn check_output_refuses_inputs_directories_devices_and_links() {
        let dir = std::env::temp_dir().join(format!("pt-check-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("a.dae");
        std::fs::write(&file, "x").unwrap();
        let other = dir.join("b.png");
        std::fs::write(&other, "y").unwrap();
        assert!(check_output("-f", &dir.join("new.png"), &[&file]).is_ok());
        assert!(check_output("-f", &other, &[&file, &dir.join("missing")]).is_ok());
        let err =
            |p: &Path, inputs: &[&Path]| check_output("-f", p, inputs).unwrap_err().to_string();
        assert!(err(&file, &[&file]).contains("same file as the input"));
        let dotted = dir.join(".").join("a.dae");
        assert!(err(&dotted, &[&file]).contains("a.dae"));
        assert!(err(&dir, &[]).contains("not a regular file"));
        #[cfg(unix)]
        {
            assert!(err(Path::new("/dev/full"), &[]).contains("not a regular file"));
            let link = dir.join("l.png");
            let _ = std::fs::remove_file(&link);
            std::os::unix::fs::symlink(&other, &link).unwrap();
            assert!(err(&link, &[]).contains("symbolic link"));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
