//! A recipe (TOML) through `Recipe::parse`: any text must give a recipe or
//! an error, never a panic or a hang. Index files it names are resolved
//! relative to a folder that does not exist, so only built-in indices load.
#![no_main]
use libfuzzer_sys::fuzz_target;
use lucent::optics::recipe::{Overrides, Recipe};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("/nonexistent-lucent-fuzz/recipe.toml");
    if let Ok(r) = Recipe::parse(text, path, Overrides::default()) {
        let _ = r.particle_volume_fraction();
        let _ = r.corrections();
        for i in 0..r.particles.len() {
            let _ = r.diameter_um(i);
        }
    }
});
