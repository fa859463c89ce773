//! The command line: subcommands parse their arguments into library calls. Every user error
//! is one line on stderr and exit code 2.

pub mod bench;
pub mod chart;
pub mod compare;
pub mod converge;
pub mod gen;
pub mod render;

use pathtracer::{bail, Error, Result};

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
