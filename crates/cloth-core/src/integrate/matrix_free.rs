//! Backward Euler with a FIXED number of matrix-free CG iterations and
//! `m^-1/2` mass scaling: the variant Volino & Magnenat-Thalmann (2001)
//! found most efficient ("backward Euler, n CG iterations"). Each step
//! solves `[M - h D - h^2 K] dv = h (f + h K v)` approximately: the unknown
//! is scaled to `y = M^1/2 dv`, so the operator `M^-1/2 A M^-1/2` has unit
//! mass part, and CG runs exactly `SolverParams::fixed_cg_iterations`
//! iterations with the product computed link by link, never assembled.

use crate::control::{Control, PinPaths};
use crate::{
    ClothModel, ClothState, SolverParams, Vec3, Workspace,
    forces::{apply_scaled_operator, assemble_matrix_free},
    integrator::{
        BackwardEuler, Linearised, StageTimes, StepError, StepReport, check_step, collide_after_step, commit,
        constrain_pins, external_forces, reject_self_collision,
    },
};
use cloth_linalg::{CgScratch, PcgError, cg_fixed_iterations};
use std::time::Instant;

/// Buffers of the matrix-free solver, allocated on first use.
#[derive(Debug, Clone)]
pub(crate) struct MatrixFreeBuffers {
    inv_sqrt_mass: Vec<f64>,
    scaled_rhs: Vec<Vec3>,
    cg: CgScratch,
}

impl MatrixFreeBuffers {
    fn new(model: &ClothModel) -> Self {
        let n = model.particle_count();
        Self {
            inv_sqrt_mass: model.masses().iter().map(|m| 1.0 / m.sqrt()).collect(),
            scaled_rhs: vec![Vec3::zeros(); n],
            cg: CgScratch::new(n),
        }
    }
}

/// Backward Euler solved by a fixed number of matrix-free CG iterations.
#[derive(Debug, Clone, Copy, Default)]
pub struct BackwardEulerFixedCg;

impl crate::Integrator for BackwardEulerFixedCg {
    fn name(&self) -> &'static str {
        crate::IntegratorKind::BackwardEulerFixedCg.name()
    }

    fn step(
        &self,
        model: &ClothModel,
        state: &mut ClothState,
        control: &Control,
        h: f64,
        ws: &mut Workspace,
        solver: &SolverParams,
    ) -> Result<StepReport, StepError> {
        check_step(model, state, h)?;
        reject_self_collision(model, self.name())?;
        let scheme = BackwardEuler;
        let has_wind = external_forces(model, state, control, ws);
        let mut terms = scheme.terms(state, &ws.aux, &ws.aux2, h);
        terms.external = has_wind.then_some(&ws.external[..]);
        let timing = assemble_matrix_free(model, &state.x, &terms, &mut ws.system);
        let t_solve = Instant::now();
        let mf = ws.matrix_free.get_or_insert_with(|| MatrixFreeBuffers::new(model));
        // Scale: b^ = M^-1/2 b; unknown y = M^1/2 dv; pins prescribe y too.
        for ((bs, b), s) in mf.scaled_rhs.iter_mut().zip(&ws.system.rhs).zip(&mf.inv_sqrt_mass) {
            *bs = b * *s;
        }
        let inv_sqrt_mass = &mf.inv_sqrt_mass;
        constrain_pins(model, state, control, h, &mut ws.filter, |target, i| {
            scheme.pinned(state, h, target, i) / inv_sqrt_mass[i]
        });
        for (i, (u, s)) in ws.unknown.iter_mut().zip(inv_sqrt_mass).enumerate() {
            *u = scheme.guess(state, &ws.aux, i) / *s;
        }
        let system = &ws.system;
        let result = cg_fixed_iterations(
            |w, y| apply_scaled_operator(model, system, inv_sqrt_mass, w, y),
            &mf.scaled_rhs,
            &ws.filter,
            solver.fixed_cg_iterations,
            &mut ws.unknown,
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
            apply_scaled_operator(model, system, inv_sqrt_mass, &ws.unknown, &mut ws.aux);
            ws.pin_forces.resize(pins.count(), Vec3::zeros());
            for (i, f) in pins.particles().zip(&mut ws.pin_forces) {
                *f = (ws.aux[i] - mf.scaled_rhs[i]) / (inv_sqrt_mass[i] * h);
            }
        }
        let solve_s = t_solve.elapsed().as_secs_f64();
        let t_update = Instant::now();
        for i in 0..state.len() {
            let dv = ws.unknown[i] * mf.inv_sqrt_mass[i];
            (ws.new_x[i], ws.new_v[i]) = scheme.advance(state, &ws.aux, h, i, dv);
        }
        let mut stages = StageTimes {
            forces_s: timing.links_s,
            assembly_s: timing.gather_s,
            solve_s,
            update_s: t_update.elapsed().as_secs_f64(),
            ..StageTimes::default()
        };
        let contacts = collide_after_step(model, state, control, h, ws, &mut stages);
        commit(state, ws, h)?;
        Ok(StepReport {
            force_evaluations: 1,
            substeps: 1,
            rejected_steps: 0,
            strain_corrections: 0,
            cg_iterations: info.iterations,
            rel_residual: info.rel_residual,
            converged: true,
            stages,
            contacts,
            newton: None,
            energy: None,
            retaken_as_backward_euler: false,
            retaken_with_newton: false,
            descent_iterations: 0,
        })
    }
}
