//! Fault injection against the real binary (issue 16): every command that writes goes
//! through one output policy (`src/io/output.rs`), and nothing the user has is lost
//! when a run is refused, fails, is killed, or runs out of disk.
//!
//! The invariants asserted everywhere: the user's files are byte-identical, previous
//! results are intact or replaced by complete new ones, no half-written folder is left
//! where results are looked for, the exit code is 1 (an error, not a panic) and the
//! message names the path and what to do.
//!
//! How the faults are made (no root, no mount needed):
//! - full disk: the binary runs under `ulimit -f` (RLIMIT_FSIZE) with SIGXFSZ ignored,
//!   so the kernel fails the first write past the limit (EFBIG, "File too large"),
//!   mid-file, the way a full disk fails it with ENOSPC;
//! - read-only folder: `chmod 555`; when the tests run as root (CI), the binary runs
//!   under `setpriv` without CAP_DAC_OVERRIDE so that the mode bits apply to it;
//! - SIGKILL at pseudo-random points of a `diagnose --quick` run on a two-story
//!   fixture campaign (`tests/fixtures/faults/tiny.toml`), then `--resume`.
//!
//! `cargo test --release --test faults` (about 15 s on 2 cores).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_frfbayes")
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn frfbayes(args: &[&str]) -> Command {
    let mut c = Command::new(bin());
    c.args(args).env("RAYON_NUM_THREADS", "1");
    c
}

fn run(mut c: Command) -> Output {
    c.output().expect("runs the binary")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts a refusal or failure: exit code 1 (not a panic's 101), message containing
/// every one of `needles`.
fn assert_fails(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "expected exit 1, got {:?}: {err}",
        o.status
    );
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "message lacks {n:?}: {err}");
    }
}

fn assert_ok(o: &Output) {
    assert!(o.status.success(), "failed: {}", stderr(o));
}

/// Every file under `root` (or `root` itself when a file) with its bytes.
fn snapshot(root: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    if root.is_file() {
        out.insert(String::new(), std::fs::read(root).unwrap());
    } else {
        walk(root, root, &mut out);
    }
    out
}

/// Asserts two snapshots are equal, naming the files that differ.
fn assert_same(a: &BTreeMap<String, Vec<u8>>, b: &BTreeMap<String, Vec<u8>>, what: &str) {
    let differ: Vec<&String> = a
        .keys()
        .chain(b.keys())
        .filter(|k| a.get(*k) != b.get(*k))
        .collect();
    assert!(differ.is_empty(), "{what}: files differ: {differ:?}");
}

/// Asserts `dir` is a complete output folder: its manifest lists exactly its files.
fn assert_complete(dir: &Path) {
    let manifest = std::fs::read_to_string(dir.join(".frfbayes-output")).unwrap();
    let listed: Vec<&str> = manifest
        .lines()
        .filter(|l| !l.contains('/') && !l.starts_with('#'))
        .collect();
    let mut present = names(dir);
    present.retain(|n| n != ".frfbayes-output");
    assert_eq!(listed, present, "{}", dir.display());
}

