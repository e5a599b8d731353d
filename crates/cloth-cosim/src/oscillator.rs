//! The two-mass oscillator, the classic co-simulation benchmark, split
//! force-displacement into two units (after Schweizer et al. and the FMI
//! cross-check literature):
//!
//! - unit A: mass `m1` on spring `k1` to ground, input the coupling force
//!   `F` (N), outputs `x1` (m) and `v1` (m/s);
//! - unit B: mass `m2` on spring `k2` to ground, coupled to `x1` by the
//!   spring `k12`; input `x1`, outputs `F = k12 (x2 - x1)`, `x2`, `v2`.
//!
//! With `m1 = m2 = 1`, `k1 = k2 = 4 pi^2`, `k12 = 16 pi^2`, `x(0) = (1, 0)`,
//! `v(0) = 0` the exact motion is `x1 = (cos 2 pi t + cos 6 pi t) / 2`,
//! `x2 = (cos 2 pi t - cos 6 pi t) / 2` ([`exact`]), energy `10 pi^2` J.
//! Each unit integrates its own ODE with classic RK4 on `substeps` equal
//! substeps, inputs linear in time within the step when given a
//! derivative, so the units' error is far below the coupling error.

use crate::unit::{Causality, StepOutcome, Unit, UnitError, UnitState, ValueRef, Variable, bytes, settable};
use std::f64::consts::PI;

/// Masses (kg) and stiffnesses (N/m) of the benchmark.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Oscillator {
    /// Mass of unit A, kg.
    pub m1: f64,
    /// Mass of unit B, kg.
    pub m2: f64,
    /// Spring of A to ground, N/m.
    pub k1: f64,
    /// Spring of B to ground, N/m.
    pub k2: f64,
    /// Coupling spring, N/m.
    pub k12: f64,
}

impl Default for Oscillator {
    /// `m1 = m2 = 1`, `k1 = k2 = 4 pi^2`, `k12 = 16 pi^2`.
    fn default() -> Self {
        Self { m1: 1.0, m2: 1.0, k1: 4.0 * PI * PI, k2: 4.0 * PI * PI, k12: 16.0 * PI * PI }
    }
}

impl Oscillator {
    /// Total energy of positions `x` (m) and velocities `v` (m/s), J.
    pub fn energy(&self, x: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (self.m1 * v[0] * v[0] + self.m2 * v[1] * v[1])
            + 0.5 * (self.k1 * x[0] * x[0] + self.k2 * x[1] * x[1] + self.k12 * (x[1] - x[0]).powi(2))
    }
}

/// The exact positions `(x1, x2)` (m) of the default benchmark at time `t`
/// (s), from `x(0) = (1, 0)` at rest: modes at 1 Hz and 3 Hz.
pub fn exact(t: f64) -> [f64; 2] {
    let (a, b) = ((2.0 * PI * t).cos(), (6.0 * PI * t).cos());
    [(a + b) / 2.0, (a - b) / 2.0]
}

/// One mass on a spring to ground plus, for unit B, a coupling spring to
/// an input position.
#[derive(Debug, Clone)]
pub struct MassUnit {
    name: String,
    vars: Vec<Variable>,
    mass: f64,
    k_ground: f64,
    /// Coupling stiffness (unit B) or 0 (unit A, which takes a force).
    k_coupling: f64,
    x: f64,
    v: f64,
    /// Input value at the start of the step and its derivative.
    input: f64,
    input_rate: f64,
    substeps: usize,
}

const TAG: &[u8; 8] = b"massunit";

impl MassUnit {
    /// Unit A of `osc`: input `F` (N), outputs `x1`, `v1`; starts at `x0` (m).
    pub fn force_driven(osc: &Oscillator, x0: f64, substeps: usize) -> Self {
        let vars = vec![
            Variable::new("F", Causality::Input, "N", "coupling force on mass 1"),
            Variable::new("x1", Causality::Output, "m", "position of mass 1").with_start(x0).with_dependencies(vec![]),
            Variable::new("v1", Causality::Output, "m/s", "velocity of mass 1").with_dependencies(vec![]),
        ];
        Self::new("A", vars, osc.m1, osc.k1, 0.0, x0, substeps)
    }

