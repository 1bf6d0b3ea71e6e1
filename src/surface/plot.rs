//! Pictures of a surface fit: `heightmap.png` (the levelled height map in
//! false colour with a colour bar in µm and axes in µm) and
//! `distribution.png` (measured D(θ) with both fits on a logarithmic axis,
//! and the 2-D (θ, φ) histogram). PNG bytes are rendered in memory
//! (see [`crate::plot`]) so the caller writes them atomically.

use super::fit::d_tilted_phi_average;
use super::map::HeightMap;
use super::report::FitReport;
use crate::plot::{legend_column, perr, render_png, short_number, viridis, Mark, PlotError};
use crate::surface::model::RoughnessModel;
use plotters::element::BitMapElement;
use plotters::prelude::*;
use std::f64::consts::PI;

const INVALID: RGBColor = RGBColor(170, 170, 170);

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// The levelled height map in false colour (y up: the surface seen from
/// above), axes in µm, colour bar in µm clipped to the 0.5–99.5 % range of
/// the heights; invalid points grey.
pub fn heightmap_png(map: &HeightMap, title: &str) -> Result<Vec<u8>, PlotError> {
    let mut valid: Vec<f64> = map.heights_m.iter().copied().filter(|h| h.is_finite()).collect();
    if valid.is_empty() {
        return Err(perr("height map has no valid point"));
    }
    valid.sort_by(f64::total_cmp);
    let (lo, hi) = (percentile(&valid, 0.005) * 1e6, percentile(&valid, 0.995) * 1e6);
    let (lo, hi) = if hi > lo { (lo, hi) } else { (lo - 1e-6, lo + 1e-6) };
    let (wx, wy) = (map.nx as f64 * map.pitch_x_m * 1e6, map.ny as f64 * map.pitch_y_m * 1e6);
    // Plot area of at most 640 px on the longer side, aspect as the map's.
    let (pw, ph) = if wx >= wy { (640.0, (640.0 * wy / wx).max(60.0)) } else { ((640.0 * wx / wy).max(60.0), 640.0) };
    let (pw, ph) = (pw.round() as u32, ph.round() as u32);
    let (margin, xl, yl, title_h, bar_w) = (12u32, 45u32, 75u32, 40u32, 170u32);
    let width = pw + 2 * margin + yl + bar_w;
    let height = ph + 2 * margin + xl + title_h;
    let invalid = map.nx * map.ny - valid.len();
    render_png(width, height, |root| {
        let (top, body) = root.split_vertically(title_h);
        let caption = if invalid > 0 { format!("{title} ({invalid} invalid points grey)") } else { title.to_string() };
        top.titled(&caption, ("sans-serif", 18)).map_err(perr)?;
        let (left, right) = body.split_horizontally(pw + 2 * margin + yl);
        let mut chart = ChartBuilder::on(&left)
            .margin(margin)
            .x_label_area_size(xl)
            .y_label_area_size(yl)
            .build_cartesian_2d(0.0..wx, 0.0..wy)
            .map_err(perr)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x [µm]")
            .y_desc("y [µm]")
            .x_label_formatter(&|v| short_number(*v))
            .y_label_formatter(&|v| short_number(*v))
            .draw()
            .map_err(perr)?;
        let (aw, ah) = chart.plotting_area().dim_in_pixel();
        // Box-average the heights into aw × ah display pixels (top row = largest y).
        let mut buf = vec![0u8; (aw * ah * 3) as usize];
        for py in 0..ah as usize {
            let j1 = map.ny as f64 * (1.0 - py as f64 / ah as f64);
            let j0 = map.ny as f64 * (1.0 - (py + 1) as f64 / ah as f64);
            let (ja, jb) = (j0.floor() as usize, (j1.ceil() as usize).max(j0.floor() as usize + 1).min(map.ny));
            for px in 0..aw as usize {
                let i0 = map.nx as f64 * px as f64 / aw as f64;
                let i1 = map.nx as f64 * (px + 1) as f64 / aw as f64;
                let (ia, ib) = (i0.floor() as usize, (i1.ceil() as usize).max(i0.floor() as usize + 1).min(map.nx));
                let (mut s, mut n) = (0.0, 0usize);
                for j in ja..jb {
                    for i in ia..ib {
                        let h = map.at(i, j);
                        if h.is_finite() {
                            s += h;
                            n += 1;
                        }
                    }
                }
                let c = if n == 0 { INVALID } else { viridis((s / n as f64 * 1e6 - lo) / (hi - lo)) };
                let k = 3 * (py * aw as usize + px);
                buf[k..k + 3].copy_from_slice(&[c.0, c.1, c.2]);
            }
        }
        let img = BitMapElement::with_owned_buffer((0.0, wy), (aw, ah), buf)
            .ok_or_else(|| perr("height-map bitmap has the wrong size"))?;
        chart.draw_series(std::iter::once(img)).map_err(perr)?;
        // Colour bar.
        let mut bar = ChartBuilder::on(&right)
            .margin_top(margin)
            .margin_bottom(margin + xl)
            .margin_right(10)
            .y_label_area_size(90)
            .build_cartesian_2d(0.0..1.0, lo..hi)
            .map_err(perr)?;
        let tiny = 1e-9 * (hi - lo);
        bar.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_desc("height [µm] (0.5–99.5 % range)")
            .y_label_formatter(&|v| short_number(if v.abs() < tiny { 0.0 } else { *v }))
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .draw()
            .map_err(perr)?;
        let steps = 200;
        bar.draw_series((0..steps).map(|k| {
            let a = lo + (hi - lo) * k as f64 / steps as f64;
            let b = lo + (hi - lo) * (k + 1) as f64 / steps as f64;
            Rectangle::new([(0.0, a), (1.0, b)], viridis((0.5 * (a + b) - lo) / (hi - lo)).filled())
        }))
        .map_err(perr)?;
        Ok(())
    })
}

