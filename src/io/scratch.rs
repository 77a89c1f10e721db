//! Private scratch folders and folder contents in memory, for runs spread over several
//! ranks (see `crate::dist`): only rank 0 writes outputs, so another rank computes
//! into a scratch folder of its own, and a folder it built travels to rank 0 as
//! `(relative path, bytes)` pairs that rank 0 writes.

use super::atomic::write_atomic;
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// A folder of this process under the system's temporary folder, deleted (with all it
/// holds) when dropped.
#[derive(Debug)]
pub struct ScratchDir {
    path: PathBuf,
}

impl ScratchDir {
    /// Creates `frfbayes-<what>-<pid>-<n>` in the temporary folder.
    pub fn new(what: &str) -> Result<Self> {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let name = format!("frfbayes-{what}-{}-{n}", std::process::id());
        let path = std::env::temp_dir().join(name);
        if path.exists() {
            std::fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
        }
        std::fs::create_dir_all(&path).map_err(|e| Error::io(&path, e))?;
        Ok(ScratchDir { path })
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// Every file under `root` as `(relative path with '/', bytes)`, sorted by path.
pub fn read_tree(root: &Path) -> Result<Vec<(String, Vec<u8>)>> {
    let mut out = Vec::new();
    let mut dirs = vec![root.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).map_err(|e| Error::io(&dir, e))? {
            let path = entry.map_err(|e| Error::io(&dir, e))?.path();
            if path.is_dir() {
                dirs.push(path);
            } else {
                let rel = path
                    .strip_prefix(root)
                    .map_err(|_| Error::invalid(&path, "outside the folder read"))?;
                let rel: Vec<String> = rel
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect();
                let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
                out.push((rel.join("/"), bytes));
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// Writes files read by [`read_tree`] under `root` (each atomically). Refuses paths
/// that would leave `root`.
pub fn write_tree(root: &Path, files: &[(String, Vec<u8>)]) -> Result<()> {
    for (rel, bytes) in files {
        if rel
            .split('/')
            .any(|p| p.is_empty() || p == "." || p == "..")
        {
            return Err(Error::invalid(root, format!("refusing to write {rel:?}")));
        }
        write_atomic(&root.join(rel), bytes)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_travels_and_the_scratch_is_deleted() {
        let a = ScratchDir::new("test-a").unwrap();
        let b = ScratchDir::new("test-b").unwrap();
        write_atomic(&a.path().join("x/y.txt"), b"hello").unwrap();
        write_atomic(&a.path().join("z.bin"), &[0, 1, 2]).unwrap();
        let files = read_tree(a.path()).unwrap();
        assert_eq!(files[0], ("x/y.txt".to_string(), b"hello".to_vec()));
        write_tree(b.path(), &files).unwrap();
        assert_eq!(read_tree(b.path()).unwrap(), files);
        assert!(write_tree(b.path(), &[("../up".into(), vec![])]).is_err());
        let p = a.path().to_path_buf();
        drop(a);
        assert!(!p.exists());
    }
}
