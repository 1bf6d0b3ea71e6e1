//! The type hints `python/lucent.pyi` against the module's source
//! `python/src/lib.rs`: every function the module registers (by its Python
//! name, `#[pyo3(name = "…")]`) has a `def` in the stub file with the same
//! parameters in the same order, the same keyword-only marker `*` and the
//! same defaults, and the stub declares no function the module lacks.
//!
//! Besides checking the stubs, this test target makes `cargo test
//! --workspace` build the extension itself (the library is a dependency of
//! every integration test), so `make test` can import that build. The test
//! does not reference the library, so nothing here links libpython.

use std::collections::BTreeMap;
use std::path::Path;

fn read(rel: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// Splits `text` at the commas outside brackets (also `<…>`) and quotes, trimmed, empty parts dropped.
fn split_top(text: &str) -> Vec<String> {
    let (mut parts, mut cur, mut depth, mut quoted) = (Vec::new(), String::new(), 0i32, false);
    for c in text.chars() {
        match c {
            '"' => quoted = !quoted,
            '(' | '[' | '{' | '<' if !quoted => depth += 1,
            ')' | ']' | '}' | '>' if !quoted => depth -= 1,
            ',' if !quoted && depth == 0 => {
                parts.push(std::mem::take(&mut cur));
                continue;
            }
            _ => {}
        }
        cur.push(c);
    }
    parts.push(cur);
    parts.into_iter().map(|p| p.trim().to_string()).filter(|p| !p.is_empty()).collect()
}

/// The text inside the parentheses that open at `text[open]`.
fn parenthesised(text: &str, open: usize) -> &str {
    let mut depth = 0;
    for (i, c) in text[open..].char_indices() {
        match c {
            '(' => depth += 1,
            ')' => {
                depth -= 1;
                if depth == 0 {
                    return &text[open + 1..open + i];
                }
            }
            _ => {}
        }
    }
    panic!("unbalanced parentheses: {}", &text[open..])
}

/// A parameter as "name" or "name=default" (Python spelling of Rust's
/// `true`/`false`), or "*".
fn param(name: &str, default: Option<&str>) -> String {
    match default.map(str::trim) {
        None => name.trim().to_string(),
        Some(d) => format!("{}={}", name.trim(), d.replace("false", "False").replace("true", "True")),
    }
}

/// The `#[pyfunction]`s by Python name (the `name = "…"` of the
/// `#[pyo3(…)]` attribute that follows each `#[pyfunction]`), with their
/// parameters: those of `signature = (…)`, else the Rust function's
/// arguments after `py: Python`.
fn module_functions(src: &str) -> BTreeMap<String, Vec<String>> {
    let mut out = BTreeMap::new();
    let mut rest = src;
    while let Some(at) = rest.find("#[pyfunction]") {
        rest = &rest[at + "#[pyfunction]".len()..];
        let attr = rest.trim_start();
        assert!(
            attr.starts_with("#[pyo3("),
            "#[pyfunction] without #[pyo3(name = …)]: {}",
            &attr[..60.min(attr.len())]
        );
        let args = parenthesised(attr, attr.find('(').unwrap());
        let name = args.split("name = \"").nth(1).expect("name = \"…\"");
        let name = name[..name.find('"').expect("closing quote")].to_string();
        let params = match args.find("signature = (") {
            Some(i) => split_top(parenthesised(args, i + "signature = ".len()))
                .iter()
                .map(|p| match p.split_once('=') {
                    Some((n, d)) => param(n, Some(d)),
                    None => param(p, None),
                })
                .collect(),
            None => {
                let f = attr.find("\nfn ").expect("fn after #[pyo3(…)]");
                let open = f + attr[f..].find('(').expect("fn name(");
                split_top(parenthesised(attr, open))
                    .iter()
                    .map(|a| a.split_once(':').expect("name: type").0.to_string())
                    .filter(|n| n != "py")
                    .collect()
            }
        };
        out.insert(name, params);
    }
    out
}

/// The top-level `def`s of a stub file with their parameters.
fn stub_functions(pyi: &str) -> BTreeMap<String, Vec<String>> {
    let mut out = BTreeMap::new();
    for (i, _) in pyi.match_indices("\ndef ").chain(pyi.starts_with("def ").then_some((usize::MAX, ""))) {
        let start = if i == usize::MAX { 0 } else { i + 1 };
        let def = &pyi[start + "def ".len()..];
        let open = def.find('(').expect("def name(");
        let params = split_top(parenthesised(def, open))
            .iter()
            .map(|p| {
                let (name, default) = match p.split_once('=') {
                    Some((n, d)) => (n, Some(d)),
                    None => (p.as_str(), None),
                };
                param(name.split(':').next().unwrap_or(name), default)
            })
            .collect();
        out.insert(def[..open].trim().to_string(), params);
    }
    out
}

#[test]
fn stubs_declare_the_module_functions() {
    let module = module_functions(&read("src/lib.rs"));
    let stubs = stub_functions(&read("lucent.pyi"));
    assert!(module.len() >= 10, "found only {module:?} in src/lib.rs");
    assert_eq!(
        module.keys().collect::<Vec<_>>(),
        stubs.keys().collect::<Vec<_>>(),
        "functions of src/lib.rs vs lucent.pyi"
    );
    for (name, params) in &module {
        assert_eq!(params, &stubs[name], "parameters of {name}: src/lib.rs vs lucent.pyi");
    }
}

#[test]
fn parsers_read_names_and_parameters() {
    let src = "#[pyfunction]\n#[pyo3(name = \"a\", signature = (x, *, y = \"p, q\", z = false))]\nfn py_a() {}\n\
               #[pyfunction]\n#[pyo3(name = \"b\")]\nfn py_b<'py>(py: Python<'py>, u: &Bound<'py, PyAny>, v: f64) {}\n";
    let m = module_functions(src);
    assert_eq!(m["a"], ["x", "*", "y=\"p, q\"", "z=False"]);
    assert_eq!(m["b"], ["u", "v"]);
    let pyi =
        "def a(x: int, *, y: str = \"p, q\", z: bool = False) -> int: ...\nclass B:\n    def c(self) -> None: ...\n\
               def b(\n    u: Callable[[float, str], object],\n    v: float,\n) -> None: ...\n";
    let s = stub_functions(pyi);
    assert_eq!(s.keys().collect::<Vec<_>>(), ["a", "b"]);
    assert_eq!(s["a"], m["a"]);
    assert_eq!(s["b"], m["b"]);
}
