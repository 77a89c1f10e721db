//! One `report.html` per study: a self-contained page a person opens in a browser.
//!
//! It renders what a study already wrote, never computes science: the study's Markdown
//! files (through `pulldown-cmark`, tables included), its PNG figures inlined as base64
//! `data:` URIs (those the Markdown shows as images where they are, every other PNG of
//! the folder under the Markdown's "Figures" section or a new one), and its `run.json`
//! last. Sections named as the verdict (level-2 or level-3 headings such as "Verdict",
//! "Findings", "In short") come first, sections named as the run's settings ("Run",
//! "Timings", "Data") last.
//!
//! The page needs nothing outside itself (no network, no other file). A small script
//! sets `data-figures="<decoded>/<total>"` and `data-errors="<n>"` on `<body>` once the
//! page has loaded, so a headless browser can check that every figure decoded and
//! nothing failed (`tests/report_html.rs`).

mod sections;

use crate::error::{Error, Result};
use base64::Engine;
use pulldown_cmark::{CowStr, Event, Options, Parser, Tag};
use sections::{split_sections, Section};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// What a study's report is made of, all read from its output folder.
#[derive(Clone, Debug, Default)]
pub struct HtmlReport<'a> {
    /// Markdown files of the folder, in reading order; missing files are skipped.
    pub markdown: &'a [&'a str],
    /// Prefixes of level-2 headings that hold the verdict, moved to the top.
    pub lead: &'a [&'a str],
    /// Prefixes of level-2 headings that hold the run's settings, moved to the end.
    pub tail: &'a [&'a str],
    /// Page title; `None`: the first file's level-1 heading (then taken out of the text).
    pub title: Option<&'a str>,
}

/// Headings that usually hold the verdict and the settings in this crate's reports.
pub const LEAD: &[&str] = &["Verdict", "Findings", "In short", "Summary"];
pub const TAIL: &[&str] = &["Run", "Timings", "Data", "Settings"];

/// Writes `<dir>/report.html` (atomically) and returns its path.
pub fn write_html_report(dir: &Path, spec: &HtmlReport) -> Result<PathBuf> {
    let html = render_html(dir, spec)?;
    let path = dir.join("report.html");
    crate::io::write_atomic(&path, html.as_bytes())?;
    Ok(path)
}

/// The page as a string (see the module docs).
pub fn render_html(dir: &Path, spec: &HtmlReport) -> Result<String> {
    let mut texts = Vec::new();
    for name in spec.markdown {
        let path = dir.join(name);
        match std::fs::read_to_string(&path) {
            Ok(t) => texts.push(t),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(&path, e)),
        }
    }
    let (h1, sections) = split_sections(&texts, spec.lead, spec.tail, spec.title.is_none());
    let title = spec
        .title
        .map(str::to_owned)
        .or(h1)
        .unwrap_or("Report".into());
    let mut shown = BTreeSet::new();
    let mut body = String::new();
    let mut figures_at = None;
    for part in [Section::Lead, Section::Body] {
        for md in sections.iter().filter(|s| s.0 == part) {
            body += &markdown_html(&md.1, dir, &mut shown)?;
            if figures_at.is_none() && part == Section::Body && md.1.starts_with("## Figures") {
                figures_at = Some(body.len());
            }
        }
    }
    // After the Markdown's own "Figures" section (which names them), else at the end.
    let figures = other_figures(dir, &shown, figures_at.is_none())?;
    body.insert_str(figures_at.unwrap_or(body.len()), &figures);
    for md in sections.iter().filter(|s| s.0 == Section::Tail) {
        body += &markdown_html(&md.1, dir, &mut shown)?;
    }
    body += &run_settings(dir)?;
    Ok(page(&title, &body))
}

/// `s` escaped for HTML text and attribute values.
fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    // Writing into a String cannot fail.
    let _ = pulldown_cmark_escape::escape_html(&mut out, s);
    out
}

/// A relative link to a PNG file of `dir` (no scheme, no parent directory), if it exists.
fn local_png(dir: &Path, url: &str) -> Option<PathBuf> {
    let rel = Path::new(url);
    let plain = !url.contains(':') && rel.is_relative();
    let inside = rel
        .components()
        .all(|c| matches!(c, std::path::Component::Normal(_)));
    let png = rel
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let path = dir.join(rel);
    (plain && inside && png && path.is_file()).then_some(path)
}

