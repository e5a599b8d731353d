//! Master algorithms: connect outputs to inputs and advance units together
//! in macro steps.
//!
//! - Jacobi: every unit steps from the outputs of the last communication
//!   point (parallel in principle).
//! - Gauss-Seidel: units step in a given order; a unit sees the new outputs
//!   of the units before it.
//! - Iterated strong coupling: repeat the macro step from saved states,
//!   feeding the end-of-step outputs back as inputs (with relaxation), until
//!   the interface values change less than a tolerance.
//!
//! At a communication point the masters read an output with direct
//! feedthrough ([`crate::Variable::dependencies`]) only after the inputs it
//! depends on are set to their values there, in dependency order; a cycle
//! of feedthrough outputs is a real algebraic loop and is reported
//! ([`CosimError::AlgebraicLoop`]).
//!
//! Inputs between communication points are held (zero-order hold) or
//! extrapolated linearly from the last two (first-order hold) for the
//! explicit masters; the iterated master holds its end-of-step guess or
//! interpolates linearly from the start value to it.

use crate::unit::{Causality, StepOutcome, Unit, UnitError, UnitState, ValueRef};

/// A variable of one unit of a co-simulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Port {
    /// Index of the unit.
    pub unit: usize,
    /// The variable.
    pub var: ValueRef,
}

/// An output feeding an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Connection {
    /// The output.
    pub from: Port,
    /// The input.
    pub to: Port,
}

/// How an input evolves over a macro step of an explicit master.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Extrapolation {
    /// The last output value, given without a derivative: held by most
    /// units, continued from the previous value by the cloth's pins (first
    /// order in the macro step).
    #[default]
    ZeroOrderHold,
    /// A line through the last two output values, continued over the
    /// step (needs units that take input derivatives; second order).
    FirstOrderHold,
}

/// How the iterated master presents its guess of the end-of-step value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputOverStep {
    /// Linear from the start value to the guess (needs input derivatives; second order).
    #[default]
    Linear,
    /// The guess held over the whole step, a derivative of 0 (first order,
    /// like backward Euler).
    EndValue,
}

/// How the iterated master updates its guess from a residual `r = y - u`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Relaxation {
    /// `u += omega r`, omega in (0, 1].
    Fixed(f64),
    /// Interface quasi-Newton with an inverse Jacobian from least squares
    /// (IQN-ILS, Degroote, Bathe & Vierendeels 2009): after a first
    /// relaxed iteration with `initial`, the guess is `y_k + W alpha` where
    /// `alpha` minimises `|V alpha + r_k|` over the differences `V` of the
    /// residuals and `W` of the outputs seen in this macro step. Rows are
    /// scaled by each value's tolerance so forces and positions weigh alike.
    /// A scalar dynamic factor (Aitken's) was tried and failed to converge on
    /// the oscillator benchmark, whose interface map has complex eigenvalues.
    QuasiNewton {
        /// omega of the first iteration.
        initial: f64,
    },
}

/// Jacobi master parameters.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JacobiParams {
    /// Input extrapolation.
    pub extrapolation: Extrapolation,
}

/// Gauss-Seidel master parameters.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GaussSeidelParams {
    /// The order in which units step (every unit once); empty: index order.
    pub order: Vec<usize>,
    /// Extrapolation of inputs from units not yet stepped; inputs from
    /// units already stepped are held at their new value (zero-order) or
    /// interpolated from the old to the new value (first-order).
    pub extrapolation: Extrapolation,
}

/// Iterated strong coupling parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IteratedParams {
    /// Most repetitions of a macro step. Default 50.
    pub max_iterations: usize,
    /// Converged when every interface value changes by less than
    /// `abs_tol + rel_tol |value|`. Defaults 1e-10 and 1e-8.
    pub abs_tol: f64,
    /// See `abs_tol`.
    pub rel_tol: f64,
    /// Guess update. Default quasi-Newton (IQN-ILS) after a first step of 0.5.
    pub relaxation: Relaxation,
    /// How the guess is seen over the step. Default linear.
    pub inputs: InputOverStep,
    /// First guess of the end value: the held last output or its linear
    /// extrapolation. Default first-order.
    pub initial_guess: Extrapolation,
    /// Accept the last iterate when `max_iterations` is reached (reported
    /// as unconverged) instead of failing. Default false.
    pub accept_unconverged: bool,
}

