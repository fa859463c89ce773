//! Output files written all or none: each is written to a temporary file beside it, and the
//! temporaries are renamed into place only once every file of the command is complete. A
//! failure (or a signal) before that leaves the old files as they were and no temporary.
//!
//! Every temporary is registered while it exists, so that a signal handler (the CLI's) can
//! remove them with [`abandon_temporaries`] before the process exits.

use std::fs::File;
use std::hash::{Hash, Hasher};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use crate::{Error, Result};

/// The temporaries that exist now. Creating, renaming and removing them happen under this
/// lock, so a signal handler holding it sees each one either absent or registered.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn temporaries() -> MutexGuard<'static, Vec<PathBuf>> {
    TEMPORARIES.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes every registered temporary and keeps the registry locked, so no new one is made and
/// no rename happens: for a process about to exit on a signal.
pub fn abandon_temporaries() {
    let guard = temporaries();
    for tmp in guard.iter() {
        let _ = std::fs::remove_file(tmp);
    }
    std::mem::forget(guard);
}

/// A set of output files written together: [`stage`](Self::stage) each, then
/// [`commit`](Self::commit). Dropped without a commit, it removes its temporaries.
#[derive(Default)]
pub struct Outputs {
    /// (temporary, final path) of each staged file.
    staged: Vec<(PathBuf, PathBuf)>,
}

impl Outputs {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `path`'s contents, through `write`, into its temporary.
    pub fn stage<E: std::fmt::Display>(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut BufWriter<File>) -> std::result::Result<(), E>,
    ) -> Result<()> {
        let fail = |e: &dyn std::fmt::Display| Error::io(path, "cannot write", e);
        let tmp = temporary_path(path);
        let file = {
            let mut registry = temporaries();
            let file = File::create(&tmp).map_err(|e| fail(&e))?;
            registry.push(tmp.clone());
            file
        };
        self.staged.push((tmp, path.to_path_buf()));
        let mut w = BufWriter::new(file);
        write(&mut w).map_err(|e| fail(&e))?;
        w.flush().map_err(|e| fail(&e))?;
        w.get_ref().sync_all().map_err(|e| fail(&e))
    }

    /// Stages `bytes` as the contents of `path`.
    pub fn stage_bytes(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        self.stage(path, |w| w.write_all(bytes))
    }

    /// Renames every temporary over its file, all or none. The renames run under the
    /// registry's lock, so a signal never lands between two of them. Before them, each file
    /// that exists gets a second name (a hard link, so it never disappears); if a rename fails
    /// (rare: the temporary sits beside its file), the files already replaced get their old
    /// contents back, the ones that did not exist are removed again, and no temporary is left.
    /// On a file system without hard links a failed commit cannot restore the files it already
    /// replaced.
    pub fn commit(mut self) -> Result<()> {
        let mut registry = temporaries();
        let staged = std::mem::take(&mut self.staged);
        let backups: Vec<Option<PathBuf>> =
            staged.iter().map(|(_, path)| keep_old_contents(path, &mut registry)).collect();
        let mut result = Ok(());
        let mut replaced = 0;
        for (tmp, path) in &staged {
            if result.is_ok() {
                result = std::fs::rename(tmp, path).map_err(|e| Error::io(path, "cannot write", e));
                replaced += result.is_ok() as usize;
            }
            if result.is_err() {
                let _ = std::fs::remove_file(tmp);
            }
            registry.retain(|t| t != tmp);
        }
        if result.is_err() {
            for ((_, path), backup) in staged.iter().zip(&backups).take(replaced) {
                let _ = match backup {
                    Some(backup) => std::fs::rename(backup, path),
                    None => std::fs::remove_file(path),
                };
            }
        }
        for backup in backups.iter().flatten() {
            let _ = std::fs::remove_file(backup);
            registry.retain(|t| t != backup);
        }
        result
    }
}

/// A second name for `path`'s current contents (`dir/.NAME.old-PID`, registered like a
/// temporary), if it is a file and the file system allows hard links; `None` otherwise.
fn keep_old_contents(path: &Path, registry: &mut Vec<PathBuf>) -> Option<PathBuf> {
    if !std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file()) {
        return None;
    }
    let backup = sibling_path(path, "old");
    let _ = std::fs::remove_file(&backup);
    std::fs::hard_link(path, &backup).ok()?;
    registry.push(backup.clone());
    Some(backup)
}

impl Drop for Outputs {
    fn drop(&mut self) {
        if self.staged.is_empty() {
            return;
        }
        let mut registry = temporaries();
        for (tmp, _) in self.staged.drain(..) {
            let _ = std::fs::remove_file(&tmp);
            registry.retain(|t| *t != tmp);
        }
    }
}

