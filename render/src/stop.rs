//! When a Monte Carlo run ends ([`Stop`]): the one stop rule of the slab
//! simulator ([`crate::slab`], whose samples are the light paths of a
//! slice) and of the path tracer ([`crate::tracer`], whose samples are the
//! samples per pixel of a render). Four conditions, each optional, the
//! first met ending the run:
//!
//! - a sample count (paths, or samples per pixel);
//! - a wall-time budget in seconds (the run stops after the round or pass
//!   that reaches it);
//! - a target relative standard error of the total (the slice sum; a
//!   fraction in (0, 1));
//! - a target median per-pixel relative standard error (a fraction in
//!   (0, 1); over the slice's bright pixels, or over the object's pixels of
//!   a render).
//!
//! An integrator that cannot honour a condition refuses it with
//! [`StopError::Unsupported`] ([`Stop::refuse_unsupported`]), never
//! ignores it. Only a sample count alone splits a run exactly into shards
//! ([`Stop::shard_samples`]): time and error targets depend on the whole
//! run.

use std::fmt;

/// When to stop; the first condition met ends the run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stop {
    /// Samples in all: light paths of a slab slice, samples per pixel of a
    /// render.
    pub samples: Option<u64>,
    /// Wall-time budget, seconds.
    pub time_s: Option<f64>,
    /// Target relative standard error of the total (the slice sum), a
    /// fraction.
    pub rel_error: Option<f64>,
    /// Target median per-pixel relative standard error, a fraction: over
    /// the pixels above [`PIXEL_MASK_FRACTION`](crate::slab::PIXEL_MASK_FRACTION)
    /// of the maximum of a slice, over the object's pixels of a render
    /// ([`RegionErrors::object`](crate::tracer::RegionErrors::object)).
    pub pixel_rel_error: Option<f64>,
}

/// One of a [`Stop`]'s four conditions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Condition {
    /// [`Stop::samples`].
    Samples,
    /// [`Stop::time_s`].
    Time,
    /// [`Stop::rel_error`].
    RelError,
    /// [`Stop::pixel_rel_error`].
    PixelRelError,
}

impl Condition {
    /// All four, in the order a run checks them.
    pub const ALL: [Condition; 4] =
        [Condition::Samples, Condition::Time, Condition::RelError, Condition::PixelRelError];

    /// The field's name ("samples", "time_s", "rel_error", "pixel_rel_error").
    pub fn key(self) -> &'static str {
        match self {
            Condition::Samples => "samples",
            Condition::Time => "time_s",
            Condition::RelError => "rel_error",
            Condition::PixelRelError => "pixel_rel_error",
        }
    }

    /// Whether it is an error target (of the total or per pixel).
    pub fn is_error_target(self) -> bool {
        matches!(self, Condition::RelError | Condition::PixelRelError)
    }
}

impl fmt::Display for Condition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Condition::Samples => "a sample count",
            Condition::Time => "a time budget",
            Condition::RelError => "a relative error target of the total",
            Condition::PixelRelError => "a median per-pixel error target",
        })
    }
}

/// A stop rule that cannot be used.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum StopError {
    #[error("the stop rule needs a sample count, a time budget or a target relative error")]
    Empty,
    #[error("{name} = {value} is invalid: {reason}")]
    Parameter { name: &'static str, value: f64, reason: &'static str },
    #[error("a sample count of {samples} is more than {integrator} can take (at most {max})")]
    TooManySamples { integrator: &'static str, samples: u64, max: u64 },
    #[error("{integrator} cannot stop on {condition} ({key})", key = condition.key())]
    Unsupported { integrator: &'static str, condition: Condition },
}

/// Why a stop rule does not split exactly into shards ([`Stop::shard_samples`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum NotSplittable {
    #[error("no sample count: only a fixed number of samples splits exactly")]
    NoSamples,
    #[error("{0} depends on the whole run and cannot be split exactly")]
    Beside(Condition),
}

/// Where a run stands after a round or pass, as [`Stop::met`] reads it;
/// `None` where a figure is not measured (yet), so no condition on it is met.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Standing {
    pub samples: Option<u64>,
    pub elapsed_s: f64,
    pub rel_error: Option<f64>,
    pub pixel_rel_error: Option<f64>,
}

impl Stop {
    /// Stop after `n` samples, nothing else.
    pub const fn samples(n: u64) -> Self {
        Self { samples: Some(n), time_s: None, rel_error: None, pixel_rel_error: None }
    }