impl Default for IteratedParams {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            abs_tol: 1e-10,
            rel_tol: 1e-8,
            relaxation: Relaxation::QuasiNewton { initial: 0.5 },
            inputs: InputOverStep::Linear,
            initial_guess: Extrapolation::FirstOrderHold,
            accept_unconverged: false,
        }
    }
}

/// A master algorithm and its parameters.
#[derive(Debug, Clone, PartialEq)]
pub enum Master {
    /// Jacobi.
    Jacobi(JacobiParams),
    /// Gauss-Seidel.
    GaussSeidel(GaussSeidelParams),
    /// Iterated strong coupling.
    Iterated(IteratedParams),
}

/// What one macro step did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MacroStepReport {
    /// Times the units were stepped over this macro step (1 for the
    /// explicit masters).
    pub iterations: usize,
    /// False when the iterated master stopped at `max_iterations`.
    pub converged: bool,
    /// Largest scaled interface residual of the last iteration (0 for explicit masters).
    pub residual: f64,
}

/// Why a co-simulation could not be set up or advanced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CosimError {
    /// A unit refused a call.
    #[error(transparent)]
    Unit(#[from] UnitError),
    /// A connection is invalid.
    #[error("connection {index}: {message}")]
    Connection {
        /// Index of the connection.
        index: usize,
        /// Why.
        message: String,
    },
    /// The Gauss-Seidel order is not a permutation of the units.
    #[error("gauss-seidel order {order:?}: must list every one of the {units} units once")]
    Order {
        /// The order given.
        order: Vec<usize>,
        /// Number of units.
        units: usize,
    },
    /// A unit discarded the step; every unit is back at the start of it.
    #[error("unit {unit} discarded the step from t = {time_s} s at {last_time_s} s: {reason}")]
    Discarded {
        /// The unit's name.
        unit: String,
        /// Start of the macro step, s.
        time_s: f64,
        /// Where the unit stopped, s.
        last_time_s: f64,
        /// The unit's reason.
        reason: String,
    },
    /// Outputs with direct feedthrough feed each other's inputs in a cycle:
    /// no explicit master can order them.
    #[error("algebraic loop: the outputs {outputs:?} depend directly on inputs they feed, in a cycle")]
    AlgebraicLoop {
        /// The outputs in the loop (and those waiting on it), `unit.variable`.
        outputs: Vec<String>,
    },
    /// The macro step is not finite and positive.
    #[error("macro step {h} s: must be finite and > 0")]
    InvalidStep {
        /// The step, s.
        h: f64,
    },
    /// The iterated master did not converge; every unit is back at the start of the step.
    #[error("t = {time_s} s: interface not converged after {iterations} iterations (scaled residual {residual})")]
    NotConverged {
        /// Start of the macro step, s.
        time_s: f64,
        /// Iterations made.
        iterations: usize,
        /// Last scaled residual.
        residual: f64,
    },
}

/// Units, their connections and a master: a co-simulation.
pub struct CoSimulation {
    units: Vec<Box<dyn Unit>>,
    connections: Vec<Connection>,
    master: Master,
    time_s: f64,
    /// Each connection's output at the last communication point before
    /// this one, and the step between them (for first-order hold).
    previous: Option<(Vec<f64>, f64)>,
}

impl std::fmt::Debug for CoSimulation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<_> = self.units.iter().map(|u| u.name().to_string()).collect();
        f.debug_struct("CoSimulation")
            .field("units", &names)
            .field("connections", &self.connections)
            .field("master", &self.master)
            .field("time_s", &self.time_s)
            .finish()
    }
}

impl CoSimulation {
    /// Checks the connections (output to input, each input fed once) and
    /// the master's parameters.
    pub fn new(units: Vec<Box<dyn Unit>>, connections: Vec<Connection>, master: Master) -> Result<Self, CosimError> {
        let mut fed = std::collections::HashSet::new();
        for (index, c) in connections.iter().enumerate() {
            let bad = |message: String| CosimError::Connection { index, message };
            for (port, want, what) in [(c.from, Causality::Output, "from"), (c.to, Causality::Input, "to")] {
                let unit = units.get(port.unit).ok_or_else(|| bad(format!("{what}: no unit {}", port.unit)))?;
                let var = unit
                    .variables()
                    .get(port.var)
                    .ok_or_else(|| bad(format!("{what}: unit {} has no variable {}", unit.name(), port.var)))?;
                if var.causality != want {
                    return Err(bad(format!("{what}: {}.{} is not an {want:?}", unit.name(), var.name)));
                }
            }
            if !fed.insert(c.to) {
                return Err(bad("this input is already fed by another connection".into()));
            }
        }
        if let Master::GaussSeidel(p) = &master {
            let mut sorted = p.order.clone();
            sorted.sort_unstable();
            if !p.order.is_empty() && sorted != (0..units.len()).collect::<Vec<_>>() {
                return Err(CosimError::Order { order: p.order.clone(), units: units.len() });
            }
        }
        let mut sim = Self { units, connections, master, time_s: 0.0, previous: None };
        sim.initialize()?;
        Ok(sim)
    }

