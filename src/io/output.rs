//! One output policy for every command that writes a folder (issue 16).
//!
//! An output folder is *claimed* before anything is computed ([`OutputClaim::claim`]):
//!
//! - an `--out` that is an existing file (or a symbolic link, or anything but a folder)
//!   is refused and left untouched;
//! - an existing folder is replaced only when it is empty, or when everything in it was
//!   written by frfbayes: its manifest [`MANIFEST`] (written into every folder frfbayes
//!   commits) lists every entry, or (folders written before the manifest existed) it
//!   holds a `run.json` or `diagnosis.json`. A folder with anything else in it is refused, naming the
//!   foreign entries, and left untouched;
//! - a folder another command wrote is refused too (its manifest's first line names the
//!   command: `frf --out` never wipes `sample`'s results);
//! - one run at a time per folder: the claim holds an OS lock on the file
//!   `.<name>.frfbayes.lock` beside the folder, with the holder's pid in it; a second
//!   run refuses with that pid ([`OutputClaim::claim_waiting`] waits instead). The OS
//!   releases the lock when its holder dies, even by SIGKILL, so a stale lock file is
//!   taken over without asking;
//! - the new folder is built aside (`.<name>.<pid>.frfbayes-staging`, or
//!   `.<name>.frfbayes-partial` for runs that resume) and swapped in by
//!   [`OutputClaim::commit`] only when complete: the previous folder is renamed to
//!   `.<name>.<pid>.frfbayes-old`, the new one renamed into place, and the old one
//!   deleted. A run killed between the two renames leaves the old folder aside; the next
//!   claim puts it back. A failed run leaves the previous folder as it was.
//!
//! Nothing is ever moved or deleted that frfbayes did not create: leftovers are
//! recognised by these hidden names with a process id in them, and only under the lock.

use crate::error::{Error, Result};
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The manifest file frfbayes writes into every folder it commits: one relative path
/// (with `/`) per line, every file and folder it wrote.
pub const MANIFEST: &str = ".frfbayes-output";

/// Legacy markers: a folder written before the manifest existed, with the `run.json`
/// record of `repro`, `run`, `real`, `sample`, `simulate`, or a `diagnosis.json`.
const LEGACY_MARKERS: [&str; 2] = ["run.json", "diagnosis.json"];

/// An output folder claimed by this process: checked, and locked until dropped.
#[derive(Debug)]
pub struct OutputClaim {
    target: PathBuf,
    /// Refuse a folder another command wrote (user outputs; not caches).
    strict: bool,
    _lock: OutputLock,
}

impl OutputClaim {
    /// Claims `target`; refuses a file, a folder with foreign content, or a folder
    /// another run is writing.
    pub fn claim(target: &Path) -> Result<Self> {
        Self::claim_with(target, false)
    }

    /// Like [`OutputClaim::claim`], but waits for another run writing `target`.
    pub fn claim_waiting(target: &Path) -> Result<Self> {
        Self::claim_with(target, true)
    }

    fn claim_with(target: &Path, wait: bool) -> Result<Self> {
        let target = if target.file_name().is_some() {
            target.to_path_buf()
        } else {
            // `out/` or `.`: name the folder itself.
            std::path::absolute(target).map_err(|e| Error::io(target, e))?
        };
        if target.file_name().is_none() {
            return Err(Error::invalid(
                &target,
                "cannot be an output folder (it has no name); give a folder path",
            ));
        }
        let strict = !wait;
        check_target(&target, strict)?;
        let parent = parent_of(&target);
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        let lock = OutputLock::acquire(&target, wait)?;
        let claim = OutputClaim {
            target,
            strict,
            _lock: lock,
        };
        claim.recover_leftovers()?;
        check_target(&claim.target, claim.strict)?;
        Ok(claim)
    }

    /// The claimed folder.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// The staging folder of this process.
    pub fn staging_path(&self) -> PathBuf {
        self.sibling(&format!("{}.frfbayes-staging", std::process::id()))
    }

    /// The staging folder of a resumable run (the same for every process).
    pub fn partial_path(&self) -> PathBuf {
        partial_path_of(&self.target)
    }

    fn sibling(&self, suffix: &str) -> PathBuf {
        self.target
            .with_file_name(format!(".{}.{suffix}", name_of(&self.target)))
    }