/// Names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// The two-story fixture campaign, simulated once per test process.
fn campaign() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    let dir = DIR.get_or_init(|| {
        let d = tempfile::tempdir().unwrap();
        let model = repo().join("tests/fixtures/faults/tiny.toml");
        let out = d.path().join("camp");
        assert_ok(&run(frfbayes(&[
            "simulate",
            "--model",
            model.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])));
        d
    });
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| dir.path().join("camp"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `frf` of the fixture campaign into `out`.
fn frf(out: &Path) -> Command {
    frfbayes(&["frf", s(campaign()), "--out", s(out)])
}

/// `diagnose --quick` of `camp` into `out`.
fn diagnose(camp: &Path, out: &Path, resume: bool) -> Command {
    let mut c = frfbayes(&["diagnose", s(camp), "--out", s(out), "--quick"]);
    if resume {
        c.arg("--resume");
    }
    c
}

/// Observation 1 of the issue: `--out <existing file>` moved the file aside and
/// failed after succeeding. Every writing command now refuses it, the file untouched.
#[test]
fn every_writing_command_refuses_an_out_that_is_a_file() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("results.txt");
    let content = b"the user's own notes\n".to_vec();
    std::fs::write(&file, &content).unwrap();
    let shared = tmp.path().join("shared");
    std::fs::create_dir_all(shared.join("data/real/four-story-modal")).unwrap();
    let cases = tmp.path().join("cases.toml");
    std::fs::write(
        &cases,
        format!(
            "hypotheses = []\n[[case]]\nid = \"tiny\"\nmodel = {:?}\nverdict = \"none\"\n\
             location = {{}}\nsize = \"-\"\nnoise_scale = 1.0\nseed = 1\n",
            s(&repo().join("tests/fixtures/faults/tiny.toml"))
        ),
    )
    .unwrap();
    let work = tmp.path().join("work");
    std::fs::create_dir_all(work.join("campaigns")).unwrap();
    let case_file = work.join("campaigns/tiny");
    std::fs::write(&case_file, &content).unwrap();
    let model = repo().join("tests/fixtures/faults/tiny.toml");
    let f = s(&file);
    let commands: Vec<(&str, Vec<&str>, &Path)> = vec![
        ("frf", vec!["frf", s(campaign()), "--out", f], &file),
        (
            "diagnose",
            vec!["diagnose", s(campaign()), "--out", f, "--quick"],
            &file,
        ),
        (
            "simulate",
            vec!["simulate", "--model", s(&model), "--out", f],
            &file,
        ),
        (
            "sample",
            vec!["sample", "--campaign", s(campaign()), "--out", f],
            &file,
        ),
        (
            "fit",
            vec!["fit", "--campaign", s(campaign()), "--out", f],
            &file,
        ),
        ("repro", vec!["repro", "--out", f], &file),
        (
            "run",
            vec!["run", "experiments/paper_repro.toml", "--out", f],
            &file,
        ),
        (
            "real",
            vec![
                "real",
                "four-story-modal",
                "--shared",
                s(&shared),
                "--out",
                f,
            ],
            &file,
        ),
        (
            "diagnose-benchmark",
            vec![
                "diagnose-benchmark",
                "--cases",
                s(&cases),
                "--work",
                s(&work),
                "--quick",
            ],
            &case_file,
        ),
    ];
    let before = names(tmp.path());
    for (name, args, target) in commands {
        let mut c = frfbayes(&args);
        c.current_dir(repo());
        let o = run(c);
        assert_fails(&o, &[s(target), "is an existing file", "left untouched"]);
        assert_eq!(
            std::fs::read(target).unwrap(),
            content,
            "{name} changed the file"
        );
        assert_eq!(names(tmp.path()), before, "{name} left something beside it");
        assert_eq!(names(&work.join("campaigns")), ["tiny"], "{name}");
    }
}

/// Policy for folders: its own previous output is replaced (nothing left aside); a
/// folder with anything frfbayes did not write is refused and left as it was.
#[test]
fn only_its_own_output_folders_are_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("res");
    assert_ok(&run(frf(&out)));
    let first = snapshot(&out);
    assert!(first.contains_key(".frfbayes-output"));
    assert_ok(&run(frf(&out)));
    assert_same(&snapshot(&out), &first, "same input, same output");
    assert_eq!(
        names(tmp.path()),
        ["res"],
        "no staging, backup or lock file left"
    );
    // The user adds a file: the folder is no longer frfbayes' alone.
    std::fs::write(out.join("hammer-floor1/my-notes.txt"), "keep me").unwrap();
    let with_notes = snapshot(&out);
    let o = run(frf(&out));
    assert_fails(
        &o,
        &[s(&out), "hammer-floor1/my-notes.txt", "did not write"],
    );
    assert_same(&snapshot(&out), &with_notes, "");
    // A folder of the user's own.
    let mine = tmp.path().join("mine");
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("thesis.tex"), "chapter 1").unwrap();
    let o = run(frf(&mine));
    assert_fails(&o, &["thesis.tex", "choose another output folder"]);
    assert_eq!(snapshot(&mine).len(), 1);
    // Another command's results are not replaced either (`frf` wiping `sample`'s).
    std::fs::remove_file(out.join("hammer-floor1/my-notes.txt")).unwrap();
    let o = run(diagnose(campaign(), &out, false));
    assert_fails(
        &o,
        &["holds the results of `frfbayes frf`", "`frfbayes diagnose`"],
    );
    assert_same(&snapshot(&out), &first, "another command's folder");
    assert_eq!(names(tmp.path()), ["mine", "res"]);
}

