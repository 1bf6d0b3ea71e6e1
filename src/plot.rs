//! Plots people look at instead of reading tables: spectra of the optical
//! properties, a polar plot of the phase function, and the per-patch ΔE of a
//! colour calibration. PNG bytes are rendered
//! in memory (plotters bitmap backend, embedded DejaVu Sans font) so the
//! caller writes them atomically.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;
use std::f64::consts::PI;
use std::sync::Once;

const FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
static FONT_ONCE: Once = Once::new();

/// A plot that could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// plotters failed while drawing; its error type depends on the backend
    /// and the drawing call, so its message is kept.
    #[error("cannot draw plot: {0}")]
    Draw(String),
    /// The PNG encoder failed.
    #[error("cannot encode plot as PNG: {0}")]
    Encode(#[from] image::ImageError),
    /// The pixel buffer does not hold `width` × `height` RGB pixels.
    #[error("cannot draw plot: {len} bytes for a {width} × {height} RGB image")]
    Buffer { len: usize, width: usize, height: usize },
    /// Inputs that do not fit together: `plot` needs `need`.
    #[error("cannot draw {plot}: it needs {need}")]
    Input { plot: &'static str, need: &'static str },
    /// NaN or ±inf among the values of `plot`.
    #[error("cannot draw {plot}: its values must be finite")]
    NonFinite { plot: &'static str },
}

pub(crate) fn perr<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Draw(e.to_string())
}

fn register_font() {
    FONT_ONCE.call_once(|| {
        // The font is compiled in; failure would be a build defect.
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .unwrap_or_else(|_| panic!("embedded DejaVuSans.ttf is a valid font"));
    });
}

/// Renders with `draw` onto a white `width` × `height` canvas and returns
/// PNG bytes.
pub(crate) fn render_png(
    width: u32,
    height: u32,
    draw: impl FnOnce(&DrawingArea<BitMapBackend, plotters::coord::Shift>) -> Result<(), PlotError>,
) -> Result<Vec<u8>, PlotError> {
    register_font();
    let mut buf = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(perr)?;
        draw(&root)?;
        root.present().map_err(perr)?;
    }
    let len = buf.len();
    let img = image::RgbImage::from_raw(width, height, buf).ok_or(PlotError::Buffer {
        len,
        width: width as usize,
        height: height as usize,
    })?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)?;
    Ok(out.into_inner())
}

/// Viridis (van der Walt & Smith, matplotlib's default map) for false-colour
/// images (slices, height maps, distributions): plotters' 8-stop table,
/// linear in between; `t` clamped to [0, 1], non-finite → 0.
pub(crate) fn viridis(t: f64) -> RGBColor {
    use plotters::style::colors::colormaps::ViridisRGB;
    ViridisRGB::get_color(if t.is_finite() { t } else { 0.0 })
}

pub(crate) fn palette(i: usize) -> RGBColor {
    const C: [RGBColor; 12] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(0, 0, 128),
        RGBColor(128, 0, 0),
    ];
    C[i % C.len()]
}

/// A tick label with up to three significant digits and no trailing zeros:
/// plain from 0.01 to below 10⁴ ("400", "0.95", "2500"), else scientific
/// ("1e4", "2.5e5", "1.5e-3"); never "400.0".
pub(crate) fn short_number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-2..1e4).contains(&a) {
        let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.2e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa =
            if mantissa.contains('.') { mantissa.trim_end_matches('0').trim_end_matches('.') } else { mantissa };
        format!("{mantissa}e{exponent}")
    }
}

/// Mantissas of the labelled ticks of a logarithmic axis, coarsest first:
/// [`log_axis`] takes the first set that labels at least
/// [`LOG_AXIS_MIN_LABELS`] values in the range.
const LOG_AXIS_MANTISSAS: [&[f64]; 4] =
    [&[1.0], &[1.0, 2.0, 5.0], &[1.0, 2.0, 3.0, 5.0], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]];
/// Fewest labelled ticks on a logarithmic axis.
pub(crate) const LOG_AXIS_MIN_LABELS: usize = 5;

/// Tick values of a logarithmic axis over [lo, hi] (0 < lo < hi):
/// `(labelled, grid)`. Every decade in the range is labelled, and as many
/// of 2, 3, 5 or all of 2 … 9 times the decade as it takes to have at least
/// [`LOG_AXIS_MIN_LABELS`] labels (a range under a decade falls back to
/// mantissa steps of 0.1); the light grid lines are at every 1 … 9 times a
/// decade, so a value between two labels can be read off. plotters' own
/// logarithmic key points label only a few decades or multiples (1e4, 2e4).
pub(crate) fn log_axis_points(lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return (Vec::new(), Vec::new());
    }
    let (d0, d1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let in_range = |v: &f64| *v >= lo * (1.0 - 1e-12) && *v <= hi * (1.0 + 1e-12);
    let points = |mantissas: &[f64]| -> Vec<f64> {
        (d0..=d1).flat_map(|d| mantissas.iter().map(move |m| m * 10f64.powi(d))).filter(in_range).collect()
    };
    let tenths: Vec<f64> = (10..100).map(|m| m as f64 / 10.0).collect();
    let labelled = LOG_AXIS_MANTISSAS
        .iter()
        .map(|m| points(m))
        .find(|p| p.len() >= LOG_AXIS_MIN_LABELS)
        .unwrap_or_else(|| points(&tenths));
    let grid = if d1 - d0 <= 8 { points(LOG_AXIS_MANTISSAS[3]) } else { points(&[1.0]) };
    (labelled, grid)
}

/// A logarithmic axis over [lo, hi] with the ticks of [`log_axis_points`].
pub(crate) fn log_axis(
    lo: f64,
    hi: f64,
) -> plotters::coord::combinators::WithKeyPoints<plotters::coord::combinators::LogCoord<f64>> {
    use plotters::coord::combinators::BindKeyPoints;
    let (labelled, grid) = log_axis_points(lo, hi);
    (lo..hi).log_scale().with_key_points(labelled).with_light_points(grid)
}

/// One sample's optical properties against wavelength, as plain slices (the
/// optics stage builds it from its `OpticalSpectrum`; this module depends on
/// no model type).
#[derive(Debug, Clone, Copy)]
pub struct SpectrumSeries<'a> {
    /// Sample name (legend, and title of a one-sample figure).
    pub name: &'a str,
    /// Name of the absorption model, said in a one-sample title.
    pub absorption_model: &'a str,
    pub wavelength_nm: &'a [f64],
    /// Scattering coefficient [1/m], one per wavelength.
    pub mu_s_per_m: &'a [f64],
    /// Absorption coefficient [1/m], one per wavelength.
    pub mu_a_per_m: &'a [f64],
    /// Asymmetry parameter, one per wavelength.
    pub g: &'a [f64],
}

