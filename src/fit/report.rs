//! Outputs of a fit: the fitted recipe (the original TOML text with the
//! fitted values written in, comments kept) and the plot of the objective
//! against each parameter.
//!
//! ```
//! use lucent::fit::report::set_particle_key;
//! let text = "name = \"x\"\n[[particles]]\nname = \"A\"\nweight_percent = 0.65   # as made\n";
//! let out = set_particle_key(text, 0, "weight_percent", "0.4251").unwrap();
//! assert!(out.contains("weight_percent = 0.4251   # as made"));
//! ```

use super::{FitResult, ParameterKind};
use crate::plot::{legend_column, palette, perr, render_png, Mark, PlotError};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Sets `key = value` in the `particle`-th `[[particles]]` table of recipe
/// text (replacing the existing line, keeping its trailing comment, or
/// inserting the line after the table header). `None` when the recipe has
/// fewer particle tables.
pub fn set_particle_key(text: &str, particle: usize, key: &str, value: &str) -> Option<String> {
    let lines: Vec<&str> = text.lines().collect();
    let headers: Vec<usize> =
        lines.iter().enumerate().filter(|(_, l)| l.trim() == "[[particles]]").map(|(i, _)| i).collect();
    let start = *headers.get(particle)?;
    let end = lines
        .iter()
        .enumerate()
        .skip(start + 1)
        .find(|(_, l)| l.trim_start().starts_with('['))
        .map(|(i, _)| i)
        .unwrap_or(lines.len());
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let found = (start + 1..end).find(|&i| {
        let t = lines[i].trim_start();
        t.strip_prefix(key).is_some_and(|rest| rest.trim_start().starts_with('='))
    });
    match found {
        Some(i) => {
            let line = lines[i];
            let comment = line.find('#').map(|c| &line[c..]).unwrap_or("");
            let indent = &line[..line.len() - line.trim_start().len()];
            let pad = if comment.is_empty() { String::new() } else { "   ".into() };
            out[i] = format!("{indent}{key} = {value}{pad}{comment}");
        }
        None => out.insert(start + 1, format!("{key} = {value}")),
    }
    let mut s = out.join("\n");
    if text.ends_with('\n') {
        s.push('\n');
    }
    Some(s)
}

/// Makes relative `index = "…"` and `fit = "…"` paths of recipe text
/// absolute (relative to `recipe_dir`), so the text can live elsewhere.
pub fn absolutise_paths(text: &str, recipe_dir: &Path) -> String {
    let mut out = Vec::new();
    for line in text.lines() {
        let t = line.trim_start();
        let mut replaced = None;
        for key in ["index", "fit"] {
            if let Some(rest) = t.strip_prefix(key) {
                let rest = rest.trim_start();
                if let Some(rest) = rest.strip_prefix('=') {
                    let rest = rest.trim_start();
                    if let Some(body) = rest.strip_prefix('"')
                        && let Some(end) = body.find('"')
                    {
                        let value = &body[..end];
                        if !value.starts_with("builtin:") && !Path::new(value).is_absolute() {
                            let abs = recipe_dir.join(value);
                            let abs = abs.canonicalize().unwrap_or(abs);
                            replaced = Some(format!(
                                "{}{key} = \"{}\"{}",
                                &line[..line.len() - t.len()],
                                abs.display(),
                                &body[end + 1..]
                            ));
                        }
                    }
                }
            }
        }
        out.push(replaced.unwrap_or_else(|| line.to_string()));
    }
    let mut s = out.join("\n");
    if text.ends_with('\n') {
        s.push('\n');
    }
    s
}

