//! Rigid bodies inside the cloth's linear solve (monolithic coupling).
//!
//! A body that drives some of the model's external solids and pins (a
//! rapier body the cloth touches or hangs from) can join the implicit
//! step as six unknowns: the change of its mean linear and angular
//! velocity over the step from the motion the control set. The particles
//! it holds (its pins, and the contacts with its solids) then follow it
//! in the solve, and it takes their reactions: `M_b dq_b = -h sum_i J_i^T
//! f_i`, the same impulse `h f` the cloth reports on it
//! ([`crate::Simulation::solid_impulse`], pin reactions). The solve is
//! [`cloth_linalg::CoupledPcg`]'s reduced saddle-point system, positive
//! definite with the cloth's matrix.
//!
//! The motion set for the body is a guess (its free flight, or where it
//! went last step); `BodyInSolve::ahead_m_s` says how far the guess is
//! from the free flight, so that the body row reads `M (dq + ahead) = -h
//! J^T f`.
//!
//! In the cloth's unknown a body's change is `y = g dq` with `g = h /
//! (dx'/du)` (`h` for BDF2, whose unknown is a displacement, `1` for
//! backward Euler's velocity change), and its mass block is `K = c_f /
//! (h g) M_b` with the scheme's force coefficient `c_f`: the body row
//! then reads `M_b dq = -h J^T f` for the force `f = (A x - b) / c_f` that
//! the constrained rows carry.
//!
//! Friction on a body's contacts is decided in the solve, as on a
//! prescribed solid: a stuck particle follows the body in all three
//! directions, a sliding one's `mu N` loads the body's row. Newton
//! corrections (when asked for) see the bodies on the motion the settled
//! solve gave them.

use super::bodies::{BodyInSolve, lever};
use crate::contacts::{Contacts, FrictionMode, SolidContact};
use crate::control::SolidMotion;
use crate::{ClothModel, Mat3, Vec3};
use cloth_collide::BodyPose;
use cloth_linalg::{ConstraintFilter, CoupledPcg, RigidCoupling};
use nalgebra::UnitQuaternion;
use nalgebra::{Matrix6, Vector6};

/// Sweeps of [`BodyBuffers::stop_separation`] over the contacts: fixed, so
/// that results do not depend on a tolerance.
const NO_BOUNCE_SWEEPS: usize = 8;

/// A particle's body, while linking: none yet, one, or several (a
/// particle between two bodies, or a body and a fixed solid, stays
/// outside the coupling: its contacts act on it as on prescribed solids).
const NO_BODY: usize = usize::MAX;
const MIXED: usize = usize::MAX - 1;

/// The step's bodies and their coupled solve.
#[derive(Debug, Clone, Default)]
pub(crate) struct BodyBuffers {
    coupling: RigidCoupling,
    solver: CoupledPcg,
    /// Each body's unknown in the cloth's units.
    y: Vec<Vector6<f64>>,
    /// `g`: the cloth unknown per body velocity (see the module).
    unknown_per_velocity: f64,
    /// The scheme's force coefficient `c_f`.
    force_coefficient: f64,
    /// Each body's centre of mass at the end of the step.
    com: Vec<Vec3>,
    /// Each body's load from its guess's head start, `-K g ahead`.
    ahead: Vec<Vector6<f64>>,
    /// Each body's mass block `K` in the cloth's units.
    mass_block: Vec<Matrix6<f64>>,
    /// Scratch of [`BodyBuffers::correct`]: each body's unknown before.
    y_before: Vec<Vector6<f64>>,
    /// The body of each model solid, or `NO_BODY`.
    solid_body: Vec<usize>,
    /// `(body, particle, lever)` of every pin on a body.
    pins: Vec<(usize, usize, Vec3)>,
    /// Scratch: each particle's body among its active contacts.
    particle_body: Vec<usize>,
    /// Whether the solver has the model's multigrid hierarchy.
    has_multigrid: bool,
    /// Each body's mean velocity change over the step, m/s and rad/s.
    pub(crate) velocity_change: Vec<(Vec3, Vec3)>,
    /// Each body's inverse mass (1 / kg) and inverse world inertia
    /// (1 / (kg m^2)).
    inverse_mass: Vec<(f64, Mat3)>,
    /// Scratch: each body's velocity change from no-bounce impacts.
    impact_change: Vec<(Vec3, Vec3)>,
}

