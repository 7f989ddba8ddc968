//! Size limits for the next engineer: no source file over [`MAX_FILE_LINES`] lines and
//! no function over [`MAX_FN_LINES`] lines in any crate's `src/`, tests left out
//! (`tests.rs` files, `tests/` directories and `#[cfg(test)] mod … { … }` blocks).
//!
//! The measure: a file's length is its line count without the test blocks. A function
//! starts at a line whose code begins with `fn` (after `pub`, `pub(…)`, `const`,
//! `async`, `unsafe`, `extern "…"`) at indentation I, and ends at the next line that is
//! exactly I spaces and `}`; its length counts both lines. Declarations without a body
//! (trait methods ending in `;`) and one-line functions are not functions here.

use std::path::{Path, PathBuf};

/// Longest source file, lines.
const MAX_FILE_LINES: usize = 800;
/// Longest function, lines (signature and closing brace included).
const MAX_FN_LINES: usize = 80;
/// Longest board `main.rs`, lines: it creates peripherals and spawns tasks that call
/// the runtime, and decides nothing itself (ARCHITECTURE.md, "One runtime").
const MAX_BOARD_MAIN_LINES: usize = 400;

/// The crates whose `src/` is checked.
const CRATES: &[&str] = &[
    "foc",
    "ecat-slave-stack",
    "efw",
    "firmware",
    "bootloader",
    "commission",
    "xtask",
    "tests-host",
    "tests-host/qemu",
    "tests-host/qemu/bench",
];

/// Files (`None`) and functions (`Some(name)`) still over the limits: being split in
/// other branches now. The integrator empties this list after merging them; an entry
/// that is no longer over its limit fails the test, so the list cannot go stale.
const ALLOWED: &[(&str, Option<&str>)] = &[];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.rs` file under `dir`, without `tests/` directories and `tests.rs` files.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name();
        if p.is_dir() {
            if name != "tests" {
                sources(&p, out);
            }
        } else if p.extension().is_some_and(|x| x == "rs") && name != "tests.rs" {
            out.push(p);
        }
    }
}

fn indent(line: &str) -> usize {
    line.len() - line.trim_start().len()
}

/// `line` with the block of `mod name {` following a `#[cfg(test)]` line removed:
/// which lines are code (true) and which belong to a test module (false).
fn code_lines(lines: &[&str]) -> Vec<bool> {
    let mut code = vec![true; lines.len()];
    let mut i = 0;
    while i < lines.len() {
        let next = lines.get(i + 1).map(|l| l.trim_start());
        let opens_mod = next.is_some_and(|l| {
            let l = l.strip_prefix("pub ").unwrap_or(l);
            l.starts_with("mod ") && l.ends_with('{')
        });
        if lines[i].trim() == "#[cfg(test)]" && opens_mod {
            let close = format!("{}}}", " ".repeat(indent(lines[i + 1])));
            let end = (i + 2..lines.len())
                .find(|&j| lines[j] == close)
                .unwrap_or(lines.len() - 1);
            code[i..=end].iter_mut().for_each(|c| *c = false);
            i = end + 1;
        } else {
            i += 1;
        }
    }
    code
}

/// The function name if `line` starts a function definition or declaration.
fn fn_name(line: &str) -> Option<&str> {
    let mut s = line.trim_start();
    loop {
        let before = s;
        for q in ["pub ", "const ", "async ", "unsafe ", "default "] {
            s = s.strip_prefix(q).unwrap_or(s);
        }
        if let Some(rest) = s.strip_prefix("pub(") {
            s = rest.split_once(") ").map_or(rest, |(_, r)| r);
        }
        if let Some(rest) = s.strip_prefix("extern \"") {
            s = rest.split_once("\" ").map_or(rest, |(_, r)| r);
        }
        if s == before {
            break;
        }
    }
    let rest = s.strip_prefix("fn ")?;
    let end = rest
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(rest.len());
    Some(&rest[..end]).filter(|n| !n.is_empty())
}

/// (name, first line index, length) of every function with a body outside test blocks.
fn functions(lines: &[&str], code: &[bool]) -> Vec<(String, usize, usize)> {
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        if !code[i] {
            continue;
        }
        let Some(name) = fn_name(line) else {
            continue;
        };
        // The signature ends at the first line ending in `{` (a body) or `;` (none).
        let Some(sig_end) = (i..lines.len()).find(|&j| {
            let t = lines[j].trim_end();
            t.ends_with('{') || t.ends_with(';') || t.ends_with('}')
        }) else {
            continue;
        };
        if !lines[sig_end].trim_end().ends_with('{') {
            continue;
        }
        let close = format!("{}}}", " ".repeat(indent(line)));
        if let Some(end) = (sig_end + 1..lines.len()).find(|&j| lines[j] == close) {
            out.push((name.to_string(), i, end - i + 1));
        }
    }
    out
}

