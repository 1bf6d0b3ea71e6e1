//! Command-line flags that take one of a fixed set of words. A library type
//! that is such a set (its names derived once, by strum, in its own crate)
//! is read by [`named`]: its own `FromStr` (every spelling the library reads
//! works), its names listed in `--help` and in clap's error for a bad word
//! (exit 2). The sets that exist only on the command line are
//! [`clap::ValueEnum`]s here; spellings users typed before the switch to
//! clap are kept as aliases (case is ignored where it was before).

use crate::pipeline::Stage;
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::ValueEnum;
use std::ffi::OsStr;
use std::marker::PhantomData;
use std::str::FromStr;
use strum::{EnumMessage, VariantArray};

/// The value parser of a flag whose value is one of the names of `T`.
pub fn named<T>() -> Named<T> {
    Named(PhantomData)
}

/// See [`named`].
pub struct Named<T>(PhantomData<fn() -> T>);

impl<T> Clone for Named<T> {
    fn clone(&self) -> Self {
        Named(PhantomData)
    }
}

impl<T> TypedValueParser for Named<T>
where
    T: FromStr + VariantArray + EnumMessage + Copy + Send + Sync + 'static,
    &'static str: From<T>,
{
    type Value = T;

    fn parse_ref(&self, cmd: &clap::Command, arg: Option<&clap::Arg>, value: &OsStr) -> Result<T, clap::Error> {
        if let Some(v) = value.to_str().and_then(|s| s.parse::<T>().ok()) {
            return Ok(v);
        }
        // Not a spelling of T: clap's own refusal of a word outside the list.
        let names = T::VARIANTS.iter().map(|&v| <&'static str>::from(v));
        match PossibleValuesParser::new(names).parse_ref(cmd, arg, value) {
            Err(e) => Err(e),
            Ok(_) => Err(clap::Error::new(clap::error::ErrorKind::InvalidValue).with_cmd(cmd)),
        }
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(T::VARIANTS.iter().map(|&v| {
            let value = PossibleValue::new(<&'static str>::from(v));
            match v.get_documentation().and_then(|d| d.lines().next()) {
                Some(line) => value.help(line.trim().to_string()),
                None => value,
            }
        })))
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

/// `compare --refine`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RefineChoice {
    /// OpenCV findTransformECC.
    Ecc,
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

/// A pipeline stage by its name ([`Stage::name`], also its folder), for
/// `run --until`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StageChoice(pub Stage);

const STAGE_CHOICES: [StageChoice; 12] = [
    StageChoice(Stage::Optics),
    StageChoice(Stage::Surface),
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

const FORCE_CHOICES: [ForceChoice; 13] = [
    ForceChoice(None),
    ForceChoice(Some(Stage::Optics)),
    ForceChoice(Some(Stage::Surface)),
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

    /// Every spelling a library type reads (its name and its other
    /// serializations) is accepted through [`named`], any other word is
    /// refused as clap refuses a value outside a list, and the list offered
    /// is the type's names in order.
    #[test]
    fn named_reads_every_spelling_and_lists_the_names() {
        fn check<T>(names: &[&str])
        where
            T: FromStr + VariantArray + EnumMessage + Copy + Send + Sync + PartialEq + std::fmt::Debug + 'static,
            &'static str: From<T>,
        {
            let cmd = clap::Command::new("t");
            let parser = named::<T>();
            let offered: Vec<String> = parser.possible_values().unwrap().map(|v| v.get_name().to_string()).collect();
            assert_eq!(offered, names);
            for &v in T::VARIANTS {
                for s in v.get_serializations() {
                    for text in [s.to_string(), s.to_ascii_uppercase()] {
                        assert_eq!(parser.parse_ref(&cmd, None, OsStr::new(&text)).unwrap(), v, "{text}");
                    }
                }
            }
            let e = parser.parse_ref(&cmd, None, OsStr::new("nope")).unwrap_err();
            assert_eq!(e.kind(), clap::error::ErrorKind::InvalidValue);
        }
        check::<lucent_calib::demosaic::Demosaic>(&["malvar", "bilinear"]);
        check::<lucent_calib::raw::WhiteBalance>(&["none", "camera"]);
        check::<lucent_calib::camera::DistortionModel>(&["pinhole-k3", "rational", "fisheye"]);
        check::<lucent_calib::cv::Detector>(&["auto", "sector-based", "classic"]);
        check::<lucent_calib::ecc::Motion>(&["translation", "euclidean", "affine", "homography"]);
        check::<lucent_calib::hdr::ResponseMethod>(&["debevec", "robertson"]);
        check::<lucent_colour::ccm::CcmMethod>(&["Cheung 2004", "Finlayson 2015", "Finlayson 1997"]);
        check::<crate::compare::Luminance>(&["cie-rgb", "rec709"]);
        check::<crate::surface::grid::LengthUnit>(&["m", "mm", "um", "nm"]);
        check::<crate::surface::model::RoughnessModel>(&["tr", "beckmann"]);
        check::<crate::surface::x3p::PointType>(&["I", "L", "F", "D"]);
        check::<crate::synth::InputSpace>(&["cie-rgb", "xyz-d50"]);
    }
}