/// Height of the legend band under the D(θ) chart of [`distribution_png`], pixels.
pub const DISTRIBUTION_LEGEND_H: u32 = 100;

/// Measured D(θ) (points with Poisson error bars) with both fits on a
/// logarithmic axis and a legend in a band under the chart (off the data), and the 2-D (θ, φ) histogram as a polar
/// map (radius θ, angle φ, colour log₁₀ D over three decades).
pub fn distribution_png(report: &FitReport) -> Result<Vec<u8>, PlotError> {
    let d = &report.distribution;
    let ymax = d.d_per_sr.iter().copied().fold(0.0, f64::max);
    if ymax.is_nan() || ymax <= 0.0 {
        return Err(perr("distribution has no positive value"));
    }
    let ymin_data = d.d_per_sr.iter().copied().filter(|v| *v > 0.0).fold(f64::INFINITY, f64::min);
    let (lo, hi) = ((ymin_data / 2.0).max(ymax * 1e-7), ymax * 3.0);
    render_png(1500, 700 + DISTRIBUTION_LEGEND_H, |root| {
        let (left, right) = root.split_horizontally(900);
        let (left, legend) = left.split_vertically(700);
        draw_d_theta(&left, &legend, report, lo, hi)?;
        draw_polar_histogram(&right, d)
    })
}

