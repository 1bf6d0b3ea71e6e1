//! The simulator's input errors ([`SlabError`], one variant per kind of
//! invalid input) and the one check the numeric parameters go through.

use crate::medium::MediumError;
use crate::stop::StopError;

/// Invalid simulator input.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SlabError {
    #[error("{name} = {value} is invalid: {reason}")]
    Parameter { name: &'static str, value: f64, reason: &'static str },
    #[error("beam map: {values} values do not fill {width} × {height} pixels")]
    BeamMapSize { values: usize, width: usize, height: usize },
    #[error("beam map: pixel ({column}, {row}) is not a finite number")]
    BeamMapNotFinite { column: usize, row: usize },
    #[error("beam map: pixel ({column}, {row}) is negative")]
    BeamMapNegative { column: usize, row: usize },
    #[error("beam map: all pixels are zero")]
    BeamMapAllZero,
    /// A stop rule that is empty, out of range or asks what the run cannot honour.
    #[error(transparent)]
    Stop(#[from] StopError),
    #[error("the ring connection needs exactly one of θ_i, θ_o to be 0°, a slab at least 40 optical depths thick along the exit direction and a smooth top")]
    RingNotApplicable,
    #[error(
        "the lobe connection needs a slab at least 40 optical depths thick along the exit direction (through a rough top: 40 optical depths thick)"
    )]
    LobeNotApplicable,
}

/// `value` if `ok` and finite, else [`SlabError::Parameter`] with `name`
/// and `reason`.
pub(super) fn check(name: &'static str, value: f64, ok: bool, reason: &'static str) -> Result<f64, SlabError> {
    if ok && value.is_finite() {
        Ok(value)
    } else {
        Err(SlabError::Parameter { name, value, reason })
    }
}

impl From<MediumError> for SlabError {
    fn from(e: MediumError) -> Self {
        SlabError::Parameter { name: e.name, value: e.value, reason: e.reason }
    }
}
