//! The README and the documents under `docs/` hold on a clean clone: every relative
//! link points at a file that exists (and, with `#anchor`, at a heading of that file),
//! every repository path they quote in backticks exists, and the README stays a front
//! page (at most 10 KB).

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The Markdown files the checks cover: README, ARCHITECTURE, BENCHMARKS and `docs/**`.
fn documents() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "md") {
                out.push(p);
            }
        }
    }
    let r = root();
    let mut out = vec![
        r.join("README.md"),
        r.join("ARCHITECTURE.md"),
        r.join("BENCHMARKS.md"),
    ];
    walk(&r.join("docs"), &mut out);
    out
}

/// GitHub's anchor of a heading: lower case, spaces to '-', punctuation dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a Markdown file's headings (outside code blocks).
fn anchors(text: &str) -> Vec<String> {
    let mut fenced = false;
    let mut out = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced && line.starts_with('#') {
            out.push(slug(line.trim_start_matches('#')));
        }
    }
    out
}

/// `](target)` links of a Markdown text, outside code blocks.
fn links(text: &str) -> Vec<String> {
    let mut fenced = false;
    let mut out = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let mut rest = line;
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let Some(end) = after.find(')') else { break };
            out.push(after[..end].to_string());
            rest = &after[end..];
        }
    }
    out
}

#[test]
fn every_relative_link_resolves() {
    let mut bad = Vec::new();
    let mut checked = 0;
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).expect("readable document");
        let dir = doc.parent().expect("a directory");
        for link in links(&text) {
            if link.starts_with("http://") || link.starts_with("https://") {
                continue;
            }
            checked += 1;
            let (file, anchor) = match link.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (link.as_str(), None),
            };
            let target = if file.is_empty() {
                doc.clone()
            } else {
                dir.join(file)
            };
            if !target.exists() {
                bad.push(format!("{}: {link} (no such file)", doc.display()));
                continue;
            }
            if let Some(a) = anchor {
                let t = std::fs::read_to_string(&target).unwrap_or_default();
                if !anchors(&t).iter().any(|h| h == a) {
                    bad.push(format!("{}: {link} (no such heading)", doc.display()));
                }
            }
        }
    }
    assert!(
        checked > 50,
        "only {checked} links found: is the parser right?"
    );
    assert!(bad.is_empty(), "broken links:\n{}", bad.join("\n"));
}

/// Repository paths quoted in backticks (`firmware/src/board.rs`) exist.
#[test]
fn quoted_repository_paths_exist() {
    const TOP: &[&str] = &[
        "firmware/",
        "foc/",
        "ecat-slave-stack/",
        "tests-host/",
        "xtask/",
        "efw/",
        "bootloader/",
        "docs/",
        "keys/",
        "commission/",
    ];
    let r = root();
    let mut bad = Vec::new();
    let mut checked = 0;
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).expect("readable document");
        for (i, quoted) in text.split('`').enumerate() {
            if i % 2 == 0 || quoted.contains(['<', '*', ' ', '{', '|']) {
                continue;
            }
            if !TOP.iter().any(|t| quoted.starts_with(t)) {
                continue;
            }
            checked += 1;
            // `path::item` names an item in the file.
            let path = quoted.split("::").next().unwrap_or(quoted);
            if !r.join(path.trim_end_matches(':')).exists() {
                bad.push(format!("{}: `{quoted}`", doc.display()));
            }
        }
    }
    assert!(
        checked > 30,
        "only {checked} paths found: is the parser right?"
    );
    assert!(
        bad.is_empty(),
        "quoted paths that do not exist:\n{}",
        bad.join("\n")
    );
}

#[test]
fn readme_is_a_front_page() {
    let len = std::fs::metadata(root().join("README.md"))
        .expect("README.md")
        .len();
    assert!(
        len <= 10 * 1024,
        "README.md is {len} bytes, more than 10 KB"
    );
}
