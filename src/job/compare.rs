//! The compare stage: [`CompareJob::run`] compares a photo with one or two
//! renders of its twin ([`crate::compare`]: RMSE, SSIM, the noise-aware
//! model RMSE, the paired test of two twins, ECC refinement, the twins'
//! bands) and writes metrics.json, triplet.png and difference.exr
//! ([`CompareFiles`](crate::compare::CompareFiles)) into the job's folder. `lucent compare` and the
//! pipeline's compare stage both run it; the command only parses its flags
//! into the job and prints [`CompareRun::summary`].

mod section;
pub use section::{verdict_sentence, CompareSection};

use super::context::Context;
use super::spec::CompareJob;
use crate::compare::{self, CompareError, MaskSpec, Metrics, Outcome, Request};
use std::path::{Path, PathBuf};

/// What a compare job produced: the comparison and the files it wrote
/// (their names: [`CompareFiles::in_dir`](crate::compare::CompareFiles::in_dir) of the job's `out`).
pub struct CompareRun {
    pub outcome: Outcome,
    /// The paths written, in the order they were written.
    pub written: Vec<PathBuf>,
}

impl CompareJob {
    /// The comparison the job asks for, with the warnings about its files
    /// (one file in two roles).
    pub fn request(&self) -> Result<(Request, Vec<String>), CompareError> {
        let (mask, mask_also) = match (&self.mask, &self.mask_object, &self.mask_board) {
            (m, Some(p), _) => (MaskSpec::Object(p.clone()), m.clone()),
            (m, _, Some(p)) => (MaskSpec::Board(p.clone()), m.clone()),
            (Some(p), None, None) => (MaskSpec::Image(p.clone()), None),
            (None, None, None) => (MaskSpec::None, None),
        };
        let (render, render_b) = match self.render.as_slice() {
            [] => return Err(CompareError::Renders { count: 0 }),
            [a] => (a.clone(), None),
            [a, b] => (a.clone(), Some(b.clone())),
            more => return Err(CompareError::Renders { count: more.len() }),
        };
        if self.twin_names.is_some() && render_b.is_none() {
            return Err(CompareError::TwinNamesWithoutTwoRenders);
        }
        let warnings = same_file_in_two_roles(&self.photo, &self.render, self.photo_repeat.as_deref())?;
        let request = Request {
            photo: self.photo.clone(),
            render,
            render_b,
            mask,
            mask_also,
            scene: self.scene.clone(),
            data_range: self.data_range,
            luminance: self.luminance,
            exposure: self.exposure,
            refine: self.refine,
            photo_variance: self.photo_variance.clone(),
            photo_repeat: self.photo_repeat.clone(),
            twin_names: self.twin_names.clone(),
            bands: self.band.iter().map(|p| compare::band::TwinBands::read(p)).collect::<Result<_, _>>()?,
        };
        Ok((request, warnings))
    }

    /// Compares and writes the outputs (staged: Ctrl-C or SIGTERM while
    /// they are written removes the staging folder; a failure leaves no
    /// partial result). Warnings and notes go to `ctx`.
    pub fn run(&self, ctx: &Context) -> Result<CompareRun, CompareError> {
        let (req, warnings) = self.request()?;
        for w in &warnings {
            ctx.warn(w);
        }
        // A large pair says first what it is and roughly how long it takes
        // (`lucent bench compare`: the metrics ≈ 0.2 s per Mpixel per twin on
        // 2 cores, reading and writing the files ≈ 0.5 s per Mpixel; ECC
        // refinement more).
        if let Ok((w, h)) = crate::imageio::image_size(&req.photo) {
            let mpix = (w * h) as f64 / 1e6;
            if mpix >= 2.0 {
                let twins = 1 + usize::from(req.render_b.is_some());
                ctx.say(&format!(
                    "comparing {w} × {h} px ({mpix:.1} Mpixel, {twins} twin(s)){}: expect ≈ {:.0} s",
                    if req.refine.is_some() { " with ECC refinement" } else { "" },
                    (mpix * (0.5 + 0.2 * twins as f64) * if req.refine.is_some() { 3.0 } else { 1.0 }).max(1.0)
                ));
            }
        }
        let outcome = compare::compare_files(&req)?;
        for n in &outcome.notes {
            match n.strip_prefix("warning: ") {
                Some(w) => ctx.warn(w),
                None => ctx.note(n),
            }
        }
        let interrupt = crate::interrupt::Interrupt::abort_on_first();
        let staging = crate::interrupt::remove_on_abort(&compare::staging_path(&self.out));
        let written = compare::write_outputs(&self.out, &outcome)?;
        drop((staging, interrupt));
        Ok(CompareRun { outcome, written })
    }
}

