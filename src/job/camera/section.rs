//! The calibrate and pose stages' sections in the run's report (under
//! "Calibration"): the camera's intrinsics, distortion and RMS reprojection
//! error with the residual plot, beside the known camera when
//! `[calibration] truth` gives one; the board's pose with its picture,
//! beside the known pose when `[pose] truth` gives one (the distance between
//! the camera centres in mm, the angle between the orientations).

use crate::job::report::{
    e4, esc, f3, f4, num, read_json, table, to_value, trim, Metrics, ReportError, ReportSection, SectionContext,
};
use lucent_calib::calibrate::CalibrationFiles;
use lucent_calib::scene::PoseFiles;
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::Path;

/// The camera calibration (stage calibrate's `files`), beside the known
/// camera `truth` (a camera.json) when there is one; empty when the stage
/// has not run.
pub struct CalibrateSection<'a> {
    pub files: CalibrationFiles,
    /// `[calibration] truth`.
    pub truth: Option<&'a Path>,
}

impl ReportSection for CalibrateSection<'_> {
    fn section(&self, ctx: &mut SectionContext<'_>, metrics: &mut Metrics) -> Result<String, ReportError> {
        let mut h = String::new();
        type Calibration = lucent_calib::camera::Calibration;
        let Some(c) = read_json::<Calibration>(&self.files.camera, "a camera.json")? else {
            return Ok(String::new());
        };
        let (k, d) = (&c.camera.intrinsics, &c.camera.distortion);
        h.push_str("<h3>Camera (Zhang)</h3>");
        h.push_str(&table(
            &["fx [px]", "fy [px]", "cx [px]", "cy [px]", "k1", "k2", "p1", "p2", "k3", "RMS [px]", "views"],
            &[vec![
                num(k.fx, f3),
                num(k.fy, f3),
                num(k.cx, f3),
                num(k.cy, f3),
                num(d.k1, f4),
                num(d.k2, f4),
                num(d.p1, e4),
                num(d.p2, e4),
                num(d.k3, f4),
                num(c.rms_px, f4),
                c.views.len().to_string(),
            ]],
        ));
        let truth = match self.truth {
            Some(p) => read_json::<Calibration>(p, "a camera.json ([calibration] truth)")?,
            None => None,
        };
        let mut truth_json = None;
        if let Some(t) = &truth {
            // Synthetic views from a known camera: truth, recovered and their difference.
            let values = |c: &Calibration| {
                let (k, d) = (&c.camera.intrinsics, &c.camera.distortion);
                [
                    ("fx", k.fx),
                    ("fy", k.fy),
                    ("cx", k.cx),
                    ("cy", k.cy),
                    ("k1", d.k1),
                    ("k2", d.k2),
                    ("p1", d.p1),
                    ("p2", d.p2),
                    ("k3", d.k3),
                ]
            };
            let mut rows = Vec::new();
            let mut tj = serde_json::Map::new();
            for ((name, tv), (_, rv)) in values(t).into_iter().zip(values(&c)) {
                let fmt = |x: f64| format!("{x:.5}");
                rows.push(vec![name.to_string(), fmt(tv), fmt(rv), fmt(rv - tv)]);
                tj.insert(name.into(), json!({"truth": tv, "recovered": rv, "error": rv - tv}));
            }
            h.push_str("<h3>Recovered vs known camera (synthetic views)</h3>");
            h.push_str(&table(&["parameter", "truth", "recovered", "recovered − truth"], &rows));
            truth_json = Some(Value::Object(tj));
        }
        h.push_str(&ctx.page.img(&self.files.residuals_png, "reprojection residuals per view")?);
        let mut cj = trim(&to_value(&c), 16);
        if let Some(t) = truth_json {
            cj["truth_vs_recovered"] = t;
        }
        cj["views"] = json!(c.views.iter().map(|v| json!({"image": v.image, "rms_px": v.rms_px})).collect::<Vec<_>>());
        metrics.insert("calibration".into(), cj);
        Ok(h)
    }
}

/// The board's pose (stage pose's `files`), beside the known pose `truth`
/// (a scene file with `[camera] camera_to_world`) when there is one; empty
/// when the stage has not run.
pub struct PoseSection<'a> {
    pub files: PoseFiles,
    /// `[pose] truth`.
    pub truth: Option<&'a Path>,
}

impl ReportSection for PoseSection<'_> {
    fn section(&self, ctx: &mut SectionContext<'_>, metrics: &mut Metrics) -> Result<String, ReportError> {
        let mut h = String::new();
        type Pose = lucent_calib::scene::SceneDescription;
        let Some(p) = read_json::<Pose>(&self.files.json, "a scene.json of `lucent pose`")? else {
            return Ok(String::new());
        };
        h.push_str("<h3>Board pose</h3>");
        let mut pj = trim(&to_value(&p), 16);
        if let Some(t) = self.truth {
            let text = crate::io::read_text(t).map_err(|source| ReportError::Read {
                path: t.to_path_buf(),
                what: "a scene file ([pose] truth)",
                source,
            })?;
            match crate::scene::parse(&text, t).map_err(|e| ReportError::PoseTruth(Box::new(e)))?.camera.camera_to_world
            {
                Some(k) => {
                    let (mm, deg) = pose_error(&k, &p.camera_to_world);
                    let _ = write!(
                        h,
                        "<p>Known camera pose ({}): recovered camera position {mm:.2} mm from the truth, \
                             orientation {deg:.3}° off.</p>",
                        esc(&t.display().to_string())
                    );
                    pj["truth_vs_recovered"] = json!({"position_error_mm": mm, "rotation_error_deg": deg});
                }
                None => h.push_str("<p class=\"note\">[pose] truth has no [camera] camera_to_world.</p>"),
            }
        }
        h.push_str(&ctx.page.img(&self.files.view_png, "board pose and sample outline")?);
        metrics.insert("pose".into(), pj);
        Ok(h)
    }
}

/// Distance between two camera-to-world poses' centres (mm, the matrices in
/// metres) and the angle of the rotation between them (degrees).
fn pose_error(truth: &[[f64; 4]; 4], rec: &[[f64; 4]; 4]) -> (f64, f64) {
    let d: f64 = (0..3).map(|r| (truth[r][3] - rec[r][3]).powi(2)).sum::<f64>().sqrt();
    // trace(Rtᵀ Rr) = 1 + 2 cos θ
    let trace: f64 = (0..3).map(|i| (0..3).map(|k| truth[k][i] * rec[k][i]).sum::<f64>()).sum();
    let angle = ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
    (1000.0 * d, angle)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_error_measures_distance_and_angle() {
        let t = [[1.0, 0.0, 0.0, 0.1], [0.0, 1.0, 0.0, 0.2], [0.0, 0.0, 1.0, 0.3], [0.0, 0.0, 0.0, 1.0]];
        let (c, s) = (2f64.to_radians().cos(), 2f64.to_radians().sin());
        let r = [[c, -s, 0.0, 0.103], [s, c, 0.0, 0.196], [0.0, 0.0, 1.0, 0.3], [0.0, 0.0, 0.0, 1.0]];
        let (mm, deg) = pose_error(&t, &r);
        assert!((mm - 5.0).abs() < 1e-9 && (deg - 2.0).abs() < 1e-9, "{mm} {deg}");
        assert_eq!(pose_error(&t, &t), (0.0, 0.0));
    }
}
