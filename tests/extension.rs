//! Extending the library from outside its crates: an integrator and a
//! force term written here, plugged in through the builders.

use cloth_core::terms::{At, ForceBuffers, ForceTerm, Jacobian, JacobianBlocks, VertexBlock};
use cloth_core::{
    Capabilities, ClothModel, Contacts, GridPanel, Integrator, IntegratorKind, Mat3, Material, Simulation,
    SolverParams, StageTimer, Step, StepError, StepOutput, StepReport, Vec3,
};
use std::sync::Arc;

/// Symplectic Euler (`v' = v + h f / m`, `x' = x + h v'`) with fixed pins,
/// written with the public force loop only; its scratch (the forces and
/// the force loop's buffers) is its own, allocated on its first step.
#[derive(Debug, Default)]
struct OutsideSymplecticEuler {
    scratch: Option<(ForceBuffers, Vec<Vec3>)>,
}

impl Integrator for OutsideSymplecticEuler {
    fn name(&self) -> &'static str {
        "outside-symplectic-euler"
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities::default()
    }

    fn solve(
        &mut self,
        step: &Step<'_>,
        _: &mut Contacts,
        out: &mut StepOutput,
        _: &mut StageTimer,
    ) -> Result<StepReport, StepError> {
        let (model, state, h) = (step.model, step.state, step.h);
        let (buffers, f) =
            self.scratch.get_or_insert_with(|| (ForceBuffers::new(model), vec![Vec3::zeros(); model.particle_count()]));
        cloth_core::forces_into(model, &state.x, &state.v, &state.stitches_closed, buffers, f);
        let (x, v) = out.state_mut();
        for i in 0..state.len() {
            if model.is_pinned(i) {
                (x[i], v[i]) = (state.x[i], Vec3::zeros());
                continue;
            }
            v[i] = state.v[i] + f[i] * (h / model.masses()[i]);
            x[i] = state.x[i] + v[i] * h;
        }
        Ok(StepReport { force_evaluations: 1, substeps: 1, converged: true, ..Default::default() })
    }
}

fn hanging_cloth() -> ClothModel {
    ClothModel::builder()
        .panel(GridPanel::flat([11, 11], [0.5, 0.5]).origin([0.0, 0.0, 1.0]))
        .gravity([0.0, 0.0, -9.81])
        .damping()
        .pin_nodes(0, [[0, 10], [10, 10]])
        .build()
        .unwrap()
}

/// The outside integrator swings the cloth as the built-in symplectic
/// Euler does, bit for bit, and the simulation reports its name.
#[test]
fn an_integrator_from_outside_the_crate_steps_a_simulation() {
    let h = 2e-4;
    let mut outside =
        Simulation::builder(hanging_cloth()).custom_integrator(Box::<OutsideSymplecticEuler>::default()).build();
    let mut built_in = Simulation::builder(hanging_cloth()).integrator(IntegratorKind::SymplecticEuler).build();
    assert_eq!(outside.integrator_name(), "outside-symplectic-euler");
    assert_eq!(built_in.integrator_name(), "symplectic-euler");
    for _ in 0..500 {
        outside.step(h).unwrap();
        built_in.step(h).unwrap();
    }
    let gap = outside.state().x.iter().zip(&built_in.state().x).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    let fall = 1.0 - outside.state().x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    println!("after 0.1 s: {gap:e} m apart, lowest point {fall:.4} m down");
    assert!(fall > 0.04, "the cloth fell only {fall} m");
    assert_eq!(gap, 0.0, "the same arithmetic in the same order");
}

/// A harmonic well of the caller's own: every particle pulled towards its
/// anchor with `f_i = -m_i w^2 (x_i - a_i)`, energy `m_i w^2 |x_i - a_i|^2 / 2`.
#[derive(Debug)]
struct Well {
    anchors: Vec<Vec3>,
    omega_rad_s: f64,
}

impl ForceTerm for Well {
    fn name(&self) -> &'static str {
        "well"
    }

    fn acts_on(&self, _: &ClothModel) -> bool {
        true
    }

    fn energy(&self, at: &At<'_>) -> f64 {
        let k = self.omega_rad_s * self.omega_rad_s;
        at.x.iter()
            .zip(&self.anchors)
            .zip(at.model.masses())
            .map(|((x, a), m)| 0.5 * m * k * (x - a).norm_squared())
            .sum()
    }

    fn add_forces(&self, at: &At<'_>, _: &mut ForceBuffers, out: &mut [Vec3]) {
        for (i, f) in out.iter_mut().enumerate() {
            *f += self.vertex(at, i).force;
        }
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let k = at.model.masses()[i] * self.omega_rad_s * self.omega_rad_s;
        VertexBlock { force: (self.anchors[i] - at.x[i]) * k, stiffness: Mat3::identity() * k, ..VertexBlock::zero() }
    }
}