/// A run holding the folder's lock makes another refuse, naming its pid; once the
/// holder is gone (its lock released, even with the lock file left behind, as after
/// SIGKILL) the next run takes over.
#[test]
fn a_folder_being_written_is_refused_and_a_stale_lock_taken_over() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("res");
    assert_ok(&run(frf(&out)));
    let before = snapshot(&out);
    let lock_path = tmp.path().join(".res.frfbayes.lock");
    let lock = std::fs::File::create(&lock_path).unwrap();
    lock.try_lock().unwrap();
    std::fs::write(&lock_path, "424242").unwrap();
    let o = run(frf(&out));
    assert_fails(
        &o,
        &[s(&out), "pid 424242", "is writing this output folder"],
    );
    assert_same(&snapshot(&out), &before, "");
    drop(lock); // released; the file (with a dead pid) stays, as after a SIGKILL
    assert!(lock_path.exists());
    assert_ok(&run(frf(&out)));
    assert_same(&snapshot(&out), &before, "");
    assert_eq!(names(tmp.path()), ["res"]);
}

/// Observation 2 of the issue: three `frf` at once into one folder gave an error from
/// the file system. Now each either succeeds or refuses with the lock message, and the
/// folder ends complete.
#[test]
fn concurrent_runs_into_one_folder_serialise_or_refuse() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = tmp.path().join("reference");
    assert_ok(&run(frf(&reference)));
    let out = tmp.path().join("res");
    for _round in 0..3 {
        let children: Vec<_> = (0..3)
            .map(|_| {
                frf(&out)
                    .stdout(Stdio::null())
                    .stderr(Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        let outputs: Vec<Output> = children
            .into_iter()
            .map(|c| c.wait_with_output().unwrap())
            .collect();
        let ok = outputs.iter().filter(|o| o.status.success()).count();
        assert!(ok >= 1, "no run succeeded");
        for o in outputs.iter().filter(|o| !o.status.success()) {
            assert_fails(o, &["is writing this output folder", "wait for it"]);
        }
        assert_same(&snapshot(&out), &snapshot(&reference), "");
        assert_eq!(names(tmp.path()), ["reference", "res"]);
    }
}

/// Runs `c` with a file-size limit of `kib` KiB: writes past it fail with EFBIG.
fn with_size_limit(c: Command, kib: u64) -> Command {
    let mut sh = Command::new("sh");
    sh.arg("-c")
        .arg(format!("trap '' XFSZ; ulimit -f {}; exec \"$@\"", kib * 2))
        .arg("sh")
        .arg(c.get_program())
        .args(c.get_args())
        .env("RAYON_NUM_THREADS", "1");
    sh
}

/// A full disk in the middle of a run: an error naming the file, a hint, and the
/// previous results exactly as they were.
#[test]
fn full_disk_leaves_previous_results_intact() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("res");
    assert_ok(&run(frf(&out)));
    let before = snapshot(&out);
    let o = run(with_size_limit(frf(&out), 4));
    assert_fails(
        &o,
        &[
            "File too large",
            "frf.csv",
            "hint: the disk",
            "previous results",
        ],
    );
    assert_same(&snapshot(&out), &before, "");
    assert_eq!(names(tmp.path()), ["res"]);
    // The same for a diagnosis and a simulated campaign.
    let diag = tmp.path().join("diag");
    assert_ok(&run(diagnose(campaign(), &diag, false)));
    let before = snapshot(&diag);
    let o = run(with_size_limit(diagnose(campaign(), &diag, false), 8));
    assert_fails(&o, &["File too large", "hint: the disk"]);
    assert_same(&snapshot(&diag), &before, "");
    let sim = tmp.path().join("sim");
    let model = repo().join("tests/fixtures/faults/tiny.toml");
    let simulate = || frfbayes(&["simulate", "--model", s(&model), "--out", s(&sim)]);
    assert_ok(&run(simulate()));
    let before = snapshot(&sim);
    let o = run(with_size_limit(simulate(), 16));
    assert_fails(&o, &["File too large", "data.csv"]);
    assert_same(&snapshot(&sim), &before, "");
}

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("Uid:"))
                .map(|l| l.split_whitespace().nth(2) == Some("0"))
        })
        .unwrap_or(false)
}

