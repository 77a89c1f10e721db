//! Resumable stages: the results of a long run's stages, each in its own file, so that a
//! run killed at any point continues from its last complete stage (`--resume`) and ends
//! with the same output as an uninterrupted run.
//!
//! A stage file is the 8 magic bytes `FRFBSTG1`, the CRC-32 of the payload (`u32`,
//! little-endian), the payload length (`u64`), and the payload: the stage's value in
//! CBOR (every `f64` exact). It is written atomically ([`super::write_atomic`]) and read
//! back only when magic, length and checksum agree: a half-written or corrupted file is
//! never taken for a result, it is an error naming the file and what to do.
//!
//! The folder also holds `inputs.txt`, a fingerprint of the run's inputs (the CRC-32 of
//! every input file and of the settings): resuming with changed inputs is refused,
//! naming what changed.

use super::atomic::write_atomic;
use crate::error::{Error, Result};
use serde::{de::DeserializeOwned, Serialize};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"FRFBSTG1";
const HEADER_LEN: usize = 8 + 4 + 8;
const INPUTS: &str = "inputs.txt";

/// A run's inputs: `(name, CRC-32)` of every input file (relative path) and setting.
pub type Fingerprint = Vec<(String, u32)>;

/// The stage files of one run.
#[derive(Debug)]
pub struct Stages {
    dir: PathBuf,
    /// False for a reader that must not write (another rank of an MPI run reading
    /// the stages rank 0 saves).
    writable: bool,
}

impl Stages {
    /// Opens the stage folder `dir` for a run with `inputs`. With `resume`, an existing
    /// folder must have been made for the same inputs (else the error names what
    /// changed); without, any existing stages are discarded.
    pub fn open(dir: &Path, resume: bool, inputs: &Fingerprint) -> Result<Self> {
        let inputs_path = dir.join(INPUTS);
        let text = fingerprint_text(inputs);
        if resume && inputs_path.exists() {
            let old =
                std::fs::read_to_string(&inputs_path).map_err(|e| Error::io(&inputs_path, e))?;
            if old != text {
                return Err(Error::invalid(
                    &inputs_path,
                    format!(
                        "the inputs changed since the interrupted run ({}); its stages do \
                         not apply: rerun without --resume to start over",
                        differences(&old, &text)
                    ),
                ));
            }
        } else {
            if dir.exists() {
                std::fs::remove_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
            write_atomic(&inputs_path, text.as_bytes())?;
        }
        Ok(Stages {
            dir: dir.to_path_buf(),
            writable: true,
        })
    }

    /// The stages in `dir` as a reader: [`Stages::get_or_run`] reads back the stages
    /// present and computes the others without saving them. For the ranks other than 0
    /// of an MPI run (rank 0 opened `dir`, checked its inputs, and saves every stage).
    pub fn read_only(dir: &Path) -> Self {
        Stages {
            dir: dir.to_path_buf(),
            writable: false,
        }
    }

    /// Saves stage `key` unless it is saved already or the stages are read-only (a
    /// result computed elsewhere, e.g. on another rank).
    pub fn save_if_absent<T: Serialize>(&self, key: &str, value: &T) -> Result<()> {
        let path = self.path(key);
        if self.writable && !path.exists() {
            write_stage(&path, value)?;
        }
        Ok(())
    }

    /// The file of stage `key`.
    pub fn path(&self, key: &str) -> PathBuf {
        let safe: String = key
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        self.dir.join(format!("{safe}.stage"))
    }

    /// Stage `key`: read back when done, else computed by `f` and saved.
    pub fn get_or_run<T: Serialize + DeserializeOwned>(
        &self,
        key: &str,
        f: impl FnOnce() -> Result<T>,
    ) -> Result<T> {
        let path = self.path(key);
        if path.exists() {
            return read_stage(&path);
        }
        let value = f()?;
        if self.writable {
            write_stage(&path, &value)?;
        }
        Ok(value)
    }
}

/// [`Stages::get_or_run`] when there are stages, else just `f`.
pub fn staged<T: Serialize + DeserializeOwned>(
    stages: Option<&Stages>,
    key: &str,
    f: impl FnOnce() -> Result<T>,
) -> Result<T> {
    match stages {
        Some(s) => s.get_or_run(key, f),
        None => f(),
    }
}

/// Writes one stage file (format in the module docs).
pub fn write_stage<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let mut payload = Vec::new();
    ciborium::into_writer(value, &mut payload).map_err(|e| {
        Error::Numerical(format!("{}: cannot encode the stage: {e}", path.display()))
    })?;
    let mut bytes = Vec::with_capacity(HEADER_LEN + payload.len());
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&payload);
    write_atomic(path, &bytes)
}

