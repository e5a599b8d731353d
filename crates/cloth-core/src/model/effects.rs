//! Every effect a model can compute, declared once: its name in scene
//! files, what it adds, and what switches it on in a [`ModelSpec`]. The
//! scene's `simulation.effects`, the builder's [`crate::ModelBuilder::effect`]
//! and the model all read this one table. An effect that is off costs
//! nothing: no links are built and no loop runs for it.

use super::spec::{ModelSpec, StrainLimit};
use crate::Vec3;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The values an effect takes when switched on: gravity's acceleration,
/// the deformation constraints' settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectValues {
    /// Gravitational acceleration, m/s^2.
    pub gravity_m_s2: Vec3,
    /// Provot's deformation constraints.
    pub strain_limit: StrainLimit,
}

impl Default for EffectValues {
    /// Earth's gravity along `-z`, the default constraints.
    fn default() -> Self {
        Self { gravity_m_s2: Vec3::new(0.0, 0.0, -9.81), strain_limit: StrainLimit::default() }
    }
}

/// Declares [`Effect`] and its table: for each effect its variant, its
/// name in scene files, whether a spec has it, and how to switch it on.
macro_rules! effects {
    ($( $(#[doc = $doc:literal])+ $variant:ident = $name:literal, $is_on:expr, $switch_on:expr; )+) => {
        /// An effect a model can compute (its name in a scene's
        /// `simulation.effects`).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum Effect {
            $( $(#[doc = $doc])+ $variant, )+
        }

        impl Effect {
            /// Every effect, in the table's order.
            pub const ALL: &'static [Effect] = &[$(Effect::$variant),+];

            /// Its name in scene files.
            pub fn name(self) -> &'static str {
                match self {
                    $(Effect::$variant => $name,)+
                }
            }

            /// Whether `spec` computes it.
            pub fn is_on(self, spec: &ModelSpec) -> bool {
                let is_on: fn(&ModelSpec) -> bool = match self {
                    $(Effect::$variant => $is_on,)+
                };
                is_on(spec)
            }

            /// Switches it on in `spec`, with `values`.
            pub fn switch_on(self, spec: &mut ModelSpec, values: &EffectValues) {
                let switch_on: fn(&mut ModelSpec, &EffectValues) = match self {
                    $(Effect::$variant => $switch_on,)+
                };
                switch_on(spec, values)
            }
        }
    };
}

effects! {
    /// Uniform gravity `f_i = m_i g` (`simulation.gravity_m_s2`; the term
    /// [`crate::terms::Gravity`]).
    Gravity = "gravity", |s| s.effects.gravity.is_some(), |s, v| s.effects.gravity = Some(v.gravity_m_s2);
    /// Directional damping along the links (`material.damping_n_s_m`).
    Damping = "damping", |s| s.effects.damping, |s, _| s.effects.damping = true;
    /// Bending and compression resistance: Choi & Ko's type-2
    /// interactions, Provot's flexion springs, Volino's bending elements
    /// (`material.flexural_rigidity_n_m`, `buckling_stiffness_n_m`).
    Bending = "bending", |s| s.effects.bending, |s, _| s.effects.bending = true;
    /// Provot's deformation constraints after each step (`[constraints]`).
    StrainLimit = "strain-limit", |s| s.strain_limit.is_some(), |s, v| s.strain_limit = Some(v.strain_limit);
    /// Viscous drag on every particle (`material.drag_n_s_m3`; the term
    /// [`crate::terms::Drag`]).
    Drag = "drag", |s| s.effects.drag, |s, _| s.effects.drag = true;
    /// Provot's viscous fluid force along the particles' normals (`[wind]`;
    /// the term [`crate::terms::Fluid`]).
    Wind = "wind", |s| s.effects.wind, |s, _| s.effects.wind = true;
    /// Aerodynamic drag and lift on triangles (`[wind]`; the term
    /// [`crate::terms::Aerodynamics`]).
    Aerodynamics = "aerodynamics", |s| s.effects.aerodynamics, |s, _| s.effects.aerodynamics = true;
}

impl Effect {
    /// The effect named `name` in scene files.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|e| e.name() == name)
    }
}

impl Serialize for Effect {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for Effect {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        Effect::from_name(&name).ok_or_else(|| {
            let names: Vec<&str> = Effect::ALL.iter().map(|e| e.name()).collect();
            serde::de::Error::custom(format!("unknown effect `{name}`, expected one of {}", names.join(", ")))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each effect switched on alone is on, and only it; names round-trip.
    #[test]
    fn each_effect_switches_itself_on_and_nothing_else() {
        for &effect in Effect::ALL {
            let mut spec = ModelSpec::default();
            assert!(Effect::ALL.iter().all(|e| !e.is_on(&spec)), "a default spec computes {}", effect.name());
            effect.switch_on(&mut spec, &EffectValues::default());
            for &other in Effect::ALL {
                assert_eq!(other.is_on(&spec), other == effect, "{} switched {} on", effect.name(), other.name());
            }
            assert_eq!(Effect::from_name(effect.name()), Some(effect));
        }
        assert_eq!(Effect::from_name("gravitas"), None);
    }
}
