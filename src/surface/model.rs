//! The microfacet distributions a measured surface is described by, the
//! one range of their roughness α every file and command takes
//! ([`check_alpha`]), and the one typed roughness choice ([`RoughnessSpec`],
//! the top boundary of a slab or an object) that scene files (`[material]
//! roughness`), `lucent bssrdf --roughness`, its job's `roughness` and a
//! project's `[bssrdf] roughness` share, written as the same text in all of
//! them. A leaf module: the recipe, the surface fits and the command line
//! all depend on it, it on none of them.
//!
//! Trowbridge–Reitz (Trowbridge & Reitz 1975; "GGX" in Walter et al. 2007)
//! and Beckmann (Beckmann & Spizzichino 1963) distributions of normals with
//! roughness α (dimensionless, the RMS slope for Beckmann).

use lucent_render::microfacet::{Distribution, MAX_ALPHA};
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
    #[error("α = {0} must be a number in [0, {MAX_ALPHA}]")]
    Alpha(f64),
    #[error("unknown model {0:?}")]
    UnknownModel(String),
    #[error("measured: names no file")]
    NoFile,
}

/// The range of a microfacet roughness α (dimensionless) in every file and
/// command that takes one — `--roughness`, a job's and `[bssrdf]`'s
/// `roughness`, a scene's `[material] roughness`, a recipe's `[surface]
/// alpha`, `lucent surface synth --alpha` (which also needs α > 0): finite
/// and in [0, 4] ([`MAX_ALPHA`], the renderer's limit; below 10⁻⁴ a
/// boundary is smooth).
///
/// ```
/// use lucent::surface::model::{check_alpha, RoughnessSyntax};
/// assert_eq!(check_alpha(0.0084), Ok(0.0084));
/// assert_eq!(check_alpha(4.5), Err(RoughnessSyntax::Alpha(4.5)));
/// assert!(check_alpha(f64::NAN).is_err() && check_alpha(-0.1).is_err());
/// ```
pub fn check_alpha(alpha: f64) -> Result<f64, RoughnessSyntax> {
    if alpha.is_finite() && (0.0..=MAX_ALPHA).contains(&alpha) {
        Ok(alpha)
    } else {
        Err(RoughnessSyntax::Alpha(alpha))
    }
}

/// The words a roughness choice is written in, for messages.
pub const ROUGHNESS_WORDS: &str = "recipe, smooth, tr:ALPHA (ggx:ALPHA), beckmann:ALPHA or measured:FIT.json";

/// A roughness choice — the top boundary of a slab (`lucent bssrdf
/// --roughness`) or of a scene's object (`[material] roughness`) — as its
/// text:
///
/// * `recipe`: the recipe's `[surface]` (smooth without one);
/// * `smooth`;
/// * `MODEL:ALPHA`: an analytic distribution, MODEL `tr` (also `ggx`,
///   `trowbridge-reitz`) or `beckmann`, α in [0, 4] ([`check_alpha`]);
/// * `measured:PATH`: a `fit.json` of `lucent surface fit` (its
///   `normals.exr` beside it) or that `normals.exr` (the slab only).
///
/// Written back ([`std::fmt::Display`], and so in a job file) as the
/// canonical text: the model's listed name (`tr`, `beckmann`) and α as the
/// shortest decimal that reads back as the same number.
///
/// ```
/// use lucent::surface::model::{RoughnessModel, RoughnessSpec};
/// let s: RoughnessSpec = "ggx:0.0084".parse().unwrap();
/// assert_eq!(s, RoughnessSpec::Analytic { model: RoughnessModel::TrowbridgeReitz, alpha: 0.0084 });
/// assert_eq!(s.to_string(), "tr:0.0084");
/// let e = "tr:5".parse::<RoughnessSpec>().unwrap_err().to_string();
/// assert!(e.contains("[0, 4]") && e.contains("measured:FIT.json"), "{e}");
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum RoughnessSpec {
    Recipe,
    Smooth,
    Analytic { model: RoughnessModel, alpha: f64 },
    Measured(PathBuf),
}

