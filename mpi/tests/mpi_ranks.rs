//! `mpirun -n 2 frfbayes-mpi ...` gives the same results as one process (issue 15, item 1),
//! on the built binary (`frfbayes-mpi`, this package):
//! - `sample`: one posterior whose walker evaluations are spread over the ranks;
//! - `diagnose --quick`: the hypotheses' searches and evidence runs on different ranks;
//! - `diagnose-benchmark --quick` on two cases: one case per rank, written by rank 0;
//!   a rank that fails is named in the error, and the case rank 0 finished is reused
//!   by the rerun;
//! - `real bridge-fe --quick`: the bridge study on the 946-DOF model read from
//!   `../shared` (skipped with a message, checking nothing, when the data are absent),
//!   its posterior's walkers spread over the ranks.
//!
//! Outputs are compared byte for byte, except the records of wall time: `run.json`,
//! `seconds.txt`, wall-time keys of JSON files, `<number> s` (and `ms`, `us`, speed
//! ratios `(<number>x)`) and tables of wall times in Markdown and HTML, the copy of
//! `run.json` that ends `report.html`, the time column of the benchmark report.
//!
//! Needs OpenMPI's `mpirun`; without it the tests print a skip message, unless
//! `FRFBAYES_REQUIRE_EXTERNAL=1` (CI), which makes a missing tool a failure.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_frfbayes-mpi");

/// The repository (this package is its `mpi/`).
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

/// One test at a time: each runs two ranks, and the machine may have two cores.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner())
}

/// True when `mpirun` runs; otherwise a skip message, or a panic under
/// `FRFBAYES_REQUIRE_EXTERNAL=1`.
fn have_mpirun() -> bool {
    let ok = Command::new("mpirun")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        let msg = "mpirun not found (Debian: apt-get install openmpi-bin libopenmpi-dev)";
        if std::env::var("FRFBAYES_REQUIRE_EXTERNAL").is_ok_and(|v| v == "1") {
            panic!("{msg}; FRFBAYES_REQUIRE_EXTERNAL=1 makes this a failure");
        }
        eprintln!("skipping: {msg}");
    }
    ok
}

/// Prints a wall time (the README's scaling table comes from these lines).
fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    let t0 = std::time::Instant::now();
    let v = f();
    eprintln!("timing: {what}: {:.1} s", t0.elapsed().as_secs_f64());
    v
}

