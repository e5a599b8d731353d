//! Piecewise-linear keyframe tracks of 3-vectors, shared by pin paths and
//! wind profiles.

use crate::FieldError;
use crate::Vec3;

/// The value at time `t` of the track through `(times[k], values[k])`:
/// linear between keyframes, held before the first and after the last.
/// `times` must be non-empty and strictly increasing (see [`validate`]).
pub(crate) fn interpolate(times: &[f64], values: &[[f64; 3]], t: f64) -> Vec3 {
    let k = times.partition_point(|&tk| tk <= t);
    if k == 0 {
        return Vec3::from(values[0]);
    }
    if k == times.len() {
        return Vec3::from(values[k - 1]);
    }
    let a = (t - times[k - 1]) / (times[k] - times[k - 1]);
    Vec3::from(values[k - 1]) * (1.0 - a) + Vec3::from(values[k]) * a
}

/// The slope of the segment containing `t` (zero outside the keyframes).
pub(crate) fn slope(times: &[f64], values: &[[f64; 3]], t: f64) -> Vec3 {
    let k = times.partition_point(|&tk| tk <= t);
    if k == 0 || k == times.len() {
        return Vec3::zeros();
    }
    (Vec3::from(values[k]) - Vec3::from(values[k - 1])) / (times[k] - times[k - 1])
}

/// Checks a track; `values_field` names the values in errors.
pub(crate) fn validate(times: &[f64], values: &[[f64; 3]], values_field: &'static str) -> Result<(), FieldError> {
    if times.is_empty() || times.len() != values.len() {
        return Err(FieldError::new(
            values_field,
            format!("needs one value per time and at least one ({} times, {} values)", times.len(), values.len()),
        ));
    }
    if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] <= w[0]) {
        return Err(FieldError::new("times_s", "must be finite and strictly increasing"));
    }
    values.iter().try_for_each(|v| finite3(values_field, v))
}

/// Checks a frequency is finite and non-negative (Hz).
pub(crate) fn frequency(f: f64) -> Result<(), FieldError> {
    if f.is_finite() && f >= 0.0 {
        Ok(())
    } else {
        Err(FieldError::new("frequency_hz", format!("must be finite and >= 0, got {f}")))
    }
}

/// Checks every component of `v` is finite.
pub(crate) fn finite3(name: &'static str, v: &[f64; 3]) -> Result<(), FieldError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(FieldError::new(name, format!("must be finite, got {v:?}")))
    }
}