/// Reads one stage file, refusing anything truncated, corrupted or of another format.
pub fn read_stage<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let bad = |what: &str| {
        Error::invalid(
            path,
            format!(
                "{what}: this stage file of an interrupted run is damaged; delete it (the \
                 stage is computed again on --resume) or rerun without --resume"
            ),
        )
    };
    if bytes.len() < HEADER_LEN || &bytes[..8] != MAGIC {
        return Err(bad("not a frfbayes stage file (bad header)"));
    }
    let crc = u32::from_le_bytes(bytes[8..12].try_into().unwrap_or_default());
    let len = u64::from_le_bytes(bytes[12..20].try_into().unwrap_or_default());
    let payload = &bytes[HEADER_LEN..];
    if payload.len() as u64 != len {
        return Err(bad(&format!(
            "truncated ({} of {len} payload bytes)",
            payload.len()
        )));
    }
    if crc32fast::hash(payload) != crc {
        return Err(bad("checksum mismatch"));
    }
    ciborium::from_reader(payload).map_err(|e| bad(&format!("undecodable ({e})")))
}

/// Fingerprint of every file under `root` (relative paths with `/`, sorted), hidden
/// files skipped.
pub fn fingerprint_folder(root: &Path) -> Result<Fingerprint> {
    fn walk(root: &Path, dir: &Path, out: &mut Fingerprint) -> Result<()> {
        for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
            let entry = entry.map_err(|e| Error::io(dir, e))?;
            if entry.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            let path = entry.path();
            if path.is_dir() {
                walk(root, &path, out)?;
            } else {
                let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
                let rel = path.strip_prefix(root).unwrap_or(&path);
                let parts: Vec<String> = rel
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect();
                out.push((parts.join("/"), crc32fast::hash(&bytes)));
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    if root.is_dir() {
        walk(root, root, &mut out)?;
    } else {
        let bytes = std::fs::read(root).map_err(|e| Error::io(root, e))?;
        out.push((root.display().to_string(), crc32fast::hash(&bytes)));
    }
    out.sort();
    Ok(out)
}

/// Fingerprint entry of a setting (its text form).
pub fn fingerprint_setting(name: &str, text: &str) -> (String, u32) {
    (name.to_string(), crc32fast::hash(text.as_bytes()))
}

fn fingerprint_text(inputs: &Fingerprint) -> String {
    inputs
        .iter()
        .map(|(name, crc)| format!("{crc:08x} {name}\n"))
        .collect()
}

/// What differs between two fingerprint texts, for the message.
fn differences(old: &str, new: &str) -> String {
    let parse = |t: &str| -> std::collections::BTreeMap<String, String> {
        t.lines()
            .filter_map(|l| l.split_once(' '))
            .map(|(crc, name)| (name.to_string(), crc.to_string()))
            .collect()
    };
    let (a, b) = (parse(old), parse(new));
    let mut out = Vec::new();
    for (name, crc) in &b {
        match a.get(name) {
            None => out.push(format!("{name} is new")),
            Some(c) if c != crc => out.push(format!("{name} changed")),
            _ => {}
        }
    }
    out.extend(
        a.keys()
            .filter(|n| !b.contains_key(*n))
            .map(|n| format!("{n} is gone")),
    );
    let n = out.len();
    out.truncate(5);
    if n > 5 {
        out.push(format!("{} more", n - 5));
    }
    out.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_round_trips_exactly_and_damage_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let inputs = vec![fingerprint_setting("options", "a")];
        let stages = Stages::open(&dir.path().join("st"), false, &inputs).unwrap();
        let value = vec![0.1_f64, f64::INFINITY, -0.0, 1e-310, std::f64::consts::PI];
        let mut calls = 0;
        let got: Vec<f64> = stages
            .get_or_run("a b", || {
                calls += 1;
                Ok(value.clone())
            })
            .unwrap();
        let again: Vec<f64> = stages
            .get_or_run("a b", || {
                calls += 1;
                Ok(vec![])
            })
            .unwrap();
        assert_eq!(calls, 1);
        for (x, y) in value.iter().zip(got.iter().chain(&again)) {
            assert_eq!(x.to_bits(), y.to_bits());
        }
        // Truncated, then one byte flipped: errors naming the file.
        let path = stages.path("a b");
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        let e = read_stage::<Vec<f64>>(&path).unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("a_b.stage"), "{e}");
        let mut flipped = bytes.clone();
        *flipped.last_mut().unwrap() ^= 1;
        std::fs::write(&path, &flipped).unwrap();
        let e = read_stage::<Vec<f64>>(&path).unwrap_err().to_string();
        assert!(e.contains("checksum"), "{e}");
        // Resuming with other inputs is refused, naming the change.
        let other = vec![fingerprint_setting("options", "b")];
        let e = Stages::open(&dir.path().join("st"), true, &other)
            .unwrap_err()
            .to_string();
        assert!(e.contains("options changed"), "{e}");
        // Without resume the old stages are discarded.
        let fresh = Stages::open(&dir.path().join("st"), false, &other).unwrap();
        assert!(!fresh.path("a b").exists());
    }
}