/// The free cloth in the well, 1 cm above its anchors: it moves as one,
/// `z(t) = a + d cos(w t)`, its links never stretched.
fn in_a_well(omega_rad_s: f64, d: f64) -> ClothModel {
    let free =
        ClothModel::builder().panel(GridPanel::flat([9, 9], [0.4, 0.4]).origin([0.0, 0.0, 1.0])).bending().damping();
    let anchors = free.build().unwrap().rest_positions().iter().map(|p| p - Vec3::new(0.0, 0.0, d)).collect();
    free.force_term(Arc::new(Well { anchors, omega_rad_s })).build().unwrap()
}

fn mean_height(sim: &Simulation) -> f64 {
    sim.state().x.iter().map(|p| p.z).sum::<f64>() / sim.state().len() as f64
}

/// A force term from outside the crate acts in the explicit and in the
/// implicit steps: the cloth swings in the well at `w`.
#[test]
fn a_force_term_from_outside_the_crate_swings_the_cloth_at_its_frequency() {
    let (omega, d) = (2.0 * std::f64::consts::PI, 0.01);
    let anchor_z = 1.0 - d;
    // Symplectic Euler, 1e-4 s: after a whole period, back where it began.
    let mut explicit = Simulation::builder(in_a_well(omega, d)).integrator(IntegratorKind::SymplecticEuler).build();
    for _ in 0..10_000 {
        explicit.step(1e-4).unwrap();
    }
    let explicit_error = (mean_height(&explicit) - (anchor_z + d)).abs();
    // BDF2 and backward Euler, 1 ms: after half a period, on the far
    // side, less their numerical damping.
    let half_period = |integrator| {
        let solver = SolverParams { rel_tol: 1e-10, ..SolverParams::default() };
        let mut sim = Simulation::builder(in_a_well(omega, d)).integrator(integrator).solver(solver).build();
        for _ in 0..500 {
            sim.step(1e-3).unwrap();
        }
        (mean_height(&sim) - (anchor_z - d), sim.model().max_stretch_ratio(&sim.state().x))
    };
    let (implicit_error, stretch) = half_period(IntegratorKind::Bdf2);
    let implicit_error = implicit_error.abs();
    let (euler_gap, _) = half_period(IntegratorKind::BackwardEuler);
    // Backward Euler's amplitude decays by (1 + w^2 h^2)^(-1/2) a step.
    let euler_expected = d * (1.0 - (1.0 + (omega * 1e-3_f64).powi(2)).powf(-250.0));
    let euler_error = (euler_gap - euler_expected).abs();
    println!(
        "explicit {explicit_error:.3e} m, BDF2 {implicit_error:.3e} m off; backward Euler {euler_gap:.4e} m short against {euler_expected:.4e} ({euler_error:.2e} m); stretch {stretch}"
    );
    // Measured 3.3e-13 m, 3.0e-7 m (BDF2's damping over 500 steps) and
    // 8.5e-12 m from backward Euler's exact damping.
    assert!(explicit_error < 1e-12, "symplectic Euler {explicit_error} m off");
    assert!(implicit_error < 5e-7, "BDF2 {implicit_error} m off");
    assert!(euler_error < 1e-10, "backward Euler {euler_gap} m short, expected {euler_expected}");
    assert!((stretch - 1.0).abs() < 1e-9, "the links stretched to {stretch}");
}

/// Springs of the caller's own between pairs of particles: `f_i = k (d -
/// L) u` on the first of each pair, `u` from it to the second, the
/// opposite on the second; energy `k (d - L)^2 / 2`. With its full
/// Jacobian (`full`), the blocks between the two ends included; without,
/// only each end's own block. As the built-in links, a compressed spring
/// leaves its (negative) transverse stiffness out of the Jacobian, which
/// the implicit steps need positive semidefinite.
#[derive(Debug)]
struct Tethers {
    pairs: Vec<[usize; 2]>,
    rest_m: Vec<f64>,
    stiffness_n_m: f64,
    full: bool,
}

impl Tethers {
    /// `-df_i/dx_j` of pair `k` at `x`: `H = k [u u^T + (d - L)/d (I - u u^T)]`.
    fn block(&self, x: &[Vec3], k: usize) -> (Vec3, Mat3) {
        let [i, j] = self.pairs[k];
        let r = x[j] - x[i];
        let d = r.norm();
        let u = r / d;
        let uu = u * u.transpose();
        let stretch = d - self.rest_m[k];
        let transverse = if stretch > 0.0 { (Mat3::identity() - uu) * (stretch / d) } else { Mat3::zeros() };
        let h = (uu + transverse) * self.stiffness_n_m;
        (u * (self.stiffness_n_m * stretch), h)
    }
}

