//! Backward Euler with a FIXED number of matrix-free CG iterations and
//! `m^-1/2` mass scaling: the variant Volino & Magnenat-Thalmann (2001)
//! found most efficient ("backward Euler, n CG iterations"). Each step
//! solves `[M - h D - h^2 K] dv = h (f + h K v)` approximately: the unknown
//! is scaled to `y = M^1/2 dv`, so the operator `M^-1/2 A M^-1/2` has unit
//! mass part, and CG runs exactly `SolverParams::fixed_cg_iterations`
//! iterations with the product computed link by link, never assembled.

use super::implicit::{EulerScheme, Linearised, constrain_pins};
use super::step::{Capabilities, Integrator, Step, StepOutput};
use super::timer::{Stage, StageTimer};
use crate::contacts::Contacts;
use crate::control::PinPaths;
use crate::system::{SystemBuffers, apply_scaled_operator, assemble_matrix_free};
use crate::{ClothModel, StepError, StepReport, Vec3};
use cloth_linalg::{CgScratch, ConstraintFilter, PcgError, cg_fixed_iterations};

/// Buffers of the matrix-free solver, allocated on first use.
#[derive(Debug)]
pub(crate) struct MatrixFreeBuffers {
    system: SystemBuffers,
    filter: ConstraintFilter,
    unknown: Vec<Vec3>,
    /// Scratch of the operator product (the scheme needs no vectors of
    /// its own: backward Euler's are empty).
    product: Vec<Vec3>,
    inv_sqrt_mass: Vec<f64>,
    scaled_rhs: Vec<Vec3>,
    cg: CgScratch,
}

impl MatrixFreeBuffers {
    fn new(model: &ClothModel) -> Self {
        let n = model.particle_count();
        Self {
            system: SystemBuffers::new(model),
            filter: ConstraintFilter::new(n),
            unknown: vec![Vec3::zeros(); n],
            product: vec![Vec3::zeros(); n],
            inv_sqrt_mass: model.masses().iter().map(|m| 1.0 / m.sqrt()).collect(),
            scaled_rhs: vec![Vec3::zeros(); n],
            cg: CgScratch::new(n),
        }
    }
}

/// Backward Euler solved by a fixed number of matrix-free CG iterations.
#[derive(Debug, Default)]
pub struct BackwardEulerFixedCg {
    buffers: Option<Box<MatrixFreeBuffers>>,
}

impl BackwardEulerFixedCg {
    /// Its name in scene files.
    pub(crate) const NAME: &'static str = "backward-euler-fixed-cg";
}

impl Integrator for BackwardEulerFixedCg {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities { loads_at_start: true, linear_solve: true, ..Capabilities::default() }
    }

    /// The link blocks and the right-hand side; no matrix.
    fn assemble(&mut self, step: &Step<'_>, _: &mut Contacts, timer: &mut StageTimer) -> Result<(), StepError> {
        let Step { model, state, h, loads, .. } = *step;
        let mf = self.buffers.get_or_insert_with(|| Box::new(MatrixFreeBuffers::new(model)));
        let mut terms = EulerScheme.terms(state, &[], &[], h);
        terms.external = loads.forces();
        let timing = assemble_matrix_free(model, &state.x, &terms, &mut mf.system);
        timer.add(Stage::Forces, timing.links_s);
        timer.add(Stage::Assembly, timing.gather_s);
        Ok(())
    }

    fn solve(
        &mut self,
        step: &Step<'_>,
        _: &mut Contacts,
        out: &mut StepOutput,
        timer: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        let Step { model, state, control, h, solver, .. } = *step;
        let scheme = EulerScheme;
        let mf = self.buffers.as_mut().expect("assembled before solved");
        let lap = timer.start();
        // Scale: b^ = M^-1/2 b; unknown y = M^1/2 dv; pins prescribe y too.
        for ((bs, b), s) in mf.scaled_rhs.iter_mut().zip(&mf.system.rhs).zip(&mf.inv_sqrt_mass) {
            *bs = b * *s;
        }
        let inv_sqrt_mass = &mf.inv_sqrt_mass;
        constrain_pins(model, state, control, h, &mut mf.filter, |target, i| {
            scheme.pinned(state, h, target, i) / inv_sqrt_mass[i]
        });
        for (i, (u, s)) in mf.unknown.iter_mut().zip(inv_sqrt_mass).enumerate() {
            *u = scheme.guess(state, &[], i) / *s;
        }
        let system = &mf.system;
        let result = cg_fixed_iterations(
            |w, y| apply_scaled_operator(model, system, inv_sqrt_mass, w, y),
            &mf.scaled_rhs,
            &mf.filter,
            solver.fixed_cg_iterations,
            &mut mf.unknown,
            &mut mf.cg,
        );
        let info = match result {
            Ok(info) => info,
            Err(source @ (PcgError::NotPositiveDefinite { .. } | PcgError::NonFinite { .. })) => {
                return Err(StepError::Solver { step: state.steps + 1, time_s: state.time_s, source });
            }
            Err(other) => unreachable!("fixed-iteration CG reports only curvature and finiteness: {other}"),
        };
        let pins = PinPaths::new(model, control, &state.x, state.time_s, h);
        if pins.count() > 0 {
            // Pin forces from the unfiltered residual, one more operator product.
            apply_scaled_operator(model, system, inv_sqrt_mass, &mf.unknown, &mut mf.product);
            let forces = out.pin_forces_mut(pins.count());
            for (i, f) in pins.particles().zip(forces) {
                *f = (mf.product[i] - mf.scaled_rhs[i]) / (inv_sqrt_mass[i] * h);
            }
        }
        timer.stop(lap, Stage::Solve);
        let lap = timer.start();
        for i in 0..state.len() {
            let dv = mf.unknown[i] * mf.inv_sqrt_mass[i];
            (out.x[i], out.v[i]) = scheme.advance(state, &[], h, i, dv);
        }
        timer.stop(lap, Stage::Update);
        Ok(StepReport {
            force_evaluations: 1,
            substeps: 1,
            cg_iterations: info.iterations,
            rel_residual: info.rel_residual,
            converged: true,
            ..StepReport::default()
        })
    }

    fn reset(&mut self) {
        self.buffers = None;
    }
}