/// The recipe text with the fitted values written in (identifiable fits
/// only), headed by a comment naming the fit.
pub fn fitted_recipe_text(original: &str, recipe_dir: &Path, result: &FitResult) -> Option<String> {
    if !result.identifiable {
        return None;
    }
    let mut text = absolutise_paths(original, recipe_dir);
    let mut notes = Vec::new();
    for (p, free) in result.parameters.iter().zip(result_free(result)) {
        let value = p.value?;
        let se = p.std_error.unwrap_or(f64::NAN);
        notes.push(format!("# {} {} → {value:.6} ± {se:.2e}", p.name, p.start));
        // The fit's standard error travels as the value's uncertainty
        // (`lucent render --uncertainty` carries it to the twin's band).
        let v = if se.is_finite() && se > 0.0 {
            format!("{{ value = {value:.6}, sd = {se:.6e} }}")
        } else {
            format!("{value:.6}")
        };
        let (kind, particle) = free;
        text = match kind {
            ParameterKind::WeightPercent => set_particle_key(&text, particle, "weight_percent", &v)?,
            ParameterKind::DiameterUm => {
                set_particle_key(&text, particle, "size", &format!("{{ kind = \"diameter\", diameter_um = {v} }}"))?
            }
            ParameterKind::RealPartN => set_particle_key(
                &text,
                particle,
                "real_part",
                &format!("{{ wavelength_nm = {}, n = {v}, mode = \"shift\" }}", result.wavelength_nm),
            )?,
        };
    }
    Some(format!(
        "# Fitted by `lucent fit` ({} objective, {} configuration(s), {} nm): see fit.json. Each fitted value\n# carries the fit's standard error as its sd (parameters taken as independent).\n{}\n{text}",
        result.objective.name(),
        result.configurations.len(),
        result.wavelength_nm,
        notes.join("\n")
    ))
}

/// (kind, particle) of each fitted parameter, parsed back from its name.
fn result_free(result: &FitResult) -> Vec<(ParameterKind, usize)> {
    result
        .parameters
        .iter()
        .map(|p| {
            let (name, k) = p.name.split_once('@').unwrap_or((&p.name, "1"));
            let kind =
                ParameterKind::ALL.into_iter().find(|x| x.name() == name).unwrap_or(ParameterKind::WeightPercent);
            (kind, k.parse::<usize>().unwrap_or(1).saturating_sub(1))
        })
        .collect()
}

/// Width of the legend column beside each panel of [`objective_png`], pixels.
pub const OBJECTIVE_LEGEND_W: u32 = 290;
/// Width and height of one chart panel of [`objective_png`], pixels.
pub const OBJECTIVE_PANEL: (u32, u32) = (900, 560);

/// The light blue of the 95 % interval band: palette blue at 12 % over white.
const INTERVAL_FILL: RGBColor = RGBColor(228, 239, 246);