    /// Whether no condition is set (the run would never end).
    pub fn is_empty(&self) -> bool {
        self.conditions().next().is_none()
    }

    /// Whether `c` is set.
    pub fn has(&self, c: Condition) -> bool {
        match c {
            Condition::Samples => self.samples.is_some(),
            Condition::Time => self.time_s.is_some(),
            Condition::RelError => self.rel_error.is_some(),
            Condition::PixelRelError => self.pixel_rel_error.is_some(),
        }
    }

    /// The conditions set, in [`Condition::ALL`]'s order.
    pub fn conditions(&self) -> impl Iterator<Item = Condition> + '_ {
        Condition::ALL.into_iter().filter(|&c| self.has(c))
    }

    /// Whether an error target (of the total or per pixel) is set.
    pub fn has_error_target(&self) -> bool {
        self.conditions().any(Condition::is_error_target)
    }

    /// Checks the rule: at least one condition ([`StopError::Empty`]), the
    /// error targets in (0, 1) and the time budget > 0 (finite;
    /// [`StopError::Parameter`]).
    pub fn check(&self) -> Result<(), StopError> {
        if self.is_empty() {
            return Err(StopError::Empty);
        }
        let check = |name, value: f64, ok: bool, reason| {
            if ok && value.is_finite() {
                Ok(())
            } else {
                Err(StopError::Parameter { name, value, reason })
            }
        };
        if let Some(e) = self.rel_error {
            check("rel_error", e, e > 0.0 && e < 1.0, "must lie in (0, 1)")?;
        }
        if let Some(e) = self.pixel_rel_error {
            check("pixel_rel_error", e, e > 0.0 && e < 1.0, "must lie in (0, 1)")?;
        }
        if let Some(t) = self.time_s {
            check("time_s", t, t > 0.0, "must be > 0")?;
        }
        Ok(())
    }

    /// [`StopError::Unsupported`] for the first condition set that
    /// `integrator` (named in the message) cannot honour, i.e. is not in
    /// `supported`.
    pub fn refuse_unsupported(&self, integrator: &'static str, supported: &[Condition]) -> Result<(), StopError> {
        match self.conditions().find(|c| !supported.contains(c)) {
            Some(condition) => Err(StopError::Unsupported { integrator, condition }),
            None => Ok(()),
        }
    }

    /// The sample count when the rule splits exactly into shards: a sample
    /// count and no other condition (a time budget or an error target
    /// depends on the whole run).
    ///
    /// ```
    /// use lucent_render::stop::{Condition, NotSplittable, Stop};
    /// assert_eq!(Stop::samples(64).shard_samples(), Ok(64));
    /// let timed = Stop { time_s: Some(9.0), ..Stop::samples(64) };
    /// assert_eq!(timed.shard_samples(), Err(NotSplittable::Beside(Condition::Time)));
    /// assert_eq!(Stop::default().shard_samples(), Err(NotSplittable::NoSamples));
    /// ```
    pub fn shard_samples(&self) -> Result<u64, NotSplittable> {
        let n = self.samples.ok_or(NotSplittable::NoSamples)?;
        match self.conditions().find(|&c| c != Condition::Samples) {
            Some(c) => Err(NotSplittable::Beside(c)),
            None => Ok(n),
        }
    }

    /// The first condition met at `s` ([`Condition::ALL`]'s order), `None`
    /// while the run goes on.
    pub fn met(&self, s: &Standing) -> Option<Condition> {
        let below = |target: Option<f64>, now: Option<f64>| target.zip(now).is_some_and(|(t, e)| e <= t);
        if self.samples.zip(s.samples).is_some_and(|(n, done)| done >= n) {
            Some(Condition::Samples)
        } else if self.time_s.is_some_and(|t| s.elapsed_s >= t) {
            Some(Condition::Time)
        } else if below(self.rel_error, s.rel_error) {
            Some(Condition::RelError)
        } else if below(self.pixel_rel_error, s.pixel_rel_error) {
            Some(Condition::PixelRelError)
        } else {
            None
        }
    }

    /// The rule in words for messages, with `unit` the samples' unit
    /// ("paths", "spp"): e.g. "up to 1024 spp, until the median error per
    /// pixel is 5.0 %, at most 60 s"; "no stop rule" when empty.
    ///
    /// ```
    /// use lucent_render::stop::Stop;
    /// assert_eq!(Stop::samples(8).describe("spp"), "8 spp");
    /// let s = Stop { rel_error: Some(0.01), time_s: Some(600.0), ..Stop::default() };
    /// assert_eq!(s.describe("paths"), "until the relative error of the total is 1.0 %, at most 600 s");
    /// ```
    pub fn describe(&self, unit: &str) -> String {
        let targets = self.has_error_target();
        let mut parts = Vec::new();
        if let Some(n) = self.samples {
            parts.push(if targets || self.time_s.is_some() {
                format!("up to {n} {unit}")
            } else {
                format!("{n} {unit}")
            });
        }
        if let Some(e) = self.rel_error {
            parts.push(format!("until the relative error of the total is {:.1} %", 100.0 * e));
        }
        if let Some(e) = self.pixel_rel_error {
            parts.push(format!("until the median error per pixel is {:.1} %", 100.0 * e));
        }
        if let Some(t) = self.time_s {
            parts.push(format!("at most {t} s"));
        }
        if parts.is_empty() {
            "no stop rule".into()
        } else {
            parts.join(", ")
        }
    }
}

