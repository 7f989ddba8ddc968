//! `docs/safety.md` stays true: every hazard row names at least one test, and every
//! test it names exists (as `fn name`) in the file the row links.

use std::path::Path;

/// The test column's links: (file, test names after it).
fn links(cell: &str) -> Vec<(String, Vec<String>)> {
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    let mut rest = cell;
    while let Some(open) = rest.find("](../") {
        let after = &rest[open + 5..];
        let Some(close) = after.find(')') else { break };
        let file = after[..close].to_string();
        let tail = &after[close + 1..];
        let next = tail.find("[`").unwrap_or(tail.len());
        let names = tail[..next]
            .split('`')
            .skip(1)
            .step_by(2)
            .map(|n| n.rsplit("::").next().unwrap_or(n).to_string())
            .filter(|n| {
                n.chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
            })
            .collect();
        out.push((file, names));
        rest = &tail[next..];
    }
    out
}

#[test]
fn every_hazard_row_links_tests_that_exist() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let doc = std::fs::read_to_string(root.join("docs/safety.md")).expect("docs/safety.md");
    let mut rows = 0;
    for line in doc.lines().filter(|l| l.starts_with("| ")) {
        let cells: Vec<&str> = line.split(" | ").collect();
        if cells[0] == "| hazard" || cells.len() < 5 {
            continue;
        }
        rows += 1;
        let found = links(cells[3]);
        let named: usize = found.iter().map(|(_, n)| n.len()).sum();
        assert!(named > 0, "row without a test: {}", cells[0]);
        for (file, names) in found {
            let src = std::fs::read_to_string(root.join(&file))
                .unwrap_or_else(|e| panic!("{file} (row {}): {e}", cells[0]));
            for n in names {
                assert!(
                    src.contains(&format!("fn {n}(")),
                    "{file} has no test `{n}` (row {})",
                    cells[0]
                );
            }
        }
    }
    assert!(rows >= 10, "only {rows} hazard rows");
}