impl ForceTerm for Tethers {
    fn name(&self) -> &'static str {
        "tethers"
    }

    fn acts_on(&self, _: &ClothModel) -> bool {
        true
    }

    fn energy(&self, at: &At<'_>) -> f64 {
        let pair = |(k, [i, j]): (usize, &[usize; 2])| (at.x[*j] - at.x[*i]).norm() - self.rest_m[k];
        self.pairs.iter().enumerate().map(|p| 0.5 * self.stiffness_n_m * pair(p).powi(2)).sum()
    }

    fn add_forces(&self, at: &At<'_>, _: &mut ForceBuffers, out: &mut [Vec3]) {
        for (k, &[i, j]) in self.pairs.iter().enumerate() {
            let (f, _) = self.block(at.x, k);
            out[i] += f;
            out[j] -= f;
        }
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let mut block = VertexBlock::zero();
        for (k, pair) in self.pairs.iter().enumerate().filter(|(_, p)| p.contains(&i)) {
            let (f, h) = self.block(at.x, k);
            block.force += if pair[0] == i { f } else { -f };
            block.stiffness += h;
        }
        block
    }

    fn coupled_pairs(&self, _: &ClothModel) -> Vec<[usize; 2]> {
        if self.full { self.pairs.clone() } else { Vec::new() }
    }

    fn jacobian(&self, at: &At<'_>, out: &mut Jacobian<'_>) {
        if !self.full {
            for i in 0..at.x.len() {
                let b = self.vertex(at, i);
                out.add_force(i, b.force);
                out.add_stiffness(i, i, &b.stiffness);
            }
            return;
        }
        for (k, &[i, j]) in self.pairs.iter().enumerate() {
            let (f, h) = self.block(at.x, k);
            out.add_force(i, f);
            out.add_force(j, -f);
            out.add_stiffness(i, i, &h);
            out.add_stiffness(j, j, &h);
            out.add_stiffness(i, j, &-h);
            out.add_stiffness(j, i, &-h);
        }
    }
}

/// A 9 x 9 sheet of Volino's model (20 cm, damped by viscous drag)
/// hanging from its top corners, whose bottom corners a tether of
/// stiffness `k` (N/m) and rest length `ratio` times their distance
/// pushes apart (`ratio > 1`) or pulls together; `None`: no tether.
fn tethered_sheet(k: Option<f64>, ratio: f64, full: bool) -> ClothModel {
    let sheet = ClothModel::builder()
        .panel(GridPanel::flat([9, 9], [0.2, 0.2]).origin([0.0, 0.0, 1.0]))
        .kind(cloth_core::ModelKind::Volino)
        .material(Material { drag_n_s_m3: 1.0, ..Material::default() })
        .drag()
        .gravity([0.0, 0.0, -9.81])
        .bending()
        .damping()
        .pin_nodes(0, [[0, 8], [8, 8]])
        .build()
        .unwrap();
    let Some(stiffness_n_m) = k else { return sheet };
    let width = (sheet.rest_positions()[8] - sheet.rest_positions()[0]).norm();
    let tethers = Tethers { pairs: vec![[0, 8]], rest_m: vec![ratio * width], stiffness_n_m, full };
    sheet.with_force_term(Arc::new(tethers))
}

/// The tether's Jacobian, the blocks between its ends included, against
/// finite differences of its forces (stretched, where it is exact).
#[test]
fn a_coupling_term_from_outside_gives_its_blocks_between_particles() {
    let model = tethered_sheet(Some(20.0), 0.8, true);
    let term = model.extra_terms()[0].as_ref();
    let x: Vec<Vec3> =
        model.rest_positions().iter().map(|p| p + Vec3::new(0.01 * p.y, -0.02 * p.x, 0.03 * p.x)).collect();
    let still = vec![Vec3::zeros(); x.len()];
    let blocks = JacobianBlocks::of(term, &At::new(&model, &x, &still, &[]));
    let forces = |y: &[Vec3]| {
        let mut out = vec![Vec3::zeros(); y.len()];
        term.add_forces(&At::new(&model, y, &still, &[]), &mut ForceBuffers::new(&model), &mut out);
        out
    };
    let (step, mut worst, mut largest) = (1e-7, 0.0_f64, 0.0_f64);
    for j in [0, 8] {
        for c in 0..3 {
            let (mut plus, mut minus) = (x.clone(), x.clone());
            plus[j][c] += step;
            minus[j][c] -= step;
            let (fp, fm) = (forces(&plus), forces(&minus));
            for i in [0, 8] {
                let dfdx = (fp[i] - fm[i]) / (2.0 * step);
                worst = worst.max((blocks.stiffness(i, j).column(c) + dfdx).abs().max());
                largest = largest.max(blocks.stiffness(i, j).abs().max());
            }
        }
    }
    println!("tether blocks off by {worst:.2e} N/m of {largest:.2e}; (0, 8) = {}", blocks.stiffness(0, 8));
    // Measured 2.8e-9 N/m of 20.
    assert!(blocks.stiffness(0, 8) != Mat3::zeros());
    assert!(worst < 1e-7 * largest, "{worst:e}");
}

