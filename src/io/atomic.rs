//! Atomic outputs: nothing the user already has is lost or half-overwritten by a failed
//! run. Files are written to a temporary sibling and renamed into place; directories are
//! built in a temporary sibling and swapped in only when complete.

use super::output::OutputClaim;
use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename).
/// Creates missing parent folders.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Like [`write_atomic`], with a closure that streams into a buffered writer.
pub fn write_atomic_with(
    path: &Path,
    f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let tmp = temp_sibling(path);
    let result = (|| -> std::io::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        f(&mut w)?;
        w.flush()?;
        w.get_ref().sync_all()?;
        Ok(())
    })();
    if let Err(e) = result.and_then(|()| std::fs::rename(&tmp, path)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// A folder being built: everything goes into a staging folder beside the target, and
/// [`StagedDir::commit`] swaps it into place ([`OutputClaim::commit`]: the output policy
/// of [`super::output`]). Dropping without commit removes the staging folder (unless it
/// is the resumable one) and leaves any existing folder untouched.
#[derive(Debug)]
pub struct StagedDir {
    claim: OutputClaim,
    staging: PathBuf,
    committed: bool,
    /// A resumable run's staging folder survives a failed run.
    keep: bool,
}

impl StagedDir {
    /// Claims `target` ([`OutputClaim::claim`]) and starts building it.
    pub fn new(target: &Path) -> Result<Self> {
        Self::in_claim(OutputClaim::claim(target)?)
    }

    /// Starts building the folder `claim` holds, in a staging folder of this process.
    pub fn in_claim(claim: OutputClaim) -> Result<Self> {
        let staging = claim.staging_path();
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        std::fs::create_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        Ok(StagedDir {
            claim,
            staging,
            committed: false,
            keep: false,
        })
    }

    /// Starts or continues building the folder `claim` holds in its resumable staging
    /// folder ([`OutputClaim::partial_path`]), which a failed or killed run leaves for
    /// `--resume`. With `resume` false, an earlier run's partial folder is discarded.
    /// Returns whether an earlier partial folder was there.
    pub fn resumable(claim: OutputClaim, resume: bool) -> Result<(Self, bool)> {
        let staging = claim.partial_path();
        let existed = staging.is_dir();
        if existed && !resume {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        std::fs::create_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        let staged = StagedDir {
            claim,
            staging,
            committed: false,
            keep: true,
        };
        Ok((staged, existed))
    }

    /// Where to write the folder's content now.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The folder being built.
    pub fn target(&self) -> &Path {
        self.claim.target()
    }

    /// Replaces the target with the staged folder (the previous one is deleted only
    /// after the swap succeeded). Releases the claim.
    pub fn commit(mut self) -> Result<PathBuf> {
        let out = self.claim.commit(&self.staging)?;
        self.committed = true;
        Ok(out)
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed && !self.keep {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

fn temp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staged_dir_keeps_old_content_until_commit() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        let first = StagedDir::new(&target).unwrap();
        std::fs::write(first.path().join("a.txt"), "old").unwrap();
        first.commit().unwrap();
        {
            let staged = StagedDir::new(&target).unwrap();
            std::fs::write(staged.path().join("a.txt"), "new").unwrap();
            // dropped without commit: old content survives
        }
        assert_eq!(
            std::fs::read_to_string(target.join("a.txt")).unwrap(),
            "old"
        );
        let staged = StagedDir::new(&target).unwrap();
        std::fs::write(staged.path().join("a.txt"), "new").unwrap();
        staged.commit().unwrap();
        assert_eq!(
            std::fs::read_to_string(target.join("a.txt")).unwrap(),
            "new"
        );
        // Only the folder is left (no staging folder, no lock file).
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().collect();
        assert_eq!(left.len(), 1, "{left:?}");
    }

    #[test]
    fn write_atomic_replaces_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/x.json");
        write_atomic(&p, b"1").unwrap();
        write_atomic(&p, b"2").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"2");
    }
}