    /// Unit B of `osc`: input `x1` (m), outputs `F = k12 (x2 - x1)` (N),
    /// `x2`, `v2`; starts at `x0` (m).
    pub fn displacement_driven(osc: &Oscillator, x0: f64, substeps: usize) -> Self {
        let vars = vec![
            Variable::new("x1", Causality::Input, "m", "position of mass 1"),
            // F reads the input x1 directly: feedthrough.
            Variable::new("F", Causality::Output, "N", "coupling force on mass 1, k12 (x2 - x1)")
                .with_dependencies(vec![0]),
            Variable::new("x2", Causality::Output, "m", "position of mass 2").with_start(x0).with_dependencies(vec![]),
            Variable::new("v2", Causality::Output, "m/s", "velocity of mass 2").with_dependencies(vec![]),
        ];
        Self::new("B", vars, osc.m2, osc.k2, osc.k12, x0, substeps)
    }

    fn new(
        name: &str,
        vars: Vec<Variable>,
        mass: f64,
        k_ground: f64,
        k_coupling: f64,
        x0: f64,
        substeps: usize,
    ) -> Self {
        let name = name.to_string();
        Self { name, vars, mass, k_ground, k_coupling, x: x0, v: 0.0, input: 0.0, input_rate: 0.0, substeps }
    }

    /// Acceleration at position `x` with input value `u`, m/s^2.
    fn acceleration(&self, x: f64, u: f64) -> f64 {
        let coupling = if self.k_coupling > 0.0 { -self.k_coupling * (x - u) } else { u };
        (-self.k_ground * x + coupling) / self.mass
    }
}

impl Unit for MassUnit {
    fn name(&self) -> &str {
        &self.name
    }

    fn variables(&self) -> &[Variable] {
        &self.vars
    }

    fn set(&mut self, vr: ValueRef, value: f64) -> Result<(), UnitError> {
        settable(&self.name, &self.vars, vr, value)?;
        (self.input, self.input_rate) = (value, 0.0);
        Ok(())
    }

    fn set_input_derivative(&mut self, vr: ValueRef, du: f64) -> Result<(), UnitError> {
        settable(&self.name, &self.vars, vr, du)?;
        self.input_rate = du;
        Ok(())
    }

    fn get(&self, vr: ValueRef) -> Result<f64, UnitError> {
        let no = || UnitError::NoSuchVariable { unit: self.name.clone(), vr, count: self.vars.len() };
        // A: [F in, x1, v1]; B: [x1 in, F, x2, v2].
        let force_out = self.k_coupling > 0.0;
        Ok(match (force_out, vr) {
            (_, 0) => self.input,
            (true, 1) => self.k_coupling * (self.x - self.input),
            (false, 1) | (true, 2) => self.x,
            (false, 2) | (true, 3) => self.v,
            _ => return Err(no()),
        })
    }

