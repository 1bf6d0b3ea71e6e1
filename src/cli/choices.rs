//! Command-line flags that take one of a fixed set of words, as
//! [`clap::ValueEnum`]s: clap lists the choices in `--help` and in its error
//! for a bad word (exit 2). The library crates (calib, colour, render) and
//! the library modules of this crate do not depend on clap; each choice here
//! converts into the library's own type. Spellings users typed before the
//! switch to clap are kept as aliases (case is ignored where it was before).

use crate::optics::recipe::RoughnessModel;
use crate::pipeline::Stage;
use clap::builder::PossibleValue;
use clap::ValueEnum;

/// The name a choice is given by on the command line (its first spelling).
pub fn name<T: ValueEnum>(choice: &T) -> String {
    choice.to_possible_value().map(|v| v.get_name().to_string()).unwrap_or_default()
}

/// `raw decode --demosaic`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DemosaicChoice {
    /// Malvar, He & Cutler (2004), gradient-corrected bilinear.
    #[value(alias = "mhc", alias = "malvar-he-cutler", alias = "malvar2004")]
    Malvar,
    /// Mean of the nearest same-colour neighbours.
    #[value(alias = "linear")]
    Bilinear,
}

impl From<DemosaicChoice> for lucent_calib::demosaic::Demosaic {
    fn from(c: DemosaicChoice) -> Self {
        match c {
            DemosaicChoice::Malvar => Self::MalvarHeCutler2004,
            DemosaicChoice::Bilinear => Self::Bilinear,
        }
    }
}

/// `raw decode --white-balance`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WhiteBalanceChoice {
    /// Camera RGB as recorded.
    None,
    /// The as-shot multipliers, green = 1.
    #[value(alias = "as-shot")]
    Camera,
}

impl From<WhiteBalanceChoice> for lucent_calib::raw::WhiteBalance {
    fn from(c: WhiteBalanceChoice) -> Self {
        match c {
            WhiteBalanceChoice::None => Self::None,
            WhiteBalanceChoice::Camera => Self::Camera,
        }
    }
}

/// `calibrate --model`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DistortionChoice {
    /// k1 k2 p1 p2 k3.
    #[value(alias = "k3", alias = "brown-conrady")]
    PinholeK3,
    /// k1..k6 p1 p2 (OpenCV's rational model), for wide lenses.
    Rational,
    /// Kannala–Brandt k1..k4 (OpenCV's fisheye module).
    #[value(alias = "kannala-brandt")]
    Fisheye,
}

impl From<DistortionChoice> for lucent_calib::camera::DistortionModel {
    fn from(c: DistortionChoice) -> Self {
        match c {
            DistortionChoice::PinholeK3 => Self::PinholeK3,
            DistortionChoice::Rational => Self::Rational,
            DistortionChoice::Fisheye => Self::Fisheye,
        }
    }
}

/// `calibrate --detector`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DetectorChoice {
    /// Sector-based, else classic + cornerSubPix.
    Auto,
    /// findChessboardCornersSB only.
    #[value(alias = "sb")]
    SectorBased,
    /// findChessboardCorners + cornerSubPix only.
    Classic,
}

impl From<DetectorChoice> for lucent_calib::cv::Detector {
    fn from(c: DetectorChoice) -> Self {
        match c {
            DetectorChoice::Auto => Self::Auto,
            DetectorChoice::SectorBased => Self::SectorBased,
            DetectorChoice::Classic => Self::Classic,
        }
    }
}

/// `undistort --to`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ProjectionChoice {
    /// The photo's size, a distortion-free camera.
    Pinhole,
    /// A 2:1 latitude–longitude map of the sphere around the lens.
    #[value(alias = "equirectangular")]
    Equirect,
}

/// `compare --luminance`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LuminanceChoice {
    /// 0.1769, 0.8124, 0.0107 (Y row of CIE 1931 RGB → XYZ).
    #[value(alias = "cie")]
    CieRgb,
    /// 0.2126, 0.7152, 0.0722 (Y row of linear sRGB / Rec. 709 → XYZ).
    #[value(alias = "srgb")]
    Rec709,
}

impl From<LuminanceChoice> for crate::compare::Luminance {
    fn from(c: LuminanceChoice) -> Self {
        match c {
            LuminanceChoice::CieRgb => Self::CieRgb,
            LuminanceChoice::Rec709 => Self::Rec709,
        }
    }
}

/// `compare --refine`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RefineChoice {
    /// OpenCV findTransformECC.
    Ecc,
}

/// `compare --refine-motion`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MotionChoice {
    /// Shift (2 parameters).
    Translation,
    /// Rotation and translation (3).
    Euclidean,
    /// 2 × 3 affine matrix (6).
    Affine,
    /// 3 × 3 homography (8).
    Homography,
}