/// `frfbayes-mpi args` in one process (from the repository) (one thread, as each rank below).
fn single(args: &[&str]) -> Output {
    let out = Command::new(BIN)
        .current_dir(REPO)
        .arg("--threads")
        .arg("1")
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// `mpirun -n 2 frfbayes-mpi --threads 1 args` (from the repository) (on a 2-core machine shared with others:
/// oversubscription allowed; root allowed, as in CI).
fn two_ranks(args: &[&str]) -> Output {
    Command::new("mpirun")
        .current_dir(REPO)
        .args(["-n", "2", "--oversubscribe", "--bind-to", "none"])
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .arg(BIN)
        .args(["--threads", "1"])
        .args(args)
        .output()
        .unwrap()
}

fn ok(out: Output) -> Output {
    assert!(
        out.status.success(),
        "mpirun failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Every file under `dir` by relative path, with the wall-time records blanked.
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    for (rel, bytes) in frfbayes::io::read_tree(dir).unwrap() {
        let name = rel.rsplit('/').next().unwrap_or_default();
        if matches!(name, "run.json" | "seconds.txt") {
            continue;
        }
        let bytes = if name.ends_with(".json") {
            let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
            drop_wall_times(&mut v);
            v.to_string().into_bytes()
        } else if name.ends_with(".md") || name.ends_with(".html") {
            mask_wall_times(&String::from_utf8_lossy(&bytes)).into_bytes()
        } else {
            bytes
        };
        out.insert(rel, bytes);
    }
    out
}

/// Keys of wall times in the JSON records (and every key ending `wall_s`).
const WALL_TIME_KEYS: [&str; 8] = [
    "wall_s",
    "elapsed_s",
    "timings",
    "timings_s",
    "build_s",
    "polish_s",
    "reduced_eval_s",
    "exact_eval_s",
];

fn drop_wall_times(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(m) => {
            m.retain(|k, _| !WALL_TIME_KEYS.contains(&k.as_str()) && !k.ends_with("wall_s"));
            m.values_mut().for_each(drop_wall_times);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(drop_wall_times),
        _ => {}
    }
}

/// The text with every `<number> s` (`ms`, `us`; and a speed ratio `(<number>x)`)
/// replaced by `# s` and the rows of a table of wall times (Markdown or HTML) left out.
fn mask_wall_times(text: &str) -> String {
    let mut out = String::new();
    let mut in_table = false;
    for line in text.lines() {
        if line.contains("<code>run.json</code>") {
            break; // report.html ends with the run's record (command line, start, times)
        }
        if line.contains("wall time") || line.contains("wall (s)") {
            in_table = true;
            continue;
        }
        if in_table {
            let md_row = line.starts_with('|');
            let html_row = line.starts_with("<tr") || line.starts_with("<td") || line == "</tr>";
            if md_row || html_row || line.contains("</t") {
                continue;
            }
            in_table = false;
        }
        out.push_str(&mask_seconds(line));
        out.push('\n');
    }
    out
}

fn mask_seconds(line: &str) -> String {
    let b = line.as_bytes();
    let mut out = String::new();
    let mut i = 0;
    while i < b.len() {
        let num_start = i;
        while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
            i += 1;
        }
        if i > num_start {
            let unit = [" s", " ms", " us", " µs", "x)"]
                .into_iter()
                .find(|u| line[i..].starts_with(u));
            let next = unit.and_then(|u| b.get(i + u.len()).copied());
            if unit.is_some() && !next.unwrap_or(b' ').is_ascii_alphanumeric() {
                out.push('#');
            } else {
                out.push_str(&line[num_start..i]);
            }
        } else {
            let len = line[i..].chars().next().map_or(1, char::len_utf8);
            out.push_str(&line[i..i + len]);
            i += len;
        }
    }
    out
}

fn assert_same_trees(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    assert!(!ta.is_empty(), "{} is empty", a.display());
    assert_eq!(
        ta.keys().collect::<Vec<_>>(),
        tb.keys().collect::<Vec<_>>(),
        "same files"
    );
    let differ: Vec<&String> = ta.keys().filter(|k| ta[*k] != tb[*k]).collect();
    assert!(
        differ.is_empty(),
        "files differ between 1 and 2 ranks: {differ:?}"
    );
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn sample_on_two_ranks_is_bit_identical() {
    if !have_mpirun() {
        return;
    }
    let _serial = serial();
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("one"), tmp.path().join("two"));
    let run = |out: &PathBuf| -> Vec<String> {
        [
            "sample",
            "--tests",
            "shake_table",
            "--damping",
            "rayleigh",
            "--frf",
            "receptance",
            "--seed",
            "5",
            "--max-steps",
            "200",
            "--out",
            path_str(out),
        ]
        .map(String::from)
        .to_vec()
    };
    let args_a = run(&a);
    let args_b = run(&b);
    let (args_a, args_b): (Vec<&str>, Vec<&str>) = (
        args_a.iter().map(String::as_str).collect(),
        args_b.iter().map(String::as_str).collect(),
    );
    timed("sample, 1 process", || single(&args_a));
    timed("sample, 2 ranks", || ok(two_ranks(&args_b)));
    assert!(a.join("posterior.json").exists());
    assert_same_trees(&a, &b);
    // Only rank 0 wrote: no scratch left, nothing beside the output.
    let names: Vec<String> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

/// Ignored in the default run to keep CI within its 25 minutes (about 4 min of two
/// diagnoses); the benchmark test below farms diagnoses over the ranks too:
///
/// ```sh
/// cargo test --release -p frfbayes-mpi --test mpi_ranks -- --ignored
/// ```
#[test]
#[ignore]
fn diagnose_on_two_ranks_is_bit_identical() {
    if !have_mpirun() {
        return;
    }
    let _serial = serial();
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("campaign");
    let model = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../experiments/models/discrepancy/secondary_oscillator-1.toml"
    );
    single(&["simulate", "--model", model, "--out", path_str(&campaign)]);
    let (a, b) = (tmp.path().join("one"), tmp.path().join("two"));
    let args = |out: &Path| {
        [
            "diagnose",
            path_str(&campaign),
            "--quick",
            "--only",
            "base_flexibility,secondary_oscillator",
            "--seed",
            "2",
            "--out",
            path_str(out),
        ]
        .map(String::from)
    };
    timed("diagnose, 1 process", || {
        single(&args(&a).each_ref().map(String::as_str))
    });
    timed("diagnose, 2 ranks", || {
        ok(two_ranks(&args(&b).each_ref().map(String::as_str)))
    });
    assert_same_trees(&a, &b);
}

/// The general model's benchmark (six-DOF campaigns: a `--quick` diagnosis with one
/// hypothesis takes 9-18 s on one thread, a four-story case's 35-40 s, most of it the
/// longer records' FRF estimation and consistency checks).
const CASES: &str = "experiments/models/discrepancy/general/cases.toml";

#[test]
fn benchmark_on_two_ranks_is_bit_identical_and_a_failed_rank_is_named() {
    if !have_mpirun() {
        return;
    }
    let _serial = serial();
    let tmp = tempfile::tempdir().unwrap();
    let cases = Path::new(REPO).join(CASES);
    let bench = |work: &Path| {
        [
            "diagnose-benchmark",
            "--quick",
            "--cases",
            path_str(&cases),
            "--only",
            "general-none-1,general-oscillator-1",
            "--hypotheses",
            "sensor_timing",
            "--work",
            path_str(work),
            "--report",
            path_str(&work.join("report.md")),
        ]
        .map(String::from)
    };
    let (a, b) = (tmp.path().join("one"), tmp.path().join("two"));
    timed("benchmark, 2 cases, 1 process", || {
        single(&bench(&a).each_ref().map(String::as_str))
    });
    // Rank 1 cannot write its scratch folder: the run fails, naming rank 1 and why;
    // rank 0's case is written and reused by the rerun.
    let t0 = std::time::Instant::now();
    let failed = Command::new("mpirun")
        .current_dir(REPO)
        .args(["--oversubscribe", "--bind-to", "none"])
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .args(["-n", "1", BIN, "--threads", "1"])
        .args(bench(&b))
        .args([
            ":",
            "-n",
            "1",
            "-x",
            "TMPDIR=/dev/null/none",
            BIN,
            "--threads",
            "1",
        ])
        .args(bench(&b))
        .output()
        .unwrap();
    let secs = t0.elapsed().as_secs_f64();
    eprintln!("timing: benchmark, 2 cases, 2 ranks (rank 1 fails at the end): {secs:.1} s");
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(!failed.status.success(), "{stderr}");
    assert!(stderr.contains("rank 1 of 2 failed"), "{stderr}");
    assert!(
        b.join("diagnoses/general-none-1/diagnosis.json").exists(),
        "{stderr}"
    );
    assert!(!b.join("diagnoses/general-oscillator-1").exists());
    let out = timed("benchmark, 1 case left (rerun), 2 ranks", || {
        ok(two_ranks(&bench(&b).each_ref().map(String::as_str)))
    });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("general-none-1: read back"), "{stderr}");
    for id in ["general-none-1", "general-oscillator-1"] {
        let d = format!("diagnoses/{id}");
        assert_same_trees(&a.join(&d), &b.join(&d));
    }
    // The report differs only in its time column.
    let table = |w: &Path| -> Vec<String> {
        let md = std::fs::read_to_string(w.join("report.md")).unwrap();
        md.lines()
            .map(|l| match l.rfind(" | ") {
                Some(i) if l.starts_with("| ") && l.ends_with(" |") => l[..i].to_string(),
                _ => l.to_string(),
            })
            .collect()
    };
    assert_eq!(table(&a), table(&b));
}