    /// FMI's initialisation mode: copies outputs to inputs until they agree,
    /// so outputs that depend directly on inputs (a force from a
    /// displacement) start consistent. One pass per connection resolves
    /// any chain without an algebraic loop.
    fn initialize(&mut self) -> Result<(), CosimError> {
        for _ in 0..self.connections.len() {
            for k in 0..self.connections.len() {
                let value = self.get(self.connections[k].from)?;
                self.feed(k, value, None)?;
            }
        }
        Ok(())
    }

    /// Time of the last communication point, s.
    pub fn time(&self) -> f64 {
        self.time_s
    }

    /// Unit `k`.
    pub fn unit(&self, k: usize) -> &dyn Unit {
        self.units[k].as_ref()
    }

    /// Unit `k`, to set parameters or read anything.
    pub fn unit_mut(&mut self, k: usize) -> &mut dyn Unit {
        self.units[k].as_mut()
    }

    /// Reads `port`.
    pub fn get(&self, port: Port) -> Result<f64, CosimError> {
        Ok(self.units[port.unit].get(port.var)?)
    }

    /// The master.
    pub fn master(&self) -> &Master {
        &self.master
    }

    /// Advances every unit by the macro step `h` (s).
    pub fn step(&mut self, h: f64) -> Result<MacroStepReport, CosimError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(CosimError::InvalidStep { h });
        }
        let start = self.resolved_outputs()?;
        let report = match self.master.clone() {
            Master::Jacobi(p) => self.jacobi(&start, h, p)?,
            Master::GaussSeidel(p) => self.gauss_seidel(&start, h, &p)?,
            Master::Iterated(p) => self.iterated(&start, h, &p)?,
        };
        self.previous = Some((start, h));
        self.time_s += h;
        Ok(report)
    }

    /// Every connection's source value now.
    fn outputs(&self) -> Result<Vec<f64>, CosimError> {
        self.connections.iter().map(|c| self.get(c.from)).collect()
    }

    /// Every connection's source value at this communication point, each
    /// output read once the connected inputs it depends on directly hold
    /// their values here (set as they are resolved, in connection order
    /// within each round, so the order is fixed).
    fn resolved_outputs(&mut self) -> Result<Vec<f64>, CosimError> {
        let n = self.connections.len();
        let mut value: Vec<Option<f64>> = vec![None; n];
        while value.iter().any(Option::is_none) {
            let mut progress = false;
            for k in 0..n {
                if value[k].is_some() || !self.inputs_resolved(self.connections[k].from, &value) {
                    continue;
                }
                let v = self.get(self.connections[k].from)?;
                let to = self.connections[k].to;
                self.units[to.unit].set(to.var, v)?;
                value[k] = Some(v);
                progress = true;
            }
            if !progress {
                let outputs = (0..n)
                    .filter(|&k| value[k].is_none())
                    .map(|k| {
                        let from = self.connections[k].from;
                        let unit = &self.units[from.unit];
                        format!("{}.{}", unit.name(), unit.variables()[from.var].name)
                    })
                    .collect();
                return Err(CosimError::AlgebraicLoop { outputs });
            }
        }
        Ok(value.into_iter().map(|v| v.expect("every value resolved")).collect())
    }

    /// Whether every input that output `from` depends on directly, and that
    /// a connection feeds, holds its value at this communication point.
    fn inputs_resolved(&self, from: Port, value: &[Option<f64>]) -> bool {
        let vars = self.units[from.unit].variables();
        let depends = |input: ValueRef| match &vars[from.var].dependencies {
            Some(inputs) => inputs.contains(&input),
            None => vars[input].causality == Causality::Input,
        };
        self.connections.iter().zip(value).all(|(c, v)| v.is_some() || c.to.unit != from.unit || !depends(c.to.var))
    }

    /// Slope of each connection's value from the last communication point
    /// to `now`, per second (0 at the first step).
    fn slopes(&self, now: &[f64]) -> Vec<f64> {
        match &self.previous {
            Some((before, dt)) => now.iter().zip(before).map(|(a, b)| (a - b) / dt).collect(),
            None => vec![0.0; now.len()],
        }
    }

    /// Sets connection `k`'s input to `value`, and its derivative to `rate`
    /// when given. `None` leaves the input's course over the step to the
    /// unit; `Some(0.0)` holds it, which a unit refusing derivatives does
    /// anyway, so only a non-zero rate needs a unit that takes one.
    fn feed(&mut self, k: usize, value: f64, rate: Option<f64>) -> Result<(), CosimError> {
        let to = self.connections[k].to;
        let unit = &mut self.units[to.unit];
        unit.set(to.var, value)?;
        match rate.map(|rate| (rate, unit.set_input_derivative(to.var, rate))) {
            None | Some((_, Ok(()))) => Ok(()),
            Some((0.0, Err(UnitError::Unsupported { .. }))) => Ok(()),
            Some((_, Err(e))) => Err(e.into()),
        }
    }

    fn step_unit(&mut self, u: usize, h: f64) -> Result<(), CosimError> {
        match self.units[u].do_step(self.time_s, h)? {
            StepOutcome::Completed => Ok(()),
            StepOutcome::Discarded { last_time_s, reason } => Err(CosimError::Discarded {
                unit: self.units[u].name().to_string(),
                time_s: self.time_s,
                last_time_s,
                reason,
            }),
        }
    }

    fn save(&self) -> Vec<UnitState> {
        self.units.iter().map(|u| u.get_state()).collect()
    }

    fn restore(&mut self, saved: &[UnitState]) -> Result<(), CosimError> {
        for (u, s) in self.units.iter_mut().zip(saved) {
            u.set_state(s)?;
        }
        Ok(())
    }

    /// Runs `body`; if it fails, puts every unit back where it started.
    fn atomic<T>(
        &mut self,
        body: impl FnOnce(&mut Self, &[UnitState]) -> Result<T, CosimError>,
    ) -> Result<T, CosimError> {
        let saved = self.save();
        let result = body(self, &saved);
        if result.is_err() {
            self.restore(&saved)?;
        }
        result
    }

    fn jacobi(&mut self, start: &[f64], h: f64, p: JacobiParams) -> Result<MacroStepReport, CosimError> {
        let slopes = self.slopes(start);
        self.atomic(|sim, _| {
            for (k, &value) in start.iter().enumerate() {
                let rate = (p.extrapolation == Extrapolation::FirstOrderHold).then_some(slopes[k]);
                sim.feed(k, value, rate)?;
            }
            for u in 0..sim.units.len() {
                sim.step_unit(u, h)?;
            }
            Ok(MacroStepReport { iterations: 1, converged: true, residual: 0.0 })
        })
    }

    fn gauss_seidel(&mut self, start: &[f64], h: f64, p: &GaussSeidelParams) -> Result<MacroStepReport, CosimError> {
        let order: Vec<usize> = if p.order.is_empty() { (0..self.units.len()).collect() } else { p.order.clone() };
        let slopes = self.slopes(start);
        let first_order = p.extrapolation == Extrapolation::FirstOrderHold;
        self.atomic(|sim, _| {
            let mut stepped = vec![false; sim.units.len()];
            for &u in &order {
                for k in 0..sim.connections.len() {
                    let c = sim.connections[k];
                    if c.to.unit != u {
                        continue;
                    }
                    if stepped[c.from.unit] {
                        let new = sim.get(c.from)?;
                        // The new value held (zero-order) or reached linearly (first-order).
                        let (value, rate) = if first_order { (start[k], (new - start[k]) / h) } else { (new, 0.0) };
                        sim.feed(k, value, Some(rate))?;
                    } else {
                        sim.feed(k, start[k], first_order.then_some(slopes[k]))?;
                    }
                }
                sim.step_unit(u, h)?;
                stepped[u] = true;
            }
            Ok(MacroStepReport { iterations: 1, converged: true, residual: 0.0 })
        })
    }

    fn iterated(&mut self, start: &[f64], h: f64, p: &IteratedParams) -> Result<MacroStepReport, CosimError> {
        let slopes = self.slopes(start);
        let mut guess: Vec<f64> = match p.initial_guess {
            Extrapolation::ZeroOrderHold => start.to_vec(),
            Extrapolation::FirstOrderHold => start.iter().zip(&slopes).map(|(y, s)| y + s * h).collect(),
        };
        let time_s = self.time_s;
        self.atomic(|sim, saved| {
            let mut update = GuessUpdate::new(p.relaxation);
            let mut scaled = f64::INFINITY;
            for iteration in 1..=p.max_iterations.max(1) {
                if iteration > 1 {
                    sim.restore(saved)?;
                }
                for k in 0..guess.len() {
                    match p.inputs {
                        InputOverStep::Linear => sim.feed(k, start[k], Some((guess[k] - start[k]) / h))?,
                        InputOverStep::EndValue => sim.feed(k, guess[k], Some(0.0))?,
                    }
                }
                for u in 0..sim.units.len() {
                    sim.step_unit(u, h)?;
                }
                let end = sim.outputs()?;
                let weight: Vec<f64> = end.iter().map(|y| 1.0 / (p.abs_tol + p.rel_tol * y.abs())).collect();
                scaled = end.iter().zip(&guess).zip(&weight).map(|((y, u), w)| (y - u).abs() * w).fold(0.0, f64::max);
                if scaled <= 1.0 {
                    return Ok(MacroStepReport { iterations: iteration, converged: true, residual: scaled });
                }
                update.next(&mut guess, &end, &weight);
            }
            if p.accept_unconverged {
                Ok(MacroStepReport { iterations: p.max_iterations.max(1), converged: false, residual: scaled })
            } else {
                Err(CosimError::NotConverged { time_s, iterations: p.max_iterations.max(1), residual: scaled })
            }
        })
    }
}