/// A drawing area of a PNG picture.
type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// The D(θ) chart of [`distribution_png`] on `left` (logarithmic axis from
/// `lo` to `hi`), its legend on `legend`.
fn draw_d_theta(left: &Area, legend: &Area, report: &FitReport, lo: f64, hi: f64) -> Result<(), PlotError> {
    let d = &report.distribution;
    let centres = d.centres_rad();
    let tmax_deg = d.theta_max_rad.to_degrees();
    let mut chart = ChartBuilder::on(left)
        .margin(15)
        .caption(format!("measured D(θ) of {} normals, least-squares fits", d.normals), ("sans-serif", 20))
        .x_label_area_size(60)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..tmax_deg, crate::plot::log_axis(lo, hi))
        .map_err(perr)?;
    chart
        .configure_mesh()
        .x_desc(format!(
            "θ_m [°]   ({} bins of {:.3}°, Freedman–Diaconis; range to the 99.9th percentile)",
            d.counts.len(),
            d.bin_width_rad.to_degrees()
        ))
        .y_desc("D(θ) [1/sr], logarithmic axis")
        .x_label_formatter(&|v| short_number(*v))
        .y_label_formatter(&|v| short_number(*v))
        .draw()
        .map_err(perr)?;
    let black = RGBColor(0, 0, 0);
    let pts: Vec<(f64, f64)> =
        centres.iter().zip(&d.d_per_sr).filter(|(_, v)| **v > 0.0).map(|(t, v)| (t.to_degrees(), *v)).collect();
    chart
        .draw_series(
            centres.iter().zip(d.d_per_sr.iter().zip(&d.d_std_error_per_sr)).filter(|(_, (v, e))| **v - **e > 0.0).map(
                |(t, (v, e))| PathElement::new(vec![(t.to_degrees(), v - e), (t.to_degrees(), v + e)], black.mix(0.5)),
            ),
        )
        .map_err(perr)?;
    chart.draw_series(pts.iter().map(|p| Circle::new(*p, 2, black.filled()))).map_err(perr)?;
    let mut items = vec![("measured (± Poisson error)".to_string(), Mark::Dot(black))];
    let fine: Vec<f64> = (0..=400).map(|k| d.theta_max_rad * k as f64 / 400.0).collect();
    for (k, &model) in RoughnessModel::ALL.iter().enumerate() {
        let f = report.fits.get(model);
        let colour = crate::plot::palette(if k == 0 { 3 } else { 0 });
        let curve: Vec<(f64, f64)> = fine
            .iter()
            .map(|t| (t.to_degrees(), f.scale * d_tilted_phi_average(model, f.alpha, f.tilt_deg.to_radians(), *t)))
            .filter(|(_, v)| *v >= lo)
            .collect();
        let name = model.label();
        let tilt = if f.tilt_fitted { format!(", tilt {:.3}°", f.tilt_deg) } else { String::new() };
        let better = if report.better_model == model { "  ← better" } else { "" };
        chart.draw_series(LineSeries::new(curve, colour.stroke_width(2))).map_err(perr)?;
        let label = format!(
            "{name}: α = {}, scale {:.4}{tilt}, MSE {:.3e}/sr²{better}",
            short_number(f.alpha),
            f.scale,
            f.mse_per_sr2
        );
        items.push((label, Mark::Line(colour, 2)));
    }
    // The legend band starts at the left edge of the plotting area.
    let legend = legend.margin(0, 0, 80 + 15 - 6, 0);
    legend_column(&legend, 16, &items)?;
    Ok(())
}