/// μ_s, μ_a (both on a logarithmic axis, said in the panel titles) and g
/// against wavelength, one line per spectrum. Each panel has its legend in
/// a column to its right, outside the plotting area; a figure of one
/// sample is titled with its name.
pub fn spectra_png(spectra: &[SpectrumSeries]) -> Result<Vec<u8>, PlotError> {
    let longest = spectra.iter().map(|s| s.name.chars().count()).max().unwrap_or(0) as u32;
    let legend_width = (60 + 9 * longest).clamp(150, 320);
    render_png(1000 + legend_width, 1200, |root| {
        let title = match spectra {
            [one] => format!("{}: optical properties ({} absorption model)", one.name, one.absorption_model),
            _ => format!("optical properties of {} samples", spectra.len()),
        };
        let root = root.titled(&title, ("sans-serif", 24)).map_err(perr)?;
        let panels = root.split_evenly((3, 1));
        type Get = for<'s> fn(&SpectrumSeries<'s>) -> &'s [f64];
        let rows: [(&str, Get, bool); 3] = [
            ("scattering coefficient μs [1/m], logarithmic axis", |s| s.mu_s_per_m, true),
            ("absorption coefficient μa [1/m], logarithmic axis", |s| s.mu_a_per_m, true),
            ("asymmetry parameter g, linear axis", |s| s.g, false),
        ];
        let (wmin, wmax) = spectra
            .iter()
            .flat_map(|s| s.wavelength_nm.iter().copied())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), w| (a.min(w), b.max(w)));
        let (wmin, wmax) = if wmax > wmin { (wmin, wmax) } else { (wmin - 5.0, wmin + 5.0) };
        for (row, (label, get, log)) in panels.iter().zip(rows) {
            let (panel, legend) = row.split_horizontally(1000);
            let values: Vec<f64> =
                spectra.iter().flat_map(|s| get(s).iter().copied()).filter(|v| v.is_finite()).collect();
            let positive: Vec<f64> = values.iter().copied().filter(|v| *v > 0.0).collect();
            let mut builder = ChartBuilder::on(&panel);
            builder.margin(12).x_label_area_size(40).y_label_area_size(80).caption(label, ("sans-serif", 20));
            let x_fmt = |v: &f64| short_number(*v);
            let y_fmt = |v: &f64| short_number(*v);
            let style = |i: usize| palette(i).stroke_width(2);
            if log && !positive.is_empty() {
                let lo = positive.iter().copied().fold(f64::INFINITY, f64::min) / 1.5;
                let hi = positive.iter().copied().fold(0.0, f64::max) * 1.5;
                let mut chart = builder.build_cartesian_2d(wmin..wmax, log_axis(lo, hi)).map_err(perr)?;
                chart
                    .configure_mesh()
                    .x_desc("wavelength [nm]")
                    .x_label_formatter(&x_fmt)
                    .y_label_formatter(&y_fmt)
                    .draw()
                    .map_err(perr)?;
                for (i, s) in spectra.iter().enumerate() {
                    let pts = s.wavelength_nm.iter().zip(get(s)).filter(|(_, v)| **v > 0.0).map(|(w, v)| (*w, *v));
                    chart.draw_series(LineSeries::new(pts, style(i))).map_err(perr)?;
                }
            } else {
                let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let (lo, hi) =
                    if hi > lo { (lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)) } else { (lo - 0.01, lo + 0.01) };
                let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
                let mut chart = builder.build_cartesian_2d(wmin..wmax, lo..hi).map_err(perr)?;
                chart
                    .configure_mesh()
                    .x_desc("wavelength [nm]")
                    .x_label_formatter(&x_fmt)
                    .y_label_formatter(&y_fmt)
                    .draw()
                    .map_err(perr)?;
                for (i, s) in spectra.iter().enumerate() {
                    let pts = s.wavelength_nm.iter().zip(get(s)).map(|(w, v)| (*w, *v));
                    chart.draw_series(LineSeries::new(pts, style(i))).map_err(perr)?;
                }
            }
            draw_legend(&legend, spectra.iter().map(|s| s.name))?;
        }
        Ok(())
    })
}

/// A legend (coloured line and name, one row each, colours by
/// [`palette`]) at the top of `area`, below the height of a panel caption.
fn draw_legend<'a>(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    names: impl Iterator<Item = &'a str>,
) -> Result<(), PlotError> {
    let font = ("sans-serif", 15).into_font();
    let names: Vec<&str> = names.collect();
    let (_, height) = area.dim_in_pixel();
    let row = ((height as i32 - 50) / names.len().max(1) as i32).clamp(10, 22);
    for (i, name) in names.iter().enumerate() {
        let y = 44 + row * i as i32;
        area.draw(&PathElement::new(vec![(4, y), (30, y)], palette(i).stroke_width(3))).map_err(perr)?;
        area.draw(&Text::new(name.to_string(), (36, y - 8), font.clone())).map_err(perr)?;
    }
    Ok(())
}

