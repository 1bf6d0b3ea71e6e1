//! The surface-fit job: [`SurfaceFitJob::run`] fits microfacet normal
//! distributions to a measured height map (`lucent surface fit`; the work
//! is [`crate::surface`], docs/method.md#surface).
//!
//! The height map (X3P, a text grid, a 32-bit float TIFF or an EXR; the
//! job's pitches and height unit where the file has none, or overriding
//! its pitch) is levelled (its least-squares plane removed unless
//! `keep_tilt`), a normal is fitted per pixel as the plane of its
//! Gaussian-weighted `window` × `window` neighbourhood, and the
//! distribution of the normals' slopes is fitted with Trowbridge–Reitz and
//! Beckmann (α, a scale, and with `fit_tilt` a tilt of the axis). It writes
//! into the job's `out` ([`SurfaceFitFiles`]): `fit.json` (the
//! [`FitReport`]: what was read, the plane, S_q and S_dq, the histogram,
//! both fits with their MSE in 1/sr² and NRMSE, the better model and the
//! wall time in seconds), `heightmap.png`, `distribution.png` and
//! `normals.exr` ([`crate::surface::write_fit_outputs`]).

mod section;

use super::context::Context;
use super::fields::{bad, by_name_opt, s, JobError, Line};
use crate::surface::model::RoughnessModel;
use crate::surface::{
    fit_surface, read_height_map, write_fit_outputs, FitOptions, FitReport, LengthUnit, ReadOptions, SurfaceError,
    SurfaceFitFiles,
};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use thiserror::Error;

/// `lucent surface fit`: a height map → its normals and fitted roughness
/// ([`SurfaceFitJob::run`]). The keys unset or at their defaults may be
/// left out of a job file and are not written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceFitJob {
    /// The height map (.x3p, .csv/.txt/.asc/.dat, .tif/.tiff, .exr).
    pub heightmap: PathBuf,
    /// `--pitch-um`: point spacing in µm (overrides the file's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_um: Option<f64>,
    /// `--pitch-y-um`: row spacing in µm, if it differs (with `pitch_um`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_y_um: Option<f64>,
    /// `--height-unit`: the unit of the stored heights ("m", "mm", "um", "nm").
    #[serde(default, with = "by_name_opt", skip_serializing_if = "Option::is_none")]
    pub height_unit: Option<LengthUnit>,
    /// `--window`: side of the plane fits' window in pixels (odd, 3 … 201).
    #[serde(default = "defaults::window", skip_serializing_if = "defaults::is_window")]
    pub window: usize,
    /// `--sigma-px`: σ of the plane fits' Gaussian weights in pixels.
    #[serde(default = "defaults::sigma_px", skip_serializing_if = "defaults::is_sigma_px")]
    pub sigma_px: f64,
    /// `--min-weight`: the least fraction of the window's weight on valid points for a normal.
    #[serde(default = "defaults::min_weight", skip_serializing_if = "defaults::is_min_weight")]
    pub min_weight: f64,
    /// `--keep-tilt`: do not subtract the least-squares plane first.
    #[serde(default, skip_serializing_if = "is_false")]
    pub keep_tilt: bool,
    /// `--fit-tilt`: fit a tilt of the distribution's axis too.
    #[serde(default, skip_serializing_if = "is_false")]
    pub fit_tilt: bool,
    /// The output folder.
    pub out: PathBuf,
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// The defaults of `lucent surface fit`'s flags (those of [`FitOptions`]).
pub mod defaults {
    pub const WINDOW: usize = 15;
    pub const SIGMA_PX: f64 = 1.0;
    pub const MIN_WEIGHT: f64 = 0.9;

    pub(super) fn window() -> usize {
        WINDOW
    }
    pub(super) fn is_window(v: &usize) -> bool {
        *v == WINDOW
    }
    pub(super) fn sigma_px() -> f64 {
        SIGMA_PX
    }
    pub(super) fn is_sigma_px(v: &f64) -> bool {
        *v == SIGMA_PX
    }
    pub(super) fn min_weight() -> f64 {
        MIN_WEIGHT
    }
    pub(super) fn is_min_weight(v: &f64) -> bool {
        *v == MIN_WEIGHT
    }
}

