//! What `fit.json` holds ([`FitReport`]): the input read, the options, the
//! global plane, S_q/S_dq, the distribution and both fits.

use super::options::FitOptions;
use super::{distribution, fit, normals};
use crate::surface::model::RoughnessModel;
use serde::{Deserialize, Serialize};

/// What was read.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct InputSummary {
    pub origin: String,
    pub nx: usize,
    pub ny: usize,
    pub pitch_x_m: f64,
    pub pitch_y_m: f64,
    pub valid_points: usize,
    pub invalid_points: usize,
    pub notes: Vec<String>,
}

/// The global plane (least squares over all valid points).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct TiltReport {
    /// ∂z/∂x and ∂z/∂y of the plane (dimensionless).
    pub slope_x: f64,
    pub slope_y: f64,
    /// Angle between the plane's normal and z, degrees.
    pub tilt_deg: f64,
    /// Azimuth of the plane's normal (its horizontal part), degrees from +x towards +y.
    pub normal_azimuth_deg: f64,
    /// Whether the plane was subtracted before the normals were computed.
    pub removed: bool,
}

/// The two fits and which one is better.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Fits {
    #[serde(rename = "trowbridge-reitz")]
    pub trowbridge_reitz: fit::ModelFit,
    pub beckmann: fit::ModelFit,
}

impl Fits {
    /// The fit of one model.
    pub fn get(&self, model: RoughnessModel) -> &fit::ModelFit {
        match model {
            RoughnessModel::TrowbridgeReitz => &self.trowbridge_reitz,
            RoughnessModel::Beckmann => &self.beckmann,
        }
    }
}

/// Everything `fit.json` holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FitReport {
    /// "lucent.surface.fit/1".
    pub schema: String,
    pub input: InputSummary,
    pub options: FitOptions,
    pub global_plane: TiltReport,
    pub roughness: normals::Roughness,
    pub distribution: distribution::Distribution,
    pub fits: Fits,
    /// The model with the lower MSE.
    pub better_model: RoughnessModel,
    /// Wall time of levelling, normals, histogram and fits, seconds.
    pub seconds: f64,
}