/// Henyey–Greenstein phase function per steradian.
fn henyey_greenstein(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// Width of the legend column of [`phase_polar_png`], pixels.
pub const POLAR_LEGEND_W: u32 = 300;
/// Side of the square polar chart of [`phase_polar_png`], pixels.
pub const POLAR_SIDE: u32 = 900;
/// Height of the title band above the chart of [`phase_polar_png`], pixels.
pub const POLAR_TITLE_H: u32 = 40;

/// Polar plot of a tabulated phase function (values per steradian at θ
/// uniform over [0, π]) against Henyey–Greenstein with the same g; the
/// radius is log₁₀ of the phase function. The chart is a
/// [`POLAR_SIDE`]-pixel square under a title band; the legend is in a column
/// [`POLAR_LEGEND_W`] px wide to its right, off the curves.
pub fn phase_polar_png(title: &str, theta_samples: &[f64], g: f64) -> Result<Vec<u8>, PlotError> {
    let n = theta_samples.len();
    if n < 2 {
        return Err(PlotError::Input { plot: "the phase plot", need: "a phase table of at least 2 entries" });
    }
    let theta = |i: usize| PI * i as f64 / (n - 1) as f64;
    let hg: Vec<f64> = (0..n).map(|i| henyey_greenstein(g, theta(i).cos())).collect();
    let all = theta_samples.iter().chain(&hg).copied().filter(|v| *v > 0.0 && v.is_finite());
    let (pmin, pmax) = all.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if !(pmin.is_finite() && pmax > 0.0) {
        return Err(PlotError::Input { plot: "the phase plot", need: "a phase function with positive values" });
    }
    let dec_lo = pmin.log10().floor();
    let dec_hi = pmax.log10().ceil().max(dec_lo + 1.0);
    let span = dec_hi - dec_lo;
    let radius = |p: f64| ((p.max(10f64.powf(dec_lo))).log10() - dec_lo) / span;
    render_png(POLAR_SIDE + POLAR_LEGEND_W, POLAR_SIDE + POLAR_TITLE_H, |root| {
        let (top, body) = root.split_vertically(POLAR_TITLE_H);
        top.titled(title, ("sans-serif", 22)).map_err(perr)?;
        let (plot_area, legend) = body.split_horizontally(POLAR_SIDE);
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(20)
            .build_cartesian_2d(-1.15f64..1.15f64, -1.15f64..1.15f64)
            .map_err(perr)?;
        // Decade circles with labels, and angle spokes every 30°.
        for d in 0..=(span as i32) {
            let r = d as f64 / span;
            let circle = (0..=360).map(|k| {
                let a = k as f64 * PI / 180.0;
                (r * a.cos(), r * a.sin())
            });
            chart.draw_series(LineSeries::new(circle, RGBColor(200, 200, 200))).map_err(perr)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("1e{} /sr", dec_lo as i32 + d),
                    (r * 0.70, r * 0.72 + 0.01),
                    ("sans-serif", 13).into_font().color(&RGBColor(90, 90, 90)),
                )))
                .map_err(perr)?;
        }
        for k in 0..12 {
            let a = k as f64 * PI / 6.0;
            chart
                .draw_series(LineSeries::new([(0.0, 0.0), (a.cos(), a.sin())], RGBColor(220, 220, 220)))
                .map_err(perr)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("{}°", (k * 30) % 360),
                    (1.07 * a.cos() - 0.03, 1.07 * a.sin() + 0.02),
                    ("sans-serif", 14).into_font(),
                )))
                .map_err(perr)?;
        }
        let curve = |values: &[f64]| -> Vec<(f64, f64)> {
            // θ from 0 to π on the upper half, mirrored on the lower half.
            let upper = (0..n).map(|i| (theta(i), values[i]));
            let lower = (0..n).rev().map(|i| (-theta(i), values[i]));
            upper.chain(lower).map(|(t, p)| (radius(p) * t.cos(), radius(p) * t.sin())).collect()
        };
        let (blue, red) = (palette(0), palette(3));
        chart.draw_series(LineSeries::new(curve(theta_samples), blue.stroke_width(2))).map_err(perr)?;
        chart.draw_series(LineSeries::new(curve(&hg), red.stroke_width(2))).map_err(perr)?;
        let items = [
            ("Lorenz–Mie".to_string(), Mark::Line(blue, 2)),
            ("Henyey–Greenstein,".to_string(), Mark::Line(red, 2)),
            (format!("g = {g:.4}"), Mark::None),
            (String::new(), Mark::None),
            ("radius: log₁₀ p [1/sr],".to_string(), Mark::None),
            ("one grey circle per decade;".to_string(), Mark::None),
            ("angle: scattering angle θ".to_string(), Mark::None),
            ("(mirrored below the axis)".to_string(), Mark::None),
        ];
        legend_column(&legend, 60, &items)?;
        Ok(())
    })
}

/// Per-patch colour differences of a colour calibration: one bar per patch
/// for ΔE00 (filled with the patch's reference colour, 8-bit sRGB), a black
/// tick for ΔE*ab, and the mean ΔE00 as a dashed line; the legend in a
/// column to the right, off the bars.
pub fn delta_e_bars_png(
    title: &str,
    labels: &[String],
    de2000: &[f64],
    de76: &[f64],
    colours: &[[u8; 3]],
) -> Result<Vec<u8>, PlotError> {
    let n = labels.len();
    if n == 0 || de2000.len() != n || de76.len() != n || colours.len() != n {
        return Err(PlotError::Input { plot: "the ΔE plot", need: "one label, ΔE00, ΔE76 and colour per patch" });
    }
    if de2000.iter().chain(de76).any(|v| !v.is_finite()) {
        return Err(PlotError::NonFinite { plot: "the ΔE plot" });
    }
    let top = de2000.iter().chain(de76).copied().fold(1.0f64, f64::max) * 1.12;
    let mean = de2000.iter().sum::<f64>() / n as f64;
    render_png(1200 + 290, 620, |root| {
        let (root, legend) = root.split_horizontally(1200);
        let root = &root;
        let red = RGBColor(214, 39, 40);
        let items = [
            ("ΔE00 (CIEDE2000): bar in".to_string(), Mark::Box(RGBColor(150, 150, 150))),
            ("the patch's reference colour".to_string(), Mark::None),
            ("ΔE*ab (CIE 1976)".to_string(), Mark::Line(BLACK, 3)),
            (format!("mean ΔE00 = {mean:.2}"), Mark::Line(red, 2)),
        ];
        legend_column(&legend, 70, &items)?;
        let mut chart = ChartBuilder::on(root)
            .margin(16)
            .x_label_area_size(150)
            .y_label_area_size(60)
            .caption(title, ("sans-serif", 22))
            .build_cartesian_2d(0f64..n as f64, 0f64..top)
            .map_err(perr)?;
        chart.configure_mesh().disable_x_mesh().x_labels(0).y_desc("colour difference").draw().map_err(perr)?;
        // Patch labels below the bars, rotated, placed in pixels.
        let font = ("sans-serif", 13).into_font().transform(FontTransform::Rotate90);
        for (i, label) in labels.iter().enumerate() {
            let (px, py) = chart.backend_coord(&(i as f64 + 0.5, 0.0));
            root.draw(&Text::new(label.clone(), (px + 7, py + 8), font.clone())).map_err(perr)?;
        }
        chart
            .draw_series((0..n).map(|i| {
                let [r, g, b] = colours[i];
                Rectangle::new([(i as f64 + 0.15, 0.0), (i as f64 + 0.85, de2000[i])], RGBColor(r, g, b).filled())
            }))
            .map_err(perr)?;
        chart
            .draw_series((0..n).map(|i| Rectangle::new([(i as f64 + 0.15, 0.0), (i as f64 + 0.85, de2000[i])], BLACK)))
            .map_err(perr)?;
        chart
            .draw_series((0..n).map(|i| {
                PathElement::new(vec![(i as f64 + 0.05, de76[i]), (i as f64 + 0.95, de76[i])], BLACK.stroke_width(3))
            }))
            .map_err(perr)?;
        let dashes = (0..(2 * n)).step_by(2).map(|k| {
            PathElement::new(
                vec![(k as f64 * 0.5, mean), (k as f64 * 0.5 + 0.5, mean)],
                RGBColor(214, 39, 40).stroke_width(2),
            )
        });
        chart.draw_series(dashes).map_err(perr)?;
        Ok(())
    })
}