/// Objective against each parameter: every evaluation (search points open,
/// final points filled), the fitted parabola, the fitted value and its 95 %
/// interval; the start value as a dark grey line. One panel per parameter, each with its
/// legend in a column [`OBJECTIVE_LEGEND_W`] px wide to its right, off the
/// data.
pub fn objective_png(result: &FitResult) -> Result<Vec<u8>, PlotError> {
    let n = result.parameters.len();
    let (pw, ph) = OBJECTIVE_PANEL;
    render_png(pw + OBJECTIVE_LEGEND_W, ph * n as u32, |root| {
        let areas = root.split_evenly((n, 1));
        for (i, (row, p)) in areas.iter().zip(&result.parameters).enumerate() {
            let (area, legend) = row.split_horizontally(pw);
            let pts: Vec<(f64, f64, &str)> = result
                .history
                .iter()
                .filter(|e| e.objective.is_finite())
                .map(|e| (e.values[i], e.objective, e.stage))
                .collect();
            let mut x0 = pts.iter().map(|p| p.0).fold(f64::INFINITY, f64::min).min(p.start);
            let mut x1 = pts.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max).max(p.start);
            if let Some([a, b]) = p.interval_95 {
                x0 = x0.min(a);
                x1 = x1.max(b);
            }
            let pad = 0.05 * (x1 - x0).max(1e-9);
            let (x0, x1) = (x0 - pad, x1 + pad);
            let y1 = pts.iter().map(|p| p.1).fold(0.0, f64::max) * 1.08;
            let y1 = if y1 > 0.0 { y1 } else { 1.0 };
            let caption = match (p.value, p.std_error) {
                (Some(v), Some(s)) => format!(
                    "{} objective vs {}: {:.4} → {v:.4} ± {s:.4} (95 %: {:.4} … {:.4})",
                    result.objective.name(),
                    p.name,
                    p.start,
                    p.interval_95.map(|i| i[0]).unwrap_or(f64::NAN),
                    p.interval_95.map(|i| i[1]).unwrap_or(f64::NAN)
                ),
                _ => format!("{} objective vs {}: not identifiable", result.objective.name(), p.name),
            };
            let mut chart = ChartBuilder::on(&area)
                .margin(15)
                .caption(caption, ("sans-serif", 18))
                .x_label_area_size(40)
                .y_label_area_size(80)
                .build_cartesian_2d(x0..x1, 0.0..y1)
                .map_err(perr)?;
            chart
                .configure_mesh()
                .x_desc(p.name.as_str())
                .y_desc(format!("objective ({})", result.objective.name()))
                .y_label_formatter(&|v| format!("{v:.1e}"))
                .draw()
                .map_err(perr)?;
            let mut items: Vec<(String, Mark)> = Vec::new();
            if let Some([a, b]) = p.interval_95 {
                chart
                    .draw_series(std::iter::once(Rectangle::new([(a, 0.0), (b, y1)], INTERVAL_FILL.filled())))
                    .map_err(perr)?;
                items.push(("95 % interval".into(), Mark::Box(INTERVAL_FILL)));
            }
            let red = palette(3);
            if n == 1 && !result.model_curve.is_empty() {
                let curve: Vec<(f64, f64)> = result
                    .model_curve
                    .iter()
                    .map(|p| (p[0], p[1]))
                    .filter(|(x, y)| (0.0..=y1).contains(y) && (x0..=x1).contains(x))
                    .collect();
                chart.draw_series(LineSeries::new(curve, red.stroke_width(2))).map_err(perr)?;
                items.push(("local model through".into(), Mark::Line(red, 2)));
                items.push(("the final points".into(), Mark::None));
            }
            let grey = RGBColor(110, 110, 110);
            chart
                .draw_series(
                    pts.iter().filter(|p| p.2 != "final").map(|p| Circle::new((p.0, p.1), 4, grey.stroke_width(1))),
                )
                .map_err(perr)?;
            items.push(("search (¼ of the paths)".into(), Mark::Ring(grey)));
            let blue = palette(0);
            chart
                .draw_series(pts.iter().filter(|p| p.2 == "final").map(|p| Circle::new((p.0, p.1), 4, blue.filled())))
                .map_err(perr)?;
            items.push(("final (full paths)".into(), Mark::Dot(blue)));
            // The start line: dark grey, 2 px, so it stands out from a mesh line at the same x.
            let start_grey = RGBColor(60, 60, 60);
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(p.start, 0.0), (p.start, y1)],
                    start_grey.stroke_width(2),
                )))
                .map_err(perr)?;
            items.push((format!("start {:.4}", p.start), Mark::Line(start_grey, 2)));
            if let Some(v) = p.value {
                chart
                    .draw_series(std::iter::once(PathElement::new(vec![(v, 0.0), (v, y1)], blue.stroke_width(2))))
                    .map_err(perr)?;
                items.push((format!("fitted {v:.4}"), Mark::Line(blue, 2)));
            }
            legend_column(&legend, 60, &items)?;
        }
        Ok(())
    })
}

/// The file `lucent fit` writes with the measured profile of configuration
/// θi/θo (degrees) against the simulated ones at the recipe and at the fit.
pub fn profiles_name(theta_i_deg: f64, theta_o_deg: f64) -> String {
    let (start, end) = FitFiles::PROFILES;
    format!("{start}ti{theta_i_deg}_to{theta_o_deg}{end}")
}

