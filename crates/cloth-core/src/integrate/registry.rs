//! The built-in integrators, found by name: each scene name maps to a
//! constructor, and what an integrator can do sits on the
//! [`crate::Integrator`] trait ([`crate::Capabilities`]).

use super::step::Integrator;
use serde::{Deserialize, Serialize};

/// Which integrator a simulation uses (scene name in brackets).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IntegratorKind {
    /// Forward Euler (`forward-euler`): order 1, one force evaluation.
    ForwardEuler,
    /// Symplectic (semi-implicit) Euler (`symplectic-euler`): order 1.
    SymplecticEuler,
    /// Explicit midpoint (`midpoint`): order 2, two force evaluations.
    Midpoint,
    /// Classic Runge-Kutta (`rk4`): order 4, four force evaluations.
    Rk4,
    /// Dormand-Prince 5(4) with adaptive substeps (`dopri5`): order 5,
    /// error controlled by [`AdaptiveParams::error_tolerance`](crate::AdaptiveParams::error_tolerance).
    Dopri5,
    /// Backward Euler, Baraff & Witkin (1998) (`backward-euler`): first
    /// order, strongly damping; PCG to a tolerance.
    BackwardEuler,
    /// Backward Euler with a fixed number of matrix-free, mass-scaled CG
    /// iterations (`backward-euler-fixed-cg`), Volino & Magnenat-Thalmann
    /// (2001); the count is [`SolverParams::fixed_cg_iterations`](crate::SolverParams::fixed_cg_iterations).
    BackwardEulerFixedCg,
    /// Bdf2 (`bdf2`): second-order BDF, Choi & Ko (2002) Eq. 20; starts with
    /// one backward-Euler step.
    Bdf2,
    /// Vertex Block Descent (`vbd`), Chen, Macklin et al. (2024): backward
    /// Euler's incremental potential minimised by coloured Gauss-Seidel
    /// sweeps of per-particle Newton steps ([`crate::vbd`]); the sweeps
    /// are [`SolverParams::vbd`](crate::SolverParams::vbd)'s.
    Vbd,
}

/// One built-in integrator: its kind, its name in scene files, and how
/// to make one (with empty scratch and memory).
struct Entry {
    kind: IntegratorKind,
    name: &'static str,
    build: fn() -> Box<dyn Integrator>,
}

/// Every built-in integrator, in [`IntegratorKind::ALL`]'s order. One line
/// an integrator.
const REGISTRY: [Entry; 9] = [
    Entry {
        kind: IntegratorKind::ForwardEuler,
        name: "forward-euler",
        build: || explicit(IntegratorKind::ForwardEuler),
    },
    Entry {
        kind: IntegratorKind::SymplecticEuler,
        name: "symplectic-euler",
        build: || explicit(IntegratorKind::SymplecticEuler),
    },
    Entry { kind: IntegratorKind::Midpoint, name: "midpoint", build: || explicit(IntegratorKind::Midpoint) },
    Entry { kind: IntegratorKind::Rk4, name: "rk4", build: || explicit(IntegratorKind::Rk4) },
    Entry { kind: IntegratorKind::Dopri5, name: "dopri5", build: || explicit(IntegratorKind::Dopri5) },
    Entry {
        kind: IntegratorKind::BackwardEuler,
        name: "backward-euler",
        build: || Box::new(super::implicit::BackwardEuler::default()),
    },
    Entry {
        kind: IntegratorKind::BackwardEulerFixedCg,
        name: "backward-euler-fixed-cg",
        build: || Box::new(super::matrix_free::BackwardEulerFixedCg::default()),
    },
    Entry { kind: IntegratorKind::Bdf2, name: "bdf2", build: || Box::new(super::implicit::Bdf2::default()) },
    Entry { kind: IntegratorKind::Vbd, name: "vbd", build: || Box::new(super::vbd::Vbd::default()) },
];

fn explicit(kind: IntegratorKind) -> Box<dyn Integrator> {
    Box::new(super::explicit::Explicit::new(kind))
}

impl IntegratorKind {
    /// Every kind, in the order above.
    pub const ALL: [IntegratorKind; 9] = [
        IntegratorKind::ForwardEuler,
        IntegratorKind::SymplecticEuler,
        IntegratorKind::Midpoint,
        IntegratorKind::Rk4,
        IntegratorKind::Dopri5,
        IntegratorKind::BackwardEuler,
        IntegratorKind::BackwardEulerFixedCg,
        IntegratorKind::Bdf2,
        IntegratorKind::Vbd,
    ];

    fn entry(self) -> &'static Entry {
        &REGISTRY[self as usize]
    }

    /// A new integrator of this kind.
    pub fn build(self) -> Box<dyn Integrator> {
        (self.entry().build)()
    }

    /// Name as written in scene files.
    pub fn name(self) -> &'static str {
        self.entry().name
    }

    /// The kind named `name` in scene files.
    pub fn from_name(name: &str) -> Option<Self> {
        REGISTRY.iter().find(|e| e.name == name).map(|e| e.kind)
    }

    /// What integrators of this kind can do.
    pub fn capabilities(self) -> crate::Capabilities {
        self.build().capabilities()
    }

    /// Whether the integrator solves a linear system each step.
    pub fn is_implicit(self) -> bool {
        self.capabilities().linear_solve
    }

    /// Whether the integrator handles self-collision (inside its solve:
    /// the assembled implicit steps and the vertex solver).
    pub fn handles_self_collision(self) -> bool {
        self.capabilities().contacts.handles_self_collision()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_registry_lists_every_kind_in_order_under_its_scene_name() {
        for (k, kind) in IntegratorKind::ALL.into_iter().enumerate() {
            assert_eq!(REGISTRY[k].kind, kind);
            let name = toml::Value::try_from(kind).unwrap();
            assert_eq!(name.as_str(), Some(kind.name()));
            assert_eq!(IntegratorKind::from_name(kind.name()), Some(kind));
            assert_eq!(kind.build().name(), kind.name());
        }
        assert_eq!(IntegratorKind::from_name("leapfrog"), None);
    }
}
