//! The library's module graph, read from its source: which module of
//! `src/` names which other, in code (not in comments, string literals or
//! test modules): `crate::a::b`, `super::c`, `self::d`, a child module by
//! its bare name (`e::f`, `use e::…`, `e::g(…)` where the module declares
//! `mod e;`), and the paths serde's attributes hold as strings
//! (`default = "super::one"`). A file that a `#[path = "…"] mod x;`
//! declares is the module `x` of the declaring module, wherever the file
//! lies. A method called on a value (`job.run()`) names no module: a
//! dependency only through one is not seen. The graph must have no cycle,
//! and nothing below the command line may import it: `cli` is the top
//! floor, `pipeline` the one beneath (only `cli` imports it).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

/// Every `.rs` file under `dir`, with its text.
fn sources(dir: &Path, out: &mut BTreeMap<PathBuf, String>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let path = e.path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|x| x == "rs") {
            let text = std::fs::read_to_string(&path).expect("read a source file");
            out.insert(path, text);
        }
    }
}

/// `p` with its `.` and `..` resolved by their names, as the file system
/// would when nothing is a link.
fn lexical(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `module::child` ("child" below the crate root).
fn child_of(module: &str, child: &str) -> String {
    if module.is_empty() {
        child.to_string()
    } else {
        format!("{module}::{child}")
    }
}

/// The module path (`a::b`, "" for the crate root) and text of each source
/// file under `src` (`files`, keyed by path): by the file's place (`a/b.rs`
/// and `a/b/mod.rs` are `a::b`), except a file that a `#[path = "…"] mod x;`
/// declares, which is `x` of the declaring module; its file is named
/// relative to the declaring file's folder, as rustc reads a `#[path]` that
/// is not inside an inline module. `main.rs` is the binary, not a module of
/// the library.
fn modules(src: &Path, files: &BTreeMap<PathBuf, String>) -> BTreeMap<String, String> {
    let mut name: BTreeMap<&Path, String> = BTreeMap::new();
    for path in files.keys() {
        let Ok(rel) = path.strip_prefix(src) else { continue };
        let mut segs: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
        let Some(file) = segs.pop() else { continue };
        let Some(stem) = file.strip_suffix(".rs") else { continue };
        match stem {
            "main" => continue,
            "mod" | "lib" => {}
            _ => segs.push(stem.to_string()),
        }
        name.insert(path, segs.join("::"));
    }
    // A `#[path]` module may itself declare one: repeat until the names settle.
    for _ in 0..=files.len() {
        let mut changed = false;
        for (path, text) in files {
            let Some(module) = name.get(path.as_path()).cloned() else { continue };
            let dir = path.parent().unwrap_or(src);
            for (file, x) in path_declarations(&code_and_strings(text)) {
                let target = lexical(&dir.join(file));
                let want = child_of(&module, &x);
                if let Some(n) = name.get_mut(target.as_path())
                    && *n != want
                {
                    *n = want;
                    changed = true;
                }
            }
        }
        if !changed {
            return name.into_iter().map(|(path, m)| (m, files[path].clone())).collect();
        }
    }
    panic!("#[path] declarations that never settle (a file declaring itself?)");
}

/// The file and module name of each `#[path = "FILE"] mod NAME;` in `code`
/// (other attributes and a visibility may stand between them).
fn path_declarations(code: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(i) = code[from..].find("#[path") {
        from += i + "#[path".len();
        let rest = code[from..].trim_start();
        let Some(rest) = rest.strip_prefix('=') else { continue };
        let Some(rest) = rest.trim_start().strip_prefix('"') else { continue };
        let Some(q) = rest.find('"') else { continue };
        let file = &rest[..q];
        let Some(mut rest) = rest[q + 1..].trim_start().strip_prefix(']') else { continue };
        // Other attributes (`#[cfg(…)]`, `#[doc = …]`), then a visibility.
        loop {
            rest = rest.trim_start();
            let Some(attr) = rest.strip_prefix("#[") else { break };
            let mut depth = 1usize;
            let end = attr.char_indices().find_map(|(k, c)| {
                match c {
                    '[' => depth += 1,
                    ']' => depth -= 1,
                    _ => {}
                }
                (depth == 0).then_some(k)
            });
            let Some(end) = end else { break };
            rest = &attr[end + 1..];
        }
        if let Some(r) = rest.strip_prefix("pub") {
            rest = r.trim_start();
            if rest.starts_with('(') {
                let Some(close) = rest.find(')') else { continue };
                rest = &rest[close + 1..];
            }
        }
        let Some(rest) = rest.trim_start().strip_prefix("mod") else { continue };
        if let Some((name, after)) = module_name(rest)
            && after.starts_with(';')
        {
            out.push((file.to_string(), name.to_string()));
        }
    }
    out
}

/// After the keyword `mod`: the module's name and the text after it
/// (trimmed), when whitespace and a name follow.
fn module_name(after_mod: &str) -> Option<(&str, &str)> {
    if !after_mod.starts_with(char::is_whitespace) {
        return None;
    }
    let rest = after_mod.trim_start();
    let end = rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(rest.len());
    (end > 0).then(|| (&rest[..end], rest[end..].trim_start()))
}

/// Each `mod NAME` in `code` (the word `mod`, not the end of another
/// word): the name and the text after it (trimmed), a declaration from a
/// file of its own when that starts with `;`, an inline module when `{`.
fn mod_items(code: &str) -> Vec<(&str, &str)> {
    let bytes = code.as_bytes();
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(i) = code[from..].find("mod") {
        let at = from + i;
        from = at + "mod".len();
        if at > 0 && (bytes[at - 1].is_ascii_alphanumeric() || bytes[at - 1] == b'_') {
            continue;
        }
        out.extend(module_name(&code[from..]));
    }
    out
}

/// The modules `module` declares from a file of their own (`mod x;`,
/// `pub mod x;`, `pub(crate) mod x;`, with or without a `#[path]`): those
/// its code may name by their bare names.
fn children(module: &str, code: &str, known: &BTreeMap<String, String>) -> BTreeSet<String> {
    mod_items(code)
        .into_iter()
        .filter(|(name, after)| after.starts_with(';') && known.contains_key(&child_of(module, name)))
        .map(|(name, _)| name.to_string())
        .collect()
}

/// A source file without its comments and its test modules
/// (`#[cfg(test)] mod x { … }`); with `drop_strings`, the contents of its
/// string literals removed too, except those that are paths to code:
/// serde's `default = "…"`, `with = "…"`, `serialize_with`,
/// `deserialize_with` and `skip_serializing_if`.
fn strip(text: &str, drop_strings: bool) -> String {
    let mut out = String::new();
    for line in text.lines() {
        let mut in_str = false;
        let mut keep = !drop_strings;
        let mut prev = ' ';
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            if !in_str && c == '/' && chars.peek() == Some(&'/') {
                break; // a comment to the end of the line
            }
            if c == '"' && prev != '\\' {
                if !in_str && drop_strings {
                    keep = names_code(&out);
                }
                in_str = !in_str;
                out.push(c);
            } else if !in_str || keep {
                out.push(c);
            }
            prev = c;
        }
        out.push('\n');
    }
    without_tests(&out)
}

