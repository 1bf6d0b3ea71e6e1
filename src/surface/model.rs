//! The microfacet distributions a measured surface is described by, and the
//! one text form of a roughness choice that scene files (`[material]
//! roughness`) and `lucent bssrdf --roughness` share. A leaf module: the
//! recipe, the surface fits and the command line all depend on it, it on
//! none of them.
//!
//! Trowbridge–Reitz (Trowbridge & Reitz 1975; "GGX" in Walter et al. 2007)
//! and Beckmann (Beckmann & Spizzichino 1963) distributions of normals with
//! roughness α (dimensionless, the RMS slope for Beckmann).

use lucent_render::microfacet::Distribution;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::str::FromStr;
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// Microfacet distribution of a measured surface.
/// Files spell the models `trowbridge-reitz` and `beckmann`; the command
/// line and the roughness text also read `tr` (the name listed) and `ggx`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
#[derive(EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "kebab-case", ascii_case_insensitive)]
pub enum RoughnessModel {
    /// Trowbridge–Reitz (GGX).
    #[strum(to_string = "tr", serialize = "ggx", serialize = "trowbridge-reitz")]
    TrowbridgeReitz,
    Beckmann,
}

impl RoughnessModel {
    /// Both models, Trowbridge–Reitz first.
    pub const ALL: &'static [RoughnessModel] = <Self as strum::VariantArray>::VARIANTS;

    /// Any spelling of a model (case ignored).
    pub fn from_name(name: &str) -> Result<Self, RoughnessSyntax> {
        let name = name.trim();
        name.parse().map_err(|_| RoughnessSyntax::UnknownModel(name.to_ascii_lowercase()))
    }

    /// The name for people ("Trowbridge–Reitz", "Beckmann").
    pub fn label(self) -> &'static str {
        match self {
            RoughnessModel::TrowbridgeReitz => "Trowbridge–Reitz",
            RoughnessModel::Beckmann => "Beckmann",
        }
    }

    /// The renderer's distribution of this model with roughness `alpha`.
    pub fn distribution(self, alpha: f64) -> Distribution {
        match self {
            RoughnessModel::TrowbridgeReitz => Distribution::TrowbridgeReitz { alpha },
            RoughnessModel::Beckmann => Distribution::Beckmann { alpha },
        }
    }
}

/// What is wrong with the text of a roughness choice.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RoughnessSyntax {
    #[error("no MODEL:VALUE")]
    NoModel,
    #[error("{0:?} is not a number")]
    NotANumber(String),
    #[error("α = {0} must be a number in [0, 4]")]
    Alpha(f64),
    #[error("unknown model {0:?}")]
    UnknownModel(String),
}

/// A roughness choice as written: `recipe` (the recipe's `[surface]`),
/// `smooth`, `MODEL:ALPHA` (an analytic distribution, α finite and ≥ 0), or
/// `measured:PATH` (a `fit.json` of `lucent surface fit` or its
/// `normals.exr`).
#[derive(Debug, Clone, PartialEq)]
pub enum RoughnessSpec {
    Recipe,
    Smooth,
    Analytic { model: RoughnessModel, alpha: f64 },
    Measured(PathBuf),
}

impl FromStr for RoughnessSpec {
    type Err = RoughnessSyntax;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let t = text.trim();
        match t {
            "recipe" => return Ok(RoughnessSpec::Recipe),
            "smooth" => return Ok(RoughnessSpec::Smooth),
            _ => {}
        }
        let (kind, value) = t.split_once(':').ok_or(RoughnessSyntax::NoModel)?;
        if kind.trim().eq_ignore_ascii_case("measured") {
            return Ok(RoughnessSpec::Measured(PathBuf::from(value.trim())));
        }
        let model = RoughnessModel::from_name(kind)?;
        let alpha: f64 = value.trim().parse().map_err(|_| RoughnessSyntax::NotANumber(value.into()))?;
        if !(alpha.is_finite() && alpha >= 0.0) {
            return Err(RoughnessSyntax::Alpha(alpha));
        }
        Ok(RoughnessSpec::Analytic { model, alpha })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_spelling_parses() {
        for t in ["tr:0.1", "ggx:0.1", "trowbridge-reitz:0.1", " GGX : 0.1 "] {
            assert_eq!(
                t.parse::<RoughnessSpec>(),
                Ok(RoughnessSpec::Analytic { model: RoughnessModel::TrowbridgeReitz, alpha: 0.1 }),
                "{t}"
            );
        }
        assert_eq!(
            "beckmann:0.3".parse::<RoughnessSpec>(),
            Ok(RoughnessSpec::Analytic { model: RoughnessModel::Beckmann, alpha: 0.3 })
        );
        assert_eq!("smooth".parse::<RoughnessSpec>(), Ok(RoughnessSpec::Smooth));
        assert_eq!("recipe".parse::<RoughnessSpec>(), Ok(RoughnessSpec::Recipe));
        assert_eq!(
            "measured:a/fit.json".parse::<RoughnessSpec>(),
            Ok(RoughnessSpec::Measured(PathBuf::from("a/fit.json")))
        );
    }

    #[test]
    fn bad_text_says_what_is_wrong() {
        assert_eq!("0.1".parse::<RoughnessSpec>(), Err(RoughnessSyntax::NoModel));
        assert_eq!("tr:x".parse::<RoughnessSpec>(), Err(RoughnessSyntax::NotANumber("x".into())));
        assert_eq!("tr:-1".parse::<RoughnessSpec>(), Err(RoughnessSyntax::Alpha(-1.0)));
        assert!(matches!("tr:NaN".parse::<RoughnessSpec>(), Err(RoughnessSyntax::Alpha(a)) if a.is_nan()));
        assert_eq!("phong:1".parse::<RoughnessSpec>(), Err(RoughnessSyntax::UnknownModel("phong".into())));
    }
}