    /// Swaps the complete folder `built` in as the target (see the module docs); writes
    /// its manifest first. Returns the target.
    pub fn commit(&self, built: &Path) -> Result<PathBuf> {
        write_manifest(built)?;
        let target = &self.target;
        let exists = match std::fs::symlink_metadata(target) {
            Ok(_) => true,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
            Err(e) => return Err(Error::io(target, e)),
        };
        if !exists {
            std::fs::rename(built, target).map_err(|e| Error::io(target, e))?;
            return Ok(target.clone());
        }
        // The user may have added files while the run was going: check again.
        check_target(target, self.strict)?;
        let old = self.sibling(&format!("{}.frfbayes-old", std::process::id()));
        std::fs::rename(target, &old).map_err(|e| Error::io(target, e))?;
        if let Err(e) = std::fs::rename(built, target) {
            let _ = std::fs::rename(&old, target);
            return Err(Error::io(target, e));
        }
        if let Err(e) = std::fs::remove_dir_all(&old) {
            // The new results are in place: say what is left, do not fail the run.
            eprintln!(
                "warning: {}: could not delete the previous results moved aside ({e}); \
                 delete that folder yourself",
                old.display()
            );
        }
        Ok(target.clone())
    }

    /// Rewrites the manifest of the target after a run that changed it in place
    /// (`sample --resume` of a finished run).
    pub fn refresh_manifest(&self) -> Result<()> {
        write_manifest(&self.target)
    }

    /// Leftovers of killed runs on this target (we hold the lock, so no live run owns
    /// them): staging folders are deleted, a previous folder moved aside is put back
    /// when the target is missing (deleted otherwise).
    fn recover_leftovers(&self) -> Result<()> {
        let parent = parent_of(&self.target);
        let prefix = format!(".{}.", name_of(&self.target));
        let entries = std::fs::read_dir(parent).map_err(|e| Error::io(parent, e))?;
        for entry in entries.flatten() {
            let file_name = entry.file_name().to_string_lossy().into_owned();
            let Some(rest) = file_name.strip_prefix(&prefix) else {
                continue;
            };
            let leftover = |suffix: &str| {
                rest.strip_suffix(suffix)
                    .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
            };
            let path = entry.path();
            if leftover(".frfbayes-staging") {
                std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
            } else if leftover(".frfbayes-old") {
                if std::fs::symlink_metadata(&self.target).is_err() {
                    eprintln!(
                        "note: {}: putting back the previous results of an interrupted run",
                        self.target.display()
                    );
                    std::fs::rename(&path, &self.target).map_err(|e| Error::io(&path, e))?;
                } else {
                    std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
                }
            }
        }
        Ok(())
    }
}

fn parent_of(target: &Path) -> &Path {
    target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// The partial folder of a resumable run into `target` ([`OutputClaim::partial_path`]),
/// for readers that do not claim it (the other ranks of an MPI run).
pub fn partial_path_of(target: &Path) -> PathBuf {
    target.with_file_name(format!(".{}.frfbayes-partial", name_of(target)))
}

fn name_of(target: &Path) -> String {
    target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into())
}

/// The command of this process (`frf`, `sample`, ...), recorded in the manifests it
/// writes; set once by the binary.
static COMMAND: OnceLock<String> = OnceLock::new();

/// Records the command this process runs (the binary calls it once, first).
pub fn set_command(name: &str) {
    let _ = COMMAND.set(name.to_string());
}

const WRITTEN_BY: &str = "# written by frfbayes ";