impl SurfaceFitJob {
    /// `heightmap` fitted into `out`, every flag at its default.
    pub fn new(heightmap: PathBuf, out: PathBuf) -> Self {
        SurfaceFitJob {
            heightmap,
            pitch_um: None,
            pitch_y_um: None,
            height_unit: None,
            window: defaults::WINDOW,
            sigma_px: defaults::SIGMA_PX,
            min_weight: defaults::MIN_WEIGHT,
            keep_tilt: false,
            fit_tilt: false,
            out,
        }
    }

    /// The plane fits' parameters.
    pub fn options(&self) -> FitOptions {
        FitOptions {
            window_px: self.window,
            sigma_px: self.sigma_px,
            min_weight_fraction: self.min_weight,
            remove_tilt: !self.keep_tilt,
            fit_tilt: self.fit_tilt,
        }
    }

    /// The pitches (positive, finite; a row pitch only with a point pitch)
    /// and the plane fits' parameters ([`FitOptions::validate`]).
    pub fn validate(&self) -> Result<(), JobError> {
        for (field, v) in [("pitch_um", self.pitch_um), ("pitch_y_um", self.pitch_y_um)] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return Err(bad(field, v, "must be a positive finite number of µm"));
            }
        }
        if let (Some(v), None) = (self.pitch_y_um, self.pitch_um) {
            return Err(bad("pitch_y_um", v, "needs --pitch-um (the point spacing) too"));
        }
        match self.options().validate() {
            Err(SurfaceError::Parameter { name, value, reason }) => {
                let field = match name.as_str() {
                    "window" => "window",
                    "sigma-px" => "sigma_px",
                    _ => "min_weight",
                };
                Err(JobError { field, value, reason })
            }
            _ => Ok(()),
        }
    }

    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["surface", "fit"]);
        l.word(s(&self.heightmap));
        if let Some(p) = self.pitch_um {
            l.word(format!("--pitch-um={p}"));
        }
        if let Some(p) = self.pitch_y_um {
            l.word(format!("--pitch-y-um={p}"));
        }
        l.opt("--height-unit", &self.height_unit.map(<&str>::from));
        if !defaults::is_window(&self.window) {
            l.flag("--window", self.window);
        }
        if !defaults::is_sigma_px(&self.sigma_px) {
            l.word(format!("--sigma-px={}", self.sigma_px));
        }
        if !defaults::is_min_weight(&self.min_weight) {
            l.word(format!("--min-weight={}", self.min_weight));
        }
        l.switch("--keep-tilt", self.keep_tilt).switch("--fit-tilt", self.fit_tilt);
        l.flag("--out", s(&self.out));
        l.0
    }
}