impl From<MotionChoice> for lucent_calib::ecc::Motion {
    fn from(c: MotionChoice) -> Self {
        match c {
            MotionChoice::Translation => Self::Translation,
            MotionChoice::Euclidean => Self::Euclidean,
            MotionChoice::Affine => Self::Affine,
            MotionChoice::Homography => Self::Homography,
        }
    }
}

/// `env merge --method`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ResponseChoice {
    /// Debevec & Malik 1997.
    #[value(alias = "debevec-malik")]
    Debevec,
    /// Robertson, Borman & Stevenson 2003.
    Robertson,
}

impl From<ResponseChoice> for lucent_calib::hdr::ResponseMethod {
    fn from(c: ResponseChoice) -> Self {
        match c {
            ResponseChoice::Debevec => Self::Debevec,
            ResponseChoice::Robertson => Self::Robertson,
        }
    }
}

/// `colour calibrate --method`. The names as written in ccm.json; the
/// spellings without the space (`cheung-2004`, `cheung2004`) also work.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CcmMethodChoice {
    /// 3 × 3 linear least squares.
    #[value(name = "Cheung 2004", alias = "cheung-2004", alias = "cheung2004", alias = "cheung_2004")]
    Cheung2004,
    /// Root-polynomial (degree 2), exposure invariant, 3 × 6.
    #[value(name = "Finlayson 2015", alias = "finlayson-2015", alias = "finlayson2015", alias = "finlayson_2015")]
    Finlayson2015,
    /// 3 × 3 white-point preserving least squares.
    #[value(name = "Finlayson 1997", alias = "finlayson-1997", alias = "finlayson1997", alias = "finlayson_1997")]
    Finlayson1997,
}

impl From<CcmMethodChoice> for lucent_colour::ccm::CcmMethod {
    fn from(c: CcmMethodChoice) -> Self {
        match c {
            CcmMethodChoice::Cheung2004 => Self::Cheung2004,
            CcmMethodChoice::Finlayson2015 => Self::Finlayson2015,
            CcmMethodChoice::Finlayson1997 => Self::Finlayson1997,
        }
    }
}

/// `colour apply --to`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TargetChoice {
    /// CIE 1931 RGB, white E.
    #[value(alias = "ciergb", alias = "cie1931rgb", alias = "cie-1931-rgb")]
    CieRgb,
    /// CIE XYZ, D50-adapted as fitted.
    Xyz,
    /// Linear sRGB, D65.
    #[value(alias = "rec709", alias = "linear-srgb")]
    Srgb,
}

/// `colour apply --adaptation`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AdaptationChoice {
    Bradford,
    #[value(alias = "von kries", alias = "vonkries", alias = "von_kries")]
    VonKries,
    Cat02,
    /// No chromatic adaptation.
    None,
}

impl AdaptationChoice {
    /// The transform, `None` for no adaptation.
    pub fn cat(self) -> Option<lucent_colour::adaptation::Cat> {
        use lucent_colour::adaptation::Cat;
        match self {
            AdaptationChoice::Bradford => Some(Cat::Bradford),
            AdaptationChoice::VonKries => Some(Cat::VonKries),
            AdaptationChoice::Cat02 => Some(Cat::Cat02),
            AdaptationChoice::None => None,
        }
    }
}

/// `surface fit --height-unit`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LengthUnitChoice {
    M,
    Mm,
    #[value(alias = "µm", alias = "μm", alias = "micron", alias = "microns")]
    Um,
    Nm,
}

impl From<LengthUnitChoice> for crate::surface::grid::LengthUnit {
    fn from(c: LengthUnitChoice) -> Self {
        match c {
            LengthUnitChoice::M => Self::M,
            LengthUnitChoice::Mm => Self::Mm,
            LengthUnitChoice::Um => Self::Um,
            LengthUnitChoice::Nm => Self::Nm,
        }
    }
}

/// `surface synth --model`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RoughnessChoice {
    /// Trowbridge–Reitz (GGX).
    #[value(alias = "ggx", alias = "trowbridge-reitz")]
    Tr,
    Beckmann,
}

impl From<RoughnessChoice> for RoughnessModel {
    fn from(c: RoughnessChoice) -> Self {
        match c {
            RoughnessChoice::Tr => Self::TrowbridgeReitz,
            RoughnessChoice::Beckmann => Self::Beckmann,
        }
    }
}

/// `surface synth --point-type` (X3P's letters).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PointTypeChoice {
    /// int16.
    #[value(name = "I")]
    I,
    /// int32.
    #[value(name = "L")]
    L,
    /// float32.
    #[value(name = "F")]
    F,
    /// float64.
    #[value(name = "D")]
    D,
}