/// Refuses a target that is not a folder frfbayes may replace (module docs); `strict`:
/// nor one another command wrote.
fn check_target(target: &Path, strict: bool) -> Result<()> {
    let meta = match std::fs::symlink_metadata(target) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(Error::io(target, e)),
    };
    if meta.file_type().is_symlink() {
        return Err(Error::invalid(
            target,
            "is a symbolic link; frfbayes replaces output folders and does not follow \
             links there: give the folder it points to, or a new path (the link was left \
             untouched)",
        ));
    }
    if !meta.is_dir() {
        return Err(Error::invalid(
            target,
            "is an existing file, not a folder; frfbayes writes a folder of results and \
             never replaces a file: give a new or existing folder path (the file was left \
             untouched)",
        ));
    }
    let foreign = foreign_entries(target)?;
    if foreign.is_empty() {
        return if strict {
            check_same_command(target)
        } else {
            Ok(())
        };
    }
    let shown: Vec<&str> = foreign.iter().take(5).map(String::as_str).collect();
    let more = foreign.len().saturating_sub(shown.len());
    let tail = if more > 0 {
        format!(" and {more} more")
    } else {
        String::new()
    };
    Err(Error::invalid(
        target,
        format!(
            "holds files frfbayes did not write ({}{tail}); it replaces only its own output \
             folders: move those files out or choose another output folder (nothing was \
             changed)",
            shown.join(", ")
        ),
    ))
}

/// Refuses a folder whose manifest says another command wrote it: `frf --out` must
/// not wipe the hours of `sample` that happen to be there.
fn check_same_command(target: &Path) -> Result<()> {
    let Some(current) = COMMAND.get() else {
        return Ok(());
    };
    let text = std::fs::read_to_string(target.join(MANIFEST)).unwrap_or_default();
    let Some(previous) = text.lines().next().and_then(|l| l.strip_prefix(WRITTEN_BY)) else {
        return Ok(());
    };
    if previous == current {
        return Ok(());
    }
    Err(Error::invalid(
        target,
        format!(
            "holds the results of `frfbayes {previous}`; `frfbayes {current}` replaces only \
             its own: choose another output folder, or delete that one first (nothing was \
             changed)"
        ),
    ))
}

/// Entries of the folder `dir` not written by frfbayes (empty: it may be replaced).
fn foreign_entries(dir: &Path) -> Result<Vec<String>> {
    let entries = relative_entries(dir)?;
    if entries.is_empty() {
        return Ok(Vec::new());
    }
    let manifest_path = dir.join(MANIFEST);
    match std::fs::read_to_string(&manifest_path) {
        Ok(text) => {
            let listed: std::collections::BTreeSet<&str> =
                text.lines().filter(|l| !l.starts_with('#')).collect();
            Ok(entries
                .into_iter()
                .filter(|e| e != MANIFEST && !listed.contains(e.as_str()))
                .collect())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if LEGACY_MARKERS.iter().any(|m| dir.join(m).is_file()) {
                Ok(Vec::new())
            } else {
                Ok(entries.into_iter().filter(|e| !e.contains('/')).collect())
            }
        }
        Err(e) => Err(Error::io(&manifest_path, e)),
    }
}