/// `c` such that the mode bits apply to it: as is, or as root through `setpriv`
/// without the capabilities that override them. `None` when that is not possible.
fn subject_to_permissions(c: Command) -> Option<Command> {
    if !is_root() {
        return Some(c);
    }
    let caps = "-dac_override,-dac_read_search,-fowner";
    let probe = Command::new("setpriv")
        .args(["--inh-caps", caps, "--bounding-set", caps, "true"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        return None;
    }
    let mut p = Command::new("setpriv");
    p.args(["--inh-caps", caps, "--bounding-set", caps])
        .arg(c.get_program())
        .args(c.get_args())
        .env("RAYON_NUM_THREADS", "1");
    Some(p)
}

/// A read-only output location: an error naming the path, a hint, nothing changed.
#[test]
fn read_only_folder_is_an_error_and_changes_nothing() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = tempfile::tempdir().unwrap();
    let ro = tmp.path().join("ro");
    let out = ro.join("res");
    assert_ok(&run(frf(&out)));
    let before = snapshot(&out);
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
    let Some(c) = subject_to_permissions(frf(&out)) else {
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
        let msg = "running as root without setpriv (util-linux): cannot make a folder \
                   read-only for the binary";
        assert!(
            std::env::var_os("FRFBAYES_REQUIRE_EXTERNAL").is_none(),
            "{msg}"
        );
        println!("skipped: {msg}");
        return;
    };
    let o = run(c);
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    assert_fails(
        &o,
        &[
            s(&ro),
            "Permission denied",
            "hint: that folder is not writable",
        ],
    );
    assert_same(&snapshot(&out), &before, "");
    assert_eq!(names(&ro), ["res"]);
}

/// Starts `c`, waits until `ready()` or `after`, then SIGKILLs it. Returns whether it
/// was still running when killed.
fn kill_when(mut c: Command, after: Duration, ready: impl Fn() -> bool) -> bool {
    let mut child = c
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while t0.elapsed() < after && !ready() {
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let running = child.try_wait().unwrap().is_none();
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    running
}

/// `diagnose` killed with SIGKILL at pseudo-random points, then `--resume`d: the same
/// `diagnosis.json` as an uninterrupted run, and the previous results untouched until
/// the new ones are complete.
#[test]
fn diagnose_killed_anywhere_resumes_to_the_same_diagnosis() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = tmp.path().join("reference");
    let t0 = Instant::now();
    assert_ok(&run(diagnose(campaign(), &reference, false)));
    let full = t0.elapsed();
    let expected = std::fs::read(reference.join("diagnosis.json")).unwrap();
    let out = tmp.path().join("out");
    assert_ok(&run(diagnose(campaign(), &out, false)));
    let previous = snapshot(&out);
    // Kill points spread over the run (a fixed pseudo-random sequence).
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    for _ in 0..3 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let fraction = 0.1 + 0.8 * (x % 1000) as f64 / 1000.0;
        let at = full.mul_f64(fraction);
        if kill_when(diagnose(campaign(), &out, false), at, || false) {
            // Killed before its swap: the previous results; after: the new ones.
            let now = snapshot(&out);
            if now != previous {
                assert_eq!(now["diagnosis.json"], expected, "killed at {at:?}");
                assert_complete(&out);
            }
            assert_ok(&run(diagnose(campaign(), &out, true)));
        }
        // Killed and resumed, or (on a slow machine) finished before the kill.
        assert_complete(&out);
        assert_eq!(std::fs::read(out.join("diagnosis.json")).unwrap(), expected);
        assert_eq!(
            names(tmp.path()),
            ["out", "reference"],
            "leftovers after resume"
        );
    }
}