impl From<PointTypeChoice> for crate::surface::x3p::PointType {
    fn from(c: PointTypeChoice) -> Self {
        match c {
            PointTypeChoice::I => Self::I,
            PointTypeChoice::L => Self::L,
            PointTypeChoice::F => Self::F,
            PointTypeChoice::D => Self::D,
        }
    }
}

/// `synth capture --space`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InputSpaceChoice {
    /// CIE 1931 RGB, white E (a render).
    CieRgb,
    /// CIE XYZ under D50 (`synth chart`).
    #[value(alias = "xyz")]
    XyzD50,
}

impl From<InputSpaceChoice> for crate::synth::InputSpace {
    fn from(c: InputSpaceChoice) -> Self {
        match c {
            InputSpaceChoice::CieRgb => Self::CieRgb,
            InputSpaceChoice::XyzD50 => Self::XyzD50,
        }
    }
}

/// A pipeline stage by its name ([`Stage::name`], also its folder), for
/// `run --until`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StageChoice(pub Stage);

const STAGE_CHOICES: [StageChoice; 11] = [
    StageChoice(Stage::Optics),
    StageChoice(Stage::Bssrdf),
    StageChoice(Stage::Fit),
    StageChoice(Stage::Calibrate),
    StageChoice(Stage::Colour),
    StageChoice(Stage::Develop),
    StageChoice(Stage::Pose),
    StageChoice(Stage::EnvScale),
    StageChoice(Stage::Render),
    StageChoice(Stage::Compare),
    StageChoice(Stage::Report),
];

impl ValueEnum for StageChoice {
    fn value_variants<'a>() -> &'a [Self] {
        &STAGE_CHOICES
    }
    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()))
    }
}

/// A stage or `all`, for `run --force`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ForceChoice(pub Option<Stage>);

const FORCE_CHOICES: [ForceChoice; 12] = [
    ForceChoice(None),
    ForceChoice(Some(Stage::Optics)),
    ForceChoice(Some(Stage::Bssrdf)),
    ForceChoice(Some(Stage::Fit)),
    ForceChoice(Some(Stage::Calibrate)),
    ForceChoice(Some(Stage::Colour)),
    ForceChoice(Some(Stage::Develop)),
    ForceChoice(Some(Stage::Pose)),
    ForceChoice(Some(Stage::EnvScale)),
    ForceChoice(Some(Stage::Render)),
    ForceChoice(Some(Stage::Compare)),
    ForceChoice(Some(Stage::Report)),
];

impl ValueEnum for ForceChoice {
    fn value_variants<'a>() -> &'a [Self] {
        &FORCE_CHOICES
    }
    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(match self.0 {
            None => PossibleValue::new("all").help("every stage"),
            Some(s) => PossibleValue::new(s.name()),
        })
    }
}

impl ForceChoice {
    /// The stages this choice names.
    pub fn stages(self) -> Vec<Stage> {
        match self.0 {
            None => Stage::ALL.to_vec(),
            Some(s) => vec![s],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stage is offered, under the name its folder has.
    #[test]
    fn stage_choices_cover_every_stage_once() {
        let names: Vec<&str> = STAGE_CHOICES.iter().map(|c| c.0.name()).collect();
        let expected: Vec<&str> = Stage::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(names, expected);
        assert_eq!(FORCE_CHOICES.len(), Stage::ALL.len() + 1);
        for (c, s) in FORCE_CHOICES[1..].iter().zip(Stage::ALL) {
            assert_eq!(c.0, Some(s));
        }
    }

    /// The calib/colour names the library parsers accept map to the same
    /// values through clap (the choices are a second spelling list, so this
    /// keeps them in step).
    #[test]
    fn choices_agree_with_the_library_parsers() {
        use lucent_calib::{camera::DistortionModel, demosaic::Demosaic, ecc::Motion, hdr::ResponseMethod};
        for c in DemosaicChoice::value_variants() {
            let name = c.to_possible_value().unwrap();
            assert_eq!(Demosaic::from_name(name.get_name()).unwrap(), Demosaic::from(*c));
        }
        for c in DistortionChoice::value_variants() {
            let name = c.to_possible_value().unwrap();
            assert_eq!(DistortionModel::from_name(name.get_name()).unwrap(), DistortionModel::from(*c));
        }
        for c in MotionChoice::value_variants() {
            let name = c.to_possible_value().unwrap();
            assert_eq!(Motion::from_name(name.get_name()).unwrap(), Motion::from(*c));
        }
        for c in ResponseChoice::value_variants() {
            let name = c.to_possible_value().unwrap();
            assert_eq!(ResponseMethod::from_name(name.get_name()).unwrap(), ResponseMethod::from(*c));
        }
        for c in CcmMethodChoice::value_variants() {
            let name = c.to_possible_value().unwrap();
            let m: lucent_colour::ccm::CcmMethod = name.get_name().parse().unwrap();
            assert_eq!(m, (*c).into());
        }
    }
}