/// `n` colours no two of which are alike: [`palette`] up to its 12
/// entries; up to 20, Tableau 20 (its ten strong colours, then the ten
/// light ones); beyond, `⌈n/2⌉` hues evenly spaced around the HSL circle, each
/// at a dark (L = 0.32) and a light (L = 0.58) shade.
pub(crate) fn distinct_colours(n: usize) -> Vec<RGBColor> {
    if n <= 12 {
        return (0..n).map(palette).collect();
    }
    if n <= 20 {
        // Tableau 20: the ten strong colours, then their ten light partners.
        const LIGHT: [RGBColor; 10] = [
            RGBColor(174, 199, 232),
            RGBColor(255, 187, 120),
            RGBColor(152, 223, 138),
            RGBColor(255, 152, 150),
            RGBColor(197, 176, 213),
            RGBColor(196, 156, 148),
            RGBColor(247, 182, 210),
            RGBColor(199, 199, 199),
            RGBColor(219, 219, 141),
            RGBColor(158, 218, 229),
        ];
        return (0..n).map(|i| if i < 10 { palette(i) } else { LIGHT[i - 10] }).collect();
    }
    let hues = n.div_ceil(2);
    (0..n)
        .map(|i| {
            let (h, l) = (i / 2, if i % 2 == 0 { 0.32 } else { 0.58 });
            // Offset the light shades by half a step so neighbours differ in hue too.
            let hue = (h as f64 + 0.5 * (i % 2) as f64) / hues as f64;
            let c = HSLColor(hue, 0.85, l).to_rgba();
            RGBColor(c.0, c.1, c.2)
        })
        .collect()
}

/// Width of the view legend column of [`residuals_png`], pixels.
const RESIDUAL_LEGEND_W: u32 = 280;

/// Reprojection residuals of a camera calibration: left, every corner's
/// residual (detected − reprojected, pixels) as a dot coloured by view with
/// the overall RMS as a circle (named in the title and the legend); middle,
/// the legend (one row per view: its colour, name and RMS); right, the RMS
/// of each view as a bar.
/// Each view has its own colour (`distinct_colours`).
pub fn residuals_png(views: &[(String, Vec<[f64; 2]>)], rms_px: f64) -> Result<Vec<u8>, PlotError> {
    if views.is_empty() || views.iter().any(|(_, r)| r.is_empty()) {
        return Err(PlotError::Input { plot: "the residual plot", need: "at least one view with residuals" });
    }
    if !rms_px.is_finite() || views.iter().flat_map(|(_, r)| r).any(|p| !(p[0].is_finite() && p[1].is_finite())) {
        return Err(PlotError::NonFinite { plot: "the residual plot" });
    }
    let reach = views.iter().flat_map(|(_, r)| r).map(|p| p[0].abs().max(p[1].abs())).fold(rms_px, f64::max) * 1.1;
    let per_view: Vec<f64> = views
        .iter()
        .map(|(_, r)| (r.iter().map(|p| p[0] * p[0] + p[1] * p[1]).sum::<f64>() / r.len() as f64).sqrt())
        .collect();
    let top = per_view.iter().copied().fold(rms_px, f64::max) * 1.15;
    let colours = distinct_colours(views.len());
    render_png(700 + RESIDUAL_LEGEND_W + 700, 700, |root| {
        let (left, rest) = root.split_horizontally(700);
        let (legend, right) = rest.split_horizontally(RESIDUAL_LEGEND_W);
        let mut chart = ChartBuilder::on(&left)
            .margin(16)
            .x_label_area_size(45)
            .y_label_area_size(65)
            .caption(format!("reprojection residuals; black circle: RMS {rms_px:.3} px"), ("sans-serif", 21))
            .build_cartesian_2d(-reach..reach, -reach..reach)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_desc("Δu [px] (detected − reprojected)")
            .y_desc("Δv [px]")
            .x_label_formatter(&|v| format!("{v:.2}"))
            .y_label_formatter(&|v| format!("{v:.2}"))
            .draw()
            .map_err(perr)?;
        for ((_, r), colour) in views.iter().zip(&colours) {
            chart.draw_series(r.iter().map(|p| Circle::new((p[0], p[1]), 3, colour.filled()))).map_err(perr)?;
        }
        let ring = (0..=96).map(|k| {
            let a = 2.0 * PI * k as f64 / 96.0;
            (rms_px * a.cos(), rms_px * a.sin())
        });
        chart.draw_series(LineSeries::new(ring, BLACK.stroke_width(2))).map_err(perr)?;
        // Legend: one row per view, in columns when they do not fit.
        let (lw, lh) = legend.dim_in_pixel();
        legend.draw(&Text::new("views (RMS per view, px)", (8, 20), ("sans-serif", 17).into_font())).map_err(perr)?;
        let ring = format!("all views: RMS {rms_px:.3} px");
        legend.draw(&Circle::new((14, lh as i32 - 40), 6, BLACK.stroke_width(2))).map_err(perr)?;
        legend.draw(&Text::new(ring, (26, lh as i32 - 48), ("sans-serif", 15).into_font())).map_err(perr)?;
        let (first, bottom) = (52, lh as i32 - 60);
        let n = views.len() as i32;
        let row = ((bottom - first) / n).clamp(14, 24);
        let per_col = ((bottom - first) / row).max(1);
        let cols = (n + per_col - 1) / per_col;
        let col_w = lw as i32 / cols;
        let size = (row - 6).clamp(11, 15);
        for (i, ((name, _), colour)) in views.iter().zip(&colours).enumerate() {
            let (c, r) = (i as i32 / per_col, i as i32 % per_col);
            let (x, y) = (8 + c * col_w, first + r * row);
            legend.draw(&Circle::new((x + 6, y), 5, colour.filled())).map_err(perr)?;
            let text = format!("{name}  {:.3}", per_view[i]);
            legend
                .draw(&Text::new(text, (x + 16, y - size / 2 - 1), ("sans-serif", size).into_font()))
                .map_err(perr)?;
        }

        let n = views.len();
        let mut bars = ChartBuilder::on(&right)
            .margin(16)
            .x_label_area_size(120)
            .y_label_area_size(65)
            .caption("RMS per view [px]", ("sans-serif", 22))
            .build_cartesian_2d(0f64..n as f64, 0f64..top)
            .map_err(perr)?;
        bars.configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_label_formatter(&|v| format!("{v:.2}"))
            .draw()
            .map_err(perr)?;
        bars.draw_series(
            (0..n)
                .map(|i| Rectangle::new([(i as f64 + 0.15, 0.0), (i as f64 + 0.85, per_view[i])], colours[i].filled())),
        )
        .map_err(perr)?;
        bars.draw_series(std::iter::once(PathElement::new(
            vec![(0.0, rms_px), (n as f64, rms_px)],
            BLACK.stroke_width(2),
        )))
        .map_err(perr)?;
        let (_, by) = bars.backend_coord(&(0.0, rms_px));
        let (bx, _) = bars.backend_coord(&(n as f64, rms_px));
        let all = TextStyle::from(("sans-serif", 14).into_font()).pos(Pos::new(HPos::Right, VPos::Bottom));
        root.draw(&Text::new(format!("all views {rms_px:.3}"), (bx - 4, by - 3), all)).map_err(perr)?;
        let font = ("sans-serif", 13).into_font().transform(FontTransform::Rotate90);
        for (i, (name, _)) in views.iter().enumerate() {
            let (px, py) = bars.backend_coord(&(i as f64 + 0.5, 0.0));
            root.draw(&Text::new(name.clone(), (px + 7, py + 8), font.clone())).map_err(perr)?;
        }
        Ok(())
    })
}