/// Why a surface fit failed; every variant names the file or parameter.
#[derive(Debug, Error)]
pub enum SurfaceFitError {
    #[error(transparent)]
    Invalid(#[from] JobError),
    /// The height map cannot be read, or the outputs written.
    #[error(transparent)]
    Surface(#[from] SurfaceError),
    /// The fit failed on the map read (the source says why; boxed, the largest error).
    #[error("{}: fitting", heightmap.display())]
    Fit { heightmap: PathBuf, source: Box<SurfaceError> },
}

/// What a surface fit found and wrote.
pub struct SurfaceFitRun {
    /// The height map fitted.
    pub heightmap: PathBuf,
    /// `fit.json`.
    pub report: FitReport,
    /// The files written.
    pub files: SurfaceFitFiles,
}

impl SurfaceFitRun {
    /// What `lucent surface fit` prints on its standard output: the map,
    /// its roughness, each model's fit and the files.
    pub fn summary(&self) -> Vec<String> {
        let r = &self.report;
        let mut lines = vec![
            format!(
                "{}: {} × {} points at {:.4} × {:.4} µm, {} valid; global plane tilt {:.4}° (normal azimuth {:.1}°){}",
                self.heightmap.display(),
                r.input.nx,
                r.input.ny,
                r.input.pitch_x_m * 1e6,
                r.input.pitch_y_m * 1e6,
                r.input.valid_points,
                r.global_plane.tilt_deg,
                r.global_plane.normal_azimuth_deg,
                if r.global_plane.removed { ", removed" } else { ", kept" }
            ),
            format!(
                "S_q {:.4} µm, S_dq {:.5} (plane-fit normals {:.5}); {} normals ({} × {} window, σ {} px); anisotropy {:.3}",
                r.roughness.sq_m * 1e6,
                r.roughness.sdq,
                r.roughness.sdq_plane_fit,
                r.distribution.normals,
                r.options.window_px,
                r.options.window_px,
                r.options.sigma_px,
                r.distribution.anisotropy.ratio
            ),
            format!("bins: {}", r.distribution.bin_rule),
        ];
        for &m in RoughnessModel::ALL {
            let f = r.fits.get(m);
            let tilt = if f.tilt_fitted { format!(", tilt {:.4}°", f.tilt_deg) } else { String::new() };
            lines.push(format!(
                "{:<17} α = {:.5}, scale {:.4}{tilt}, MSE {:.4e} /sr², NRMSE {:.4}{}",
                RoughnessModel::label(m),
                f.alpha,
                f.scale,
                f.mse_per_sr2,
                f.nrmse,
                if m == r.better_model { "  ← better" } else { "" }
            ));
        }
        let written: Vec<String> = self.files.all().iter().map(|p| p.display().to_string()).collect();
        lines.push(format!("{:.2} s; wrote {}", r.seconds, written.join(", ")));
        lines
    }
}

impl SurfaceFitJob {
    /// Reads the height map, fits it and writes the outputs; the reader's
    /// notes (e.g. a unit assumed) go to `ctx`.
    pub fn run(&self, ctx: &Context) -> Result<SurfaceFitRun, SurfaceFitError> {
        self.validate()?;
        let read = ReadOptions {
            pitch_x_m: self.pitch_um.map(|p| p * 1e-6),
            pitch_y_m: self.pitch_y_um.map(|p| p * 1e-6),
            height_unit: self.height_unit,
        };
        let map = read_height_map(&self.heightmap, &read)?;
        for n in &map.notes {
            ctx.note(n);
        }
        let fit = fit_surface(&map, &self.options())
            .map_err(|e| SurfaceFitError::Fit { heightmap: self.heightmap.clone(), source: Box::new(e) })?;
        let files = write_fit_outputs(&self.out, &fit)?;
        Ok(SurfaceFitRun { heightmap: self.heightmap.clone(), report: fit.report, files })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_surface_job_refuses_what_its_flags_refuse() {
        let job = SurfaceFitJob::new("h.x3p".into(), "out".into());
        assert!(job.validate().is_ok());
        let e = SurfaceFitJob { pitch_um: Some(-1.0), ..job.clone() }.validate().unwrap_err();
        assert_eq!(e.to_string(), "--pitch-um -1: must be a positive finite number of µm");
        let e = SurfaceFitJob { window: 4, ..job.clone() }.validate().unwrap_err();
        assert_eq!(e.to_string(), "--window 4: must be an odd number of pixels from 3 to 201");
        assert_eq!(SurfaceFitJob { sigma_px: 0.0, ..job.clone() }.validate().unwrap_err().field, "sigma_px");
        assert_eq!(SurfaceFitJob { min_weight: 1.5, ..job.clone() }.validate().unwrap_err().field, "min_weight");
        assert_eq!(SurfaceFitJob { pitch_y_um: Some(1.0), ..job }.validate().unwrap_err().field, "pitch_y_um");
    }
}
