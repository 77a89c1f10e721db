use super::*;

/// A study folder: a report with a table, an image, a verdict and timings; two PNGs
/// (one referenced); run.json.
fn study() -> tempfile::TempDir {
    let t = tempfile::tempdir().unwrap();
    let md = "# Shear frame <study>\n\nIntro text.\n\n## Posterior\n\n\
              | parameter | mean |\n|---|---|\n| k1 | 1171.6 |\n\n![Traces](traces.png)\n\n\
              ## Timings\n\n- sampling: 7.8 s\n\n## Verdict\n\nThe model fits.\n";
    std::fs::write(t.path().join("report.md"), md).unwrap();
    std::fs::write(t.path().join("traces.png"), b"\x89PNG traces").unwrap();
    std::fs::write(t.path().join("corner.png"), b"\x89PNG corner").unwrap();
    std::fs::write(
        t.path().join("run.json"),
        r#"{"seed": 7, "command": "a<b"}"#,
    )
    .unwrap();
    t
}

fn spec() -> HtmlReport<'static> {
    HtmlReport {
        markdown: &["report.md", "absent.md"],
        lead: LEAD,
        tail: TAIL,
        title: None,
    }
}

fn pos(html: &str, needle: &str) -> usize {
    html.find(needle)
        .unwrap_or_else(|| panic!("{needle:?} not in the page"))
}

#[test]
fn verdict_first_tables_and_figures_inline_settings_last() {
    let t = study();
    let path = write_html_report(t.path(), &spec()).unwrap();
    let html = std::fs::read_to_string(path).unwrap();
    assert!(html.contains("<title>Shear frame &lt;study&gt;</title>"));
    // Order: verdict, body (with its table and figure), other figures, timings, run.json.
    let order = [
        "<h2>Verdict</h2>",
        "Intro text.",
        "<h2>Posterior</h2>",
        "<table>",
        "<td>1171.6</td>",
        "<h2>Figures</h2>",
        "<h2>Timings</h2>",
        "Settings of the run",
        "&quot;seed&quot;: 7",
    ];
    let at: Vec<usize> = order.iter().map(|n| pos(&html, n)).collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "{order:?} at {at:?}");
    // Figures inline, each exactly once; no file outside the page is referenced.
    let traces = base64::engine::general_purpose::STANDARD.encode(b"\x89PNG traces");
    let corner = base64::engine::general_purpose::STANDARD.encode(b"\x89PNG corner");
    assert_eq!(html.matches(&traces).count(), 1);
    assert_eq!(html.matches(&corner).count(), 1);
    assert!(pos(&html, &corner) > pos(&html, "<h2>Figures</h2>"));
    assert_eq!(html.matches("src=\"").count(), 2);
    assert_eq!(html.matches("src=\"data:image/png;base64,").count(), 2);
    assert!(html.contains("a&lt;b"), "run.json escaped");
}

#[test]
fn links_outside_the_folder_or_missing_are_left_alone() {
    let t = study();
    std::fs::write(
        t.path().join("report.md"),
        "## A\n\n![x](../secret.png) ![y](missing.png) ![z](https://example.org/a.png)\n",
    )
    .unwrap();
    let spec = HtmlReport {
        title: Some("Given <title>"),
        ..spec()
    };
    let html = render_html(t.path(), &spec).unwrap();
    assert!(html.contains("<title>Given &lt;title&gt;</title>"));
    assert!(html.contains("src=\"../secret.png\"") && html.contains("src=\"missing.png\""));
    assert!(html.contains("src=\"https://example.org/a.png\""));
}

#[test]
fn unreadable_folder_is_an_error_naming_it() {
    let t = tempfile::tempdir().unwrap();
    let gone = t.path().join("gone");
    let err = render_html(&gone, &spec()).unwrap_err().to_string();
    assert!(err.contains("gone"), "{err}");
}

#[test]
fn unshown_figures_go_under_the_markdowns_figures_section() {
    let t = study();
    std::fs::write(
        t.path().join("report.md"),
        "# S\n\n## Figures\n\n- `corner.png`: a corner plot\n\n## Model\n\nm\n\n\
         ### In short\n\nshort\n\n### Detail\n\nd\n",
    )
    .unwrap();
    let html = render_html(t.path(), &spec()).unwrap();
    assert_eq!(html.matches("<h2>Figures</h2>").count(), 1);
    let corner = base64::engine::general_purpose::STANDARD.encode(b"\x89PNG corner");
    let order = [
        "<h3>In short</h3>",
        "<h2>Figures</h2>",
        &corner,
        "<h2>Model</h2>",
        "<h3>Detail</h3>",
    ];
    let at: Vec<usize> = order.iter().map(|n| pos(&html, n)).collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "{at:?}");
}