/// How a legend row shows its series.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Mark {
    /// A line of this colour and width.
    Line(RGBColor, u32),
    /// A filled box.
    Box(RGBColor),
    /// A filled dot.
    Dot(RGBColor),
    /// An open circle.
    Ring(RGBColor),
    /// No mark (a continued label).
    None,
}

/// A legend in its own area beside a chart (so it never covers data): one
/// row per item, a mark and its label, from `top` pixels down.
pub(crate) fn legend_column(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    top: i32,
    items: &[(String, Mark)],
) -> Result<(), PlotError> {
    let font = ("sans-serif", 15).into_font();
    for (i, (label, mark)) in items.iter().enumerate() {
        let y = top + 24 * i as i32;
        match *mark {
            Mark::Line(c, w) => area.draw(&PathElement::new(vec![(6, y), (32, y)], c.stroke_width(w))),
            Mark::Box(c) => area.draw(&Rectangle::new([(8, y - 6), (30, y + 6)], c.filled())),
            Mark::Dot(c) => area.draw(&Circle::new((19, y), 4, c.filled())),
            Mark::Ring(c) => area.draw(&Circle::new((19, y), 4, c.stroke_width(1))),
            Mark::None => Ok(()),
        }
        .map_err(perr)?;
        area.draw(&Text::new(label.clone(), (40, y - 8), font.clone())).map_err(perr)?;
    }
    Ok(())
}

/// Layout of [`chart_halves_png`], pixels: patch side, gap between
/// patches, header height and the label band under each patch row.
pub(crate) const CHART_SIDE: i32 = 120;
pub(crate) const CHART_GAP: i32 = 16;
pub(crate) const CHART_HEADER: i32 = 64;
pub(crate) const CHART_LABELS: i32 = 38;

/// The top-left corner of patch `k` (0-based, 6 per row) in [`chart_halves_png`].
pub(crate) fn chart_patch_origin(k: usize) -> (i32, i32) {
    let (row, col) = ((k / 6) as i32, (k % 6) as i32);
    (CHART_GAP + col * (CHART_SIDE + CHART_GAP), CHART_HEADER + row * (CHART_SIDE + CHART_LABELS))
}

/// A colour chart (6 patches per row), each patch split in two: the left
/// half `photo[k]`, the right half `reference[k]` (8-bit sRGB each), with
/// "photo" and "reference" written under the halves, the patch's label
/// under that and a header saying what the halves are.
pub fn chart_halves_png(
    title: &str,
    labels: &[String],
    photo: &[[u8; 3]],
    reference: &[[u8; 3]],
) -> Result<Vec<u8>, PlotError> {
    let n = labels.len();
    if n == 0 || photo.len() != n || reference.len() != n {
        return Err(PlotError::Input {
            plot: "the chart plot",
            need: "one label, photo and reference colour per patch",
        });
    }
    let rows = n.div_ceil(6) as i32;
    let width = 6 * CHART_SIDE + 7 * CHART_GAP;
    let height = CHART_HEADER + rows * (CHART_SIDE + CHART_LABELS) + CHART_GAP;
    render_png(width as u32, height as u32, |root| {
        let text = |t: &str, x: i32, y: i32, size: i32, h: HPos| {
            let st = TextStyle::from(("sans-serif", size).into_font()).color(&BLACK).pos(Pos::new(h, VPos::Top));
            root.draw(&Text::new(t.to_string(), (x, y), st)).map_err(perr)
        };
        text(title, CHART_GAP, 8, 18, HPos::Left)?;
        text("each patch: left half = photo (corrected), right half = reference", CHART_GAP, 34, 16, HPos::Left)?;
        let half = CHART_SIDE / 2;
        for (k, label) in labels.iter().enumerate() {
            let (x0, y0) = chart_patch_origin(k);
            for (dx, [r, g, b]) in [(0, photo[k]), (half, reference[k])] {
                let rect = [(x0 + dx, y0), (x0 + dx + half, y0 + CHART_SIDE)];
                root.draw(&Rectangle::new(rect, RGBColor(r, g, b).filled())).map_err(perr)?;
            }
            root.draw(&Rectangle::new([(x0, y0), (x0 + CHART_SIDE, y0 + CHART_SIDE)], RGBColor(90, 90, 90)))
                .map_err(perr)?;
            root.draw(&PathElement::new(vec![(x0 + half, y0), (x0 + half, y0 + CHART_SIDE)], RGBColor(90, 90, 90)))
                .map_err(perr)?;
            text("photo", x0 + half / 2, y0 + CHART_SIDE + 2, 12, HPos::Center)?;
            text("reference", x0 + half + half / 2, y0 + CHART_SIDE + 2, 12, HPos::Center)?;
            text(label, x0 + half, y0 + CHART_SIDE + 17, 13, HPos::Center)?;
        }
        Ok(())
    })
}

/// Magnification of [`patch_overlay_png`] for an image `width` pixels wide:
/// `(up, down)` with the image enlarged `up` times (pixels repeated) to at
/// least 900 px, or reduced `down` times (every `down`-th pixel) to at most
/// 1800 px.
pub(crate) fn overlay_scale(width: usize) -> (usize, usize) {
    if width < 900 {
        (900usize.div_ceil(width.max(1)), 1)
    } else {
        (1, width.div_ceil(1800))
    }
}

