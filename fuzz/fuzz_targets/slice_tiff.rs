//! A measured slice (.tiff) through `bssrdf::read_grid`, the reader of
//! `--measured`/`--simulated`: the bytes are written to a file of that
//! extension in a private temp folder (the reader takes paths). An error or
//! a square grid of finite values, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

static DIR: OnceLock<std::path::PathBuf> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let dir = DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("lucent-fuzz-tiff-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("temp folder");
        d
    });
    let path = dir.join("slice.tiff");
    std::fs::write(&path, data).expect("write the input");
    if let Ok(g) = lucent::bssrdf::read_grid(&path, Some(0.1)) {
        assert_eq!(g.values.len(), g.size * g.size);
        assert!(g.values.iter().all(|v| v.is_finite()));
    }
});
