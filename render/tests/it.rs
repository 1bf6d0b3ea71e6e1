//! All integration tests of this crate in one binary: one link instead of one per file, which
//! keeps `make test` short. Each file stays a module of its own; `every_test_file_is_included`
//! fails when a new file under tests/ is not listed here (cargo's autotests are off).

#[path = "env.rs"]
mod env;
#[path = "microfacet.rs"]
mod microfacet;
#[path = "slab.rs"]
mod slab;
#[path = "slab_rough.rs"]
mod slab_rough;
#[path = "tracer.rs"]
mod tracer;

#[test]
fn every_test_file_is_included() {
    let here = include_str!("it.rs");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    for entry in std::fs::read_dir(&dir).expect("tests/ is readable") {
        let name = entry.expect("a directory entry").file_name().to_string_lossy().into_owned();
        if name.ends_with(".rs") && name != "it.rs" {
            let line = format!("#[path = \"{name}\"]");
            assert!(here.contains(&line), "tests/{name} is not included in tests/it.rs, so it would never run");
        }
    }
}