impl fmt::Display for Stop {
    /// [`Stop::describe`] with the unit "samples".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.describe("samples"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_condition_met_ends_the_run() {
        let stop =
            Stop { time_s: Some(10.0), rel_error: Some(0.01), pixel_rel_error: Some(0.05), ..Stop::samples(100) };
        let at = |samples, elapsed_s, rel_error, pixel_rel_error| Standing {
            samples,
            elapsed_s,
            rel_error,
            pixel_rel_error,
        };
        assert_eq!(stop.met(&at(Some(50), 1.0, Some(0.5), Some(0.5))), None);
        assert_eq!(stop.met(&at(Some(100), 11.0, None, None)), Some(Condition::Samples));
        assert_eq!(stop.met(&at(None, 10.0, Some(0.001), None)), Some(Condition::Time));
        assert_eq!(stop.met(&at(None, 1.0, Some(0.01), Some(0.01))), Some(Condition::RelError));
        assert_eq!(stop.met(&at(None, 1.0, None, Some(0.05))), Some(Condition::PixelRelError));
        // A figure not measured yet (or NaN) meets nothing.
        assert_eq!(stop.met(&at(None, 1.0, Some(f64::NAN), None)), None);
        assert_eq!(Stop::default().met(&at(Some(u64::MAX), 1e9, Some(0.0), Some(0.0))), None);
    }

    #[test]
    fn checks_name_the_condition() {
        assert_eq!(Stop::default().check(), Err(StopError::Empty));
        assert!(Stop::samples(1).check().is_ok());
        for (stop, name) in [
            (Stop { rel_error: Some(1.0), ..Stop::default() }, "rel_error"),
            (Stop { pixel_rel_error: Some(0.0), ..Stop::default() }, "pixel_rel_error"),
            (Stop { time_s: Some(f64::INFINITY), ..Stop::default() }, "time_s"),
            (Stop { time_s: Some(-1.0), ..Stop::samples(8) }, "time_s"),
        ] {
            assert!(matches!(stop.check(), Err(StopError::Parameter { name: n, .. }) if n == name), "{stop:?}");
        }
        let timed = Stop { time_s: Some(5.0), ..Stop::samples(8) };
        assert_eq!(timed.refuse_unsupported("x", &[Condition::Samples, Condition::Time]), Ok(()));
        assert_eq!(
            timed.refuse_unsupported("x", &[Condition::Samples]),
            Err(StopError::Unsupported { integrator: "x", condition: Condition::Time })
        );
    }

    #[test]
    fn only_a_sample_count_alone_splits() {
        assert_eq!(Stop::samples(9).shard_samples(), Ok(9));
        let target = Stop { pixel_rel_error: Some(0.05), ..Stop::samples(9) };
        assert_eq!(target.shard_samples(), Err(NotSplittable::Beside(Condition::PixelRelError)));
        let both = Stop { time_s: Some(1.0), rel_error: Some(0.1), ..Stop::samples(9) };
        assert_eq!(both.shard_samples(), Err(NotSplittable::Beside(Condition::Time)));
        assert_eq!(Stop { time_s: Some(1.0), ..Stop::default() }.shard_samples(), Err(NotSplittable::NoSamples));
        assert!(target.has_error_target() && !Stop::samples(9).has_error_target());
        assert_eq!(target.describe("spp"), "up to 9 spp, until the median error per pixel is 5.0 %");
        assert_eq!(Stop::default().to_string(), "no stop rule");
    }
}
