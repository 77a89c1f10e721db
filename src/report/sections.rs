//! Splitting Markdown at its headings, to put the verdict first and the run's settings
//! last. Lines that start with `## ` outside fenced code blocks split; a `### `
//! subsection is cut out only when its own heading marks it lead or tail (it then runs
//! to the next `##` or `###`); text is never changed.

/// Where a section goes on the page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Section {
    Lead,
    Body,
    Tail,
}

/// True for a line that opens or closes a fenced code block.
fn is_fence(line: &str) -> bool {
    let l = line.trim_start();
    l.starts_with("```") || l.starts_with("~~~")
}

/// Level (2 or 3) and text of a `## ` or `### ` line.
fn heading(line: &str) -> Option<(u8, &str)> {
    if let Some(h) = line.strip_prefix("## ") {
        Some((2, h.trim()))
    } else {
        line.strip_prefix("### ").map(|h| (3, h.trim()))
    }
}

fn matches(heading: &str, prefixes: &[&str]) -> bool {
    let h = heading.to_lowercase();
    prefixes.iter().any(|p| h.starts_with(&p.to_lowercase()))
}

/// Cuts Markdown files into marked sections.
struct Splitter<'p> {
    lead: &'p [&'p str],
    tail: &'p [&'p str],
    out: Vec<(Section, String)>,
    current: (Section, String),
    /// Kind of the enclosing level-2 section.
    parent: Section,
    /// The current section is a `###` cut out of its parent.
    in_cut: bool,
}

impl Splitter<'_> {
    fn kind(&self, h: &str) -> Section {
        if matches(h, self.lead) {
            Section::Lead
        } else if matches(h, self.tail) {
            Section::Tail
        } else {
            Section::Body
        }
    }

    fn start(&mut self, kind: Section) {
        let done = std::mem::replace(&mut self.current, (kind, String::new()));
        self.out.push(done);
    }

    /// Starts a new section if `level`/`h` begins one.
    fn heading(&mut self, level: u8, h: &str) {
        let kind = self.kind(h);
        if level == 2 {
            self.parent = kind;
            self.in_cut = false;
            self.start(kind);
        } else if kind != Section::Body && kind != self.parent {
            self.in_cut = true;
            self.start(kind);
        } else if self.in_cut {
            self.in_cut = false;
            self.start(self.parent);
        }
    }
}

/// The first file's level-1 heading (removed from the text when `take_title`) and every
/// file cut into sections, in order, each marked lead, body or tail.
pub(super) fn split_sections(
    texts: &[String],
    lead: &[&str],
    tail: &[&str],
    take_title: bool,
) -> (Option<String>, Vec<(Section, String)>) {
    let mut title = None;
    let mut sp = Splitter {
        lead,
        tail,
        out: Vec::new(),
        current: (Section::Body, String::new()),
        parent: Section::Body,
        in_cut: false,
    };
    for (i, text) in texts.iter().enumerate() {
        sp.parent = Section::Body;
        sp.in_cut = false;
        sp.start(Section::Body);
        let mut in_fence = false;
        for line in text.lines() {
            if is_fence(line) {
                in_fence = !in_fence;
            }
            let first = i == 0 && title.is_none() && sp.current.1.trim().is_empty();
            if !in_fence && take_title && first {
                if let Some(t) = line.strip_prefix("# ") {
                    title = Some(t.trim().to_owned());
                    continue;
                }
            }
            if let Some((level, h)) = heading(line).filter(|_| !in_fence) {
                sp.heading(level, h);
            }
            sp.current.1 += line;
            sp.current.1.push('\n');
        }
    }
    sp.start(Section::Body);
    let mut out = sp.out;
    out.retain(|s| !s.1.trim().is_empty());
    (title, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn verdict_and_settings_are_marked_and_fences_do_not_split() {
        let md = "# Study\n\nIntro.\n\n## Model\n\nm\n```\n## not a heading\n```\n\
                  ## Verdict\n\nIt fits.\n\n### Detail\n\nd\n\n## Timings\n\n- 1 s\n";
        let (title, s) = split_sections(&[md.to_owned()], &["verdict"], &["Timings"], true);
        assert_eq!(title.as_deref(), Some("Study"));
        let kinds: Vec<Section> = s.iter().map(|x| x.0).collect();
        use Section::*;
        assert_eq!(kinds, [Body, Body, Lead, Tail]);
        assert_eq!(s[0].1.trim(), "Intro.");
        assert!(s[1].1.contains("## not a heading"));
        assert!(s[2].1.starts_with("## Verdict") && s[2].1.contains("### Detail"));
        // A `###` verdict inside a body section is cut out up to the next `###`.
        let md = "## A\n\na\n\n### In short\n\ns\n\n### B\n\nb\n\n## C\n";
        let (title, s) = split_sections(&[md.to_owned()], &["in short"], &[], true);
        assert_eq!(title, None);
        let kinds: Vec<Section> = s.iter().map(|x| x.0).collect();
        assert_eq!(kinds, [Body, Lead, Body, Body]);
        assert!(s[1].1.starts_with("### In short") && !s[1].1.contains("### B"));
        assert!(s[2].1.starts_with("### B"));
        // A second file keeps its own level-1 heading.
        let (_, s) = split_sections(&[md.to_owned(), "# B\n\nb\n".to_owned()], &[], &[], true);
        assert!(s.last().unwrap().1.starts_with("# B"));
    }
}
