//! What a newcomer with their own sample tripped over, each answered by a
//! message that says what to do: a mesh in the wrong unit (its size and
//! `unit_scale_m`), and a recipe whose index table does not reach the
//! renderer's 380–780 nm (the range and the `extrapolate` key).

use lucent::scene::{self, mesh};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
use std::process::Command;

/// The 60 × 40 × 6.35 mm plaque as an OBJ whose coordinates are multiplied by `per_metre`.
fn write_plaque_obj(path: &Path, per_metre: f64) {
    let m = mesh::plaque_box(0.060, 0.040, 0.00635);
    let mut text = String::new();
    for p in &m.positions_m {
        text += &format!("v {} {} {}\n", p[0] * per_metre, p[1] * per_metre, p[2] * per_metre);
    }
    for t in &m.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

fn scene_text(mesh_key: &str, environment: &str) -> String {
    format!(
        "[camera]\nwidth = 8\nheight = 6\nposition_m = [0.0, -0.2, 0.15]\nlook_at_m = [0.0, 0.0, 0.0]\n\
         up = [0.0, 0.0, 1.0]\nvertical_fov_deg = 40.0\n\n[object]\n{mesh_key}\n\n[material]\n\
         sigma_s_per_m = [1000.0, 1000.0, 1000.0]\nsigma_a_per_m = [1.0, 1.0, 1.0]\ng = [0.5, 0.5, 0.5]\n\
         n = [1.5, 1.5, 1.5]\nphase = \"hg\"\n\n[environment]\n{environment}\n\n[render]\nspp = 1\nseed = 1\n"
    )
}

const SIZE_HINT: &str = "unit_scale_m = 0.001";

#[test]
fn a_mesh_in_millimetres_read_as_metres_is_named_with_its_size() {
    let tmp = tempfile::tempdir().unwrap();
    let obj = tmp.path().join("plaque_mm.obj");
    write_plaque_obj(&obj, 1000.0);
    // Read as metres: 60 m across.
    let (_, report) = mesh::load(&obj, 1.0).unwrap();
    assert!(report.closed);
    let w = report.warnings.join("\n");
    assert!(w.contains("60.0000 × 40.0000 × 6.3500 m") && w.contains(SIZE_HINT), "{w}");
    // With the right unit: no size warning, and none for the same plaque given in metres.
    let (_, report) = mesh::load(&obj, 1e-3).unwrap();
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    // A mesh in metres read as millimetres: 60 µm across.
    let obj_m = tmp.path().join("plaque_m.obj");
    write_plaque_obj(&obj_m, 1.0);
    let (_, report) = mesh::load(&obj_m, 1e-3).unwrap();
    let w = report.warnings.join("\n");
    assert!(w.contains("0.060 mm") && w.contains("unit_scale_m"), "{w}");
    // The scene loader: the 60 m plaque is around the camera, an error with its size and the key.
    let scene_path = tmp.path().join("scene.toml");
    std::fs::write(&scene_path, scene_text("mesh = \"plaque_mm.obj\"", "constant = [1.0, 1.0, 1.0]")).unwrap();
    let Err(e) = scene::load(&scene_path) else { panic!("the camera inside the object was taken") };
    let e = e.to_string();
    assert!(e.contains("[object] unit_scale_m") && e.contains("60.0000 × 40.0000") && e.contains(SIZE_HINT), "{e}");
}

#[test]
fn the_limits_of_a_plausible_size_are_where_the_doc_says() {
    let at = |side: f64| mesh::size_warning([0.0; 3], [side, side / 2.0, side / 4.0]);
    assert!(at(0.999).is_none() && at(1e-3).is_none());
    assert!(at(1.0).is_some_and(|w| w.contains(SIZE_HINT)));
    assert!(at(0.999e-3).is_some_and(|w| w.contains("less than a millimetre")));
}

#[test]
fn render_says_the_size_where_it_refuses_a_camera_inside_the_object() {
    // The README's 30 mm sphere (fixtures/example/part.obj, in mm) read as metres: the camera is
    // inside a 30 m object and every path would be lost; the error says the size and the key
    // (it was rendered with a warning).
    let tmp = tempfile::tempdir().unwrap();
    let mesh = format!("mesh = {:?}", root().join("fixtures/example/part.obj").display().to_string());
    let scene_path = tmp.path().join("scene.toml");
    std::fs::write(&scene_path, scene_text(&mesh, "constant = [1.0, 1.0, 1.0]")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(["render", scene_path.to_str().unwrap(), "--out", tmp.path().join("r").to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("[object] unit_scale_m") && err.contains("30.0000 × 30.0000 × 30.0000 m"), "{err}");
    assert!(err.contains(SIZE_HINT) && !tmp.path().join("r").exists(), "{err}");
}

#[test]
fn a_recipe_short_of_380_nm_names_the_range_and_the_extrapolate_key() {
    let tmp = tempfile::tempdir().unwrap();
    // PMMA (Zhang 2020) is tabulated from 400 nm: enough for `optics --wavelengths 400:700:10`, not for a render.
    let recipe = "name = \"tio2-pmma\"\nthickness_mm = 6.0\nsize_mm = [40.0, 30.0]\n[host]\nname = \"PMMA\"\n\
                  index = \"builtin:PMMA_Zhang2020_Mitsubishi\"\ndensity_g_per_ml = 1.18\n\
                  [[particles]]\nname = \"TiO2\"\nindex = \"builtin:TiO2_Siefke2016\"\ndensity_g_per_ml = 4.23\n\
                  weight_percent = 0.05\nsize = { kind = \"diameter\", diameter_um = 0.25 }\n";
    std::fs::write(tmp.path().join("r.toml"), recipe).unwrap();
    let material = "[material]\nrecipe = \"r.toml\"\nphase = \"hg\"\n";
    let text = format!(
        "[camera]\nwidth = 8\nheight = 6\nposition_m = [0.0, -0.2, 0.15]\nlook_at_m = [0.0, 0.0, 0.0]\n\
         vertical_fov_deg = 40.0\n[object]\n{material}[environment]\nconstant = [1.0, 1.0, 1.0]\n"
    );
    let scene_path = tmp.path().join("scene.toml");
    std::fs::write(&scene_path, &text).unwrap();
    let Err(e) = scene::load(&scene_path) else { panic!("a table from 400 nm cannot give 380 nm") };
    let msg = e.to_string();
    for needle in ["380:780:10", "380 nm", "400", "extrapolate = \"clamp\"", "[host]"] {
        assert!(msg.contains(needle), "{msg:?} does not mention {needle:?}");
    }
    // The key it names fixes it.
    let fixed = recipe.replace("density_g_per_ml = 1.18\n", "density_g_per_ml = 1.18\nextrapolate = \"clamp\"\n");
    std::fs::write(tmp.path().join("r.toml"), fixed).unwrap();
    scene::load(&scene_path).unwrap();
}
