//! `frfbayes check <CAMPAIGN>` as a user runs it: exit code, stdout summary, warnings and
//! errors on stderr, and never a panic.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/campaigns")
}

fn check(campaign: &Path) -> (Output, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_frfbayes"))
        .arg("check")
        .arg(campaign)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    (out, stdout, stderr)
}

#[test]
fn malformed_cell_fails_naming_file_line_and_column() {
    let (out, _, stderr) = check(&fixtures().join("non_numeric_cell"));
    assert!(!out.status.success());
    assert!(
        stderr.contains("non_numeric_cell/tests/hammer-1/data.csv:4:3:"),
        "{stderr}"
    );
    assert!(stderr.contains("`abc` is not a number"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn every_malformed_fixture_fails_cleanly() {
    let mut n = 0;
    for entry in std::fs::read_dir(fixtures()).unwrap() {
        let path = entry.unwrap().path();
        let case = path.file_name().unwrap().to_string_lossy().into_owned();
        if !path.is_dir() || case == "valid" || case == "unknown_keys" {
            continue;
        }
        let (out, stdout, stderr) = check(&path);
        assert!(!out.status.success(), "{case}: exit code 0\n{stdout}");
        assert_eq!(out.status.code(), Some(1), "{case}: {stderr}");
        assert!(stderr.starts_with("error: "), "{case}: {stderr}");
        assert!(
            stderr.contains(&format!("{case}/")),
            "{case}: file not named: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{case}: {stderr}");
        n += 1;
    }
    assert!(n >= 30, "only {n} malformed fixtures found");
}

#[test]
fn missing_folder_fails_naming_campaign_toml() {
    let (out, _, stderr) = check(&fixtures().join("no-such-campaign"));
    assert!(!out.status.success());
    assert!(
        stderr.contains("no-such-campaign/campaign.toml"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn valid_campaign_is_summarised() {
    let (out, stdout, stderr) = check(&fixtures().join("valid"));
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
    assert!(stdout.contains("title: tiny frame"), "{stdout}");
    assert!(stdout.contains("shear_frame with 2 floors"), "{stdout}");
    assert!(
        stdout
            .contains("test hammer-1: hammer at floor 1, 100 Hz, 5 samples (0.050 s), 4 channels"),
        "{stdout}"
    );
    assert!(stdout.contains("test shake: shake table"), "{stdout}");
    assert!(stdout.contains("ground_acceleration"), "{stdout}");
}

#[test]
fn warnings_go_to_stderr_and_do_not_fail() {
    let (out, stdout, stderr) = check(&fixtures().join("unknown_keys"));
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.lines().count(), 5, "{stderr}");
    assert!(
        stderr.contains("warning: campaign.toml: unknown key `operator` ignored"),
        "{stderr}"
    );
    assert!(stdout.contains("2 tests"), "{stdout}");
}

#[test]
fn thread_count_is_checked_and_honoured() {
    let run = |threads: &str| {
        Command::new(env!("CARGO_BIN_EXE_frfbayes"))
            .args(["--threads", threads, "check"])
            .arg(fixtures().join("valid"))
            .output()
            .unwrap()
    };
    let zero = run("0");
    let stderr = String::from_utf8_lossy(&zero.stderr);
    assert_eq!(zero.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("--threads 0: give a number of threads of at least 1"));
    let one = run("1");
    assert!(
        one.status.success(),
        "{}",
        String::from_utf8_lossy(&one.stderr)
    );
}