#[test]
fn no_file_or_function_over_the_limits() {
    let root = root();
    let mut files = Vec::new();
    for c in CRATES {
        let dir = root.join(c).join("src");
        assert!(dir.is_dir(), "{} is missing", dir.display());
        sources(&dir, &mut files);
    }
    files.sort();
    assert!(files.len() > 100, "only {} source files found", files.len());
    let mut over = Vec::new();
    let mut seen_allowed = Vec::new();
    let mut check = |rel: &str, f: Option<&str>, what: String| {
        if ALLOWED.contains(&(rel, f)) {
            seen_allowed.push((rel.to_string(), f.map(str::to_string)));
        } else {
            over.push(what);
        }
    };
    for path in &files {
        let rel = path
            .strip_prefix(&root)
            .unwrap_or(path)
            .to_string_lossy()
            .replace('\\', "/");
        let text = std::fs::read_to_string(path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        let code = code_lines(&lines);
        let n = code.iter().filter(|&&c| c).count();
        if n > MAX_FILE_LINES {
            check(&rel, None, format!("{rel}: {n} lines"));
        }
        for (name, at, len) in functions(&lines, &code) {
            if len > MAX_FN_LINES {
                check(
                    &rel,
                    Some(&name),
                    format!("{rel}:{}: fn {name} is {len} lines", at + 1),
                );
            }
        }
    }
    let stale: Vec<_> = ALLOWED
        .iter()
        .filter(|(p, f)| {
            !seen_allowed
                .iter()
                .any(|(sp, sf)| sp == p && sf.as_deref() == *f)
        })
        .collect();
    assert!(
        over.is_empty(),
        "over {MAX_FILE_LINES} lines per file / {MAX_FN_LINES} per function \
         (split by meaning, move unit tests to a tests.rs):\n{}",
        over.join("\n")
    );
    assert!(
        stale.is_empty(),
        "within the limits now, remove from ALLOWED: {stale:?}"
    );
}

#[test]
fn the_board_main_stays_a_wiring_file() {
    let path = root().join("firmware/src/main.rs");
    let text = std::fs::read_to_string(&path).expect("firmware/src/main.rs");
    let lines = text.lines().count();
    assert!(
        lines <= MAX_BOARD_MAIN_LINES,
        "{} has {lines} lines, more than {MAX_BOARD_MAIN_LINES}: move the logic into the \
         runtime or `hw/`",
        path.display()
    );
}

#[test]
fn the_measure_sees_bodies_not_declarations_or_tests() {
    let src = "\
pub trait T {
    fn declared(&self);
    fn one_line(&self) {}
    fn body(&self) {
        let x = 1;
    }
}
pub(crate) const unsafe fn f(
    a: u8,
) -> u8 {
    a
}
#[cfg(test)]
mod tests {
    fn inside_tests() {
    }
}
";
    let lines: Vec<&str> = src.lines().collect();
    let code = code_lines(&lines);
    assert_eq!(code.iter().filter(|&&c| c).count(), 12);
    let fns = functions(&lines, &code);
    assert_eq!(
        fns,
        vec![("body".to_string(), 3, 3), ("f".to_string(), 7, 5)]
    );
}