impl BodyBuffers {
    /// Sets the step's bodies: their mass blocks for a scheme with force
    /// coefficient `c_f` and `dx'/du = position_per_unknown`, their pins'
    /// levers to the pins' targets at `t + h`.
    pub(crate) fn prepare(
        &mut self,
        model: &ClothModel,
        multigrid: bool,
        bodies: &[BodyInSolve],
        pin_target: impl Fn(usize) -> Vec3,
        (h, c_f, position_per_unknown): (f64, f64, f64),
    ) {
        if multigrid && !bodies.is_empty() && !self.has_multigrid {
            self.solver.set_multigrid(model.multigrid());
            self.has_multigrid = true;
        }
        self.coupling.clear();
        self.pins.clear();
        self.com.clear();
        self.inverse_mass.clear();
        self.ahead.clear();
        self.mass_block.clear();
        self.solid_body.clear();
        self.solid_body.resize(model.colliders().len(), NO_BODY);
        self.unknown_per_velocity = h / position_per_unknown;
        self.force_coefficient = c_f;
        let scale = c_f / (h * self.unknown_per_velocity);
        for (k, b) in bodies.iter().enumerate() {
            let mut m = Matrix6::zeros();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(Mat3::identity() * (b.mass_kg * scale)));
            m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(b.inertia_kg_m2 * scale));
            self.coupling.add_body(m);
            self.mass_block.push(m);
            // `M (dq + ahead) = -h J^T f` in the cloth's units.
            let ahead = Vector6::new(
                b.ahead_m_s.x,
                b.ahead_m_s.y,
                b.ahead_m_s.z,
                b.ahead_rad_s.x,
                b.ahead_rad_s.y,
                b.ahead_rad_s.z,
            );
            self.ahead.push(-(m * ahead) * self.unknown_per_velocity);
            self.com.push(b.com_m);
            let inverse_inertia = b.inertia_kg_m2.try_inverse().unwrap_or_else(Mat3::zeros);
            self.inverse_mass.push((1.0 / b.mass_kg, inverse_inertia));
            for &s in &b.solids {
                self.solid_body[s] = k;
            }
            for &p in &b.pins {
                self.pins.push((k, model.pins()[p].particle, pin_target(p) - b.com_m));
            }
        }
        self.y.clear();
        self.y.resize(bodies.len(), Vector6::zeros());
        self.velocity_change.clear();
        self.velocity_change.resize(bodies.len(), (Vec3::zeros(), Vec3::zeros()));
    }

    /// Whether `c` is a contact with a body's solid.
    pub(crate) fn holds(&self, c: &SolidContact) -> bool {
        self.solid_body.get(c.collider as usize).is_some_and(|&b| b != NO_BODY)
    }

    /// Whether `c` is a contact with a body heavier than its particle, of
    /// `particle_mass` kg.
    pub(crate) fn outweighs(&self, c: &SolidContact, particle_mass: f64) -> bool {
        let body = self.solid_body.get(c.collider as usize).filter(|&&b| b != NO_BODY);
        body.is_some_and(|&b| self.inverse_mass[b].0 * particle_mass < 1.0)
    }

    /// No bounce off a body (see `stop_separation` for solids that do not
    /// move): a particle that one body's solid holds alone and that leaves
    /// it along the normal at `u` after the solve meets the body in a
    /// plastic impact, the impulse `u / (1/m + 1/M + (r x n)^T I^-1 (r x n))`
    /// along the normal shared by both, the contacts of the body then
    /// moving with its new velocity; in contact order, [`NO_BOUNCE_SWEEPS`]
    /// times. Stopping the particle alone, as against an immovable solid,
    /// hands the body its whole momentum `m u`: a ball of 1e-3 the cloth's
    /// mass, whose solve pushed four particles 4 mm out of it, was thrown
    /// at 37 m/s. Each impact loses energy; the impulse joins the contact's.
    pub(crate) fn stop_separation(&mut self, contacts: &mut [SolidContact], masses: &[f64], new_v: &mut [Vec3]) {
        if !self.active() {
            return;
        }
        // Each body's velocity change from the impacts so far.
        self.impact_change.clear();
        self.impact_change.resize(self.com.len(), (Vec3::zeros(), Vec3::zeros()));
        for _ in 0..NO_BOUNCE_SWEEPS {
            let mut moved = false;
            for group in contacts.chunk_by_mut(crate::contacts::same_particle) {
                let Some((a, None)) = crate::contacts::held_by(group) else { continue };
                let c = &mut group[a];
                if !self.holds(c) {
                    continue;
                }
                let (i, n, body) = (c.particle as usize, c.normal, self.solid_body[c.collider as usize]);
                let (r, (dv, dw)) = (c.point - self.com[body], self.impact_change[body]);
                let leaving = n.dot(&(new_v[i] - c.solid_velocity - dv - dw.cross(&r)));
                if leaving <= 0.0 {
                    continue;
                }
                let (inverse_mass, inverse_inertia) = self.inverse_mass[body];
                let arm = r.cross(&n);
                let share = 1.0 / masses[i] + inverse_mass + arm.dot(&(inverse_inertia * arm));
                let impulse = n * (leaving / share);
                new_v[i] -= impulse / masses[i];
                c.impulse_n_s -= impulse;
                let change = &mut self.impact_change[body];
                change.0 += impulse * inverse_mass;
                change.1 += inverse_inertia * r.cross(&impulse);
                moved = true;
            }
            if !moved {
                break;
            }
        }
        for c in contacts.iter_mut() {
            let body = self.solid_body[c.collider as usize];
            if body != NO_BODY {
                let (dv, dw) = self.impact_change[body];
                c.solid_velocity += dv + dw.cross(&(c.point - self.com[body]));
            }
        }
    }

    /// Whether any body joins the step.
    pub(crate) fn active(&self) -> bool {
        self.coupling.body_count() > 0
    }

    /// Links the particles the bodies hold under `filter`: their pins, and
    /// particles whose active constrained contacts are all with one body.
    pub(crate) fn link(&mut self, filter: &ConstraintFilter, contacts: &[SolidContact], n: usize) {
        self.coupling.clear_links();
        for (k, load) in self.ahead.iter().enumerate() {
            self.coupling.add_load(k, *load);
        }
        let constrained = |i: usize| Mat3::identity() - filter.projector(i);
        for &(body, i, r) in &self.pins {
            self.coupling.link(body, i, constrained(i) * lever(r));
        }
        self.particle_body.clear();
        self.particle_body.resize(n, NO_BODY);
        for c in contacts.iter().filter(|c| c.active && !c.pressed) {
            // A solid of no body counts as a body of its own: a particle
            // it also holds stays where that solid puts it.
            let (i, body) = (c.particle as usize, self.solid_body[c.collider as usize]);
            let body = if body == NO_BODY { MIXED } else { body };
            let slot = &mut self.particle_body[i];
            *slot = if *slot == NO_BODY || *slot == body { body } else { MIXED };
        }
        for c in contacts.iter().filter(|c| c.active && c.pressed) {
            // A body pressing a particle onto another solid pushes it with
            // a fixed force: the body takes the opposite.
            let body = self.solid_body[c.collider as usize];
            if body != NO_BODY {
                let j = lever(c.point - self.com[body]);
                let push = c.normal * c.normal_force_n;
                self.coupling.add_load(body, -(j.transpose() * push) * self.force_coefficient);
            }
        }
        for c in contacts.iter().filter(|c| c.active && !c.pressed) {
            let i = c.particle as usize;
            let body = self.particle_body[i];
            if body < MIXED && !filter.is_free(i) {
                let j = lever(c.point - self.com[body]);
                self.coupling.link(body, i, constrained(i) * j);
                if c.friction_mode == FrictionMode::Slide {
                    // The sliding friction the particle takes, the body gives.
                    self.coupling.add_load(body, -(j.transpose() * c.solve_constant_n) * self.force_coefficient);
                }
                // One link a particle, whatever its number of contacts.
                self.particle_body[i] = NO_BODY;
            }
        }
    }

    /// The coupled solve of `a x = b` under `filter` (see
    /// [`cloth_linalg::CoupledPcg::solve`]); `x` is the cloth's unknown.
    pub(crate) fn solve(
        &mut self,
        a: &cloth_linalg::BlockSparseMatrix,
        b: &[Vec3],
        filter: &ConstraintFilter,
        params: &cloth_linalg::PcgParams,
        x: &mut [Vec3],
    ) -> Result<cloth_linalg::PcgInfo, cloth_linalg::PcgError> {
        let result = self.solver.solve(a, b, filter, &self.coupling, params, (x, &mut self.y));
        self.set_velocity_change();
        result
    }

    /// A Newton correction of the coupled solve, after [`Self::link`]:
    /// `dx` (the cloth's) and each body's `dy` such that the body row
    /// holds at `y + dy`, `K (y + dy) = -sum G^T (A dx - b) + l` with `b`
    /// the residual's negative at the iterate. `filter` prescribes zero
    /// (`ConstraintFilter::zero_prescribed`): the links keep their
    /// particles on the body, which moves by `G dy`.
    pub(crate) fn correct(
        &mut self,
        a: &cloth_linalg::BlockSparseMatrix,
        b: &[Vec3],
        filter: &ConstraintFilter,
        params: &cloth_linalg::PcgParams,
        dx: &mut [Vec3],
    ) -> Result<cloth_linalg::PcgInfo, cloth_linalg::PcgError> {
        self.y_before.clone_from(&self.y);
        for (k, (m, y)) in self.mass_block.iter().zip(&self.y).enumerate() {
            self.coupling.add_load(k, -(m * y));
        }
        self.y.iter_mut().for_each(|y| *y = Vector6::zeros());
        let result = self.solver.solve(a, b, filter, &self.coupling, params, (dx, &mut self.y));
        for (y, before) in self.y.iter_mut().zip(&self.y_before) {
            *y += before;
        }
        self.set_velocity_change();
        result
    }

    /// `velocity_change` from the bodies' unknowns.
    fn set_velocity_change(&mut self) {
        let g = self.unknown_per_velocity;
        for (out, y) in self.velocity_change.iter_mut().zip(&self.y) {
            *out = (Vec3::new(y[0], y[1], y[2]) / g, Vec3::new(y[3], y[4], y[5]) / g);
        }
    }

    /// Moves the bodies' solids to where the solve took them: each
    /// contact's solid velocity by the body's change at the contact point,
    /// and the step's copy of each solid's motion, so what follows the
    /// solve (friction, no bounce, the last projection out of solids, the
    /// energy balance) sees the body as it moves. (Left on the guess, the
    /// projection pushed particles that had followed a body below its
    /// guess out of the guess.)
    pub(crate) fn follow(&self, contacts: &mut Contacts, h: f64) {
        for c in contacts.solid.iter_mut() {
            let body = self.solid_body[c.collider as usize];
            if body != NO_BODY {
                let (dv, dw) = self.velocity_change[body];
                c.solid_velocity += dv + dw.cross(&(c.point - self.com[body]));
            }
        }
        for (k, motion) in contacts.external.iter_mut().enumerate() {
            let body = self.solid_body.get(k).copied().unwrap_or(NO_BODY);
            let Some(m) = motion.as_mut().filter(|_| body != NO_BODY) else { continue };
            let (dv, dw) = self.velocity_change[body];
            let (end, com) = (m.pose_at(m.time_s + h), self.com[body]);
            let turn = UnitQuaternion::from_scaled_axis(dw * h);
            let moved =
                BodyPose { position: com + dv * h + turn * (end.position - com), rotation: turn * end.rotation };
            *m = SolidMotion::between(m.time_s, m.pose, moved, h);
        }
        contacts.next.time = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where a body's material point ends when the step turns the body by
    /// `h dw` about its centre of mass and moves it by `h dv` (as
    /// `BodyBuffers::follow` and rapier do).
    fn moved(point: Vec3, com: Vec3, (dv, dw): (Vec3, Vec3), h: f64) -> Vec3 {
        com + dv * h + UnitQuaternion::from_scaled_axis(dw * h) * (point - com)
    }

    /// No bounce off a body is a plastic impact of particle and body: a
    /// light ball (1e-4 kg) under four particles (1e-4 kg each) that leave
    /// it along their normals. Afterwards none leaves, the momentum of
    /// particles plus body is what it was (linear and angular about the
    /// centre of mass), the kinetic energy has not risen, and the impulses
    /// the contacts report are what the body took. Against an immovable
    /// solid (the body's mass huge) the particles alone stop, as
    /// `stop_separation` does for solids.
    #[test]
    fn no_bounce_off_a_body_is_a_plastic_impact() {
        for body_mass in [1e-4, 1e9] {
            let (m, com, radius) = (1e-4, Vec3::new(0.1, -0.2, 0.5), 0.08);
            let inertia = Mat3::identity() * (0.4 * body_mass * radius * radius);
            let mut bodies = BodyBuffers::default();
            bodies.coupling.add_body(Matrix6::identity());
            bodies.com.push(com);
            bodies.inverse_mass.push((1.0 / body_mass, inertia.try_inverse().unwrap()));
            bodies.solid_body = vec![0];
            let (v_body, w_body) = (Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 3.0, 0.0));
            let normals = [Vec3::new(0.4, 0.3, -0.866), Vec3::new(-0.4, 0.3, -0.866), Vec3::new(0.0, -0.5, -0.866)];
            let mut contacts: Vec<SolidContact> = normals
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    let n = n.normalize();
                    let point = com + n * radius;
                    SolidContact::new(i, 0, point, n, v_body + w_body.cross(&(point - com)), 0.3)
                })
                .collect();
            // Each particle leaves its contact at 0.5-1.5 m/s along the normal.
            let mut v: Vec<Vec3> = contacts
                .iter()
                .enumerate()
                .map(|(i, c)| c.solid_velocity + c.normal * (0.5 + 0.5 * i as f64))
                .collect();
            let masses = vec![m; v.len()];
            let points: Vec<Vec3> = contacts.iter().map(|c| c.point).collect();
            let momentum = |v: &[Vec3], vb: Vec3, wb: Vec3| {
                let linear = v.iter().map(|u| u * m).sum::<Vec3>() + vb * body_mass;
                let angular = points.iter().zip(v).map(|(p, u)| (p - com).cross(&(u * m))).sum::<Vec3>() + inertia * wb;
                (linear, angular)
            };
            let particles_energy = |v: &[Vec3]| v.iter().map(|u| 0.5 * m * u.norm_squared()).sum::<f64>();
            let ((p0, l0), e0) = (momentum(&v, v_body, w_body), particles_energy(&v));
            bodies.stop_separation(&mut contacts, &masses, &mut v);
            let (dv, dw) = bodies.impact_change[0];
            let (vb, wb) = (v_body + dv, w_body + dw);
            let (p1, l1) = momentum(&v, vb, wb);
            // The change of kinetic energy, the body's written so as not
            // to cancel: M (v + dv/2) . dv + (w + dw/2) . I dw.
            let gained = particles_energy(&v) - e0
                + body_mass * (v_body + dv * 0.5).dot(&dv)
                + (w_body + dw * 0.5).dot(&(inertia * dw));
            let leaving =
                contacts.iter().zip(&v).map(|(c, u)| c.normal.dot(&(u - c.solid_velocity))).fold(0.0, f64::max);
            let taken: Vec3 = contacts.iter().map(|c| -c.impulse_n_s).sum();
            let scale = body_mass.max(1.0);
            println!(
                "body {body_mass:e} kg: leaving {leaving:.1e} m/s, momentum off {:.1e} / {:.1e} N s, energy {gained:.3e} J of {e0:.3e}",
                (p1 - p0).norm(),
                (l1 - l0).norm(),
            );
            assert!(leaving < 1e-12, "a particle still leaves at {leaving} m/s");
            assert!((p1 - p0).norm() < 1e-15 * scale && (l1 - l0).norm() < 1e-15 * scale, "momentum changed");
            assert!(gained < 0.0, "the impacts made {gained} J");
            assert!((taken - dv * body_mass).norm() < 1e-12 * scale, "the body took {taken} N s");
            if body_mass > 1.0 {
                // The particles stopped against it: their momentum m u went to it.
                assert!(dv.norm() < 1e-12 && leaving < 1e-12);
            } else {
                assert!(dv.norm() > 0.1, "a light body moves with the particles");
            }
        }
    }

    /// The solve's link map `J` is the Jacobian of the rigid motion: central
    /// differences of the moved point in each of the six velocities.
    #[test]
    fn the_lever_is_the_jacobian_of_the_rigid_motion() {
        let (com, point, h) = (Vec3::new(0.3, -0.2, 1.1), Vec3::new(0.45, 0.1, 0.9), 0.01);
        let j = lever(point - com);
        let eps = 1e-4;
        let mut worst: f64 = 0.0;
        for k in 0..6 {
            let mut d = [Vec3::zeros(), Vec3::zeros()];
            d[k / 3][k % 3] = eps;
            let plus = moved(point, com, (d[0], d[1]), h);
            let minus = moved(point, com, (-d[0], -d[1]), h);
            let fd = (plus - minus) / (2.0 * eps * h);
            worst = worst.max((fd - j.column(k)).norm());
        }
        // Measured 8.2e-11: the round-off of differences of 1e-6 m.
        assert!(worst < 1e-10, "J off finite differences by {worst:e}");
        // A mutant with the lever's sign flipped is far off.
        let wrong = lever(com - point);
        assert!((wrong.column(3) - j.column(3)).norm() > 0.1);
    }

    /// The coupled step solves the coupled system whose Jacobian is taken
    /// by finite differences of the cloth's forces. A 5 x 4 sheet,
    /// stretched and moving, hangs by its top edge from a free body; one
    /// backward Euler step with the body in the solve. With `K d` the
    /// central difference of the forces along `d = h v'`, every free
    /// particle satisfies `m (v' - v) = h (f(x, v') + K d)`, the pinned
    /// ones follow the body, `v' = (p - x) / h + J dq`, and the body takes
    /// what holds them: `M_b dq = sum J^T (h (f(x, v') + K d) - m (v' - v))`.
    #[test]
    fn the_coupled_step_solves_the_system_of_finite_differences() {
        use crate::{Edge, IntegratorKind, ModelKind, PinMotion, PinSpec, Simulation, SolverParams};
        let model = ClothModel::builder()
            .grid([5, 4], [0.4, 0.3])
            .kind(ModelKind::Provot)
            .damping()
            .gravity([0.0, 0.0, -9.81])
            .pin(PinSpec { edge: Some(Edge::JMax), motion: PinMotion::External, ..PinSpec::default() })
            .build()
            .unwrap();
        let solver = SolverParams { rel_tol: 1e-13, max_iter: 10_000, ..SolverParams::default() };
        let mut sim = Simulation::new(model.clone(), IntegratorKind::BackwardEuler, solver);
        let mut start = sim.snapshot();
        for (i, (x, v)) in start.state.x.iter_mut().zip(start.state.v.iter_mut()).enumerate() {
            *x = Vec3::new(x.x * 1.03, x.y * 1.02, x.z + ((i * 7 % 5) as f64 - 2.0) * 1e-3);
            *v = Vec3::new(0.01 * i as f64, -0.02, 0.03 * (i % 3) as f64);
        }
        sim.restore(&start).unwrap();
        let h = 0.01;
        let pins: Vec<usize> = model.pins().iter().map(|p| p.particle).collect();
        let targets: Vec<Vec3> = pins.iter().map(|&i| start.state.x[i] + Vec3::new(0.02, 0.0, 0.05) * h).collect();
        for (k, t) in targets.iter().enumerate() {
            sim.set_pin_target(k, *t).unwrap();
        }
        let com = targets.iter().sum::<Vec3>() / targets.len() as f64 + Vec3::new(0.0, 0.05, 0.02);
        let (mass, inertia) = (0.3, Mat3::from_diagonal(&Vec3::new(0.01, 0.02, 0.015)));
        let body = BodyInSolve {
            mass_kg: mass,
            inertia_kg_m2: inertia,
            com_m: com,
            ahead_m_s: Vec3::zeros(),
            ahead_rad_s: Vec3::zeros(),
            solids: vec![],
            pins: (0..pins.len()).collect(),
        };
        sim.set_bodies(vec![body]).unwrap();
        sim.step(h).unwrap();
        let (dv, dw) = sim.body_velocity_change(0).unwrap();
        let (x, v, v_end) = (&start.state.x, &start.state.v, &sim.state().v);
        let forces = |x: &[Vec3], v: &[Vec3]| crate::model::forces::total_forces(&model, x, v, &[]);
        let d: Vec<Vec3> = v_end.iter().map(|u| u * h).collect();
        let eps = 1e-3;
        let shifted = |sign: f64| -> Vec<Vec3> { x.iter().zip(&d).map(|(p, q)| p + q * (sign * eps)).collect() };
        let still = vec![Vec3::zeros(); x.len()];
        let (plus, minus) = (forces(&shifted(1.0), &still), forces(&shifted(-1.0), &still));
        let f_end = forces(x, v_end);
        let masses = model.masses();
        // What the step must balance on each particle: h (f + K d) - m (v' - v).
        let unbalanced: Vec<Vec3> = (0..x.len())
            .map(|i| (f_end[i] + (plus[i] - minus[i]) / (2.0 * eps)) * h - (v_end[i] - v[i]) * masses[i])
            .collect();
        let scale = f_end.iter().map(|f| (f * h).norm()).fold(0.0, f64::max);
        let free = (0..x.len()).filter(|i| !pins.contains(i)).map(|i| unbalanced[i].norm()).fold(0.0, f64::max);
        let (mut linear, mut angular, mut follow) = (dv * mass, inertia * dw, 0.0_f64);
        for (k, &i) in pins.iter().enumerate() {
            let r = targets[k] - com;
            linear -= unbalanced[i];
            angular -= r.cross(&unbalanced[i]);
            follow = follow.max((v_end[i] - ((targets[k] - x[i]) / h + dv + dw.cross(&r))).norm());
        }
        println!(
            "free particles off balance {:.1e}, body {:.1e} (linear) {:.1e} (angular) of h |f| = {scale:.1e} N s; \
             pins off the body {follow:.1e} m/s; body dv {dv:?} dw {dw:?}",
            free,
            linear.norm(),
            angular.norm()
        );
        assert!(dv.norm() > 1e-3 && dw.norm() > 1e-3, "the cloth moves the body");
        assert!(free < 2e-9 * scale, "free particles off balance by {free:e}");
        assert!(linear.norm() < 2e-9 * scale && angular.norm() < 2e-9 * scale, "the body's rows are off");
        assert!(follow < 1e-12, "pinned particles follow the body to {follow:e} m/s");
    }
}
