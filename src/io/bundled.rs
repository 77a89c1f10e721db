//! The recorded four-story campaign, shipped inside the repository so that
//! `frfbayes repro` works on a fresh clone.
//!
//! Every file of the campaign is stored gzipped (best compression) under
//! `paper_repro/data/four-story/<relative path>.gz`. [`bundled_four_story`] decompresses
//! the bundle once into `<temp dir>/frfbayes-four-story-<content hash>/` and reuses that
//! copy afterwards.
//!
//! The copy is built in a staging folder ([`StagedDir`]) and renamed into place only when
//! complete, so a run that is killed, or two runs at once, never leave a half-written
//! copy where it is looked for. An existing copy is reused when every file is present with
//! the size recorded in its gzip trailer; otherwise it is rebuilt. The folder name carries
//! a hash of the bundle, so a changed bundle never reuses an old copy.
//!
//! ## Regenerating the bundle
//!
//! From the campaign in `../shared/data/four-story` (relative to the repository):
//!
//! ```text
//! cargo test --release --test bundled_data -- --ignored regenerate_bundle
//! ```
//!
//! which calls [`pack_bundle`]. `tests/bundled_data.rs` checks that the decompressed
//! bundle is byte-identical to `../shared/data/four-story` when that folder exists.

use super::atomic::StagedDir;
use super::output::{OutputClaim, MANIFEST};
use crate::error::{Error, Result};
use flate2::read::MultiGzDecoder;
use flate2::write::GzEncoder;
use flate2::Compression;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Where the data of an experiment come from: `bundled:four-story` or a folder.
pub fn resolve_data(spec: &str) -> Result<PathBuf> {
    match spec {
        "bundled:four-story" => bundled_four_story(),
        s if s.starts_with("bundled:") => Err(Error::Usage(format!(
            "unknown bundled dataset {s:?} (have: bundled:four-story)"
        ))),
        s => Ok(PathBuf::from(s)),
    }
}

/// Folder of the bundled four-story campaign inside the repository.
pub fn four_story_bundle_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("paper_repro/data/four-story")
}

/// The bundled four-story campaign as a plain campaign folder (decompressed on first use
/// into the temporary directory, reused afterwards). Read it with
/// [`read_campaign`](crate::io::read_campaign).
pub fn bundled_four_story() -> Result<PathBuf> {
    unpack_bundle(
        &four_story_bundle_dir(),
        &std::env::temp_dir(),
        "frfbayes-four-story",
    )
}

/// Compresses every file under `source` into `bundle/<relative path>.gz` (gzip, best
/// compression, no name or time in the header, so the same input gives the same bytes).
/// The new bundle replaces `bundle` only once complete. Returns the number of files.
pub fn pack_bundle(source: &Path, bundle: &Path) -> Result<usize> {
    let files = relative_files(source)?;
    if files.is_empty() {
        return Err(Error::invalid(source, "no files to bundle"));
    }
    let staged = StagedDir::new(bundle)?;
    for rel in &files {
        let from = source.join(rel);
        let bytes = std::fs::read(&from).map_err(|e| Error::io(&from, e))?;
        let to = staged.path().join(format!("{rel}.gz"));
        write_new_file(&to, |w| {
            let mut gz = GzEncoder::new(w, Compression::best());
            gz.write_all(&bytes)?;
            gz.finish()?;
            Ok(())
        })?;
    }
    staged.commit()?;
    Ok(files.len())
}

/// One file of a bundle: relative path without `.gz`, and the compressed bytes.
struct Entry {
    rel: String,
    gz: Vec<u8>,
}

impl Entry {
    /// Uncompressed size modulo 2^32 (the gzip trailer's ISIZE field).
    fn size_mod_2_32(&self) -> Option<u32> {
        let tail = self.gz.len().checked_sub(4).map(|k| &self.gz[k..])?;
        Some(u32::from_le_bytes(tail.try_into().ok()?))
    }
}