/// Writes one file atomically: a reader sees the old file or the complete new one.
pub fn write_file<E: std::fmt::Display>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::result::Result<(), E>,
) -> Result<()> {
    let mut outputs = Outputs::new();
    outputs.stage(path, write)?;
    outputs.commit()
}

/// Longest file name (in bytes) most file systems allow (`NAME_MAX`).
const NAME_MAX: usize = 255;

/// `dir/NAME` -> `dir/.NAME.tmp-PID`, hidden beside its file so the rename stays on one file
/// system. A name too long for that keeps its first bytes and a hash of the whole, so that a
/// legal file name never makes an illegal temporary.
pub(crate) fn temporary_path(path: &Path) -> PathBuf {
    sibling_path(path, "tmp")
}

/// `dir/NAME` -> `dir/.NAME.KIND-PID` (see `temporary_path`).
fn sibling_path(path: &Path, kind: &str) -> PathBuf {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_os_string());
    let suffix = format!(".{kind}-{}", std::process::id());
    let bytes = name.as_encoded_bytes();
    if 1 + bytes.len() + suffix.len() <= NAME_MAX {
        let mut tmp = std::ffi::OsString::from(".");
        tmp.push(&name);
        tmp.push(&suffix);
        return path.with_file_name(tmp);
    }
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    name.hash(&mut hasher);
    let hash = format!("-{:016x}", hasher.finish());
    let keep = NAME_MAX - 1 - hash.len() - suffix.len();
    // The kept prefix as text (lossy: a temporary's name only needs to be unique and legal).
    let lossy = name.to_string_lossy();
    let mut end = keep.min(lossy.len());
    while !lossy.is_char_boundary(end) {
        end -= 1;
    }
    path.with_file_name(format!(".{}{hash}{suffix}", &lossy[..end]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pt-staged-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn temporary_names_stay_legal() {
        let pid = std::process::id();
        assert_eq!(temporary_path(Path::new("d/a.png")), Path::new(&format!("d/.a.png.tmp-{pid}")));
        for long in ["x".repeat(255), "é".repeat(127), format!("{}.png", "y".repeat(251))] {
            let tmp = temporary_path(&Path::new("d").join(&long));
            let name = tmp.file_name().unwrap().len();
            assert!(name <= NAME_MAX, "{name} bytes");
            assert!(tmp.to_string_lossy().contains(".tmp-"));
            assert_ne!(tmp, temporary_path(&Path::new("d").join(format!("{long}z"))));
        }
    }

    #[test]
    fn a_failed_stage_replaces_none_of_the_files() {
        let dir = scratch("all-or-none");
        let (a, b) = (dir.join("a.txt"), dir.join("missing").join("b.txt"));
        std::fs::write(&a, "old").unwrap();
        let mut outputs = Outputs::new();
        outputs.stage_bytes(&a, b"new").unwrap();
        assert!(outputs.stage_bytes(&b, b"new").is_err());
        drop(outputs);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "a temporary was left");
        assert!(!temporaries().iter().any(|t| t.starts_with(&dir)));

        let mut outputs = Outputs::new();
        outputs.stage_bytes(&a, b"new").unwrap();
        outputs.stage_bytes(&dir.join("c.txt"), b"c").unwrap();
        outputs.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new");
        assert_eq!(std::fs::read_to_string(dir.join("c.txt")).unwrap(), "c");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A rename that fails after others succeeded (here: the last target is a directory) puts
    /// the replaced file's old contents back and removes the file that was new.
    #[test]
    fn a_failed_rename_undoes_the_renames_before_it() {
        let dir = scratch("mid-commit");
        let (a, new, blocker) = (dir.join("a.txt"), dir.join("new.txt"), dir.join("sub"));
        std::fs::write(&a, "old").unwrap();
        std::fs::create_dir(&blocker).unwrap();
        std::fs::write(blocker.join("inside"), "x").unwrap();
        let mut outputs = Outputs::new();
        outputs.stage_bytes(&a, b"new").unwrap();
        outputs.stage_bytes(&new, b"new").unwrap();
        outputs.stage_bytes(&blocker, b"new").unwrap();
        let err = outputs.commit().unwrap_err().to_string();
        assert!(err.contains("sub"), "{err}");
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        assert!(!new.exists(), "a file that did not exist was left");
        let mut left: Vec<_> =
            std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        left.sort();
        assert_eq!(left, ["a.txt", "sub"], "temporaries or second names were left");
        assert!(!temporaries().iter().any(|t| t.starts_with(&dir)));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
