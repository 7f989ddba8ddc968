//! The `firmware` library's top-level modules keep the layers of `ARCHITECTURE.md`
//! ("Module layers of the firmware library"): a module's code imports (`crate::x`
//! paths outside comments and outside its `#[cfg(test)]` modules) name only modules of
//! its own layer or of a lower one, the imports within a layer form no cycle, and the
//! only exceptions are the back edges listed in [`ALLOWED_BACK_EDGES`], each with the
//! reason it is there. The layer table is read from `ARCHITECTURE.md`, so the document
//! and this check cannot drift apart.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Imports that point to a higher layer, kept on purpose: (from, to, why).
const ALLOWED_BACK_EDGES: &[(&str, &str, &str)] = &[];

fn firmware_src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/src")
}

/// The layer table of `ARCHITECTURE.md`: module → layer number (1 = bottom).
fn layers() -> BTreeMap<String, u32> {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../ARCHITECTURE.md"))
            .expect("ARCHITECTURE.md");
    let section = doc
        .split("### Module layers of the firmware library")
        .nth(1)
        .expect("ARCHITECTURE.md has the section \"Module layers of the firmware library\"");
    let mut out = BTreeMap::new();
    for line in section.lines().take_while(|l| !l.starts_with('#')) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        // | n | name | `a`, `b` | what |
        let Some(n) = cells.get(1).and_then(|c| c.parse::<u32>().ok()) else {
            continue;
        };
        for m in cells[3].split(',') {
            let m = m.trim().trim_matches('`');
            assert!(!m.is_empty(), "empty module name in layer {n}");
            assert!(out.insert(m.to_string(), n).is_none(), "{m} listed twice");
        }
    }
    assert!(!out.is_empty(), "no layer rows found in ARCHITECTURE.md");
    out
}

/// The modules `lib.rs` declares.
fn library_modules() -> BTreeSet<String> {
    let lib = std::fs::read_to_string(firmware_src().join("lib.rs")).unwrap();
    lib.lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|l| l.trim_end_matches(';').trim().to_string())
        .collect()
}

/// The text of a file without its comments and without an inline `#[cfg(test)] mod x
/// { .. }` (the test module is the file's last item by the project's convention, so
/// everything from it on is dropped), and the names of its `#[cfg(test)] mod x;` files.
fn code_of(src: &str) -> (String, Vec<String>) {
    let mut code = String::new();
    let mut test_files = Vec::new();
    let mut cfg_test = false;
    for line in src.lines() {
        let t = line.trim_start();
        if t.starts_with("//") {
            continue;
        }
        if cfg_test {
            if let Some(rest) = t
                .strip_prefix("mod ")
                .or_else(|| t.strip_prefix("pub(crate) mod "))
            {
                match rest.trim_end().strip_suffix(';') {
                    Some(name) => {
                        test_files.push(name.trim().to_string());
                        cfg_test = false;
                        continue;
                    }
                    None => break,
                }
            }
        }
        cfg_test = t.starts_with("#[cfg(test)]");
        code.push_str(line);
        code.push('\n');
    }
    (code, test_files)
}

/// The top-level modules named by `crate::x` paths (also `crate::{x, y::z}`).
fn crate_paths(code: &str) -> BTreeSet<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = BTreeSet::new();
    for (i, _) in code.match_indices("crate::") {
        if i > 0 {
            let prev = code[..i].chars().next_back().unwrap();
            if prev.is_ascii_alphanumeric() || prev == '_' || prev == '$' {
                continue; // `my_crate::`, `$crate::`
            }
        }
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 1;
            let mut start = true;
            for (k, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 1 => start = true,
                    c if c.is_whitespace() => continue,
                    _ if start && depth == 1 => {
                        out.insert(ident(&group[k..]));
                        start = false;
                    }
                    _ => {}
                }
                if depth == 0 {
                    break;
                }
            }
        } else {
            out.insert(ident(rest));
        }
    }
    out
}

