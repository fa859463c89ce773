//! The command line: subcommands parse their arguments into library calls. Every user error
//! is one line on stderr and exit code 2.

pub mod bench;
pub mod chart;
pub mod compare;
pub mod converge;
pub mod gen;
pub mod render;

use std::path::Path;

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

/// Refuses, before any work, an output path that cannot safely be replaced: an existing
/// directory, device or other non-regular file, a symbolic link (the rename that writes the
/// file would replace the link itself, not its target), or the same file as one of `inputs`
/// (the output would destroy it). `what` names the flag, e.g. "-f" or "--csv".
pub fn check_output(what: &str, output: &Path, inputs: &[&Path]) -> Result<()> {
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

#[cfg(test)]
mod tests {
    use super::*;

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
