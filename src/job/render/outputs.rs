//! What a render writes and reports: render.exr and render.png
//! ([`RenderFiles`](scene::RenderFiles)), the report of render.json
//! ([`report`]), the per-region error figures ([`describe_errors`],
//! [`errors_report`], [`spp_by_region`]) and, with `--uncertainty`, the
//! band's uncertainty.json, band.exr and band.png ([`write_band`]).

use super::error::RenderError;
use crate::imageio::{self, RgbImage};
use crate::scene::{self, RenderReport, SceneSummary};
use lucent_render::tracer::{self, Image, Settings, Stats};
use std::path::Path;

/// "object 4.1 % (6.0 %, 9.2 %) over 51234 px, board …, all …": per region
/// the median, 90th and 99th percentile of the per-pixel relative standard error.
pub fn describe_errors(e: &tracer::RegionErrors) -> String {
    let one = |name: &str, q: &tracer::Quantiles| {
        if q.pixels == 0 {
            format!("{name}: no pixels")
        } else {
            format!(
                "{name} {:.1} % ({:.1} %, {:.1} %) over {} px",
                100.0 * q.median,
                100.0 * q.p90,
                100.0 * q.p99,
                q.pixels
            )
        }
    };
    format!("{}; {}; {}", one("object", &e.object), one("board", &e.board), one("all", &e.all))
}

/// The region figures as written into render.json.
pub fn errors_report(e: &tracer::RegionErrors) -> scene::RegionErrorsReport {
    let q = |q: &tracer::Quantiles| scene::QuantilesReport {
        pixels: q.pixels,
        median: q.median,
        p90: q.p90,
        p99: Some(q.p99),
    };
    scene::RegionErrorsReport {
        definition:
            "relative standard error of the pixel's mean, RMS over R, G, B, over the pixels that are not black \
                     (a pixel with a channel still without light counts as infinite); object: pixels where at least \
                     half the camera rays hit the object first; board: likewise the board; null: no pixels, or a \
                     quantile that is infinite"
                .into(),
        object: q(&e.object),
        board: q(&e.board),
        all: q(&e.all),
    }
}

/// Mean samples per pixel over the object's pixels and over the others.
pub fn spp_by_region(image: &Image) -> scene::SppByRegion {
    let (mut s, mut n) = ([0.0f64; 2], [0usize; 2]);
    for p in 0..image.samples.len() {
        let k = usize::from(image.region(p) != tracer::Region::Object);
        s[k] += f64::from(image.samples[p]);
        n[k] += 1;
    }
    let mean = |k: usize| if n[k] > 0 { s[k] / n[k] as f64 } else { 0.0 };
    scene::SppByRegion { object: mean(0), other: mean(1) }
}

/// Writes render.exr and render.png; returns their names.
pub fn write_outputs(out: &Path, image: &Image, exposure_stops: f64) -> Result<Vec<String>, RenderError> {
    let (w, h) = (image.width, image.height);
    let plane = |f: &dyn Fn(usize) -> f64| (0..w * h).map(|i| f(i) as f32).collect::<Vec<f32>>();
    let (r, g, b) = (plane(&|i| image.mean[i][0]), plane(&|i| image.mean[i][1]), plane(&|i| image.mean[i][2]));
    let (vr, vg, vb) = (
        plane(&|i| image.variance_of_mean[i][0]),
        plane(&|i| image.variance_of_mean[i][1]),
        plane(&|i| image.variance_of_mean[i][2]),
    );
    let spp = plane(&|i| f64::from(image.samples[i]));
    let object = plane(&|i| image.object_fraction(i));
    let board = plane(&|i| f64::from(image.board_samples[i]) / f64::from(image.samples[i].max(1)));
    let half = |k: usize, c: usize| plane(&|i| image.halves[k][i][c]);
    let (ar, ag, ab, br, bg, bb) = (half(0, 0), half(0, 1), half(0, 2), half(1, 0), half(1, 1), half(1, 2));
    let files = scene::RenderFiles::in_dir(out);
    crate::exr::write_channels(
        &files.exr,
        w,
        h,
        &[
            ("R", &r),
            ("G", &g),
            ("B", &b),
            ("variance.R", &vr),
            ("variance.G", &vg),
            ("variance.B", &vb),
            ("spp", &spp),
            ("object", &object),
            ("board", &board),
            ("half_a.R", &ar),
            ("half_a.G", &ag),
            ("half_a.B", &ab),
            ("half_b.R", &br),
            ("half_b.G", &bg),
            ("half_b.B", &bb),
        ],
    )
    .map_err(|e| RenderError::Write { path: files.exr.clone(), source: e.into() })?;
    let k = 2f64.powf(exposure_stops);
    let data: Vec<f32> = image.mean.iter().flat_map(|m| m.map(|v| (v * k) as f32)).collect();
    imageio::write_png(&files.png, &RgbImage::new(w, h, data)?)
        .map_err(|e| RenderError::Write { path: files.png.clone(), source: e.into() })?;
    Ok(scene::RenderFiles::NAMES.map(String::from).to_vec())
}