/// Refuses a repeat photo that is the photo or a render (it would claim a
/// noiseless photo); warns of another file given in two roles (the metrics
/// then compare a file with itself).
fn same_file_in_two_roles(
    photo: &Path,
    renders: &[PathBuf],
    repeat: Option<&Path>,
) -> Result<Vec<String>, CompareError> {
    let same = |x: &Path, y: &Path| x.exists() && y.exists() && crate::io::file_key(x) == crate::io::file_key(y);
    let roles: Vec<(&'static str, &Path)> = std::iter::once(("--photo", photo))
        .chain(renders.iter().map(|r| ("--render", r.as_path())))
        .chain(repeat.map(|r| ("--photo-repeat", r)))
        .collect();
    let mut warnings = Vec::new();
    for (k, (flag, path)) in roles.iter().enumerate() {
        if let Some((other, _)) = roles[..k].iter().find(|(_, p)| same(p, path)) {
            if *flag == "--photo-repeat" {
                return Err(CompareError::RepeatIsNotSecondPhoto { path: path.to_path_buf(), other });
            }
            warnings.push(format!(
                "{} is given as {other} and as {flag}: the metrics compare a file with itself",
                path.display()
            ));
        }
    }
    Ok(warnings)
}

/// One line of a comparison's metrics, as `lucent compare` prints it.
fn line(m: &Metrics) -> String {
    format!(
        "RMSE {:.4e} (R {:.3e}, G {:.3e}, B {:.3e}), SSIM Y {:.4} (R {:.4}, G {:.4}, B {:.4}), MAE {:.3e}, relative error {:.2} %, {} pixels",
        m.rmse,
        m.rmse_channels.r,
        m.rmse_channels.g,
        m.rmse_channels.b,
        m.ssim.y,
        m.ssim.r,
        m.ssim.g,
        m.ssim.b,
        m.mean_abs_error,
        100.0 * m.relative_error,
        m.pixels
    )
}

impl CompareRun {
    /// The comparison in a few lines (metrics as calibrated, the model RMSE
    /// and SSIM at zero render noise, the second twin and the paired test,
    /// the refined metrics, each band's statement, the files written).
    pub fn summary(&self) -> Vec<String> {
        let r = &self.outcome.report;
        let mut lines = vec![format!("as calibrated: {}", line(&r.as_calibrated))];
        if let Some(n) = &r.noise {
            lines.push(format!(
                "model RMSE (noise removed) {:.4e}, 95 % interval [{:.4e}, {:.4e}], noise floor {:.4e}, over {} pixels",
                n.total.model_rmse, n.total.ci95[0], n.total.ci95[1], n.total.noise_floor, n.pixels
            ));
        }
        let zero = |z: &compare::noise::SsimAtZeroNoise| {
            format!(
                "SSIM Y at zero render noise {:.4}, 95 % interval [{:.4}, {:.4}] (as measured {:.4}), over {} pixels",
                z.at_zero_noise, z.ci95[0], z.ci95[1], z.ssim, z.pixels
            )
        };
        if let Some(z) = &r.ssim_at_zero_noise {
            lines.push(zero(z));
        }
        if let Some(t) = &r.twins {
            if let Some(z) = &t.ssim_at_zero_noise_b {
                lines.push(format!("twin B: {}", zero(z)));
            }
            lines.push(format!(
                "twin B ({}): {}; model RMSE {:.4e} [{:.4e}, {:.4e}]",
                t.render_b,
                line(&t.metrics_b),
                t.noise_b.total.model_rmse,
                t.noise_b.total.ci95[0],
                t.noise_b.total.ci95[1]
            ));
            lines.push(format!(
                "A vs B over means of {c} × {c} px cells: squared-error difference {:.3e} ± {:.1e} (t {:.2}, {} blocks, \
                 p {:.2e}): {}",
                t.paired.squared_difference,
                t.paired.standard_error,
                t.paired.z,
                t.paired.blocks,
                t.paired.p_value,
                t.paired.verdict,
                c = t.paired.cell_px
            ));
        }
        if let Some(f) = &r.refined {
            lines.push(format!(
                "after ECC ({}, dx {:+.3} px, dy {:+.3} px, correlation {:.4}): {}",
                f.motion,
                f.shift_px[0],
                f.shift_px[1],
                f.correlation,
                line(&f.metrics)
            ));
        }
        for b in &r.bands {
            lines.push(format!("{}: {}", b.render, b.statement));
        }
        lines.push(format!(
            "written: {}",
            self.written.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        ));
        lines
    }
}
