//! The crate's modules form layers: a module uses only modules below it, so
//! that each can be read (and changed) knowing only what lies under it. This
//! test reads src/, takes every `crate::name` a top-level module's code
//! mentions (comments and the unit tests, at the end of a file or in a
//! tests.rs, left out) as an edge, and fails on any cycle, naming it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every .rs file under `dir`, recursively.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The code of a file without its comment lines and its `mod tests`.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The identifier at the start of `s` (a module name: lower case, digits, _).
fn ident(s: &str) -> String {
    s.chars()
        .take_while(|c| c.is_ascii_lowercase() || *c == '_' || c.is_ascii_digit())
        .collect()
}

/// The names `crate::name` mentions in `code`, grouped imports included
/// (`use crate::{a, b::C, d::{e, f}}` mentions a, b and d).
fn mentions(code: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        rest = &rest[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            // The items at the group's own depth, up to its closing brace.
            let mut depth = 0usize;
            let mut item_start = 0;
            for (k, ch) in group.char_indices() {
                match ch {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        out.insert(ident(group[item_start..k].trim_start()));
                        break;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        out.insert(ident(group[item_start..k].trim_start()));
                        item_start = k + 1;
                    }
                    _ => {}
                }
            }
        } else {
            out.insert(ident(rest));
        }
    }
    out.remove("");
    out
}

/// The module graph of src/ (lib.rs and the binaries left out).
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut by_module: BTreeMap<String, Vec<PathBuf>> = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(&src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        // Unit tests (a `mod tests` at the end of a file, or its own tests.rs)
        // may use any module.
        if module == "lib" || module == "bin" || f.ends_with("tests.rs") {
            continue;
        }
        by_module.entry(module).or_default().push(f);
    }
    let names: BTreeSet<String> = by_module.keys().cloned().collect();
    by_module
        .iter()
        .map(|(m, files)| {
            let mut uses = BTreeSet::new();
            for f in files {
                let code = code_of(&std::fs::read_to_string(f).unwrap());
                uses.extend(
                    mentions(&code)
                        .into_iter()
                        .filter(|t| t != m && names.contains(t)),
                );
            }
            (m.clone(), uses)
        })
        .collect()
}

/// A cycle of `g`, if it has one (depth-first search, the path kept).
fn find_cycle(g: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        g: &BTreeMap<String, BTreeSet<String>>,
        v: &str,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(v.to_string(), 1);
        path.push(v.to_string());
        for w in &g[v] {
            match state.get(w).copied().unwrap_or(0) {
                0 => {
                    if let Some(c) = visit(g, w, state, path) {
                        return Some(c);
                    }
                }
                1 => {
                    let start = path.iter().position(|p| p == w).unwrap();
                    let mut cycle = path[start..].to_vec();
                    cycle.push(w.clone());
                    return Some(cycle);
                }
                _ => {}
            }
        }
        path.pop();
        state.insert(v.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for v in g.keys() {
        if state.get(v).copied().unwrap_or(0) == 0
            && let Some(c) = visit(g, v, &mut state, &mut Vec::new())
        {
            return Some(c);
        }
    }
    None
}

#[test]
fn the_modules_form_layers_without_a_cycle() {
    let g = graph();
    assert!(g.len() > 20, "src/ not found or not read: {g:?}");
    assert!(
        g["problem"].contains("dual") && g["dual"].contains("factor"),
        "the reader missed known edges: {g:?}"
    );
    if let Some(cycle) = find_cycle(&g) {
        panic!(
            "an import cycle between the crate's modules: {}",
            cycle.join(" -> ")
        );
    }
}

#[test]
fn the_cycle_finder_finds_a_planted_cycle() {
    let mut g = graph();
    g.get_mut("factor").unwrap().insert("problem".to_string());
    let cycle = find_cycle(&g).expect("problem -> ... -> factor -> problem");
    assert_eq!(cycle.first(), cycle.last());
    assert!(cycle.iter().any(|m| m == "factor"));
}

#[test]
fn grouped_and_nested_imports_are_read() {
    let got = mentions("use crate::{a, b::C, d::{e, f},\n    g_2};\nlet x = crate::h::y();");
    let want: BTreeSet<String> = ["a", "b", "d", "g_2", "h"].map(String::from).into();
    assert_eq!(got, want);
}
