//! The bundled four-story campaign (`paper_repro/data/four-story/*.gz`) against the
//! original in `../shared/data/four-story`, and as a campaign in its own right.
//!
//! Regenerate the bundle from `../shared` (or from `$FRFBAYES_SHARED_DIR`):
//! `cargo test --release --test bundled_data -- --ignored regenerate_bundle`

use frfbayes::io::bundled::{bundled_four_story, four_story_bundle_dir, pack_bundle};
use frfbayes::io::{read_campaign, TestKind};
use std::path::{Path, PathBuf};

/// `../shared/data/four-story` next to the repository (`FRFBAYES_SHARED_DIR` overrides
/// `../shared`, e.g. when working in a git worktree elsewhere).
fn shared_four_story() -> Option<PathBuf> {
    let shared = std::env::var_os("FRFBAYES_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared"));
    let p = shared.join("data/four-story");
    if p.is_dir() {
        Some(p)
    } else {
        println!(
            "skipped: {} not found (no ../shared next to this clone)",
            p.display()
        );
        None
    }
}

/// Relative paths of all files under `root`, sorted, less the manifest frfbayes writes
/// into every folder it creates ([`frfbayes::io::output::MANIFEST`]: the unpacked copy is
/// one), which is not campaign data.
fn files(root: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else if p.file_name().and_then(|n| n.to_str()) == Some(frfbayes::io::output::MANIFEST)
            {
                continue;
            } else {
                out.push(p.strip_prefix(root).unwrap().to_string_lossy().into_owned());
            }
        }
    }
    let mut out = Vec::new();
    walk(root, root, &mut out);
    out.sort();
    out
}

#[test]
fn bundle_is_byte_identical_to_the_shared_campaign() {
    let Some(original) = shared_four_story() else {
        return;
    };
    let copy = bundled_four_story().unwrap();
    let original_files = files(&original);
    assert_eq!(files(&copy), original_files, "missing or extra files");
    assert_eq!(original_files.len(), 12);
    for rel in &original_files {
        let a = std::fs::read(original.join(rel)).unwrap();
        let b = std::fs::read(copy.join(rel)).unwrap();
        assert!(a == b, "{rel} differs from the original");
    }
    // A second call reuses the same complete copy.
    assert_eq!(bundled_four_story().unwrap(), copy);
}

#[test]
fn bundled_campaign_reads_without_shared() {
    let copy = bundled_four_story().unwrap();
    let c = read_campaign(&copy).unwrap();
    assert_eq!(c.title, "four-story frame");
    assert_eq!(c.nominal.n_floors(), 4);
    let names: Vec<&str> = c.tests.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "hammer-floor1",
            "hammer-floor2",
            "hammer-floor3",
            "hammer-floor4",
            "shake-table-chirp"
        ]
    );
    for (i, t) in c.tests.iter().take(4).enumerate() {
        assert_eq!(
            t.kind,
            TestKind::Hammer {
                excited_floor: i + 1
            }
        );
        assert_eq!(t.n_samples(), 60_000);
    }
    assert_eq!(c.tests[4].kind, TestKind::ShakeTable);
    assert_eq!(c.tests[4].n_samples(), 65_000);
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

#[test]
#[ignore = "rewrites paper_repro/data/four-story from ../shared; run by hand"]
fn regenerate_bundle() {
    let Some(original) = shared_four_story() else {
        return;
    };
    let n = pack_bundle(&original, &four_story_bundle_dir()).unwrap();
    println!(
        "bundled {n} files into {}",
        four_story_bundle_dir().display()
    );
}
