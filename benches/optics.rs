//! Benchmarks of the optics stage (issue: speed targets):
//! * `mie/reference_cases`: Lorenz–Mie efficiencies over the 320 miepython
//!   reference cases (one core); compare with `tools/bench_miepython.py`.
//! * `optics/all_samples_41_wavelengths`: the full default table (41
//!   wavelengths) with 4096-entry phase tables for every shipped recipe, on
//!   all cores (target: under 2 s on 2 cores).

use criterion::{criterion_group, criterion_main, Criterion};
use lucent::optics::bulk;
use lucent::optics::mie::Coefficients;
use lucent::optics::recipe::{Overrides, Recipe};
use lucent_colour::WavelengthGrid;
use num_complex::Complex64;
use rayon::prelude::*;
use std::path::Path;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn mie(c: &mut Criterion) {
    let cases = lucent::cli::read_mie_cases(&root().join("fixtures/reference/mie_miepython.csv"))
        .expect("reference cases (run tools/reference/mie_miepython.py)");
    let mut coeffs = Coefficients::new();
    c.bench_function("mie/reference_cases", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for &(m, x) in &cases {
                coeffs.recompute(m, Complex64::new(x, 0.0)).expect("valid case");
                sum += coeffs.efficiencies(x).qsca;
            }
            sum
        })
    });
}

fn all_samples(c: &mut Criterion) {
    let recipes: Vec<Recipe> = (5..=16)
        .map(|nn| {
            let p = root().join(format!("fixtures/samples/IOL1068-{nn:02}.toml"));
            Recipe::load(&p, Overrides { weight_percent: Some(1.0) }).expect("shipped recipe")
        })
        .collect();
    let grid = WavelengthGrid::visible();
    let options = bulk::Options::default();
    let mut group = c.benchmark_group("optics");
    group.sample_size(10);
    group.bench_function("all_samples_41_wavelengths", |b| {
        b.iter(|| recipes.par_iter().map(|r| bulk::compute(r, &grid, &options).expect("computes")).collect::<Vec<_>>())
    });
    group.finish();
}

criterion_group!(benches, mie, all_samples);
criterion_main!(benches);