/// The 2-D (θ, φ) histogram of `d` as a polar map on `right` (radius θ,
/// angle φ, colour log₁₀ D over three decades) with its colour bar.
fn draw_polar_histogram(right: &Area, d: &super::distribution::Distribution) -> Result<(), PlotError> {
    // Polar 2-D histogram.
    let h2 = &d.histogram_2d;
    let r = h2.theta_edges_rad.last().copied().unwrap_or(1.0).to_degrees();
    let (polar, bar) = right.split_vertically(620);
    let mut pc = ChartBuilder::on(&polar)
        .margin(20)
        .caption("D(θ, φ) to the 90th percentile of θ_m: radius θ_m [°], angle φ_m", ("sans-serif", 17))
        .x_label_area_size(30)
        .y_label_area_size(45)
        .build_cartesian_2d(-r * 1.05..r * 1.05, -r * 1.05..r * 1.05)
        .map_err(perr)?;
    pc.configure_mesh()
        .disable_mesh()
        .x_label_formatter(&|v| short_number(*v))
        .y_label_formatter(&|v| short_number(*v))
        .draw()
        .map_err(perr)?;
    let dmax = h2.d_per_sr.iter().copied().fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    let nphi = h2.phi_edges_rad.len() - 1;
    let mut cells = Vec::new();
    for (b, t) in h2.theta_edges_rad.windows(2).enumerate() {
        for (p, f) in h2.phi_edges_rad.windows(2).enumerate() {
            let v = h2.d_per_sr[b * nphi + p];
            let colour = if v > 0.0 { viridis(((v / dmax).log10() + 3.0) / 3.0) } else { RGBColor(255, 255, 255) };
            let (r0, r1) = (t[0].to_degrees(), t[1].to_degrees());
            let mut poly = Vec::new();
            for s in 0..=6 {
                let a = f[0] + (f[1] - f[0]) * s as f64 / 6.0;
                poly.push((r1 * a.cos(), r1 * a.sin()));
            }
            for s in (0..=6).rev() {
                let a = f[0] + (f[1] - f[0]) * s as f64 / 6.0;
                poly.push((r0 * a.cos(), r0 * a.sin()));
            }
            cells.push(Polygon::new(poly, colour.filled()));
        }
    }
    pc.draw_series(cells).map_err(perr)?;
    for k in 0..4 {
        let a = k as f64 * PI / 4.0;
        pc.draw_series(LineSeries::new(
            [(-r * a.cos(), -r * a.sin()), (r * a.cos(), r * a.sin())],
            RGBColor(255, 255, 255).mix(0.6),
        ))
        .map_err(perr)?;
    }
    pc.draw_series(std::iter::once(Text::new(
        "φ = 0° (+x)",
        (r * 0.62, -r * 0.08),
        ("sans-serif", 13).into_font().color(&WHITE),
    )))
    .map_err(perr)?;
    let an = &d.anisotropy;
    pc.draw_series(std::iter::once(Text::new(
        format!("anisotropy {:.3} (major axis {:.1}°)", an.ratio, an.major_azimuth_deg),
        (-r * 1.0, -r * 1.0),
        ("sans-serif", 13).into_font(),
    )))
    .map_err(perr)?;
    let mut bc = ChartBuilder::on(&bar)
        .margin_left(70)
        .margin_right(30)
        .x_label_area_size(45)
        .build_cartesian_2d(-3.0..0.0, 0.0..1.0)
        .map_err(perr)?;
    bc.configure_mesh()
        .disable_mesh()
        .disable_y_axis()
        .x_desc(format!("log10(D / D_max), D_max = {:.3e} /sr", dmax))
        .x_labels(4)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(perr)?;
    bc.draw_series((0..100).map(|k| {
        let a = -3.0 + 3.0 * k as f64 / 100.0;
        let b = a + 0.03;
        Rectangle::new([(a, 0.0), (b, 1.0)], viridis((a + 3.0) / 3.0).filled())
    }))
    .map_err(perr)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The map's ends and middle are matplotlib's viridis (its 256-entry table: 0 → #440154, 0.5 → #21918c,
    /// 1 → #fde725) to within the interpolation of plotters' 8 stops; out-of-range and NaN inputs are clamped.
    #[test]
    fn viridis_matches_matplotlib() {
        let close = |c: RGBColor, want: (u8, u8, u8), tol: i32| {
            let d = [c.0 as i32 - want.0 as i32, c.1 as i32 - want.1 as i32, c.2 as i32 - want.2 as i32];
            assert!(d.iter().all(|v| v.abs() <= tol), "{c:?} vs {want:?}");
        };
        close(viridis(0.0), (0x44, 0x01, 0x54), 0);
        close(viridis(0.5), (0x21, 0x91, 0x8c), 6);
        close(viridis(1.0), (0xfd, 0xe7, 0x25), 1);
        close(viridis(-3.0), (0x44, 0x01, 0x54), 0);
        close(viridis(f64::NAN), (0x44, 0x01, 0x54), 0);
        close(viridis(7.0), (0xfd, 0xe7, 0x25), 1);
    }
}