/// `code` without its test modules: each `#[cfg(test)]` that stands on a
/// `mod x { … }` (with other attributes and a visibility between) to the
/// module's closing brace, or on a `mod x;` to its `;`.
fn without_tests(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(i) = rest.find("#[cfg(test)]") {
        let after = &rest[i + "#[cfg(test)]".len()..];
        let mut item = after.trim_start();
        while item.starts_with("#[") {
            match item.find(']') {
                Some(k) => item = item[k + 1..].trim_start(),
                None => break,
            }
        }
        if let Some(r) = item.strip_prefix("pub") {
            item = r.trim_start();
            if item.starts_with('(') {
                item = item.find(')').map_or(item, |k| item[k + 1..].trim_start());
            }
        }
        let end = item.strip_prefix("mod").filter(|r| r.starts_with(char::is_whitespace)).and_then(|r| {
            let body = r.find(['{', ';'])?;
            if r.as_bytes()[body] == b';' {
                return Some(body + 1);
            }
            block_end(r, body)
        });
        match end {
            Some(end) => {
                let r = &item["mod".len()..];
                out.push_str(&rest[..i]);
                rest = &r[end..];
            }
            None => {
                out.push_str(&rest[..i + "#[cfg(test)]".len()]);
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// The end (just past the matching `}`) of the block that opens at byte
/// `open` of `code` (a `{`); a char literal '{' or '}' is not a brace.
fn block_end(code: &str, open: usize) -> Option<usize> {
    let bytes = code.as_bytes();
    let mut depth = 0usize;
    for k in open..bytes.len() {
        let quoted = k > 0 && bytes[k - 1] == b'\'' && bytes.get(k + 1) == Some(&b'\'');
        match bytes[k] {
            b'{' if !quoted => depth += 1,
            b'}' if !quoted => {
                depth = depth.checked_sub(1)?;
                if depth == 0 {
                    return Some(k + 1);
                }
            }
            _ => {}
        }
    }
    None
}

/// The byte ranges of the inline modules (`mod x { … }`) in `code`: their
/// `super::` is the file's module, and the file's children are not in
/// scope by their bare names.
fn inline_modules(code: &str) -> Vec<std::ops::Range<usize>> {
    mod_items(code)
        .into_iter()
        .filter(|(_, after)| after.starts_with('{'))
        .filter_map(|(_, after)| {
            let open = code.len() - after.len();
            block_end(code, open).map(|close| open..close)
        })
        .collect()
}

/// Whether a string literal after `code` holds a path to code: `code`
/// ends with one of serde's attributes that name a function or module.
fn names_code(code: &str) -> bool {
    let Some(before) = code.trim_end().strip_suffix('=') else { return false };
    let word = before.trim_end().rsplit(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).next();
    matches!(word, Some("default" | "with" | "serialize_with" | "deserialize_with" | "skip_serializing_if"))
}

/// The code of a source file: comments, string literals' contents (messages
/// name modules in prose) and test modules removed.
fn code(text: &str) -> String {
    strip(text, true)
}

/// The code of a source file with its string literals (a `#[path]`'s file).
fn code_and_strings(text: &str) -> String {
    strip(text, false)
}

/// The modules `module`'s code names.
fn imports(module: &str, code: &str, known: &BTreeMap<String, String>) -> BTreeSet<String> {
    names(module, code, known).into_keys().collect()
}

/// The modules `module`'s code names, each with the paths that name it:
/// each path that starts with `crate::`, `super::`, `self::` or the bare
/// name of one of its [`children`] (and each item of a `{…}` group after
/// one) resolved to the longest prefix that is a module; a final segment
/// called as a function (`super::run(`) is an item, not a module. Inside an
/// inline module (`mod x { … }`) `super::` is the file's module.
fn names(module: &str, code: &str, known: &BTreeMap<String, String>) -> BTreeMap<String, BTreeSet<String>> {
    let here: Vec<&str> = if module.is_empty() { vec![] } else { module.split("::").collect() };
    let kids = children(module, code, known);
    let inline = inline_modules(code);
    let starts: Vec<String> = ["crate", "super", "self"]
        .iter()
        .map(|s| s.to_string())
        .chain(kids.iter().cloned())
        .map(|s| s + "::")
        .collect();
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let bytes = code.as_bytes();
    let is_path = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == ':';
    // One pass, left to right over the paths: a group's items are read
    // with the path that opens it (`lucent_calib::{e::Y}` and
    // `crate::x::{e::Y}` do not name the child `e`).
    let mut at = 0;
    while at < code.len() {
        let boundary =
            at == 0 || !(bytes[at - 1].is_ascii_alphanumeric() || matches!(bytes[at - 1], b'_' | b':' | b'.'));
        let rest = &code[at..];
        let end = rest.find(|c: char| !is_path(c)).unwrap_or(rest.len());
        if !boundary || end == 0 {
            at += rest.chars().next().map_or(1, char::len_utf8);
            continue;
        }
        let head = &rest[..end];
        let start = at;
        // A group after the path: its items at depth one, and where it closes.
        let mut items = Vec::new();
        let mut close = 0;
        if head.ends_with("::") && rest[end..].starts_with('{') {
            let group = &rest[end + 1..];
            let mut depth = 0usize;
            let mut item_start = true;
            close = group.len();
            for (k, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        close = k + 2; // the braces
                        break;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 0 => item_start = true,
                    c if item_start && depth == 0 && !c.is_whitespace() => {
                        item_start = false;
                        let item = &group[k..];
                        let e = item.find(|c: char| !is_path(c)).unwrap_or(item.len());
                        items.push(&item[..e]);
                    }
                    _ => {}
                }
            }
        }
        at += end + close;
        if !starts.iter().any(|s| head.starts_with(s.as_str())) {
            continue;
        }
        // Inside an inline module a path starts one level lower (a level
        // that is no module of its own: the file's module).
        let depth = inline.iter().filter(|r| r.contains(&start)).count();
        let here: Vec<&str> = here.iter().copied().chain(std::iter::repeat_n("{inline}", depth)).collect();
        let paths: Vec<(String, bool)> = if close > 0 {
            items.iter().map(|item| (format!("{head}{item}"), false)).collect()
        } else {
            // (A glob's `*` is shown, not resolved: the path before it names the module.)
            let glob = if rest[end..].starts_with('*') { "*" } else { "" };
            vec![(format!("{head}{glob}"), rest[end..].starts_with('('))]
        };
        for (text, called) in paths {
            let named = text.clone();
            let mut segs: Vec<&str> = text.split("::").filter(|s| !s.is_empty() && *s != "*").collect();
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
                Some("self") => path.extend(here.iter().copied()),
                Some(kid) if depth == 0 && kids.contains(kid) => {
                    path.extend(here.iter().copied());
                    path.push(kid);
                }
                _ => continue,
            }
            path.extend(segs);
            for k in (1..=path.len()).rev() {
                let candidate = path[..k].join("::");
                if known.contains_key(&candidate) {
                    if candidate != module {
                        out.entry(candidate).or_default().insert(named);
                    }
                    break;
                }
            }
        }
    }
    out
}

/// Each module of `src/` with the modules it names, and the paths that name each.
fn named_graph() -> BTreeMap<String, BTreeMap<String, BTreeSet<String>>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = BTreeMap::new();
    sources(&src, &mut files);
    let known = modules(&src, &files);
    assert!(known.len() > 50, "read src/: {} modules", known.len());
    known.iter().map(|(m, text)| (m.clone(), names(m, &code(text), &known))).collect()
}

fn graph() -> BTreeMap<String, BTreeSet<String>> {
    named_graph().into_iter().map(|(m, names)| (m, names.into_keys().collect())).collect()
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
    let rings = cycles(&g);
    if !rings.is_empty() {
        // Which paths make each ring: the edges between its modules.
        let named = named_graph();
        let mut why = String::new();
        for ring in &rings {
            for m in ring {
                for (d, paths) in &named[m] {
                    if ring.contains(d) {
                        let paths: Vec<&str> = paths.iter().map(String::as_str).collect();
                        why += &format!("\n  {m} → {d}: {}", paths.join(", "));
                    }
                }
            }
        }
        panic!("modules that import each other (in a ring): {rings:?}{why}");
    }
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
    for m in ["a", "b", "c", "c::d", "p", "p::q", "p::r", "p::s", "p::y", "p::y::k", "p::y::m", "x", "x::q"] {
        known.insert(m.to_string(), String::new());
    }
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a", "use crate::b::Thing; // crate::c in a comment\nlet s = \"crate::c\";"),
        ("b", "fn f() { super::a::g(); }\n#[serde(default = \"crate::p::r::one\", rename = \"crate::x\")]"),
        ("c", "fn f() { super::run(); }\nuse crate::{c::d::X, b};"),
        (
            "c::d",
            "#[cfg(test)]\nmod tests {\n    use crate::c;\n    fn f() { let b = '{'; }\n}\nuse super::super::a;\nuse crate::b::*;\n#[cfg(test)]\nmod more;",
        ),
        // A parent and its child in a ring, the parent naming the child by
        // its bare name; `s` is a module but not declared here, so `s::` is
        // some other path (a crate's, say).
        ("p", "pub mod q;\n#[cfg(feature = \"x\")]\npub(crate) mod r;\nfn go() { q::run(); let z = r::Z; }\nuse s::Y;\nuse lucent_q::{q::Z};"),
        ("p::q", "use super::go;"),
        ("p::r", "use self::inner::Z;"),
        // A child named by `use child::…` and `self::child::…`, not by
        // `other::child::…`, `lucent_q::…` or a method `.q::<T>()`.
        ("x", "mod q;\nuse q::{A, B};\nfn f() { self::q::g(); crate::b::q::h(); v.q::<u8>(); }"),
        ("x::q", "use crate::c;"),
        // Inside an inline module, `super::` is the file's module (not its
        // parent) and the file's children are not in scope by bare name.
        (
            "p::y",
            "mod k;\nmod m;\nmod defaults {\n    use super::Y;\n    fn f() { m::g(); }\n}\nmod more {\n    fn f() { super::k::h(); }\n}",
        ),
    ]
    .iter()
    .map(|(m, text)| (m.to_string(), imports(m, &code(text), &known)))
    .collect();
    let set = |ms: &[&str]| ms.iter().map(|m| m.to_string()).collect::<BTreeSet<String>>();
    assert_eq!(g["a"], set(&["b"]));
    assert_eq!(g["b"], set(&["a", "p::r"]), "a serde default is a path, a rename is not");
    assert_eq!(g["c"], set(&["b", "c::d"]), "a group's items; super::run( is a function");
    assert_eq!(g["c::d"], set(&["a", "b"]), "code after a test module counts (a glob too), the module does not");
    assert_eq!(g["p"], set(&["p::q", "p::r"]), "the declared children by bare name; s is not declared");
    assert_eq!(g["p::q"], set(&["p"]));
    assert_eq!(g["p::r"], set(&[]), "self:: is the module itself");
    assert_eq!(g["x"], set(&["b", "x::q"]));
    assert_eq!(g["p::y"], set(&["p::y::k"]), "an inline module's super:: is the file's module");
    assert_eq!(
        cycles(&g),
        vec![set(&["a", "b"]).into_iter().collect::<Vec<_>>(), set(&["p", "p::q"]).into_iter().collect()]
    );
}