/// The files of `lucent fit` in its output folder, each name spelled here
/// once: the [`FitResult`] (`json`), the objective against each parameter
/// (`objective_png`), per configuration the profiles
/// ([`FitFiles::profiles_png`]) and the fitted recipe
/// ([`FitFiles::fitted_recipe`]). Written by `lucent fit`, read by `lucent
/// run`'s planning and report.
///
/// ```
/// use lucent::fit::report::FitFiles;
/// let f = FitFiles::in_dir(std::path::Path::new("out/fit/s1"));
/// assert_eq!(f.json, std::path::Path::new("out/fit/s1/fit.json"));
/// assert_eq!(f.fitted_recipe("r"), std::path::Path::new("out/fit/s1/r_fitted.toml"));
/// assert!(FitFiles::is_output("profiles_ti45_to0.png") && !FitFiles::is_output("notes.txt"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FitFiles {
    pub json: PathBuf,
    pub objective_png: PathBuf,
    dir: PathBuf,
}

impl FitFiles {
    /// The names of the files every fit writes.
    pub const NAMES: [&'static str; 2] = ["fit.json", "objective.png"];
    /// The end of a fitted recipe's name (after the recipe's stem).
    const FITTED: &'static str = "_fitted.toml";
    /// The start and end of a profiles plot's name.
    const PROFILES: (&'static str, &'static str) = ("profiles_", ".png");

    /// The files of the fit whose output folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [json, objective_png] = Self::NAMES.map(|n| dir.join(n));
        Self { json, objective_png, dir: dir.to_path_buf() }
    }

    /// The profiles plot of configuration θi/θo (degrees).
    pub fn profiles_png(&self, theta_i_deg: f64, theta_o_deg: f64) -> PathBuf {
        self.dir.join(profiles_name(theta_i_deg, theta_o_deg))
    }

    /// The fitted recipe of the recipe whose file stem is `stem`.
    pub fn fitted_recipe(&self, stem: &str) -> PathBuf {
        self.dir.join(format!("{stem}{}", Self::FITTED))
    }

    /// Whether `name` is of a file a fit writes (the next fit replaces them all).
    pub fn is_output(name: &str) -> bool {
        let (start, end) = Self::PROFILES;
        Self::NAMES.contains(&name)
            || name.ends_with(Self::FITTED)
            || (name.starts_with(&format!("{start}ti")) && name.ends_with(end))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn particle_keys_are_set_in_the_right_table() {
        let text = "a = 1\n[[particles]]\nname = \"A\"\nweight_percent = 1\n[[particles]]\nname = \"B\"\n[surface]\nalpha = 1\n";
        let out = set_particle_key(text, 1, "weight_percent", "2.5").unwrap();
        assert_eq!(out, "a = 1\n[[particles]]\nname = \"A\"\nweight_percent = 1\n[[particles]]\nweight_percent = 2.5\nname = \"B\"\n[surface]\nalpha = 1\n");
        let out = set_particle_key(text, 0, "weight_percent", "0.5").unwrap();
        assert!(out.contains("name = \"A\"\nweight_percent = 0.5\n"), "{out}");
        assert!(set_particle_key(text, 2, "weight_percent", "1").is_none());
        // A key that merely starts with the name is not the key.
        let t = "[[particles]]\nweight_percent_note = 3\n";
        assert_eq!(
            set_particle_key(t, 0, "weight_percent", "1").unwrap(),
            "[[particles]]\nweight_percent = 1\nweight_percent_note = 3\n"
        );
    }

    #[test]
    fn relative_index_paths_become_absolute() {
        let t = "index = \"builtin:PC\"\n  index = \"data/x.yml\"  # c\nfit = \"/abs/fit.json\"\n";
        let out = absolutise_paths(t, Path::new("/r"));
        assert_eq!(out, "index = \"builtin:PC\"\n  index = \"/r/data/x.yml\"  # c\nfit = \"/abs/fit.json\"\n");
    }
}
