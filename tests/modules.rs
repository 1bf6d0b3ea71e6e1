//! The library's module graph, read from its source: which module of
//! `src/` names which other (`crate::a::b`, `super::c` in code, not in
//! comments or test modules). It must have no cycle, and nothing below the
//! command line may import it: `cli` is the top floor, `pipeline` the one
//! beneath (only `cli` imports it).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Module path (`a::b`, "" for the crate root) of every `.rs` file under `src/`.
fn modules(dir: &Path, prefix: &[String], out: &mut BTreeMap<String, String>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let path = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            let mut p = prefix.to_vec();
            p.push(name);
            modules(&path, &p, out);
        } else if let Some(stem) = name.strip_suffix(".rs") {
            let mut p = prefix.to_vec();
            if !matches!(stem, "mod" | "lib" | "main") {
                p.push(stem.to_string());
            }
            if stem == "main" {
                continue; // the binary, not a module of the library
            }
            out.insert(p.join("::"), std::fs::read_to_string(&path).expect("read a source file"));
        }
    }
}

/// The code of a source file: comments, string literals' contents and
/// `#[cfg(test)] mod tests` removed.
fn code(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    let mut out = String::new();
    for line in text.lines() {
        let line = match line.find("//") {
            Some(i) => &line[..i],
            None => line,
        };
        // Drop the contents of string literals (messages name modules in prose).
        let mut in_str = false;
        let mut prev = ' ';
        for c in line.chars() {
            if c == '"' && prev != '\\' {
                in_str = !in_str;
                out.push(c);
            } else if !in_str {
                out.push(c);
            }
            prev = c;
        }
        out.push('\n');
    }
    out
}

/// The modules `module`'s code names: each `crate::…` or `super::…` path
/// (and each item of a `{…}` group after one) resolved to the longest prefix
/// that is a module; a final segment called as a function (`super::run(`)
/// is an item, not a module.
fn imports(module: &str, code: &str, known: &BTreeMap<String, String>) -> BTreeSet<String> {
    let here: Vec<&str> = if module.is_empty() { vec![] } else { module.split("::").collect() };
    let mut out = BTreeSet::new();
    let bytes = code.as_bytes();
    let is_path = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == ':';
    for start in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = code[from..].find(start) {
            let at = from + i;
            from = at + start.len();
            if at > 0 && (bytes[at - 1].is_ascii_alphanumeric() || matches!(bytes[at - 1], b'_' | b':')) {
                continue;
            }
            let rest = &code[at..];
            let end = rest.find(|c: char| !is_path(c)).unwrap_or(rest.len());
            let head = &rest[..end];
            let mut paths: Vec<(String, bool)> = Vec::new();
            if head.ends_with("::") && rest[end..].starts_with('{') {
                // A group: its items at depth one, each a path below `head`.
                let group = &rest[end + 1..];
                let mut depth = 0usize;
                let mut item_start = true;
                for (k, c) in group.char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => item_start = true,
                        c if item_start && depth == 0 && !c.is_whitespace() => {
                            item_start = false;
                            let item = &group[k..];
                            let e = item.find(|c: char| !is_path(c)).unwrap_or(item.len());
                            paths.push((format!("{head}{}", &item[..e]), false));
                        }
                        _ => {}
                    }
                }
            } else {
                paths.push((head.to_string(), rest[end..].starts_with('(')));
            }
            for (text, called) in paths {
                let mut segs: Vec<&str> = text.split("::").filter(|s| !s.is_empty()).collect();
                if called {
                    segs.pop();
                }
                let mut segs = segs.into_iter().peekable();
                let mut path: Vec<&str> = Vec::new();
                match segs.next() {
                    Some("crate") => {}
                    Some("super") => {
                        path.extend(here.iter().copied());
                        path.pop();
                        while segs.peek() == Some(&"super") {
                            segs.next();
                            path.pop();
                        }
                    }
                    _ => continue,
                }
                path.extend(segs);
                for k in (1..=path.len()).rev() {
                    let candidate = path[..k].join("::");
                    if known.contains_key(&candidate) {
                        if candidate != module {
                            out.insert(candidate);
                        }
                        break;
                    }
                }
            }
        }
    }
    out
}

fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let mut known = BTreeMap::new();
    modules(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), &[], &mut known);
    assert!(known.len() > 50, "read src/: {} modules", known.len());
    known.iter().map(|(m, text)| (m.clone(), imports(m, &code(text), &known))).collect()
}

/// Strongly connected components of more than one module (Tarjan).
fn cycles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct T<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a str) {
        let n = t.index.len();
        t.index.insert(v, n);
        t.low.insert(v, n);
        t.stack.push(v);
        t.on.insert(v);
        for w in t.g.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !t.index.contains_key(w) {
                visit(t, w);
                let lw = t.low[w];
                let lv = t.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if t.on.contains(w) {
                let iw = t.index[w];
                let lv = t.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T { g, index: BTreeMap::new(), low: BTreeMap::new(), stack: vec![], on: BTreeSet::new(), out: vec![] };
    for v in g.keys() {
        if !t.index.contains_key(v.as_str()) {
            visit(&mut t, v);
        }
    }
    t.out
}

fn top(m: &str) -> &str {
    m.split("::").next().unwrap_or(m)
}

#[test]
fn the_module_graph_has_no_cycle() {
    let g = graph();
    // Top-level rooms (src/x.rs, src/x/): a cycle between two rooms is a cycle
    // of the library's plan even when no two files form one.
    let mut rooms: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, deps) in &g {
        let r = rooms.entry(top(m).to_string()).or_default();
        r.extend(deps.iter().map(|d| top(d).to_string()).filter(|d| d != top(m)));
    }
    assert_eq!(cycles(&g), Vec::<Vec<String>>::new(), "modules that import each other (in a ring)");
    assert_eq!(cycles(&rooms), Vec::<Vec<String>>::new(), "top-level modules that import each other (in a ring)");
}

#[test]
fn nothing_below_the_command_line_imports_it() {
    let g = graph();
    let mut upward = Vec::new();
    for (m, deps) in &g {
        for d in deps {
            let (from, to) = (top(m), top(d));
            if (to == "cli" && from != "cli") || (to == "pipeline" && !matches!(from, "pipeline" | "cli")) {
                upward.push(format!("{m} → {d}"));
            }
        }
    }
    assert_eq!(upward, Vec::<String>::new(), "imports pointing up (cli is above pipeline, pipeline above the rest)");
}

#[test]
fn the_reader_sees_a_real_cycle() {
    // The checks above would pass on an empty graph: the reader must find a
    // ring where one is written.
    let mut known = BTreeMap::new();
    for m in ["a", "b", "c", "c::d"] {
        known.insert(m.to_string(), String::new());
    }
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a", "use crate::b::Thing; // crate::c in a comment\nlet s = \"crate::c\";"),
        ("b", "fn f() { super::a::g(); }"),
        ("c", "fn f() { super::run(); }\nuse crate::{c::d::X, b};"),
        ("c::d", "use super::super::a;"),
    ]
    .iter()
    .map(|(m, text)| (m.to_string(), imports(m, &code(text), &known)))
    .collect();
    assert_eq!(g["a"], BTreeSet::from(["b".to_string()]));
    assert_eq!(g["b"], BTreeSet::from(["a".to_string()]));
    assert_eq!(
        g["c"],
        BTreeSet::from(["b".to_string(), "c::d".to_string()]),
        "a group's items; super::run( is a function"
    );
    assert_eq!(g["c::d"], BTreeSet::from(["a".to_string()]));
    assert_eq!(cycles(&g), vec![vec!["a".to_string(), "b".to_string()]]);
}
