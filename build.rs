//! Records the rustc version for `run.json`.
fn main() {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    if let Ok(out) = std::process::Command::new(rustc).arg("--version").output() {
        if let Ok(v) = String::from_utf8(out.stdout) {
            println!("cargo:rustc-env=RUSTC_VERSION={}", v.trim());
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
}