/// Stages of an interrupted `diagnose` in `out`'s partial folder (killed as soon as
/// its first stage is saved).
fn interrupted_diagnosis(camp: &Path, out: &Path) -> PathBuf {
    let partial = out.with_file_name(format!(
        ".{}.frfbayes-partial",
        out.file_name().unwrap().to_string_lossy()
    ));
    let stage = partial.join("nominal-map.stage");
    let killed = kill_when(diagnose(camp, out, false), Duration::from_secs(60), || {
        stage.exists()
    });
    assert!(
        killed && stage.exists(),
        "the run ended before it could be killed"
    );
    stage
}

/// A truncated or corrupted stage file is never taken for a result: `--resume` stops
/// with the file's name and what to do; following that advice finishes the run.
#[test]
fn damaged_stage_files_are_refused_on_resume() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = tmp.path().join("reference");
    assert_ok(&run(diagnose(campaign(), &reference, false)));
    let out = tmp.path().join("out");
    let stage = interrupted_diagnosis(campaign(), &out);
    let bytes = std::fs::read(&stage).unwrap();
    std::fs::write(&stage, &bytes[..bytes.len() / 2]).unwrap();
    let o = run(diagnose(campaign(), &out, true));
    assert_fails(&o, &[s(&stage), "truncated", "delete it"]);
    let mut flipped = bytes.clone();
    flipped[bytes.len() - 1] ^= 0x40;
    std::fs::write(&stage, &flipped).unwrap();
    let o = run(diagnose(campaign(), &out, true));
    assert_fails(&o, &[s(&stage), "checksum mismatch"]);
    assert!(
        !out.exists(),
        "nothing written where results are looked for"
    );
    std::fs::remove_file(&stage).unwrap();
    assert_ok(&run(diagnose(campaign(), &out, true)));
    assert_eq!(
        std::fs::read(out.join("diagnosis.json")).unwrap(),
        std::fs::read(reference.join("diagnosis.json")).unwrap()
    );
}

