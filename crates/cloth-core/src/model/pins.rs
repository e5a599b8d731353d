//! Pinned particles: fixed, or following a prescribed path.
//!
//! A pin prescribes the particle's position `x(t) = x_0 + offset(t)`. In the
//! implicit step it becomes a fully constrained Baraff-Witkin filter entry,
//! so pinned particles move exactly along their path.

use crate::FieldError;
use crate::Vec3;
use crate::keyframes::{self, finite3};
use serde::{Deserialize, Serialize};

/// The path a pinned particle follows, as an offset from its initial position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum PinMotion {
    /// Stays where it started.
    Fixed,
    /// Moves at a constant velocity, m/s.
    Linear {
        /// Velocity, m/s.
        velocity_m_s: [f64; 3],
    },
    /// `offset = amplitude sin(2 pi f t)`.
    Oscillate {
        /// Peak offset, m.
        amplitude_m: [f64; 3],
        /// Frequency, Hz.
        frequency_hz: f64,
    },
    /// Piecewise-linear offsets through keyframes; held constant outside them.
    Keyframes {
        /// Strictly increasing times, s.
        times_s: Vec<f64>,
        /// Offset at each time, m.
        offsets_m: Vec<[f64; 3]>,
    },
    /// Driven from outside, step by step ([`crate::Control`]): stays where
    /// it is until a target or motion is set.
    External,
}

impl PinMotion {
    /// Offset from the initial position at time `t` (s), m.
    pub fn offset(&self, t: f64) -> Vec3 {
        match self {
            PinMotion::Fixed | PinMotion::External => Vec3::zeros(),
            PinMotion::Linear { velocity_m_s } => Vec3::from(*velocity_m_s) * t,
            PinMotion::Oscillate { amplitude_m, frequency_hz } => {
                Vec3::from(*amplitude_m) * (2.0 * std::f64::consts::PI * frequency_hz * t).sin()
            }
            PinMotion::Keyframes { times_s, offsets_m } => keyframes::interpolate(times_s, offsets_m, t),
        }
    }

    /// Velocity along the path at time `t` (s), m/s (for keyframes, the
    /// slope of the segment containing `t`; zero outside the keyframes).
    pub fn velocity(&self, t: f64) -> Vec3 {
        match self {
            PinMotion::Fixed | PinMotion::External => Vec3::zeros(),
            PinMotion::Linear { velocity_m_s } => Vec3::from(*velocity_m_s),
            PinMotion::Oscillate { amplitude_m, frequency_hz } => {
                let w = 2.0 * std::f64::consts::PI * frequency_hz;
                Vec3::from(*amplitude_m) * (w * (w * t).cos())
            }
            PinMotion::Keyframes { times_s, offsets_m } => keyframes::slope(times_s, offsets_m, t),
        }
    }

    /// Checks the motion's numbers; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
        match self {
            PinMotion::Fixed | PinMotion::External => Ok(()),
            PinMotion::Linear { velocity_m_s } => finite3("velocity_m_s", velocity_m_s),
            PinMotion::Oscillate { amplitude_m, frequency_hz } => {
                finite3("amplitude_m", amplitude_m)?;
                keyframes::frequency(*frequency_hz)
            }
            PinMotion::Keyframes { times_s, offsets_m } => keyframes::validate(times_s, offsets_m, "offsets_m"),
        }
    }
}

/// One pinned particle of a built model.
#[derive(Debug, Clone, PartialEq)]
pub struct Pin {
    /// Global particle index.
    pub particle: usize,
    /// Initial position, m.
    pub anchor: Vec3,
    /// Path relative to `anchor`.
    pub motion: PinMotion,
    /// Index of the [`crate::PinSpec`] (`[[pins]]` entry) that made it.
    pub spec: usize,
}

impl Pin {
    /// Prescribed position at time `t`, m.
    pub fn position(&self, t: f64) -> Vec3 {
        self.anchor + self.motion.offset(t)
    }

    /// Prescribed velocity at time `t`, m/s.
    pub fn velocity(&self, t: f64) -> Vec3 {
        self.motion.velocity(t)
    }

    /// Whether the pin is driven from outside ([`crate::Control::set_pin_target`]).
    pub fn is_external(&self) -> bool {
        self.motion == PinMotion::External
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keyframes_interpolate_and_hold() {
        let m = PinMotion::Keyframes { times_s: vec![1.0, 2.0], offsets_m: vec![[0.0; 3], [0.0, 0.0, 1.0]] };
        assert_eq!(m.offset(0.0), Vec3::zeros());
        assert!((m.offset(1.25).z - 0.25).abs() < 1e-15);
        assert_eq!(m.offset(5.0), Vec3::new(0.0, 0.0, 1.0));
        let bad = PinMotion::Keyframes { times_s: vec![1.0, 1.0], offsets_m: vec![[0.0; 3]; 2] };
        assert_eq!(bad.validate().unwrap_err().path, "times_s");
    }

    #[test]
    fn velocities_are_derivatives_of_offsets() {
        let motions = [
            PinMotion::Linear { velocity_m_s: [0.1, -0.2, 0.3] },
            PinMotion::Oscillate { amplitude_m: [0.0, 0.05, 0.01], frequency_hz: 1.5 },
            PinMotion::Keyframes {
                times_s: vec![0.0, 1.0, 3.0],
                offsets_m: vec![[0.0; 3], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]],
            },
        ];
        for m in motions {
            for t in [0.3, 0.71, 2.2] {
                let h = 1e-6;
                let fd = (m.offset(t + h) - m.offset(t - h)) / (2.0 * h);
                assert!((fd - m.velocity(t)).norm() < 1e-6, "{m:?} at {t}");
            }
        }
    }
}
