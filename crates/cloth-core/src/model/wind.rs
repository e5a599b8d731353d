//! Wind: a time-varying air velocity and two force models, each a scene
//! effect of its own: Provot's (1995) viscous fluid force on particles
//! (`wind`) and aerodynamic drag and lift on triangles (`aerodynamics`).
//!
//! The laws are in [`crate::aero_laws`]; the force terms that apply them
//! are [`crate::terms::Fluid`] and [`crate::terms::Aerodynamics`]. In implicit
//! steps the wind force is taken at the start of the step (explicitly);
//! its velocity dependence is mild next to the cloth's stiffness.

use crate::FieldError;
use crate::Vec3;
use crate::keyframes::{self, finite3};
use serde::{Deserialize, Serialize};

/// How the wind velocity varies in time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum WindProfile {
    /// A steady wind, m/s.
    Constant {
        /// Velocity, m/s.
        velocity_m_s: [f64; 3],
    },
    /// Gusts: `mean + amplitude sin(2 pi f t)`, m/s.
    Gust {
        /// Mean velocity, m/s.
        mean_m_s: [f64; 3],
        /// Gust amplitude, m/s.
        amplitude_m_s: [f64; 3],
        /// Gust frequency, Hz.
        frequency_hz: f64,
    },
    /// Piecewise-linear velocities through keyframes, held outside them.
    Keyframes {
        /// Strictly increasing times, s.
        times_s: Vec<f64>,
        /// Velocity at each time, m/s.
        velocities_m_s: Vec<[f64; 3]>,
    },
    /// Set from outside before each step ([`crate::Control::set_wind`],
    /// a co-simulation input), constant over the step; still air until set.
    External,
}

impl WindProfile {
    /// Air velocity at time `t` (s), m/s; `set` is the externally set
    /// velocity, used by [`WindProfile::External`] (still air without one).
    pub fn velocity(&self, t: f64, set: Option<Vec3>) -> Vec3 {
        match self {
            WindProfile::External => set.unwrap_or_else(Vec3::zeros),
            WindProfile::Constant { velocity_m_s } => Vec3::from(*velocity_m_s),
            WindProfile::Gust { mean_m_s, amplitude_m_s, frequency_hz } => {
                Vec3::from(*mean_m_s)
                    + Vec3::from(*amplitude_m_s) * (2.0 * std::f64::consts::PI * frequency_hz * t).sin()
            }
            WindProfile::Keyframes { times_s, velocities_m_s } => keyframes::interpolate(times_s, velocities_m_s, t),
        }
    }

    /// Checks the numbers; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
        match self {
            WindProfile::Constant { velocity_m_s } => finite3("velocity_m_s", velocity_m_s),
            WindProfile::Gust { mean_m_s, amplitude_m_s, frequency_hz } => {
                finite3("mean_m_s", mean_m_s)?;
                finite3("amplitude_m_s", amplitude_m_s)?;
                keyframes::frequency(*frequency_hz)
            }
            WindProfile::Keyframes { times_s, velocities_m_s } => {
                keyframes::validate(times_s, velocities_m_s, "velocities_m_s")
            }
            WindProfile::External => Ok(()),
        }
    }
}

/// The `[wind]` section: the air's motion and the force coefficients.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wind {
    /// Air velocity over time.
    pub profile: WindProfile,
    /// Provot's viscous fluid coefficient per unit area, N s/m^3 (`wind` effect).
    #[serde(default = "default_fluid")]
    pub fluid_coefficient_n_s_m3: f64,
    /// Air density, kg/m^3 (`aerodynamics` effect). Default 1.2.
    #[serde(default = "default_air")]
    pub air_density_kg_m3: f64,
    /// Drag coefficient of a triangle (`aerodynamics`). Default 1.0.
    #[serde(default = "default_drag")]
    pub drag_coefficient: f64,
    /// Lift coefficient of a triangle (`aerodynamics`). Default 0.5.
    #[serde(default = "default_lift")]
    pub lift_coefficient: f64,
}

impl Wind {
    /// Air moving as `profile`, with the default coefficients: Provot's
    /// fluid coefficient 0.5 N s/m^3, air 1.2 kg/m^3, drag 1.0, lift 0.5.
    pub fn new(profile: WindProfile) -> Self {
        Self {
            profile,
            fluid_coefficient_n_s_m3: default_fluid(),
            air_density_kg_m3: default_air(),
            drag_coefficient: default_drag(),
            lift_coefficient: default_lift(),
        }
    }
}

fn default_fluid() -> f64 {
    0.5
}
fn default_air() -> f64 {
    1.2
}
fn default_drag() -> f64 {
    1.0
}
fn default_lift() -> f64 {
    0.5
}

impl Wind {
    /// Checks the numbers; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
        self.profile.validate()?;
        for (name, v) in [
            ("fluid_coefficient_n_s_m3", self.fluid_coefficient_n_s_m3),
            ("air_density_kg_m3", self.air_density_kg_m3),
            ("drag_coefficient", self.drag_coefficient),
            ("lift_coefficient", self.lift_coefficient),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FieldError::new(name, format!("must be finite and >= 0, got {v}")));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles_vary_as_declared() {
        let g = WindProfile::Gust { mean_m_s: [5.0, 0.0, 0.0], amplitude_m_s: [2.0, 0.0, 0.0], frequency_hz: 0.5 };
        assert!((g.velocity(0.5, None).x - 7.0).abs() < 1e-12);
        let k = WindProfile::Keyframes { times_s: vec![0.0, 2.0], velocities_m_s: vec![[0.0; 3], [4.0, 0.0, 0.0]] };
        assert_eq!(k.velocity(1.0, None), Vec3::new(2.0, 0.0, 0.0));
        assert_eq!(k.velocity(9.0, None), Vec3::new(4.0, 0.0, 0.0));
        let set = Vec3::new(1.0, 2.0, 3.0);
        assert_eq!(k.velocity(9.0, Some(set)), Vec3::new(4.0, 0.0, 0.0), "only an external wind takes the set value");
        assert_eq!(WindProfile::External.velocity(4.0, Some(set)), set);
        assert_eq!(WindProfile::External.velocity(4.0, None), Vec3::zeros());
        let bad = WindProfile::Keyframes { times_s: vec![1.0, 0.0], velocities_m_s: vec![[0.0; 3]; 2] };
        assert_eq!(bad.validate().unwrap_err().path, "times_s");
    }
}