/// The report of render.json: the scene as resolved, the settings, the
/// counters and the error figures of `image`, rendered on `threads`.
pub fn report(
    summary: &SceneSummary,
    settings: &Settings,
    image: &Image,
    stats: &Stats,
    threads: usize,
    exposure: f64,
    files: &[String],
) -> RenderReport {
    let n = image.mean.len().max(1) as f64;
    let mean_rgb = std::array::from_fn(|c| image.mean.iter().map(|m| m[c]).sum::<f64>() / n);
    let errors = image.region_errors();
    RenderReport {
        lucent_version: env!("CARGO_PKG_VERSION").into(),
        scene: summary.clone(),
        spp: image.samples.iter().copied().max().unwrap_or(0),
        spp_requested: settings.spp(),
        time_budget_s: settings.stop.time_s,
        seed: settings.seed,
        threads,
        roulette_threshold: settings.roulette_threshold,
        wall_s: stats.wall_s,
        samples: stats.samples,
        samples_per_s: stats.samples as f64 / stats.wall_s.max(1e-9),
        scattering_events: stats.events,
        surface_hits: stats.surface_hits,
        leaked_paths: stats.leaked_paths,
        truncated_paths: stats.truncated_paths,
        mean_rgb,
        // The all-pixels median of the one per-pixel figure the regions use
        // (once a grey mean of the channels that read √3 too low where the
        // bands ride on one path).
        median_relative_std_error: errors.all.median,
        relative_std_error: Some(errors_report(&errors)),
        sampling: Some(match settings.sampling {
            tracer::Sampling::Uniform => scene::SamplingKey::Uniform,
            tracer::Sampling::ObjectWeighted => scene::SamplingKey::ObjectWeighted,
        }),
        spp_by_region: Some(spp_by_region(image)),
        target_rel_error: settings.stop.pixel_rel_error,
        estimator: Some(settings.into()),
        exposure_stops_png: exposure,
        files: files.to_vec(),
        interrupted: false,
        approximations: scene::approximations(summary, settings),
    }
}

/// uncertainty.json, band.exr (per pixel and band, the standard
/// deviation from the inputs and its Monte Carlo error) and band.png (the
/// relative band over the object's pixels, to look at) in `out`.
pub fn write_band(out: &Path, image: &Image, band: &scene::band::RenderBand) -> Result<(), RenderError> {
    let files = scene::band::RenderBandFiles::in_dir(out);
    let names = scene::band::RenderBandFiles::NAMES;
    let failed = |name: &'static str| {
        move |e: crate::io::WriteError| RenderError::BandFile { out: out.to_path_buf(), name, source: e }
    };
    crate::io::write_json(&files.json, band).map_err(failed(names[0]))?;
    let channel = |v: &[[f64; 3]], c: usize| -> Vec<f32> { v.iter().map(|t| t[c] as f32).collect() };
    let (sd, se) = (&band.pixel_sd, &band.pixel_sd_std_error);
    let (r, g, b) = (channel(sd, 0), channel(sd, 1), channel(sd, 2));
    let (er, eg, eb) = (channel(se, 0), channel(se, 1), channel(se, 2));
    crate::exr::write_channels(
        &files.exr,
        image.width,
        image.height,
        &[
            ("inputs_sd.R", &r),
            ("inputs_sd.G", &g),
            ("inputs_sd.B", &b),
            ("inputs_sd_std_error.R", &er),
            ("inputs_sd_std_error.G", &eg),
            ("inputs_sd_std_error.B", &eb),
        ],
    )?;
    let png = band_png(image, band)?;
    crate::io::write_atomic(&files.png, &png).map_err(failed(names[2]))?;
    Ok(())
}

/// band.png: the relative band over the object, to look at (cropped to
/// the object's pixels and a margin of a tenth of their extent).
fn band_png(image: &Image, band: &scene::band::RenderBand) -> Result<Vec<u8>, RenderError> {
    let (sd, se) = (&band.pixel_sd, &band.pixel_sd_std_error);
    let relative: Vec<f64> = (0..image.width * image.height)
        .map(|p| {
            let m = image.mean[p];
            let lum: f64 = m.iter().sum();
            if image.region(p) != tracer::Region::Object || lum <= 0.0 {
                return f64::NAN;
            }
            // The bands' sds added as a sum's (fully correlated: one input moves all bands alike).
            sd[p].iter().sum::<f64>() / lum
        })
        .collect();
    let (w, h) = (image.width, image.height);
    let on: Vec<usize> = (0..w * h).filter(|&p| relative[p].is_finite()).collect();
    let (x0, x1, y0, y1) = on.iter().fold((w, 0, h, 0), |(a, b, c, d), &p| {
        let (x, y) = (p % w, p / w);
        (a.min(x), b.max(x), c.min(y), d.max(y))
    });
    let (x0, x1, y0, y1) = if on.is_empty() {
        (0, w - 1, 0, h - 1)
    } else {
        let (mx, my) = ((x1 - x0) / 10 + 1, (y1 - y0) / 10 + 1);
        (x0.saturating_sub(mx), (x1 + mx).min(w - 1), y0.saturating_sub(my), (y1 + my).min(h - 1))
    };
    // A pixel's band is resolved where it is at least twice its own Monte Carlo error in every band.
    let resolved = |p: usize| (0..3).all(|c| sd[p][c] >= 2.0 * se[p][c]);
    let pixels = || (y0..=y1).flat_map(|y| (x0..=x1).map(move |x| y * w + x));
    let crop: Vec<f64> = pixels().map(|p| relative[p]).collect();
    let crop_resolved: Vec<bool> = pixels().map(resolved).collect();
    let shown = on.iter().filter(|&&p| resolved(p)).count();
    Ok(crate::plot::relative_band_png(
        x1 - x0 + 1,
        y1 - y0 + 1,
        &crop,
        &crop_resolved,
        &format!(
            "the twin's band per pixel (R + G + B) from the recipe's inputs;\nlight grey: under 2× its own Monte \
             Carlo error ({:.0} % of {} object px):\nmore samples resolve it; uncertainty.json has the region means",
            100.0 * (on.len() - shown) as f64 / on.len().max(1) as f64,
            on.len()
        ),
    )?)
}