    /// Classic RK4 on `substeps` substeps, input linear in time.
    fn do_step(&mut self, _t: f64, h: f64) -> Result<StepOutcome, UnitError> {
        let dt = h / self.substeps as f64;
        let (u0, du) = (self.input, self.input_rate);
        let u = |s: f64| u0 + du * s;
        let (mut x, mut v) = (self.x, self.v);
        for k in 0..self.substeps {
            let s = k as f64 * dt;
            let (k1x, k1v) = (v, self.acceleration(x, u(s)));
            let (k2x, k2v) = (v + 0.5 * dt * k1v, self.acceleration(x + 0.5 * dt * k1x, u(s + 0.5 * dt)));
            let (k3x, k3v) = (v + 0.5 * dt * k2v, self.acceleration(x + 0.5 * dt * k2x, u(s + 0.5 * dt)));
            let (k4x, k4v) = (v + dt * k3v, self.acceleration(x + dt * k3x, u(s + dt)));
            x += dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        (self.x, self.v) = (x, v);
        // The input now holds its end value; a new set replaces it.
        self.input = u(h);
        Ok(StepOutcome::Completed)
    }

    fn get_state(&self) -> UnitState {
        UnitState(Box::new([self.x, self.v, self.input, self.input_rate]))
    }

    fn set_state(&mut self, state: &UnitState) -> Result<(), UnitError> {
        let s: &[f64; 4] = state.downcast(&self.name, "mass unit")?;
        [self.x, self.v, self.input, self.input_rate] = *s;
        Ok(())
    }

    fn serialize_state(&self, state: &UnitState) -> Result<Vec<u8>, UnitError> {
        let s: &[f64; 4] = state.downcast(&self.name, "mass unit")?;
        Ok(bytes::pack(TAG, *s))
    }

    fn deserialize_state(&self, data: &[u8]) -> Result<UnitState, UnitError> {
        let values = bytes::unpack(TAG, data)
            .and_then(|v| if v.len() == 4 { Ok(v) } else { Err(format!("{} values where it holds 4", v.len())) })
            .map_err(|why| UnitError::BadState {
                unit: self.name.clone(),
                message: format!("{} bytes are not a serialised mass unit state: {why}", data.len()),
            })?;
        Ok(UnitState(Box::new([values[0], values[1], values[2], values[3]])))
    }
}

/// One run of the benchmark: errors against [`exact`] and energy drift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchmarkRun {
    /// Macro step, s.
    pub macro_step_s: f64,
    /// Largest |x_i - exact_i| over the communication points in (0, duration], m.
    pub max_error_m: f64,
    /// Relative change of the total energy from start to end, (E_T - E_0) / E_0.
    pub energy_drift: f64,
    /// Unit steps over the run (macro steps times iterations).
    pub unit_steps: usize,
}

/// Runs the default benchmark for `duration_s` with macro step `h` (s)
/// under `master`; units use `substeps` RK4 substeps per macro step.
pub fn benchmark(
    master: crate::Master,
    h: f64,
    duration_s: f64,
    substeps: usize,
) -> Result<BenchmarkRun, crate::CosimError> {
    use crate::{CoSimulation, Connection, Port};
    let osc = Oscillator::default();
    let a = MassUnit::force_driven(&osc, 1.0, substeps);
    let b = MassUnit::displacement_driven(&osc, 0.0, substeps);
    // A: [F in, x1, v1]; B: [x1 in, F, x2, v2].
    let connections = vec![
        Connection { from: Port { unit: 1, var: 1 }, to: Port { unit: 0, var: 0 } },
        Connection { from: Port { unit: 0, var: 1 }, to: Port { unit: 1, var: 0 } },
    ];
    let mut sim = CoSimulation::new(vec![Box::new(a), Box::new(b)], connections, master)?;
    let read = |sim: &CoSimulation| -> Result<([f64; 2], [f64; 2]), crate::CosimError> {
        let x = [sim.get(Port { unit: 0, var: 1 })?, sim.get(Port { unit: 1, var: 2 })?];
        let v = [sim.get(Port { unit: 0, var: 2 })?, sim.get(Port { unit: 1, var: 3 })?];
        Ok((x, v))
    };
    let (x0, v0) = read(&sim)?;
    let e0 = osc.energy(x0, v0);
    let steps = (duration_s / h).round() as usize;
    let (mut max_error_m, mut unit_steps) = (0.0f64, 0);
    for k in 1..=steps {
        unit_steps += sim.step(h)?.iterations;
        let (x, _) = read(&sim)?;
        let reference = exact(k as f64 * h);
        max_error_m = max_error_m.max((x[0] - reference[0]).abs()).max((x[1] - reference[1]).abs());
    }
    let (x, v) = read(&sim)?;
    Ok(BenchmarkRun { macro_step_s: h, max_error_m, energy_drift: (osc.energy(x, v) - e0) / e0, unit_steps })
}

/// Least-squares slope of `log(error)` against `log(h)`: the measured order.
pub fn order(runs: &[BenchmarkRun]) -> f64 {
    let pts: Vec<(f64, f64)> = runs.iter().map(|r| (r.macro_step_s.ln(), r.max_error_m.ln())).collect();
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}