/// The iterated master's guess update within one macro step (also used by
/// couplings that iterate outside a [`CoSimulation`]): feed it each
/// iterate's guess and the end values it produced; it moves the guess by
/// the [`Relaxation`].
#[derive(Debug, Clone)]
pub struct GuessUpdate {
    relaxation: Relaxation,
    omega: f64,
    /// Scaled residuals and outputs of the earlier iterations (newest last).
    residuals: Vec<Vec<f64>>,
    outputs: Vec<Vec<f64>>,
}

impl GuessUpdate {
    /// A fresh update for one macro step.
    pub fn new(relaxation: Relaxation) -> Self {
        let omega = match relaxation {
            Relaxation::Fixed(w) => w,
            Relaxation::QuasiNewton { initial } => initial,
        };
        Self { relaxation, omega, residuals: Vec::new(), outputs: Vec::new() }
    }

    /// Moves `guess` given the outputs `end` it produced; `weight` scales
    /// each value by its tolerance.
    pub fn next(&mut self, guess: &mut [f64], end: &[f64], weight: &[f64]) {
        let r: Vec<f64> = end.iter().zip(guess.iter()).zip(weight).map(|((y, u), w)| (y - u) * w).collect();
        let y: Vec<f64> = end.iter().zip(weight).map(|(y, w)| y * w).collect();
        let relaxed = |guess: &mut [f64], omega: f64| {
            for ((u, ri), w) in guess.iter_mut().zip(&r).zip(weight) {
                *u += omega * ri / w;
            }
        };
        match self.relaxation {
            Relaxation::Fixed(w) => relaxed(guess, w),
            Relaxation::QuasiNewton { .. } => {
                let (n, m) = (r.len(), self.residuals.len().min(r.len()));
                if m == 0 {
                    relaxed(guess, self.omega);
                } else {
                    // Columns: differences to the newest earlier iterate, newest first.
                    let first = self.residuals.len() - m;
                    let v = nalgebra::DMatrix::from_fn(n, m, |i, j| r[i] - self.residuals[first + m - 1 - j][i]);
                    let w = nalgebra::DMatrix::from_fn(n, m, |i, j| y[i] - self.outputs[first + m - 1 - j][i]);
                    let rhs = -nalgebra::DVector::from_column_slice(&r);
                    match v.clone().svd(true, true).solve(&rhs, 1e-12 * v.norm()) {
                        Ok(alpha) => {
                            let step = &w * alpha;
                            for (i, u) in guess.iter_mut().enumerate() {
                                *u = (y[i] + step[i]) / weight[i];
                            }
                        }
                        Err(_) => relaxed(guess, self.omega),
                    }
                }
            }
        }
        self.residuals.push(r);
        self.outputs.push(y);
    }
}