/// Relative paths (with `/`) of every file and folder under `root`, sorted.
fn relative_entries(root: &Path) -> Result<Vec<String>> {
    fn walk(dir: &Path, prefix: &str, out: &mut Vec<String>) -> Result<()> {
        for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
            let entry = entry.map_err(|e| Error::io(dir, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let rel = format!("{prefix}{name}");
            let path = entry.path();
            let ty = entry.file_type().map_err(|e| Error::io(&path, e))?;
            out.push(rel.clone());
            if ty.is_dir() {
                walk(&path, &format!("{rel}/"), out)?;
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(root, "", &mut out)?;
    out.sort();
    Ok(out)
}

/// Writes `dir/MANIFEST` listing everything under `dir`.
fn write_manifest(dir: &Path) -> Result<()> {
    let entries: Vec<String> = relative_entries(dir)?
        .into_iter()
        .filter(|e| e != MANIFEST)
        .collect();
    let mut text = match COMMAND.get() {
        Some(c) => format!("{WRITTEN_BY}{c}\n"),
        None => String::new(),
    };
    for e in &entries {
        text.push_str(e);
        text.push('\n');
    }
    super::atomic::write_atomic(&dir.join(MANIFEST), text.as_bytes())
}

/// The lock of one output folder: an OS file lock on `.<name>.frfbayes.lock` beside
/// it, holding the pid. Released (and the file deleted) on drop.
#[derive(Debug)]
struct OutputLock {
    path: PathBuf,
    file: File,
}

impl OutputLock {
    fn acquire(target: &Path, wait: bool) -> Result<Self> {
        let path = target.with_file_name(format!(".{}.frfbayes.lock", name_of(target)));
        loop {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(|e| Error::io(&path, e))?;
            let locked = if wait {
                file.lock()
                    .map(|()| true)
                    .map_err(|e| Error::io(&path, e))?
            } else {
                match file.try_lock() {
                    Ok(()) => true,
                    Err(std::fs::TryLockError::WouldBlock) => false,
                    Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(&path, e)),
                }
            };
            if !locked {
                let mut pid = String::new();
                let _ = file.read_to_string(&mut pid);
                return Err(busy(target, &path, pid.trim()));
            }
            // The previous holder may have deleted the file between our open and our
            // lock: then we hold a lock on a file no one else will see; start again.
            if !same_file(&file, &path) {
                continue;
            }
            let write_pid = |f: &mut File| -> std::io::Result<()> {
                f.set_len(0)?;
                f.seek(SeekFrom::Start(0))?;
                write!(f, "{}", std::process::id())?;
                f.flush()
            };
            write_pid(&mut file).map_err(|e| Error::io(&path, e))?;
            return Ok(OutputLock { path, file });
        }
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Delete while still holding the lock (waiters check the file is still there).
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}

fn busy(target: &Path, lock: &Path, pid: &str) -> Error {
    let holder = if pid.is_empty() {
        "another frfbayes run".to_string()
    } else {
        format!("another frfbayes run (pid {pid})")
    };
    Error::invalid(
        target,
        format!(
            "{holder} is writing this output folder (lock file {}); wait for it to finish \
             or choose another output folder (nothing was changed)",
            lock.display()
        ),
    )
}

#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &File, path: &Path) -> bool {
    path.exists()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::StagedDir;

    fn build(target: &Path, text: &str) -> PathBuf {
        let staged = StagedDir::new(target).unwrap();
        std::fs::create_dir_all(staged.path().join("sub")).unwrap();
        std::fs::write(staged.path().join("sub/a.txt"), text).unwrap();
        staged.commit().unwrap()
    }

    #[test]
    fn previous_folder_left_aside_by_a_killed_swap_is_put_back() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        build(&target, "old");
        // A run killed between its two renames: the old folder aside, no target.
        let aside = dir.path().join(".out.999999.frfbayes-old");
        std::fs::rename(&target, &aside).unwrap();
        let staging = dir.path().join(".out.999999.frfbayes-staging");
        std::fs::create_dir_all(&staging).unwrap();
        let claim = OutputClaim::claim(&target).unwrap();
        assert_eq!(
            std::fs::read_to_string(target.join("sub/a.txt")).unwrap(),
            "old"
        );
        assert!(!aside.exists() && !staging.exists());
        drop(claim);
        // With the target present, a folder aside is the stale one: deleted.
        build(&target, "new");
        std::fs::create_dir_all(&aside).unwrap();
        drop(OutputClaim::claim(&target).unwrap());
        assert!(!aside.exists());
        assert_eq!(
            std::fs::read_to_string(target.join("sub/a.txt")).unwrap(),
            "new"
        );
        let mut left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        left.sort();
        assert_eq!(left, ["out"]);
    }

    #[test]
    fn only_empty_own_or_legacy_folders_may_be_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        std::fs::create_dir_all(&target).unwrap();
        drop(OutputClaim::claim(&target).unwrap()); // empty
        std::fs::write(target.join("user.txt"), "u").unwrap();
        let e = OutputClaim::claim(&target).unwrap_err().to_string();
        assert!(e.contains("user.txt") && e.contains("did not write"), "{e}");
        std::fs::write(target.join("run.json"), "{}").unwrap();
        drop(OutputClaim::claim(&target).unwrap()); // legacy frfbayes folder
                                                    // A symbolic link is refused and left alone.
        #[cfg(unix)]
        {
            let link = dir.path().join("link");
            std::os::unix::fs::symlink(&target, &link).unwrap();
            let e = OutputClaim::claim(&link).unwrap_err().to_string();
            assert!(e.contains("symbolic link"), "{e}");
            assert!(link.join("user.txt").exists());
        }
        // A name that clashes with the prefix of another target's leftovers is not
        // mistaken for one of them.
        let other = dir.path().join(".out.x.1.frfbayes-staging");
        std::fs::create_dir_all(&other).unwrap();
        drop(OutputClaim::claim(&target).unwrap());
        assert!(other.exists());
    }
}
