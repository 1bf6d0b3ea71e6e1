//! What every job's fields share: the range checks and their error
//! ([`JobError`], naming the field as its flag and project key), the
//! command line a job writes back ([`Line`]) and the serde of a field a
//! command line names by a word ([`by_name`], [`by_name_opt`]).

use crate::bssrdf::paths_problem;
use lucent_calib::board::BoardSize;
use std::path::Path;
use thiserror::Error;

/// A job field out of range: which field (its snake-case name, the flag
/// `--field-name`, the project key `field_name`) and why.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("--{} {value}: {reason}", flag_name(field))]
pub struct JobError {
    pub field: &'static str,
    pub value: String,
    pub reason: String,
}

/// `pixel_mm` → `pixel-mm`.
pub fn flag_name(field: &str) -> String {
    field.replace('_', "-")
}

pub(super) fn bad(field: &'static str, value: impl ToString, reason: impl Into<String>) -> JobError {
    JobError { field, value: value.to_string(), reason: reason.into() }
}

/// A chessboard of squares of `square_mm` (the board's corners are checked
/// by its type).
pub(super) fn board(board: BoardSize, square_mm: f64) -> Result<lucent_calib::board::BoardSpec, JobError> {
    lucent_calib::board::BoardSpec::new(board, square_mm).map_err(|e| bad("square_mm", square_mm, e.to_string()))
}

/// A finite number > 0.
pub fn positive(field: &'static str, v: f64) -> Result<(), JobError> {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err(bad(field, v, "must be finite and > 0"))
    }
}

pub(super) fn positive_opt(field: &'static str, v: Option<f64>) -> Result<(), JobError> {
    v.map_or(Ok(()), |v| positive(field, v))
}

/// A weight percentage in (0, 100).
pub fn weight_percent(v: Option<f64>) -> Result<(), JobError> {
    match v {
        Some(w) if !(w > 0.0 && w < 100.0) => Err(bad("weight_percent", w, "must lie in (0, 100)")),
        _ => Ok(()),
    }
}

/// A fraction of a maximum in [0, 1).
pub fn threshold(v: f64) -> Result<(), JobError> {
    if (0.0..1.0).contains(&v) {
        Ok(())
    } else {
        Err(bad("threshold", v, "must lie in [0, 1) (a fraction of the maximum)"))
    }
}

pub(super) fn at_least_one<T: PartialEq + From<u8> + ToString>(
    field: &'static str,
    v: Option<T>,
) -> Result<(), JobError> {
    match v {
        Some(n) if n == T::from(0) => Err(bad(field, n, "must be at least 1")),
        _ => Ok(()),
    }
}

/// The most pixels per side of a BSSRDF slice.
pub const MAX_SLICE_PIXELS: usize = 8192;

pub(super) fn paths(v: Option<u64>) -> Result<(), JobError> {
    match v.and_then(|n| paths_problem(n).map(|r| (n, r))) {
        Some((n, reason)) => Err(bad("paths", n, reason)),
        None => Ok(()),
    }
}

pub(super) fn s(p: &Path) -> String {
    p.display().to_string()
}

/// A field of a type the command line names by its `name()` (a word its
/// `FromStr` reads back), serialised as that word.
pub(super) mod by_name {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer, T: Copy + Into<&'static str>>(v: &T, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str((*v).into())
    }

    pub fn deserialize<'de, D, T>(d: D) -> Result<T, D::Error>
    where
        D: Deserializer<'de>,
        T: std::str::FromStr,
        T::Err: std::fmt::Display,
    {
        let text = String::deserialize(d)?;
        text.parse().map_err(|e| serde::de::Error::custom(format!("{text:?}: {e}")))
    }
}

/// An optional [`by_name`] field (`null` when absent).
pub(super) mod by_name_opt {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer, T: Copy + Into<&'static str>>(v: &Option<T>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => s.serialize_str((*v).into()),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
    where
        D: Deserializer<'de>,
        T: std::str::FromStr,
        T::Err: std::fmt::Display,
    {
        match Option::<String>::deserialize(d)? {
            Some(text) => text.parse().map(Some).map_err(|e| serde::de::Error::custom(format!("{text:?}: {e}"))),
            None => Ok(None),
        }
    }
}

/// A command line under construction.
#[derive(Default)]
pub(super) struct Line(pub(super) Vec<String>);

impl Line {
    pub(super) fn new(words: &[&str]) -> Self {
        Line(words.iter().map(|w| w.to_string()).collect())
    }
    pub(super) fn word(&mut self, w: impl ToString) -> &mut Self {
        self.0.push(w.to_string());
        self
    }
    pub(super) fn words<T: ToString>(&mut self, ws: impl IntoIterator<Item = T>) -> &mut Self {
        self.0.extend(ws.into_iter().map(|w| w.to_string()));
        self
    }
    pub(super) fn flag(&mut self, f: &str, v: impl ToString) -> &mut Self {
        self.0.extend([f.to_string(), v.to_string()]);
        self
    }
    pub(super) fn opt<T: ToString>(&mut self, f: &str, v: &Option<T>) -> &mut Self {
        if let Some(v) = v {
            self.flag(f, v.to_string());
        }
        self
    }
    pub(super) fn switch(&mut self, f: &str, on: bool) -> &mut Self {
        if on {
            self.0.push(f.to_string());
        }
        self
    }
}