/// The photo of a chart (8-bit sRGB, `width × height`, interleaved R, G, B)
/// at a legible size (`overlay_scale`), each sampled square outlined in
/// magenta (corners in image pixels) and numbered 1, 2, … at its centre.
pub fn patch_overlay_png(
    width: usize,
    height: usize,
    srgb8: &[u8],
    outlines: &[[[f64; 2]; 4]],
) -> Result<Vec<u8>, PlotError> {
    if width == 0 || height == 0 || srgb8.len() != width * height * 3 {
        return Err(PlotError::Buffer { len: srgb8.len(), width, height });
    }
    let (up, down) = overlay_scale(width);
    let (ow, oh) = (width * up / down, height * up / down);
    let to_out = |p: [f64; 2]| ((p[0] * up as f64 / down as f64) as i32, (p[1] * up as f64 / down as f64) as i32);
    render_png(ow as u32, oh as u32, |root| {
        for y in 0..oh {
            for x in 0..ow {
                let (sx, sy) = ((x * down / up).min(width - 1), (y * down / up).min(height - 1));
                let i = 3 * (sy * width + sx);
                root.draw_pixel((x as i32, y as i32), &RGBColor(srgb8[i], srgb8[i + 1], srgb8[i + 2])).map_err(perr)?;
            }
        }
        let magenta = RGBColor(255, 0, 255);
        let size = ((oh as f64 / 40.0) as i32).clamp(12, 28);
        for (k, o) in outlines.iter().enumerate() {
            let mut pts: Vec<(i32, i32)> = o.iter().map(|p| to_out(*p)).collect();
            pts.push(pts[0]);
            root.draw(&PathElement::new(pts, magenta.stroke_width(2))).map_err(perr)?;
            let c = to_out([o.iter().map(|p| p[0]).sum::<f64>() / 4.0, o.iter().map(|p| p[1]).sum::<f64>() / 4.0]);
            let label = format!("{}", k + 1);
            let st = TextStyle::from(("sans-serif", size).into_font()).pos(Pos::new(HPos::Center, VPos::Center));
            // Black text on a white disc reads on every patch colour.
            root.draw(&Circle::new(c, size * 3 / 4, WHITE.mix(0.8).filled())).map_err(perr)?;
            root.draw(&Text::new(label, c, st.color(&BLACK))).map_err(perr)?;
        }
        Ok(())
    })
}

/// One twin's check against the photo for [`band_check_png`]: its name and,
/// per band R, G, B, the photo's offset from the twin's mean and the
/// predictive and recipe-only half widths (k·u), all relative to the twin's mean.
pub struct BandBars {
    pub twin: String,
    pub photo_offset: [f64; 3],
    pub predictive_half_width: [f64; 3],
    pub inputs_half_width: [f64; 3],
    pub within: bool,
}

/// The photo against each twin's predictive band, per band R, G, B, in %
/// of the twin's mean: the twin at 0, its band ±k·u (light: everything;
/// dark: the recipe's inputs alone) and the photo as a black dot.
pub fn band_check_png(twins: &[BandBars], k: f64) -> Result<Vec<u8>, PlotError> {
    if twins.is_empty() {
        return Err(PlotError::Input { plot: "the band check", need: "at least one twin" });
    }
    let all =
        twins.iter().flat_map(|t| t.photo_offset.iter().chain(&t.predictive_half_width).chain(&t.inputs_half_width));
    if all.clone().any(|v| !v.is_finite()) {
        return Err(PlotError::NonFinite { plot: "the band check" });
    }
    let reach = 100.0 * all.map(|v| v.abs()).fold(0.0, f64::max) * 1.35;
    let reach = if reach > 0.0 { reach } else { 1.0 };
    let n = twins.len();
    let channel = [RGBColor(200, 60, 60), RGBColor(60, 150, 60), RGBColor(60, 90, 200)];
    let light = [RGBColor(245, 205, 205), RGBColor(205, 235, 205), RGBColor(205, 215, 245)];
    render_png(260 + 300 * n as u32, 480, |root| {
        let mut chart = ChartBuilder::on(root)
            .margin(16)
            .x_label_area_size(60)
            .y_label_area_size(70)
            .caption(format!("photo (dot) against each twin's predictive band (k = {k})"), ("sans-serif", 20))
            .build_cartesian_2d(0f64..(4 * n) as f64, -reach..reach)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .max_light_lines(1)
            .y_desc("photo − twin [% of the twin's mean]")
            .y_label_formatter(&|v| format!("{v:+.1}"))
            .draw()
            .map_err(perr)?;
        let key = "light: the predictive band (recipe's inputs, Monte Carlo, photo noise); dark: the inputs alone";
        let at = chart.backend_coord(&(0.0, reach));
        root.draw(&Text::new(key, (at.0 + 8, at.1 + 6), ("sans-serif", 13).into_font())).map_err(perr)?;
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(0.0, 0.0), ((4 * n) as f64, 0.0)],
                BLACK.stroke_width(1),
            )))
            .map_err(perr)?;
        for (i, t) in twins.iter().enumerate() {
            for c in 0..3 {
                let x = (4 * i + c) as f64 + 0.5;
                let (p, u) = (100.0 * t.predictive_half_width[c], 100.0 * t.inputs_half_width[c]);
                chart
                    .draw_series(std::iter::once(Rectangle::new([(x, -p), (x + 0.8, p)], light[c].filled())))
                    .map_err(perr)?;
                chart
                    .draw_series(std::iter::once(Rectangle::new([(x + 0.25, -u), (x + 0.55, u)], channel[c].filled())))
                    .map_err(perr)?;
                chart
                    .draw_series(std::iter::once(Circle::new((x + 0.4, 100.0 * t.photo_offset[c]), 6, BLACK.filled())))
                    .map_err(perr)?;
            }
            for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
                let at = chart.backend_coord(&((4 * i + c) as f64 + 0.9, -reach));
                root.draw(&Text::new(name, (at.0 - 5, at.1 + 8), ("sans-serif", 15).into_font())).map_err(perr)?;
            }
            let label = format!("{}: {}", t.twin, if t.within { "within" } else { "outside" });
            let at = chart.backend_coord(&((4 * i) as f64 + 0.5, -reach));
            root.draw(&Text::new(label, (at.0, at.1 + 30), ("sans-serif", 17).into_font())).map_err(perr)?;
        }
        Ok(())
    })
}

/// A horizontal colour bar over `range` with `labels` ticks and the axis
/// `label`, each value drawn in `colour(value)` (the bars of the slice
/// heat maps and of the render's band map).
pub(crate) fn colour_bar(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    (lo, hi): (f64, f64),
    label: &str,
    labels: usize,
    colour: &dyn Fn(f64) -> RGBColor,
) -> Result<(), PlotError> {
    let mut chart = ChartBuilder::on(area)
        .margin_left(55)
        .margin_right(20)
        .x_label_area_size(45)
        .build_cartesian_2d(lo..hi, 0.0..1.0)
        .map_err(perr)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_y_axis()
        .x_desc(label)
        .x_labels(labels)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(perr)?;
    let steps = 200;
    chart
        .draw_series((0..steps).map(|k| {
            let a = lo + (hi - lo) * k as f64 / steps as f64;
            let b = lo + (hi - lo) * (k + 1) as f64 / steps as f64;
            Rectangle::new([(a, 0.0), (b, 1.0)], colour(0.5 * (a + b)).filled())
        }))
        .map_err(perr)?;
    Ok(())
}

