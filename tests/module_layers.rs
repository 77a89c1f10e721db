//! The layering of the crate's top-level modules, checked on the source text: every path
//! `crate::<module>` (and `frfbayes::<module>` in the binary's `src/cli`) outside
//! comments, including the members of grouped imports `crate::{a::x, b}`, must name a
//! module of a strictly lower layer. So there is no cycle between top-level modules, and
//! a lower layer never imports an upper one.
//!
//! `super::` paths are not followed (they stay inside a module here); `crate::error` and
//! the crate root are open to every module.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The allowed order, lowest first: a module may import only modules of earlier rows.
/// `plot` only renders (it needs `io` for atomic writes); `simulate`, `update` and `mcmc`
/// sit on the data and model layers; the studies sit on them; `cli` is the binary.
const LAYERS: &[&[&str]] = &[
    &["dist"],
    &["model"],
    &["modal"],
    &["frf"],
    &["predict"],
    &["io"],
    &["uff"],
    &["signal", "plot", "report"],
    &["simulate", "update", "mcmc"],
    &["infer"],
    &["bayes", "discrepancy"],
    &["experiment", "real"],
    &["cli"],
];

/// Modules of the crate root that every layer may use.
const OPEN: &[&str] = &["error", "Error", "Result"];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|row| row.contains(&module))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The source without comments (line, doc and block comments) and string literals,
/// newlines kept so that line numbers stay right.
fn strip_comments(src: &str) -> String {
    let b = src.as_bytes();
    let mut out = String::with_capacity(src.len());
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            let mut depth = 0;
            while i < b.len() {
                if b[i..].starts_with(b"/*") {
                    depth += 1;
                    i += 2;
                } else if b[i..].starts_with(b"*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if b[i] == b'\n' {
                        out.push('\n');
                    }
                    i += 1;
                }
            }
        } else if b[i..].starts_with(b"'\"'") || b[i..].starts_with(b"'\\\"'") {
            // the char literal '"' or '\"'
            i += if b[i + 1] == b'"' { 3 } else { 4 };
        } else if let Some(hashes) = raw_string_start(b, i) {
            let close = format!("\"{}", "#".repeat(hashes));
            let body = i + hashes + 2;
            let end = src[body..]
                .find(&close)
                .map_or(b.len(), |k| body + k + close.len());
            out.extend(src[i..end].chars().filter(|&c| c == '\n'));
            i = end;
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                } else if b[i] == b'\n' {
                    out.push('\n');
                }
                i += 1;
            }
            i += 1;
        } else {
            let len = src[i..].chars().next().unwrap().len_utf8();
            out.push_str(&src[i..i + len]);
            i += len;
        }
    }
    out
}

/// `Some(number of #)` when a raw string `r"`, `r#"`, ... starts at `b[i]`.
fn raw_string_start(b: &[u8], i: usize) -> Option<usize> {
    if b[i] != b'r' || (i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')) {
        return None;
    }
    let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
    (b.get(i + 1 + hashes) == Some(&b'"')).then_some(hashes)
}

fn ident_at(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// The first segments of the paths inside a group `{a::x, b, c::{d, e}}` that starts at
/// `s[0] == '{'`.
fn group_heads(s: &str) -> Vec<&str> {
    let mut heads = Vec::new();
    let mut depth = 0;
    let mut expect_head = true;
    for (i, c) in s.char_indices() {
        match c {
            '{' => {
                depth += 1;
                expect_head = depth == 1;
            }
            '}' => {
                depth -= 1;
                if depth == 0 {
                    break;
                }
            }
            ',' if depth == 1 => expect_head = true,
            c if expect_head && depth == 1 && (c.is_alphabetic() || c == '_') => {
                heads.push(ident_at(&s[i..]));
                expect_head = false;
            }
            _ => {}
        }
    }
    heads
}

/// `(line, imported top-level module)` of every `<root>::<module>` path in `code`.
fn imports(code: &str, root: &str) -> Vec<(usize, String)> {
    let pat = format!("{root}::");
    let mut found = Vec::new();
    for (start, _) in code.match_indices(&pat) {
        let before = code[..start].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
            continue;
        }
        let line = code[..start].matches('\n').count() + 1;
        let rest = &code[start + pat.len()..];
        if rest.starts_with('{') {
            found.extend(group_heads(rest).into_iter().map(|m| (line, m.to_string())));
        } else {
            found.push((line, ident_at(rest).to_string()));
        }
    }
    found
}

struct Edge {
    from: String,
    to: String,
    at: String,
}

fn edges(src: &Path) -> Vec<Edge> {
    let mut edges = Vec::new();
    for dir in std::fs::read_dir(src).unwrap() {
        let dir = dir.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        let from = dir.file_name().unwrap().to_str().unwrap().to_string();
        let root = if from == "cli" { "frfbayes" } else { "crate" };
        let mut files = Vec::new();
        rust_files(&dir, &mut files);
        for file in files {
            let code = strip_comments(&std::fs::read_to_string(&file).unwrap());
            for (line, to) in imports(&code, root) {
                if to != from && !OPEN.contains(&to.as_str()) {
                    let at = format!("{}:{line}", file.display());
                    edges.push(Edge {
                        from: from.clone(),
                        to,
                        at,
                    });
                }
            }
        }
    }
    edges
}

#[test]
fn every_top_level_module_has_a_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    for dir in std::fs::read_dir(&src).unwrap() {
        let dir = dir.unwrap().path();
        if dir.is_dir() {
            let name = dir.file_name().unwrap().to_str().unwrap().to_string();
            assert!(
                layer_of(&name).is_some(),
                "src/{name} has no row in LAYERS of tests/module_layers.rs: add it there"
            );
        }
    }
}

#[test]
fn modules_import_only_lower_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let edges = edges(&src);
    assert!(
        edges.iter().any(|e| e.from == "bayes" && e.to == "mcmc"),
        "the scan found no bayes -> mcmc import: the parser is broken"
    );
    let mut wrong: BTreeMap<(String, String), Vec<String>> = BTreeMap::new();
    for e in &edges {
        let (Some(from), Some(to)) = (layer_of(&e.from), layer_of(&e.to)) else {
            panic!("{}: {} -> {}: module not in LAYERS", e.at, e.from, e.to);
        };
        if to >= from {
            wrong
                .entry((e.from.clone(), e.to.clone()))
                .or_default()
                .push(e.at.clone());
        }
    }
    let report: Vec<String> = wrong
        .iter()
        .map(|((a, b), at)| format!("{a} -> {b} (layer not below): {}", at.join(", ")))
        .collect();
    assert!(
        report.is_empty(),
        "imports against the layering in tests/module_layers.rs:\n{}",
        report.join("\n")
    );
}

#[test]
fn the_scanner_reads_grouped_imports_and_skips_comments() {
    let code = strip_comments(
        "use crate::{io::x, signal};\n// crate::bayes\n/* crate::real */ let s = \"crate::cli\";\n\
         let c = '\"'; let r = r#\"crate::plot \" crate::mcmc\"#;\n\
         use crate::frf::FrfKind; mycrate::model",
    );
    let found = imports(&code, "crate");
    let want = [(1, "io"), (1, "signal"), (5, "frf")];
    assert_eq!(
        found,
        want.map(|(l, m)| (l, m.to_string())).to_vec(),
        "{code}"
    );
}
