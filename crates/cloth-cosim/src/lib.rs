//! FMI-style co-simulation without any rigid-body dependency: [`Unit`]s
//! with typed variables (name, causality, unit, description), `do_step`
//! that may be discarded, state get/set/serialise; [`Connection`]s from
//! outputs to inputs; master algorithms ([`Master`]: Jacobi, Gauss-Seidel,
//! iterated strong coupling with relaxation) with their parameters in one
//! struct each; the two-mass oscillator benchmark ([`oscillator`]) with an
//! exact solution; and [`ClothUnit`], a cloth [`cloth_core::Simulation`]
//! as a unit.

pub mod cloth_unit;
pub mod master;
pub mod oscillator;
pub mod unit;

pub use cloth_unit::ClothUnit;
pub use master::{
    CoSimulation, Connection, CosimError, Extrapolation, GaussSeidelParams, GuessUpdate, InputOverStep, IteratedParams,
    JacobiParams, MacroStepReport, Master, Port, Relaxation,
};
pub use unit::{Causality, StepOutcome, Unit, UnitError, UnitState, ValueRef, VarType, Variable};