/// Each module's imports of other top-level modules, from its file and its directory.
fn imports(modules: &BTreeSet<String>) -> BTreeMap<String, BTreeSet<String>> {
    fn walk(path: &Path, top: &str, skip: &mut BTreeSet<PathBuf>, out: &mut BTreeSet<String>) {
        let (code, tests) = code_of(&std::fs::read_to_string(path).unwrap());
        // `a.rs` and `a/mod.rs` keep their submodules in `a/`.
        let dir = if path.file_name().is_some_and(|n| n == "mod.rs") {
            path.parent().unwrap().to_path_buf()
        } else {
            path.with_extension("")
        };
        for t in tests {
            skip.insert(dir.join(format!("{t}.rs")));
            skip.insert(dir.join(&t));
        }
        out.extend(crate_paths(&code).into_iter().filter(|m| m != top));
        let Ok(entries) = std::fs::read_dir(&dir) else {
            return;
        };
        let mut entries: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
        entries.sort();
        for p in entries {
            if skip.contains(&p) || p.file_name().is_some_and(|n| n == "mod.rs") {
                continue;
            }
            // Submodule files (`b.rs`, or `b/mod.rs` without a `b.rs`); their own
            // directories are walked from them.
            if p.extension().is_some_and(|x| x == "rs") {
                walk(&p, top, skip, out);
            } else if p.is_dir() && !p.with_extension("rs").exists() && p.join("mod.rs").exists() {
                walk(&p.join("mod.rs"), top, skip, out);
            }
        }
    }
    let src = firmware_src();
    let mut all = BTreeMap::new();
    for m in modules {
        let file = src.join(format!("{m}.rs"));
        let file = if file.exists() {
            file
        } else {
            src.join(m).join("mod.rs")
        };
        let mut deps = BTreeSet::new();
        walk(&file, m, &mut BTreeSet::new(), &mut deps);
        deps.retain(|d| modules.contains(d));
        all.insert(m.clone(), deps);
    }
    all
}

#[test]
fn every_library_module_has_a_layer() {
    let layers = layers();
    let modules = library_modules();
    let listed: BTreeSet<String> = layers.keys().cloned().collect();
    assert_eq!(
        modules, listed,
        "lib.rs's modules and ARCHITECTURE.md's layer table differ"
    );
}

#[test]
fn imports_point_down_or_are_listed() {
    let layers = layers();
    let deps = imports(&library_modules());
    assert!(
        deps.values().any(|d| !d.is_empty()),
        "no imports found at all"
    );
    let mut back = BTreeSet::new();
    for (m, ds) in &deps {
        for d in ds {
            if layers[d] > layers[m] {
                back.insert((m.as_str(), d.as_str()));
            }
        }
    }
    let allowed: BTreeSet<(&str, &str)> =
        ALLOWED_BACK_EDGES.iter().map(|&(a, b, _)| (a, b)).collect();
    let unlisted: Vec<_> = back.difference(&allowed).collect();
    assert!(
        unlisted.is_empty(),
        "imports into a higher layer (move the item down, or pass the value in): {unlisted:?}"
    );
    let stale: Vec<_> = allowed.difference(&back).collect();
    assert!(
        stale.is_empty(),
        "listed back edges that no longer exist (remove them from the list): {stale:?}"
    );
}

#[test]
fn no_import_cycle_besides_the_listed_back_edges() {
    let deps = imports(&library_modules());
    let allowed: BTreeSet<(&str, &str)> =
        ALLOWED_BACK_EDGES.iter().map(|&(a, b, _)| (a, b)).collect();
    let graph: BTreeMap<&str, Vec<&str>> = deps
        .iter()
        .map(|(m, ds)| {
            let ds = ds
                .iter()
                .map(String::as_str)
                .filter(|d| !allowed.contains(&(m.as_str(), *d)))
                .collect();
            (m.as_str(), ds)
        })
        .collect();
    // Depth-first search: 1 = on the path, 2 = done.
    fn visit<'a>(
        m: &'a str,
        graph: &BTreeMap<&'a str, Vec<&'a str>>,
        state: &mut BTreeMap<&'a str, u8>,
        path: &mut Vec<&'a str>,
    ) {
        state.insert(m, 1);
        path.push(m);
        for &d in &graph[m] {
            match state.get(d) {
                Some(1) => {
                    let from = path.iter().position(|&p| p == d).unwrap();
                    panic!("import cycle: {:?} -> {d}", &path[from..]);
                }
                Some(_) => {}
                None => visit(d, graph, state, path),
            }
        }
        path.pop();
        state.insert(m, 2);
    }
    let mut state = BTreeMap::new();
    for &m in graph.keys() {
        if !state.contains_key(m) {
            visit(m, &graph, &mut state, &mut Vec::new());
        }
    }
    // With the listed back edges too, the only cycles are the ones they close.
    for &(a, b, why) in ALLOWED_BACK_EDGES {
        assert!(!why.is_empty(), "{a} -> {b} has no reason");
    }
}

#[test]
fn the_parser_sees_groups_paths_and_skips_comments() {
    let (code, tests) = code_of(
        "use crate::{a::X, b};\n// crate::c\n/// [`crate::d`]\nfn f() { crate::e::g(); my_crate::h(); }\n\
         #[cfg(test)]\nmod t_file;\n#[cfg(test)]\nmod tests {\n    use crate::z;\n}\n",
    );
    assert_eq!(tests, ["t_file"]);
    let found: Vec<String> = crate_paths(&code).into_iter().collect();
    assert_eq!(found, ["a", "b", "e"]);
}