/// The grey of a pixel with nothing to show (NaN: outside a mask or the object).
pub const MASKED: RGBColor = RGBColor(150, 150, 150);

/// The colour of a pixel whose value is below its own noise ([`relative_band_png`]).
pub const UNRESOLVED: RGBColor = RGBColor(215, 215, 215);

/// A per-pixel map of a render's relative band (the recipe's inputs' 1 σ
/// over the pixel's value, in %): `relative` row-major over `width` ×
/// `height`, NaN where there is nothing to show (outside the object), drawn
/// in viridis from 0 to the 99th percentile of the finite values, with
/// NaN in [`MASKED`] grey, pixels whose band is not
/// `resolved` (below its own noise) in [`UNRESOLVED`] and a colour bar
/// under the image.
pub fn relative_band_png(
    width: usize,
    height: usize,
    relative: &[f64],
    resolved: &[bool],
    title: &str,
) -> Result<Vec<u8>, PlotError> {
    if width == 0 || height == 0 || relative.len() != width * height || resolved.len() != relative.len() {
        return Err(PlotError::Input { plot: "the relative band", need: "one value per pixel" });
    }
    let mut finite: Vec<f64> =
        relative.iter().zip(resolved).filter(|(v, r)| v.is_finite() && **r).map(|(v, _)| *v).collect();
    if relative.iter().any(|v| *v < 0.0) {
        return Err(PlotError::Input { plot: "the relative band", need: "values ≥ 0" });
    }
    finite.sort_by(f64::total_cmp);
    let top = finite.get(((finite.len() as f64 - 1.0) * 0.99).round().max(0.0) as usize).copied().unwrap_or(0.0);
    let top = if top > 0.0 { top } else { 1.0 };
    // Each image pixel drawn as a square of `scale` screen pixels, at least 480 wide.
    let scale = 480usize.div_ceil(width).max(1);
    let (w, h) = ((width * scale) as u32, (height * scale) as u32);
    let lines: Vec<&str> = title.lines().collect();
    let head = 14 + 22 * lines.len() as u32;
    render_png(w + 40, h + head + 90, |root| {
        let (top_area, bar) = root.split_vertically(h + head + 10);
        for (k, line) in lines.iter().enumerate() {
            top_area
                .draw(&Text::new(line.to_string(), (20, 8 + 22 * k as i32), ("sans-serif", 16).into_font()))
                .map_err(perr)?;
        }
        let origin = (20i32, head as i32);
        for (i, v) in relative.iter().enumerate() {
            let (x, y) = ((i % width * scale) as i32 + origin.0, (i / width * scale) as i32 + origin.1);
            let colour = match (v.is_finite(), resolved[i]) {
                (false, _) => MASKED,
                (true, false) => UNRESOLVED,
                (true, true) => viridis((v / top).min(1.0)),
            };
            top_area
                .draw(&Rectangle::new([(x, y), (x + scale as i32, y + scale as i32)], colour.filled()))
                .map_err(perr)?;
        }
        let colour = |v: f64| viridis(v / (100.0 * top));
        colour_bar(
            &bar,
            (0.0, 100.0 * top),
            "the recipe's inputs, 1 σ, in % of the pixel's value (grey: not the object)",
            7,
            &colour,
        )?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_band_map_is_a_png_and_checks_its_input() {
        let v: Vec<f64> = (0..12).map(|i| if i % 5 == 0 { f64::NAN } else { 0.001 * i as f64 }).collect();
        let mut resolved = vec![true; 12];
        resolved[1] = false;
        let png = relative_band_png(4, 3, &v, &resolved, "band").unwrap();
        let img = image::load_from_memory(&png).unwrap().to_rgb8();
        // 480 px wide at 120 screen pixels per image pixel; pixel (0, 0) is NaN: grey.
        assert_eq!(img.width(), 4 * 120 + 40);
        let grey = img.get_pixel(20 + 60, 36 + 60);
        assert_eq!(grey.0, [MASKED.0, MASKED.1, MASKED.2]);
        // The largest value is at the top of the scale: viridis(1).
        let last = img.get_pixel(20 + 3 * 120 + 60, 36 + 2 * 120 + 60);
        let top = viridis(1.0);
        assert_eq!(last.0, [top.0, top.1, top.2]);
        let unresolved = img.get_pixel(20 + 120 + 60, 36 + 60);
        assert_eq!(unresolved.0, [UNRESOLVED.0, UNRESOLVED.1, UNRESOLVED.2]);
        assert!(relative_band_png(4, 3, &v[..11], &resolved[..11], "band").is_err());
        assert!(relative_band_png(4, 3, &[-1.0; 12], &resolved, "band").is_err());
    }

    #[test]
    fn residuals_plot_is_a_png_and_checks_its_input() {
        let views =
            vec![("a.jpg".to_string(), vec![[0.1, -0.2], [0.0, 0.05]]), ("b.jpg".to_string(), vec![[-0.3, 0.1]])];
        let png = residuals_png(&views, 0.2).unwrap();
        let img = image::load_from_memory(&png).unwrap();
        assert_eq!((img.width(), img.height()), (1680, 700));
        assert!(residuals_png(&[], 0.1).is_err());
        assert!(residuals_png(&[("x".into(), vec![[f64::NAN, 0.0]])], 0.1).is_err());
    }

    /// The legend column holds a dot of every view's colour, and no two views share one.
    #[test]
    fn residual_legend_lists_every_view_in_its_own_colour() {
        let n = 15;
        let views: Vec<(String, Vec<[f64; 2]>)> =
            (0..n).map(|i| (format!("view{i:02}.jpg"), vec![[0.01 * i as f64, -0.02], [0.0, 0.03]])).collect();
        let img = image::load_from_memory(&residuals_png(&views, 0.05).unwrap()).unwrap().to_rgb8();
        let colours = distinct_colours(n);
        for (i, c) in colours.iter().enumerate() {
            let count = (700..700 + RESIDUAL_LEGEND_W)
                .flat_map(|x| (0..700).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0 == [c.0, c.1, c.2])
                .count();
            assert!(count >= 40, "view {i}: {count} pixels of its colour in the legend");
        }
    }

    #[test]
    fn distinct_colours_do_not_repeat() {
        for n in [1, 12, 13, 20, 21, 40, 60] {
            let c = distinct_colours(n);
            assert_eq!(c.len(), n);
            for i in 0..n {
                for j in 0..i {
                    let d =
                        [c[i].0 as f64 - c[j].0 as f64, c[i].1 as f64 - c[j].1 as f64, c[i].2 as f64 - c[j].2 as f64];
                    let d = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    assert!(d > 24.0, "n = {n}: colours {j} and {i} are {d:.1} apart");
                }
            }
        }
    }

    /// Left half of each patch is the photo's colour, right half the reference's, and the header has text.
    #[test]
    fn chart_halves_are_photo_left_and_reference_right() {
        let labels: Vec<String> = (1..=24).map(|k| format!("{k} patch")).collect();
        let photo: Vec<[u8; 3]> = (0..24).map(|k| [10 * k as u8, 50, 200]).collect();
        let reference: Vec<[u8; 3]> = (0..24).map(|k| [200, 10 * k as u8, 30]).collect();
        let img = image::load_from_memory(&chart_halves_png("t", &labels, &photo, &reference).unwrap()).unwrap();
        let img = img.to_rgb8();
        for k in [0usize, 5, 6, 23] {
            let (x0, y0) = chart_patch_origin(k);
            let (l, r) = ((x0 + CHART_SIDE / 4) as u32, (x0 + 3 * CHART_SIDE / 4) as u32);
            let y = (y0 + CHART_SIDE / 2) as u32;
            assert_eq!(img.get_pixel(l, y).0, photo[k], "patch {k} left half");
            assert_eq!(img.get_pixel(r, y).0, reference[k], "patch {k} right half");
        }
        let dark = |y0: u32, y1: u32| {
            (0..img.width())
                .flat_map(|x| (y0..y1).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 100)
                .count()
        };
        assert!(dark(30, 60) > 200, "the header says which half is which");
        let (_, y0) = chart_patch_origin(0);
        assert!(
            dark((y0 + CHART_SIDE) as u32 + 1, (y0 + CHART_SIDE + 16) as u32) > 200,
            "photo/reference under the halves"
        );
        assert!(chart_halves_png("t", &labels, &photo[..3], &reference).is_err());
    }

    /// A 200-pixel-wide chart photo is drawn at least 900 px wide, the pixels kept, the squares outlined.
    #[test]
    fn patch_overlay_is_legible() {
        let (w, h) = (200usize, 140usize);
        let data: Vec<u8> = (0..w * h).flat_map(|i| [(i % 251) as u8, 40, 90]).collect();
        let outlines = [[[10.0, 10.0], [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]]];
        let img = image::load_from_memory(&patch_overlay_png(w, h, &data, &outlines).unwrap()).unwrap().to_rgb8();
        let (up, down) = overlay_scale(w);
        assert_eq!((up, down), (5, 1));
        assert_eq!((img.width(), img.height()), (1000, 700));
        // Source pixel (150, 100) fills a 5 × 5 block.
        let want = [((100 * w + 150) % 251) as u8, 40, 90];
        assert_eq!(img.get_pixel(150 * 5 + 2, 100 * 5 + 2).0, want);
        let magenta = img.pixels().filter(|p| p.0 == [255, 0, 255]).count();
        assert!(magenta > 4 * 100, "outline: {magenta} magenta pixels");
        assert_eq!(overlay_scale(4000), (1, 3));
        assert!(patch_overlay_png(w, h, &data[..10], &outlines).is_err());
    }

    #[test]
    fn log_axes_label_decades_and_enough_values_between() {
        // μa between 2 and 6 /m, as the spectra plot pads it (÷ 1.5, × 1.5): every integer labelled.
        let (labels, grid) = log_axis_points(2.0 / 1.5, 6.0 * 1.5);
        assert_eq!(labels, [2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        assert_eq!(grid, labels);
        // Three and a half decades: every decade, and 2 and 5 times it.
        let (labels, grid) = log_axis_points(0.5, 2000.0);
        assert_eq!(labels, [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0]);
        assert!(grid.contains(&3.0) && grid.contains(&400.0) && grid.len() == 5 + 9 * 3 + 2, "{grid:?}");
        // Within one decade (1e4 … 2e4 as a narrow μs range was labelled before): tenths of the decade.
        let (labels, _) = log_axis_points(1.2e4, 1.9e4);
        assert!(
            labels.len() >= LOG_AXIS_MIN_LABELS && labels.iter().all(|v| (1.19e4..=1.91e4).contains(v)),
            "{labels:?}"
        );
        // Nine decades: the decades alone, each labelled.
        let (labels, _) = log_axis_points(1.0, 1e9);
        assert_eq!(labels.len(), 10);
        assert_eq!(log_axis_points(0.0, 1.0), (vec![], vec![]));
    }

    #[test]
    fn tick_labels_are_short() {
        let cases = [
            (400.0, "400"),
            (450.0, "450"),
            (2500.0, "2500"),
            (0.95, "0.95"),
            (0.9512, "0.951"),
            (1.0, "1"),
            (30000.0, "3e4"),
            (10000.0, "1e4"),
            (9990.0, "9990"),
            (2e5, "2e5"),
            (1.5e-3, "1.5e-3"),
            (2000.0000000000002, "2000"),
            (-0.25, "-0.25"),
        ];
        for (v, want) in cases {
            assert_eq!(short_number(v), want, "{v}");
        }
    }

    #[test]
    fn polar_plot_is_a_png() {
        let g = 0.8;
        let table: Vec<f64> = (0..512).map(|i| henyey_greenstein(0.9, (PI * i as f64 / 511.0).cos())).collect();
        let png = phase_polar_png("test", &table, g).unwrap();
        let img = image::load_from_memory(&png).unwrap();
        assert_eq!((img.width(), img.height()), (POLAR_SIDE + POLAR_LEGEND_W, POLAR_SIDE + POLAR_TITLE_H));
        assert!(phase_polar_png("x", &[1.0], g).is_err());
    }

    #[test]
    fn delta_e_bars_is_a_png_and_checks_its_input() {
        let labels: Vec<String> = (1..=3).map(|i| format!("{i} patch")).collect();
        let png = delta_e_bars_png("t", &labels, &[1.0, 2.0, 0.5], &[1.5, 3.0, 0.7], &[[200, 10, 10]; 3]).unwrap();
        assert_eq!(image::load_from_memory(&png).unwrap().width(), 1490);
        assert!(delta_e_bars_png("t", &labels, &[1.0], &[1.0], &[[0; 3]]).is_err());
        assert!(delta_e_bars_png("t", &labels, &[f64::NAN, 1.0, 1.0], &[1.0; 3], &[[0; 3]; 3]).is_err());
    }
}
