//! A refractiveindex.info YAML file through `IndexSpectrum::parse`, then
//! evaluated across and beyond its range with every extrapolation: an
//! error or a value, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use lucent::optics::index::{Extrapolation, IndexSpectrum};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(s) = IndexSpectrum::parse(text, "fuzz.yml") {
        let (lo, hi) = s.range_nm();
        for e in [Extrapolation::None, Extrapolation::Clamp, Extrapolation::Linear] {
            for w in [lo, hi, 0.5 * (lo + hi), lo - 10.0, hi + 10.0, 550.0, 0.0, -1.0, f64::NAN] {
                let _ = s.at(w, e);
            }
        }
    }
});