/// A campaign edited between the interrupted run and `--resume`: refused, naming
/// the changed file; without `--resume` the run starts over.
#[test]
fn campaign_changed_before_resume_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("camp");
    std::fs::create_dir_all(&camp).unwrap();
    for (rel, bytes) in snapshot(campaign()) {
        let p = camp.join(&rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
    let out = tmp.path().join("out");
    interrupted_diagnosis(&camp, &out);
    let toml = camp.join("campaign.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    std::fs::write(&toml, text.replace("fixture", "fixture, edited")).unwrap();
    let o = run(diagnose(&camp, &out, true));
    assert_fails(&o, &["campaign.toml changed", "rerun without --resume"]);
    assert!(!out.exists());
    assert_ok(&run(diagnose(&camp, &out, false)));
    assert!(out.join("diagnosis.json").exists());
}

fn sample(out: &Path, resume: bool) -> Command {
    let mut c = frfbayes(&["sample", "--out", s(out)]);
    if resume {
        c.arg("--resume");
    } else {
        c.args(["--campaign", s(campaign()), "--max-steps", "2500"]);
        c.args(["--checkpoint-every", "25", "--starts", "4"]);
    }
    c
}

/// `sample` killed mid-run: nothing appears at `--out`, a fresh run refuses to discard
/// the interrupted one, `--resume` ends bit-identical to an
/// uninterrupted run; a truncated checkpoint is an error naming it.
#[test]
fn sample_killed_resumes_identically_and_a_truncated_checkpoint_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = tmp.path().join("reference");
    assert_ok(&run(sample(&reference, false)));
    let out = tmp.path().join("out");
    let checkpoint = tmp.path().join(".out.frfbayes-partial/checkpoint.mcmc");
    let killed = kill_when(sample(&out, false), Duration::from_secs(60), || {
        checkpoint.exists()
    });
    assert!(killed, "the run ended before it could be killed");
    assert!(!out.exists(), "nothing where results are looked for");
    let o = run(sample(&out, false));
    assert_fails(&o, &["interrupted run", "--resume"]);
    let bytes = std::fs::read(&checkpoint).unwrap();
    std::fs::write(&checkpoint, &bytes[..bytes.len() - 100]).unwrap();
    let o = run(sample(&out, true));
    assert_fails(&o, &["checkpoint.mcmc"]);
    assert!(!out.exists());
    std::fs::write(&checkpoint, &bytes).unwrap();
    assert_ok(&run(sample(&out, true)));
    for f in ["draws.npy", "posterior.json", "ln_posterior.npy"] {
        let a = std::fs::read(out.join(f)).unwrap();
        let b = std::fs::read(reference.join(f)).unwrap();
        if f == "posterior.json" {
            // Wall times differ; everything else must not.
            let strip = |v: &[u8]| -> serde_json::Value {
                let mut j: serde_json::Value = serde_json::from_slice(v).unwrap();
                j.as_object_mut().unwrap().remove("wall_s");
                j
            };
            assert_eq!(strip(&a), strip(&b), "{f}");
        } else {
            assert_eq!(a, b, "{f} differs from the uninterrupted run");
        }
    }
    assert_eq!(names(tmp.path()), ["out", "reference"]);
}

/// A case file with the fixture campaign as its one case.
fn tiny_cases(dir: &Path) -> PathBuf {
    let cases = dir.join("cases.toml");
    std::fs::write(
        &cases,
        format!(
            "hypotheses = []\n[[case]]\nid = \"tiny\"\nmodel = {:?}\nverdict = \"none\"\n\
             location = {{}}\nsize = \"-\"\nnoise_scale = 1.0\nseed = 16\n",
            s(&repo().join("tests/fixtures/faults/tiny.toml"))
        ),
    )
    .unwrap();
    cases
}

fn benchmark(cases: &Path, work: &Path, resume: bool) -> Command {
    let report = work.with_extension("md");
    let mut c = frfbayes(&["diagnose-benchmark", "--cases", s(cases), "--work", s(work)]);
    c.args(["--report", s(&report), "--quick"]);
    if resume {
        c.arg("--resume");
    }
    c
}

/// `diagnose-benchmark` killed inside a case's diagnosis and rerun with `--resume`:
/// the case's `diagnosis.json` is the uninterrupted run's.
#[test]
fn benchmark_killed_mid_case_resumes_to_the_same_diagnosis() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = tiny_cases(tmp.path());
    let reference = tmp.path().join("reference");
    assert_ok(&run(benchmark(&cases, &reference, false)));
    let work = tmp.path().join("work");
    // The nominal model's evidence stage, named as `diagnose` names it.
    let nominal = frfbayes::discrepancy::model_evidence::evidence_key("nominal");
    let stage = work.join(format!("diagnoses/.tiny.frfbayes-partial/{nominal}.stage"));
    let killed = kill_when(
        benchmark(&cases, &work, false),
        Duration::from_secs(60),
        || stage.exists(),
    );
    assert!(killed, "the run ended before it could be killed");
    assert!(!work.join("diagnoses/tiny").exists());
    assert_ok(&run(benchmark(&cases, &work, true)));
    let json = |w: &Path| std::fs::read(w.join("diagnoses/tiny/diagnosis.json")).unwrap();
    assert_eq!(json(&work), json(&reference));
    assert_eq!(names(&work.join("diagnoses")), ["tiny"]);
    assert_eq!(names(&work.join("campaigns")), ["tiny"]);
}