/// BDF2 with the tether converges as it does with the built-in terms
/// alone: every PCG solve converges, in about as many iterations, and
/// the damped sheet comes to rest where the tether's pull balances the
/// springs (the force on every particle vanishes). At large steps the
/// blocks between the tether's ends are what keeps a stiff tether stable:
/// with its full Jacobian it settles; with each end's own block only,
/// the step blows up.
#[test]
fn bdf2_converges_with_a_coupling_term_from_outside_as_with_the_built_ins() {
    // The single linearised step, whose stability the blocks decide: the
    // automatic Newton step (`auto_trigger`) would also settle the tether
    // with its ends' own blocks only, its misjudged steps taking Newton
    // iterations (0.056 m/s after 4 s).
    let newton = cloth_core::NewtonParams { auto_trigger: 0.0, ..Default::default() };
    let solver = SolverParams { rel_tol: 1e-8, newton, ..SolverParams::default() };
    let run = |model: &ClothModel, h: f64, steps: usize| -> Result<(Simulation, f64), cloth_core::StepError> {
        let mut sim = Simulation::builder(model.clone()).solver(solver).build();
        let mut iterations = 0;
        for _ in 0..steps {
            let report = sim.step(h)?;
            assert!(report.converged, "{report:?}");
            iterations += report.cg_iterations;
        }
        Ok((sim, iterations as f64 / steps as f64))
    };
    let h = 1.0 / 90.0;
    let (_, alone) = run(&tethered_sheet(None, 1.0, true), h, 900).unwrap();
    let (settled, tethered) = run(&tethered_sheet(Some(20.0), 1.2, true), h, 900).unwrap();
    let (model, state) = (settled.model(), settled.state());
    let forces = cloth_core::total_forces(model, &state.x, &state.v, &state.stitches_closed);
    let free = forces.iter().enumerate().filter(|(i, _)| !model.is_pinned(*i));
    let (residual, tether) = (
        free.map(|(_, f)| f.norm()).fold(0.0, f64::max),
        JacobianBlocks::of(
            model.extra_terms()[0].as_ref(),
            &At::new(model, &state.x, &state.v, &state.stitches_closed),
        )
        .force(0)
        .norm(),
    );
    let speed = state.v.iter().map(|v| v.norm()).fold(0.0, f64::max);
    println!(
        "CG iterations a step: {alone:.1} alone, {tethered:.1} tethered; at rest ({speed:.1e} m/s) the force on \
         any particle is at most {residual:.2e} N against the tether's {tether:.3} N"
    );
    // Measured 33.3 against 27.4 iterations (the multigrid's coarse levels
    // know the grid's couplings only); 5.1e-4 m/s, 2.2e-5 N against 0.446 N.
    assert!(tethered < 1.3 * alone, "{tethered} against {alone}");
    assert!(speed < 1e-3 && residual < 1e-4 * tether, "{speed} m/s, {residual} N");
    let (stiff, large) = (2e4, 0.02);
    let settles = |full: bool| {
        let (sim, _) = run(&tethered_sheet(Some(stiff), 1.2, full), large, 200).unwrap();
        let speed = sim.state().v.iter().map(|v| v.norm()).fold(0.0, f64::max);
        (speed, (sim.state().x[8] - sim.state().x[0]).norm())
    };
    let (full, own_blocks) = (settles(true), settles(false));
    println!(
        "stiff tether at h = {large} s after 4 s: full Jacobian {:.2e} m/s, {:.4} m apart; ends' own blocks {:.2e} m/s, {:.4} m",
        full.0, full.1, own_blocks.0, own_blocks.1
    );
    // Measured: 4.9e-3 m/s and 0.2399 m (its rest length 0.24 m); 16.7 m/s
    // and 0.078 m.
    let rest = 1.2 * 0.2;
    assert!(full.0 < 1e-2 && (full.1 / rest - 1.0).abs() < 1e-3, "the full Jacobian's step did not settle: {full:?}");
    assert!(own_blocks.0 > 1.0, "each end's own block settled too: {own_blocks:?}");
}