fn data_uri(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let b64 = base64::engine::general_purpose::STANDARD.encode(bytes);
    Ok(format!("data:image/png;base64,{b64}"))
}

/// Markdown to HTML; images that name a PNG of `dir` are inlined and recorded in `shown`.
fn markdown_html(md: &str, dir: &Path, shown: &mut BTreeSet<String>) -> Result<String> {
    let opts = Options::ENABLE_TABLES | Options::ENABLE_STRIKETHROUGH;
    let mut events = Vec::new();
    for ev in Parser::new_ext(md, opts) {
        let ev = match ev {
            Event::Start(Tag::Image {
                link_type,
                dest_url,
                title,
                id,
            }) => {
                let dest_url = match local_png(dir, &dest_url) {
                    Some(path) => {
                        shown.insert(dest_url.to_string());
                        CowStr::from(data_uri(&path)?)
                    }
                    None => dest_url,
                };
                Event::Start(Tag::Image {
                    link_type,
                    dest_url,
                    title,
                    id,
                })
            }
            other => other,
        };
        events.push(ev);
    }
    let mut html = String::new();
    pulldown_cmark::html::push_html(&mut html, events.into_iter());
    Ok(html)
}

/// Every PNG directly in `dir` not already shown, each with its file name, under a
/// "Figures" heading if `heading`.
fn other_figures(dir: &Path, shown: &BTreeSet<String>, heading: bool) -> Result<String> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut names: Vec<String> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".png") && !n.starts_with('.') && !shown.contains(n))
        .collect();
    names.sort();
    if names.is_empty() {
        return Ok(String::new());
    }
    let mut html = String::from(if heading { "<h2>Figures</h2>\n" } else { "" });
    for n in names {
        let uri = data_uri(&dir.join(&n))?;
        let n = escape(&n);
        html += &format!(
            "<figure><img src=\"{uri}\" alt=\"{n}\"><figcaption>{n}</figcaption></figure>\n"
        );
    }
    Ok(html)
}

/// `run.json` of `dir`, pretty-printed, if there is one.
fn run_settings(dir: &Path) -> Result<String> {
    let path = dir.join("run.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(String::new()),
        Err(e) => return Err(Error::io(&path, e)),
    };
    let pretty = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| serde_json::to_string_pretty(&v).ok())
        .unwrap_or(text);
    Ok(format!(
        "<h2>Settings of the run (<code>run.json</code>)</h2>\n<pre><code>{}</code></pre>\n",
        escape(&pretty)
    ))
}

const STYLE: &str = "body{font-family:'DejaVu Sans',sans-serif;max-width:1100px;\
margin:2em auto;padding:0 1em;line-height:1.45;color:#111}\
table{border-collapse:collapse;margin:1em 0;font-size:.9em;display:block;overflow-x:auto}\
th,td{border:1px solid #ccc;padding:.25em .5em;text-align:left}th{background:#f0f0f0}\
img{max-width:100%;height:auto}figure{margin:1em 0}figcaption{color:#555;font-size:.9em}\
pre{background:#f6f6f6;padding:.8em;overflow-x:auto;font-size:.85em}";

/// Counts load errors (scripts, images) from the start, and after load sets
/// `data-figures="<decoded>/<total>"` and `data-errors="<n>"` on `<body>`.
const CHECK_SCRIPT: &str = "var loadErrors=0;\
window.addEventListener('error',function(){loadErrors+=1;},true);\
window.addEventListener('load',function(){\
var i=Array.prototype.slice.call(document.images);\
var ok=i.filter(function(x){return x.complete&&x.naturalWidth>0;}).length;\
document.body.setAttribute('data-figures',ok+'/'+i.length);\
document.body.setAttribute('data-errors',String(loadErrors));});";

fn page(title: &str, body: &str) -> String {
    let t = escape(title);
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
<title>{t}</title>\n<style>{STYLE}</style>\n<script>{CHECK_SCRIPT}</script>\n</head>\n\
<body>\n<h1>{t}</h1>\n{body}</body>\n</html>\n"
    )
}

#[cfg(test)]
mod tests;
