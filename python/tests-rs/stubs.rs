//! The type hints `python/lucent.pyi` against the module's source
//! `python/src/lib.rs`: every function the module registers (by its Python
//! name, `#[pyo3(name = "…")]`) has a `def` in the stub file, and the stub
//! declares no function the module lacks.
//!
//! Besides checking the stubs, this test target makes `cargo test
//! --workspace` build the extension itself (the library is a dependency of
//! every integration test), so `make test` can import that build. The test
//! does not reference the library, so nothing here links libpython.

use std::collections::BTreeSet;
use std::path::Path;

fn read(rel: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// The Python names of the `#[pyfunction]`s: the `name = "…"` of the
/// `#[pyo3(…)]` attribute that follows each `#[pyfunction]`.
fn module_functions(src: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let mut pending = false;
    for line in src.lines().map(str::trim) {
        if line.starts_with("#[pyfunction") {
            pending = true;
        } else if pending && line.starts_with("#[pyo3(") {
            let rest = line.split("name = \"").nth(1).expect("#[pyo3(name = …)] after #[pyfunction]");
            names.insert(rest[..rest.find('"').expect("closing quote")].to_string());
            pending = false;
        } else if pending && line.starts_with("fn ") {
            panic!("#[pyfunction] without #[pyo3(name = …)]: {line}");
        }
    }
    names
}

/// The top-level `def` names of a stub file.
fn stub_functions(pyi: &str) -> BTreeSet<String> {
    pyi.lines()
        .filter_map(|l| l.strip_prefix("def "))
        .map(|l| l[..l.find('(').expect("def name(")].trim().to_string())
        .collect()
}

#[test]
fn stubs_declare_the_module_functions() {
    let module = module_functions(&read("src/lib.rs"));
    let stubs = stub_functions(&read("lucent.pyi"));
    assert!(module.len() >= 8, "found only {module:?} in src/lib.rs");
    assert_eq!(module, stubs, "functions of src/lib.rs vs lucent.pyi");
}

#[test]
fn parsers_read_names() {
    let src = "#[pyfunction]\n#[pyo3(name = \"a\", signature = (x))]\nfn py_a() {}\n";
    assert_eq!(module_functions(src), BTreeSet::from(["a".to_string()]));
    let pyi = "def a(x: int) -> int: ...\nclass B:\n    def c(self) -> None: ...\n";
    assert_eq!(stub_functions(pyi), BTreeSet::from(["a".to_string()]));
}