/// Serialises unpacking inside one process: staging folders are named by process id.
static UNPACK_LOCK: Mutex<()> = Mutex::new(());

/// Decompresses the `.gz` tree `bundle` into `cache_parent/<prefix>-<hash>` unless a
/// complete copy is already there; returns that folder.
pub(crate) fn unpack_bundle(bundle: &Path, cache_parent: &Path, prefix: &str) -> Result<PathBuf> {
    let entries = read_bundle(bundle)?;
    let target = cache_parent.join(format!("{prefix}-{}", content_hash(&entries)));
    if is_complete(&target, &entries) {
        return Ok(target);
    }
    let _guard = UNPACK_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    // Another process unpacking the same bundle: wait for it, then reuse its copy.
    let claim = OutputClaim::claim_waiting(&target)?;
    if is_complete(&target, &entries) {
        return Ok(target);
    }
    let staged = StagedDir::in_claim(claim)?;
    for e in &entries {
        let gz_path = bundle.join(format!("{}.gz", e.rel));
        let to = staged.path().join(&e.rel);
        let mut bytes = Vec::new();
        MultiGzDecoder::new(e.gz.as_slice())
            .read_to_end(&mut bytes)
            .map_err(|err| {
                Error::invalid(
                    &gz_path,
                    format!("not a valid gzip file ({err}); restore it from the repository"),
                )
            })?;
        write_new_file(&to, |w| w.write_all(&bytes))?;
    }
    // Another process may have finished first: its copy is identical, keep it.
    if is_complete(&target, &entries) {
        return Ok(target);
    }
    staged.commit()
}

/// Every `.gz` file under `bundle`, sorted by relative path.
fn read_bundle(bundle: &Path) -> Result<Vec<Entry>> {
    let mut entries = Vec::new();
    for rel in relative_files(bundle)? {
        if let Some(stem) = rel.strip_suffix(".gz") {
            let path = bundle.join(&rel);
            let gz = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
            entries.push(Entry {
                rel: stem.to_string(),
                gz,
            });
        }
    }
    if entries.is_empty() {
        return Err(Error::invalid(
            bundle,
            "no bundled .gz files; restore paper_repro/data from the repository",
        ));
    }
    Ok(entries)
}

/// Whether `target` holds every entry with its recorded size.
fn is_complete(target: &Path, entries: &[Entry]) -> bool {
    entries.iter().all(|e| {
        std::fs::metadata(target.join(&e.rel))
            .is_ok_and(|m| m.is_file() && Some(m.len() as u32) == e.size_mod_2_32())
    })
}

/// FNV-1a (64 bit) over the relative paths and compressed bytes, as 12 hex digits.
fn content_hash(entries: &[Entry]) -> String {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut h = OFFSET;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(PRIME);
        }
    };
    for e in entries {
        eat(e.rel.as_bytes());
        eat(&[0]);
        eat(&(e.gz.len() as u64).to_le_bytes());
        eat(&e.gz);
    }
    format!("{:012x}", h >> 16)
}

/// Relative paths (with `/`) of all files under `root`, sorted.
fn relative_files(root: &Path) -> Result<Vec<String>> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) -> Result<()> {
        let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| Error::io(dir, e))?;
            let path = entry.path();
            let file_type = entry.file_type().map_err(|e| Error::io(&path, e))?;
            if file_type.is_dir() {
                walk(root, &path, out)?;
            } else if dir == root && entry.file_name() == MANIFEST {
                // frfbayes' own record of what it wrote, not content.
            } else {
                let rel = path.strip_prefix(root).unwrap_or(&path);
                let parts: Vec<String> = rel
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect();
                out.push(parts.join("/"));
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(root, root, &mut out)?;
    out.sort();
    Ok(out)
}