/// The bridge data in `../shared` (or `$FRFBAYES_SHARED_DIR`), else a skip message.
fn bridge_shared() -> Option<PathBuf> {
    let root = frfbayes::model::shared_root();
    let root = if root.is_relative() {
        Path::new(REPO).join(root)
    } else {
        root
    };
    if root.join("data/real/bridge-fe").is_dir() {
        Some(root)
    } else {
        println!(
            "skipped: {}/data/real/bridge-fe not found (no ../shared beside the repository \
             and no FRFBAYES_SHARED_DIR): nothing checked",
            root.display()
        );
        None
    }
}

/// The bridge posterior (`real bridge-fe --quick`: 48 x 4 walkers, 100 steps on the
/// reduced basis; the multistart, polish and checks run on every rank) on two ranks
/// against one process: every output the same bits, `inference_data.nc` included.
#[test]
fn bridge_posterior_on_two_ranks_is_bit_identical() {
    if !have_mpirun() {
        return;
    }
    let Some(shared) = bridge_shared() else {
        return;
    };
    let _serial = serial();
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("one"), tmp.path().join("two"));
    let args = |out: &Path| {
        [
            "real",
            "bridge-fe",
            "--quick",
            "--shared",
            path_str(&shared),
            "--seed",
            "2",
            "--out",
            path_str(out),
        ]
        .map(String::from)
    };
    timed("real bridge-fe --quick, 1 process", || {
        single(&args(&a).each_ref().map(String::as_str))
    });
    timed("real bridge-fe --quick, 2 ranks", || {
        ok(two_ranks(&args(&b).each_ref().map(String::as_str)))
    });
    let post: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("posterior.json")).unwrap()).unwrap();
    assert_eq!(post["n_steps"], serde_json::json!(100), "{post}");
    assert!(a.join("inference_data.nc").is_file());
    assert_same_trees(&a, &b);
}
