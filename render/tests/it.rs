//! All integration tests of this crate in one binary: one link instead of one per file, which
//! keeps `make test` short. Each file stays a module of its own; the root crate's
//! `every_test_file_is_included` (tests/it.rs) fails when a new file under tests/ is not listed here (cargo's autotests are off).

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