#[test]
fn a_path_attribute_names_the_module_not_the_file() {
    // src/lib.rs declares p (src/p/mod.rs) and m (src/m.rs); p declares
    // `x` from src/p/x_impl.rs, m declares `e` from src/m_e.rs (beside m.rs:
    // rustc reads a #[path] relative to the declaring file's folder) and
    // `f` from src/p/f.rs; x_impl.rs names its parent (p) with super::.
    let src = Path::new("/s");
    let files: BTreeMap<PathBuf, String> = [
        ("/s/lib.rs", "pub mod m;\npub mod p;"),
        ("/s/p/mod.rs", "#[path = \"x_impl.rs\"]\npub mod x;\npub struct Item;\nfn f() { x::g(); }"),
        ("/s/p/x_impl.rs", "use super::Item;\npub fn g() {}"),
        ("/s/p/f.rs", "use super::H; // #[path = \"nothing.rs\"] mod n;"),
        (
            "/s/m.rs",
            "#[path = \"m_e.rs\"] #[allow(dead_code)] pub(crate) mod e;\n#[path = \"./p/../p/f.rs\"]\nmod f;\npub struct H;\nuse e::G;",
        ),
        ("/s/m_e.rs", "pub struct G;"),
        ("/s/main.rs", "fn main() {}"),
    ]
    .iter()
    .map(|(p, t)| (PathBuf::from(p), t.to_string()))
    .collect();
    let known = modules(src, &files);
    assert_eq!(
        known.keys().map(String::as_str).collect::<Vec<_>>(),
        ["", "m", "m::e", "m::f", "p", "p::x"],
        "modules, not files (main.rs is the binary)"
    );
    assert_eq!(known["p::x"], files[Path::new("/s/p/x_impl.rs")]);
    let g: BTreeMap<String, BTreeSet<String>> =
        known.iter().map(|(m, text)| (m.clone(), imports(m, &code(text), &known))).collect();
    assert_eq!(g["p::x"], BTreeSet::from(["p".to_string()]), "super:: of p::x is p, not the file's folder");
    assert_eq!(g["m::f"], BTreeSet::from(["m".to_string()]));
    assert_eq!(g["m"], BTreeSet::from(["m::e".to_string()]));
    assert_eq!(cycles(&g), vec![vec!["p".to_string(), "p::x".to_string()]]);
}