/// Creates `path` (and its parent folders) inside a staging folder and fills it.
fn write_new_file(
    path: &Path,
    f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let io_err = |e| Error::io(path, e);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(io_err)?;
    }
    let file = std::fs::File::create(path).map_err(io_err)?;
    let mut w = std::io::BufWriter::new(file);
    f(&mut w).map_err(io_err)?;
    w.flush().map_err(io_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny_tree(dir: &Path) {
        std::fs::create_dir_all(dir.join("tests/a")).unwrap();
        std::fs::write(dir.join("campaign.toml"), "title = \"x\"\n").unwrap();
        std::fs::write(dir.join("tests/a/data.csv"), "time_s\n0\n".repeat(100)).unwrap();
        std::fs::write(dir.join("empty.txt"), "").unwrap();
    }

    #[test]
    fn pack_then_unpack_round_trips_and_reuses_the_copy() {
        let tmp = tempfile::tempdir().unwrap();
        let source = tmp.path().join("src");
        let bundle = tmp.path().join("bundle");
        let cache = tmp.path().join("cache");
        std::fs::create_dir_all(&cache).unwrap();
        tiny_tree(&source);
        assert_eq!(pack_bundle(&source, &bundle).unwrap(), 3);
        assert_eq!(
            relative_files(&bundle).unwrap(),
            ["campaign.toml.gz", "empty.txt.gz", "tests/a/data.csv.gz"]
        );
        let out = unpack_bundle(&bundle, &cache, "t").unwrap();
        let files = relative_files(&out).unwrap();
        assert_eq!(files, relative_files(&source).unwrap());
        for rel in &files {
            assert_eq!(
                std::fs::read(out.join(rel)).unwrap(),
                std::fs::read(source.join(rel)).unwrap(),
                "{rel}"
            );
        }
        // Reuse: a marker file left in the copy survives a second call.
        std::fs::write(out.join("marker"), "m").unwrap();
        assert_eq!(unpack_bundle(&bundle, &cache, "t").unwrap(), out);
        assert!(out.join("marker").exists());
        // An incomplete copy is rebuilt, but not over a file frfbayes did not write.
        std::fs::remove_file(out.join("tests/a/data.csv")).unwrap();
        let err = unpack_bundle(&bundle, &cache, "t").unwrap_err().to_string();
        assert!(err.contains("marker"), "{err}");
        assert!(out.join("marker").exists());
        std::fs::remove_file(out.join("marker")).unwrap();
        assert_eq!(unpack_bundle(&bundle, &cache, "t").unwrap(), out);
        assert_eq!(
            std::fs::read(out.join("tests/a/data.csv")).unwrap(),
            std::fs::read(source.join("tests/a/data.csv")).unwrap()
        );
        // Only the copy is left in the cache folder (no staging or backup folders).
        assert_eq!(std::fs::read_dir(&cache).unwrap().count(), 1);
        // Packing is deterministic, and a changed bundle goes to a new folder.
        let again = tmp.path().join("bundle2");
        pack_bundle(&source, &again).unwrap();
        for rel in relative_files(&bundle).unwrap() {
            assert_eq!(
                std::fs::read(bundle.join(&rel)).unwrap(),
                std::fs::read(again.join(&rel)).unwrap()
            );
        }
        std::fs::write(source.join("campaign.toml"), "title = \"y\"\n").unwrap();
        pack_bundle(&source, &bundle).unwrap();
        assert_ne!(unpack_bundle(&bundle, &cache, "t").unwrap(), out);
    }

    #[test]
    fn corrupt_bundle_is_an_error_naming_the_file() {
        let tmp = tempfile::tempdir().unwrap();
        let bundle = tmp.path().join("bundle");
        std::fs::create_dir_all(&bundle).unwrap();
        std::fs::write(bundle.join("campaign.toml.gz"), b"not gzip at all").unwrap();
        let err = unpack_bundle(&bundle, tmp.path(), "t").unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("campaign.toml.gz"), "{msg}");
        // Nothing half-written is left where the copy is looked for.
        let names: Vec<_> = std::fs::read_dir(tmp.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["bundle"]);
        let empty = tmp.path().join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        assert!(unpack_bundle(&empty, tmp.path(), "t").is_err());
    }
}