/// A text that is not a roughness choice: the text, what is wrong, and the
/// words that are ([`ROUGHNESS_WORDS`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{text:?}: {problem} (expected {ROUGHNESS_WORDS})")]
pub struct BadRoughness {
    pub text: String,
    pub problem: RoughnessSyntax,
}

impl FromStr for RoughnessSpec {
    type Err = BadRoughness;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Self::parse_words(text).map_err(|problem| BadRoughness { text: text.into(), problem })
    }
}

impl RoughnessSpec {
    fn parse_words(text: &str) -> Result<Self, RoughnessSyntax> {
        let t = text.trim();
        match t {
            "recipe" => return Ok(RoughnessSpec::Recipe),
            "smooth" => return Ok(RoughnessSpec::Smooth),
            _ => {}
        }
        let (kind, value) = t.split_once(':').ok_or(RoughnessSyntax::NoModel)?;
        if kind.trim().eq_ignore_ascii_case("measured") {
            let path = value.trim();
            if path.is_empty() {
                return Err(RoughnessSyntax::NoFile);
            }
            return Ok(RoughnessSpec::Measured(PathBuf::from(path)));
        }
        let model = RoughnessModel::from_name(kind)?;
        let alpha: f64 = value.trim().parse().map_err(|_| RoughnessSyntax::NotANumber(value.into()))?;
        Ok(RoughnessSpec::Analytic { model, alpha: check_alpha(alpha)? })
    }
}

impl std::fmt::Display for RoughnessSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RoughnessSpec::Recipe => f.write_str("recipe"),
            RoughnessSpec::Smooth => f.write_str("smooth"),
            RoughnessSpec::Analytic { model, alpha } => write!(f, "{}:{alpha}", <&str>::from(*model)),
            RoughnessSpec::Measured(path) => write!(f, "measured:{}", path.display()),
        }
    }
}

crate::text::serde_as_text!(RoughnessSpec);

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

    fn problem(text: &str) -> RoughnessSyntax {
        text.parse::<RoughnessSpec>().unwrap_err().problem
    }

    #[test]
    fn bad_text_says_what_is_wrong() {
        assert_eq!(problem("0.1"), RoughnessSyntax::NoModel);
        assert_eq!(problem("tr:x"), RoughnessSyntax::NotANumber("x".into()));
        assert_eq!(problem("tr:-1"), RoughnessSyntax::Alpha(-1.0));
        assert_eq!(problem("beckmann:4.01"), RoughnessSyntax::Alpha(4.01));
        assert!(matches!(problem("tr:NaN"), RoughnessSyntax::Alpha(a) if a.is_nan()));
        assert_eq!(problem("phong:1"), RoughnessSyntax::UnknownModel("phong".into()));
        assert_eq!(problem("measured: "), RoughnessSyntax::NoFile);
        let e = "tr:x".parse::<RoughnessSpec>().unwrap_err().to_string();
        assert_eq!(e, format!("\"tr:x\": \"x\" is not a number (expected {ROUGHNESS_WORDS})"));
    }

    #[test]
    fn the_text_round_trips_canonically_and_is_the_json() {
        for (text, canonical) in [
            ("smooth", "smooth"),
            ("recipe", "recipe"),
            ("tr:0.0084", "tr:0.0084"),
            (" GGX : 0.10 ", "tr:0.1"),
            ("trowbridge-reitz:4", "tr:4"),
            ("beckmann:0", "beckmann:0"),
            ("measured:surface/s1/fit.json", "measured:surface/s1/fit.json"),
        ] {
            let s: RoughnessSpec = text.parse().unwrap();
            assert_eq!(s.to_string(), canonical, "{text}");
            assert_eq!(canonical.parse::<RoughnessSpec>().unwrap(), s, "{text}");
            let json = serde_json::to_string(&s).unwrap();
            assert_eq!(json, format!("\"{canonical}\""));
            assert_eq!(serde_json::from_str::<RoughnessSpec>(&json).unwrap(), s);
        }
        let e = serde_json::from_str::<RoughnessSpec>("\"tr:9\"").unwrap_err().to_string();
        assert!(e.contains("[0, 4]") && e.contains("smooth"), "{e}");
    }
}
