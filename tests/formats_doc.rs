//! docs/formats.md cannot drift from the serde types it documents:
//! every ```` ```toml recipe|scene|project ```` example parses with lucent's
//! own parser, and each key table lists exactly the keys its type accepts.
//! The accepted keys come from the types themselves: a probe key is put
//! into a valid file at the table's place, and the parser's "unknown field
//! …, expected one of …" (every type here denies unknown fields) names them.
//! Adding a key to a type without documenting it, or documenting a key the
//! type does not have, fails here.

use lucent::optics::recipe::{Overrides, Recipe};
use lucent::pipeline::project::ProjectFile;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const PROBE: &str = "zz_undocumented_probe";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn doc() -> String {
    std::fs::read_to_string(root().join("docs/formats.md")).expect("docs/formats.md")
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Format {
    Recipe,
    Scene,
    Project,
}

/// Parses `text` as `format` with the parser the commands use (the typed stage; a recipe is also
/// validated, with its builtin indices). Errors as their message.
fn parse(format: Format, text: &str) -> Result<(), String> {
    match format {
        Format::Recipe => {
            Recipe::parse(text, &root().join("probe.toml"), Overrides::default()).map(drop).map_err(|e| e.to_string())
        }
        Format::Scene => lucent::scene::parse(text, Path::new("probe.toml")).map(drop).map_err(|e| e.to_string()),
        Format::Project => toml::from_str::<ProjectFile>(text).map(drop).map_err(|e| e.to_string()),
    }
}

/// The documented keys: `(format, table heading) → keys`, from the key tables under each
/// `## Recipe|Scene|Project` and `### ` heading (the heading's first `code`, or "top" for "Top level").
fn documented(doc: &str) -> BTreeMap<(Format, String), BTreeSet<String>> {
    let mut out: BTreeMap<(Format, String), BTreeSet<String>> = BTreeMap::new();
    let (mut format, mut table) = (None, None::<String>);
    for line in doc.lines() {
        if let Some(h) = line.strip_prefix("## ") {
            format = match h.split_whitespace().next() {
                Some("Recipe") => Some(Format::Recipe),
                Some("Scene") => Some(Format::Scene),
                Some("Project") => Some(Format::Project),
                _ => None,
            };
            table = None;
        } else if let Some(h) = line.strip_prefix("### ") {
            table =
                if h.starts_with("Top level") { Some("top".into()) } else { h.split('`').nth(1).map(str::to_string) };
        } else if let (Some(f), Some(t), Some(row)) = (format, &table, line.strip_prefix("| `")) {
            // A row may document several keys: "| `min`, `max` |".
            let cell = row.split(" |").next().unwrap_or("");
            let keys = format!("`{cell}").split('`').skip(1).step_by(2).map(str::to_string).collect::<Vec<_>>();
            out.entry((f, t.clone())).or_default().extend(keys);
        }
    }
    out
}

/// The keys a parser error says it expected ("expected `a`", "`a` or `b`", "one of `a`, `b`, …").
fn expected_keys(error: &str) -> BTreeSet<String> {
    let (_, tail) = error
        .split_once(&format!("unknown field `{PROBE}`, expected "))
        .unwrap_or_else(|| panic!("the probe was not refused as an unknown field: {error}"));
    let tail = tail.lines().next().unwrap_or("");
    tail.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

const RECIPE: &str = r#"{top}
name = "probe"
thickness_mm = 6.0
[host]
name = "PMMA"
index = "builtin:PMMA_Zhang2020_Mitsubishi"
density_g_per_ml = 1.18
extrapolate = "clamp"
real_part = { wavelength_nm = 550, n = 1.49{real_part} }
imaginary_part = { mode = "scale", factor = 1.0{imaginary_part} }
{host}
[[particles]]
name = "TiO2"
index = "builtin:TiO2_Siefke2016"
density_g_per_ml = 4.23
weight_percent = 0.05
size = { kind = "diameter", diameter_um = 0.25{size} }
{particles}
[[particles]]
name = "PMMA"
index = "builtin:PMMA_Zhang2020_Mitsubishi"
extrapolate = "clamp"
density_g_per_ml = 1.18
weight_percent = 0.5
size = { kind = "range", min_um = 0.8, max_um = 1.0, distribution = "uniform"{size_range} }
imaginary_part = { mode = "replace", kappa = 0{imaginary_replace} }
[[particles]]
name = "TiO2, log-normal"
index = "builtin:TiO2_Siefke2016"
density_g_per_ml = 4.23
weight_percent = 0.01
size = { kind = "log-normal", median_diameter_um = 1.0, sigma = 0.1{size_log} }
[surface]
model = "beckmann"
alpha = 0.01
{surface}
"#;

const SCENE: &str = r#"{top}
[camera]
width = 8
height = 6
position_m = [0.0, -0.2, 0.15]
look_at_m = [0.0, 0.0, 0.0]
vertical_fov_deg = 40.0
{camera}
[object]
size_mm = [60.0, 40.0, 6.35]
{object}
[material]
sigma_s_per_m = [1000.0, 1000.0, 1000.0]
sigma_a_per_m = [1.0, 1.0, 1.0]
g = [0.5, 0.5, 0.5]
n = [1.5, 1.5, 1.5]
{material}
[board]
{board}
[environment]
constant = [1.0, 1.0, 1.0]
{environment}
[render]
{render}
"#;

const PROJECT: &str = r#"{top}
[project]
{project}
[optics]
{optics}
[surface]
{surface}
[bssrdf]
{bssrdf}
[calibration]
images = "x/*.png"
board = "9x6"
square_mm = 20
{calibration}
[[colour]]
camera = "phone"
image = "chart.exr"
{colour}
[pose]
image = "p.png"
{pose}
[render]
scene = "s.toml"
{render}
[compare]
{compare}
[fit]
free = ["weight_percent"]
{fit}
[[sample]]
name = "a"
recipe = "r.toml"
{sample}
[[sample.measured]]
config = "45/0"
file = "m.exr"
{measured}
[executor]
{executor}
"#;

/// (format, template, placeholder, the documented table it must match).
const PROBES: &[(Format, &str, &str, &str)] = &[
    (Format::Recipe, RECIPE, "top", "top"),
    (Format::Recipe, RECIPE, "host", "[host]"),
    (Format::Recipe, RECIPE, "particles", "[[particles]]"),
    (Format::Recipe, RECIPE, "surface", "[surface]"),
    (Format::Recipe, RECIPE, "real_part", "real_part"),
    (Format::Recipe, RECIPE, "imaginary_part", "imaginary_part"),
    (Format::Recipe, RECIPE, "imaginary_replace", "imaginary_part"),
    (Format::Recipe, RECIPE, "size", "size"),
    (Format::Recipe, RECIPE, "size_range", "size"),
    (Format::Recipe, RECIPE, "size_log", "size"),
    (Format::Scene, SCENE, "top", "top"),
    (Format::Scene, SCENE, "camera", "[camera]"),
    (Format::Scene, SCENE, "object", "[object]"),
    (Format::Scene, SCENE, "material", "[material]"),
    (Format::Scene, SCENE, "board", "[board]"),
    (Format::Scene, SCENE, "environment", "[environment]"),
    (Format::Scene, SCENE, "render", "[render]"),
    (Format::Project, PROJECT, "top", "top"),
    (Format::Project, PROJECT, "project", "[project]"),
    (Format::Project, PROJECT, "optics", "[optics]"),
    (Format::Project, PROJECT, "surface", "[surface]"),
    (Format::Project, PROJECT, "bssrdf", "[bssrdf]"),
    (Format::Project, PROJECT, "calibration", "[calibration]"),
    (Format::Project, PROJECT, "colour", "[[colour]]"),
    (Format::Project, PROJECT, "pose", "[pose]"),
    (Format::Project, PROJECT, "render", "[render]"),
    (Format::Project, PROJECT, "compare", "[compare]"),
    (Format::Project, PROJECT, "fit", "[fit]"),
    (Format::Project, PROJECT, "sample", "[[sample]]"),
    (Format::Project, PROJECT, "measured", "[[sample.measured]]"),
    (Format::Project, PROJECT, "executor", "[executor]"),
];

/// The tags of internally tagged enums: documented keys that serde does not list among a
/// variant's fields.
const TAGS: &[(Format, &str, &str)] = &[(Format::Recipe, "size", "kind"), (Format::Recipe, "imaginary_part", "mode")];

/// `template` with the probe at `at` (as `key = 1` on its own line, or `, key = 1` inside an
/// inline table) and every other placeholder empty.
fn probed(template: &str, at: &str) -> String {
    let mut text = template.to_string();
    for (_, t, place, _) in PROBES {
        if *t != template {
            continue;
        }
        let inline = !matches!(
            *place,
            "top"
                | "host"
                | "particles"
                | "surface"
                | "camera"
                | "object"
                | "material"
                | "board"
                | "environment"
                | "render"
                | "project"
                | "optics"
                | "bssrdf"
                | "calibration"
                | "colour"
                | "pose"
                | "compare"
                | "fit"
                | "sample"
                | "measured"
                | "executor"
        );
        let with = match (*place == at, inline) {
            (false, _) => String::new(),
            (true, true) => format!(", {PROBE} = 1"),
            (true, false) => format!("{PROBE} = 1"),
        };
        text = text.replace(&format!("{{{place}}}"), &with);
    }
    text
}

#[test]
fn the_probe_templates_are_valid_files() {
    for (format, template) in [(Format::Recipe, RECIPE), (Format::Scene, SCENE), (Format::Project, PROJECT)] {
        parse(format, &probed(template, "none")).unwrap_or_else(|e| panic!("{format:?} template: {e}"));
    }
}

#[test]
fn every_key_the_types_accept_is_documented_and_no_other() {
    let problems = undocumented(&doc());
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// What is accepted but not documented, or documented but not accepted, in `doc`.
fn undocumented(doc: &str) -> Vec<String> {
    let doc = documented(doc);
    let mut seen: BTreeMap<(Format, String), BTreeSet<String>> = BTreeMap::new();
    for (format, template, place, table) in PROBES {
        let error = parse(*format, &probed(template, place)).expect_err("the probe key must be refused");
        let accepted = expected_keys(&error);
        assert!(!accepted.is_empty(), "{format:?} {place}: no expected keys in {error}");
        seen.entry((*format, table.to_string())).or_default().extend(accepted);
    }
    let mut problems = Vec::new();
    for ((format, table), accepted) in &seen {
        let empty = BTreeSet::new();
        let documented = doc.get(&(*format, table.clone())).unwrap_or(&empty);
        for key in accepted.difference(documented) {
            problems.push(format!("{format:?} {table}: `{key}` is accepted but not in docs/formats.md"));
        }
        for key in documented.difference(accepted) {
            if !TAGS.contains(&(*format, table.as_str(), key.as_str())) {
                problems.push(format!("{format:?} {table}: `{key}` is documented but not accepted"));
            }
        }
    }
    problems
}

#[test]
fn every_toml_example_parses_as_what_it_says_it_is() {
    let doc = doc();
    let mut count = BTreeMap::new();
    let mut lines = doc.lines();
    while let Some(line) = lines.next() {
        let Some(info) = line.strip_prefix("```toml") else { continue };
        let format = match info.trim() {
            "recipe" => Format::Recipe,
            "scene" => Format::Scene,
            "project" => Format::Project,
            other => panic!("a ```toml block must say what it is (recipe, scene or project), not {other:?}"),
        };
        let text: Vec<&str> = lines.by_ref().take_while(|l| !l.starts_with("```")).collect();
        parse(format, &text.join("\n")).unwrap_or_else(|e| panic!("docs/formats.md {format:?} example: {e}"));
        *count.entry(format).or_insert(0) += 1;
    }
    assert_eq!(count.len(), 3, "an example of each format: {count:?}");
}

#[test]
fn a_key_missing_from_a_table_or_one_too_many_is_found() {
    let doc = doc();
    let without = doc.replace("| `unit_scale_m` |", "| unit_scale_m |");
    assert_ne!(without, doc);
    assert_eq!(undocumented(&without), ["Scene [object]: `unit_scale_m` is accepted but not in docs/formats.md"]);
    let extra = doc.replace("| `lift_m` |", "| `lift_m`, `lift_mm` |");
    assert_eq!(undocumented(&extra), ["Scene [object]: `lift_mm` is documented but not accepted"]);
}

#[test]
fn the_readme_worked_example_files_parse() {
    // fixtures/example/ holds the README's recipe, scene and project; the README shows them.
    let dir = root().join("fixtures/example");
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    for (file, format) in
        [("tio2_pmma.toml", Format::Recipe), ("scene.toml", Format::Scene), ("project.toml", Format::Project)]
    {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        parse(format, &text).unwrap_or_else(|e| panic!("fixtures/example/{file}: {e}"));
        // Every non-comment line of the file is in the README's copy.
        for line in text.lines().map(|l| l.split('#').next().unwrap_or("").trim_end()).filter(|l| !l.is_empty()) {
            assert!(readme.contains(line), "README's worked example lacks {file}'s line {line:?}");
        }
    }
}
