//! The built-in integrators, found by name: each scene name maps to a
//! constructor, and what an integrator can do sits on the
//! [`crate::Integrator`] trait ([`crate::Capabilities`]).

use super::explicit::{Explicit, Method};
use super::implicit::{BackwardEuler, Bdf2};
use super::matrix_free::BackwardEulerFixedCg;
use super::quasi_newton::QuasiNewton;
use super::step::Integrator;
use super::vbd::Vbd;
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
    /// sweeps of per-particle Newton steps ([`crate::Vbd`]); the sweeps
    /// are [`SolverParams::vbd`](crate::SolverParams::vbd)'s.
    Vbd,
    /// Quasi-Newton (`quasi-newton`), Liu, Bouaziz & Kavan (2017): backward
    /// Euler's incremental potential minimised by L-BFGS with a
    /// prefactored mass-plus-Laplacian initial Hessian
    /// ([`crate::QuasiNewton`]); its settings are
    /// [`SolverParams::quasi_newton`](crate::SolverParams::quasi_newton)'s.
    QuasiNewton,
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
const REGISTRY: [Entry; 10] = [
    explicit(IntegratorKind::ForwardEuler, Method::ForwardEuler),
    explicit(IntegratorKind::SymplecticEuler, Method::SymplecticEuler),
    explicit(IntegratorKind::Midpoint, Method::Midpoint),
    explicit(IntegratorKind::Rk4, Method::Rk4),
    explicit(IntegratorKind::Dopri5, Method::Dopri5),
    Entry { kind: IntegratorKind::BackwardEuler, name: BackwardEuler::NAME, build: || Box::<BackwardEuler>::default() },
    Entry {
        kind: IntegratorKind::BackwardEulerFixedCg,
        name: BackwardEulerFixedCg::NAME,
        build: || Box::<BackwardEulerFixedCg>::default(),
    },
    Entry { kind: IntegratorKind::Bdf2, name: Bdf2::NAME, build: || Box::<Bdf2>::default() },
    Entry { kind: IntegratorKind::Vbd, name: Vbd::NAME, build: || Box::<Vbd>::default() },
    Entry { kind: IntegratorKind::QuasiNewton, name: QuasiNewton::NAME, build: || Box::<QuasiNewton>::default() },
];

/// The entry of an explicit method.
const fn explicit(kind: IntegratorKind, method: Method) -> Entry {
    let build: fn() -> Box<dyn Integrator> = match method {
        Method::ForwardEuler => || Box::new(Explicit::new(Method::ForwardEuler)),
        Method::SymplecticEuler => || Box::new(Explicit::new(Method::SymplecticEuler)),
        Method::Midpoint => || Box::new(Explicit::new(Method::Midpoint)),
        Method::Rk4 => || Box::new(Explicit::new(Method::Rk4)),
        Method::Dopri5 => || Box::new(Explicit::new(Method::Dopri5)),
    };
    Entry { kind, name: method.name(), build }
}

impl IntegratorKind {
    /// Every kind, in the order above.
    pub const ALL: [IntegratorKind; 10] = [
        IntegratorKind::ForwardEuler,
        IntegratorKind::SymplecticEuler,
        IntegratorKind::Midpoint,
        IntegratorKind::Rk4,
        IntegratorKind::Dopri5,
        IntegratorKind::BackwardEuler,
        IntegratorKind::BackwardEulerFixedCg,
        IntegratorKind::Bdf2,
        IntegratorKind::Vbd,
        IntegratorKind::QuasiNewton,
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
