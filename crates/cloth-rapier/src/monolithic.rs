//! What the monolithic master hands a cloth about each dynamic body
//! (mass, inertia, where its centre of mass ends), and how the cloth's
//! impulse goes back to rapier.
//!
//! The cloth's impulse `J` reaches the body as the force `J / h` over the
//! step, which rapier integrates in each of its `N` substeps: the body
//! ends the step `J / M` faster and its centre of mass moves by
//! `h s J / M` more, with `s = (N + 1) / (2 N)` ([`gravity_share`]). The
//! cloth's solve, which sees where the body ends the step, therefore
//! takes the body's mass as `M / s` (and its inertia as `I / s`). As an
//! impulse at the start of the step instead, a body resting on cloth
//! would end each step falling at `g h (N - 1) / (2 N)` while staying
//! where it is (1.4 cm/s at 90 Hz with 4 substeps).

use crate::cloth_set::{ClothSet, CoupledCloth, CouplingError};
use crate::convert::pose_to_rapier;
use crate::convert::{vec_from_rapier, vec_to_rapier};
use crate::coupling::{BodyImpulse, Coupled, Hold, MonolithicCoupling, Pass, mean_twist};
use crate::world::world_inertia;
use cloth_core::{BodyInSolve, Snapshot, Vec3};
use nalgebra::Matrix3;
use rapier3d_f64::prelude::{LockedAxes, PhysicsHooks, PhysicsWorld, RigidBody};

/// How much stiffer than the body's own mass a locked axis is made: the
/// cloth's solve then moves the body along it by a millionth of what a free
/// one would move.
const LOCKED_SCALE: f64 = 1e6;

/// The share of `g h` by which gravity moves a body's mean velocity over
/// one rapier step: rapier's `N` substeps each add `g h / N` to the
/// velocity before moving the body, so the centre of mass moves by
/// `h v0 + g h^2 (N + 1) / (2 N)`.
pub fn gravity_share(world: &PhysicsWorld, rb: &RigidBody) -> f64 {
    let substeps = (world.integration_parameters.num_solver_iterations + rb.additional_solver_iterations()).max(1);
    let n = substeps as f64;
    (n + 1.0) / (2.0 * n)
}

impl ClothSet {
    /// One monolithic step from `guess` (each body's velocity now, 6 per
    /// body): the cloths' solves with the bodies in them, then rapier's
    /// step. When rapier's own contacts or joints end a body elsewhere than
    /// the solves left it where a cloth meets it ([`disagreement`]), the
    /// cloths are solved once more (from `start`) with rapier's extra motion
    /// in the body's guess, and the body is moved to where that solve
    /// leaves it. Rapier's contacts saw the first solve's impulse, not the
    /// second's; that difference, at the cloth, is the disagreement left.
    /// Returns the cloths' solves (1 or 2), the disagreement left over its
    /// tolerance, and the pass.
    pub(crate) fn monolithic(
        &mut self,
        world: &mut PhysicsWorld,
        coupled: &[Coupled],
        guess: &mut [f64],
        (h, p, hooks): (f64, &MonolithicCoupling, &dyn PhysicsHooks),
        start: &[Snapshot],
    ) -> Result<(usize, f64, Pass), CouplingError> {
        let layer = self.cloths_mut().map(|c| c.sim.model().contact_thickness()).fold(f64::INFINITY, f64::min);
        let tol_m = p.tol_m.unwrap_or(crate::coupling::TOL_LAYER_SHARE * layer);
        let solved = self.solve_cloths(world, coupled, guess, h, true)?;
        let mut pass = self.step_bodies(world, coupled, solved, h, hooks)?;
        let off = disagreement(coupled, (&pass.end, &pass.solved.assumed), &pass.solved.holds, h, tol_m);
        if off <= 1.0 || p.max_solves < 2 {
            return Ok((1, off, pass));
        }
        let time_s = self.cloths_mut().next().map_or(0.0, |c| c.sim.time() - h);
        let first: Vec<Snapshot> = self.cloths_mut().map(|c| c.sim.snapshot()).collect();
        self.restore_cloths(start, time_s)?;
        for ((g, end), assumed) in guess.iter_mut().zip(&pass.end).zip(&pass.solved.assumed) {
            *g += end - assumed;
        }
        let second = match self.solve_cloths(world, coupled, guess, h, true) {
            Ok(second) => second,
            Err(_) => {
                // The first solve stands, reported as disagreeing: rapier
                // has stepped with its impulses.
                self.restore_cloths(&first, time_s)?;
                return Ok((2, off, pass));
            }
        };
        let left = disagreement(coupled, (&second.assumed, &pass.end), &second.holds, h, tol_m);
        for c in coupled {
            if let Some(s) = c.slot {
                let share = gravity_share(world, &world.bodies[c.handle]);
                let ((v, w), (v_rapier, w_rapier)) = (mean_twist(&second.assumed, s), mean_twist(&pass.end, s));
                let rb = &mut world.bodies[c.handle];
                // The extra impulse acts as a force over rapier's substeps:
                // it moves the end velocity by 1 / share of the mean's change.
                let v_end = vec_from_rapier(rb.linvel()) + (v - v_rapier) / share;
                let w_end = vec_from_rapier(rb.angvel()) + (w - w_rapier) / share;
                rb.set_position(pose_to_rapier(&c.start.end_pose(h, v, w)), true);
                rb.set_linvel(vec_to_rapier(v_end), true);
                rb.set_angvel(vec_to_rapier(w_end), true);
            }
        }
        pass.end.copy_from_slice(&second.assumed);
        pass.solved = second;
        Ok((2, left, pass))
    }
}

/// How far apart two sets of mean velocities `a` and `b` (6 per body) put
/// the points where the cloths meet the bodies at the end of a step of
/// `h`, over `tol_m`: a pin's point in any direction, a contact point
/// along its normal (the cloth does not resist a body sliding or spinning
/// over it: a ball's spin that rapier's contact with another ball changed
/// does not count).
pub(crate) fn disagreement(
    coupled: &[Coupled],
    (a, b): (&[f64], &[f64]),
    holds: &[Vec<Hold>],
    h: f64,
    tol_m: f64,
) -> f64 {
    let mut worst = 0.0_f64;
    for (c, holds) in coupled.iter().zip(holds) {
        let Some(s) = c.slot else { continue };
        let ((va, wa), (vb, wb)) = (mean_twist(a, s), mean_twist(b, s));
        for hold in holds {
            let apart = (va - vb + (wa - wb).cross(&hold.lever)) * h;
            let off = hold.normal.map_or(apart.norm(), |n| apart.dot(&n).abs());
            worst = worst.max(off / tol_m);
        }
    }
    worst
}

/// Checks the monolithic master's parameters.
pub(crate) fn check(p: &MonolithicCoupling) -> Result<(), CouplingError> {
    if !(1..=2).contains(&p.max_solves) {
        return Err(CouplingError::Params {
            field: "max_solves",
            message: format!("the monolithic master solves the cloths once or twice a step, got {}", p.max_solves),
        });
    }
    if let Some(t) = p.tol_m.filter(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(CouplingError::Params { field: "tol_m", message: format!("must be finite and > 0, got {t}") });
    }
    Ok(())
}

/// How far gravity moves a body's mean velocity over one rapier step of
/// `h`, m/s (its gravity scale and [`gravity_share`] included).
pub(crate) fn free_fall(world: &PhysicsWorld, rb: &RigidBody, h: f64) -> Vec3 {
    vec_from_rapier(world.gravity) * (rb.gravity_scale() * h * gravity_share(world, rb))
}

/// The bodies of `cloth` that join its solve this step: every dynamic
/// coupled body with a solid or an attachment in this cloth, its centre of
/// mass ending at `com_end` (per coupled body, where the guess takes it).
pub(crate) fn bodies_in_solve(
    cloth: &CoupledCloth,
    world: &PhysicsWorld,
    coupled: &[Coupled],
    com_end: &[Vec3],
    h: f64,
) -> Vec<BodyInSolve> {
    let mut out = Vec::new();
    for (c, &com_m) in coupled.iter().zip(com_end) {
        if c.slot.is_none() {
            continue;
        }
        let solids: Vec<usize> = cloth.solids.iter().filter(|s| s.body == Some(c.handle)).map(|s| s.solid).collect();
        let pins: Vec<usize> = cloth.attachments.iter().filter(|a| a.body == c.handle).map(|a| a.pin).collect();
        if solids.is_empty() && pins.is_empty() {
            continue;
        }
        let rb = &world.bodies[c.handle];
        let (mass_kg, inertia_kg_m2) = effective_mass_properties(world, rb);
        out.push(BodyInSolve {
            mass_kg,
            inertia_kg_m2,
            com_m,
            // The guess leaves out gravity: it is that far ahead of free flight.
            ahead_m_s: -free_fall(world, rb, h),
            ahead_rad_s: Vec3::zeros(),
            solids,
            pins,
        });
    }
    out
}

/// Mass and world inertia, with locked axes stiffened by [`LOCKED_SCALE`]
/// (a translation lock needs a mass per axis, which the solve does not
/// take: any locked translation makes the whole mass stiff).
fn locked_mass_properties(rb: &RigidBody) -> (f64, Matrix3<f64>) {
    let locked = rb.locked_axes();
    let mut inertia = world_inertia(rb);
    let largest = inertia.symmetric_eigenvalues().max().max(f64::MIN_POSITIVE);
    for (flag, axis) in [
        (LockedAxes::ROTATION_LOCKED_X, Vec3::x()),
        (LockedAxes::ROTATION_LOCKED_Y, Vec3::y()),
        (LockedAxes::ROTATION_LOCKED_Z, Vec3::z()),
    ] {
        if locked.contains(flag) {
            inertia += axis * axis.transpose() * (largest * LOCKED_SCALE);
        }
    }
    let translation_locked = locked.intersects(LockedAxes::TRANSLATION_LOCKED);
    let mass = rb.mass() * if translation_locked { LOCKED_SCALE } else { 1.0 };
    (mass, inertia)
}

/// Mass and inertia as the end of rapier's step sees them (see the module).
fn effective_mass_properties(world: &PhysicsWorld, rb: &RigidBody) -> (f64, Matrix3<f64>) {
    let (mass, inertia) = locked_mass_properties(rb);
    let share = gravity_share(world, rb);
    (mass / share, inertia / share)
}

/// Moves a body's mean velocities `seen` (6 values) by impulse `j`: what
/// the next cloth sees of it.
pub(crate) fn add_impulse(world: &PhysicsWorld, rb: &RigidBody, j: &BodyImpulse, seen: &mut [f64]) {
    let (mass, inertia) = effective_mass_properties(world, rb);
    let dv = j.linear / mass;
    let dw = inertia.try_inverse().map_or(Vec3::zeros(), |inv| inv * j.angular);
    for k in 0..3 {
        seen[k] += dv[k];
        seen[3 + k] += dw[k];
    }
}

/// The force and torque a body's user set before the cloth's were added.
pub(crate) type UserForces = (rapier3d_f64::math::Vector, rapier3d_f64::math::AngVector);

/// Adds the cloth's impulse `j` as the force `j / h` (and torque) for the
/// coming rapier step; returns the user's own, for [`restore_forces`].
pub(crate) fn apply_as_force(rb: &mut RigidBody, j: &BodyImpulse, h: f64) -> UserForces {
    let saved = (rb.user_force(), rb.user_torque());
    rb.add_force(vec_to_rapier(j.linear / h), true);
    rb.add_torque(vec_to_rapier(j.angular / h), true);
    saved
}

/// Puts back the user's force and torque after the step, bit for bit.
pub(crate) fn restore_forces(rb: &mut RigidBody, (force, torque): UserForces) {
    rb.reset_forces(false);
    rb.reset_torques(false);
    rb.add_force(force, false);
    rb.add_torque(torque, false);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rapier3d_f64::prelude::{ColliderBuilder, RigidBodyBuilder, RigidBodyHandle};

    /// Only what moves the points where cloth meets a body counts: a spin
    /// about a ball's centre slides its contact point along the surface
    /// (not counted), a push along the contact's normal counts, and a pin
    /// counts in every direction; all as the distance over the step
    /// against `tol_m`.
    #[test]
    fn disagreement_counts_what_moves_the_cloth_s_points() {
        let rb = RigidBodyBuilder::dynamic().build();
        let c = Coupled { handle: RigidBodyHandle::invalid(), start: crate::world::BodyStart::of(&rb), slot: Some(0) };
        let (h, tol) = (0.01, 1e-3);
        let contact = Hold { lever: Vec3::new(0.0, 0.0, -0.1), normal: Some(-Vec3::z()) };
        let pin = Hold { lever: Vec3::new(0.0, 0.1, 0.0), normal: None };
        let off = |a: [f64; 6], hold: Hold| disagreement(&[c], (&a, &[0.0; 6]), &[vec![hold]], h, tol);
        let spin = [0.0, 0.0, 0.0, 2.0, 0.0, 0.0];
        assert!(off(spin, contact) < 1e-15, "{}", off(spin, contact));
        // The pin moves by (2 rad/s x 0.1 m) h = 2 mm.
        assert!((off(spin, pin) - 2.0).abs() < 1e-12, "{}", off(spin, pin));
        let slide = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        assert!(off(slide, contact) < 1e-15 && (off(slide, pin) - 10.0).abs() < 1e-12);
        let push = [0.0, 0.0, -0.05, 0.0, 0.0, 0.0];
        assert!((off(push, contact) - 0.5).abs() < 1e-12, "{}", off(push, contact));
        // Either way along the normal: a body that left the cloth behind counts too.
        let back = [0.0, 0.0, 0.05, 0.0, 0.0, 0.0];
        assert!((off(back, contact) - 0.5).abs() < 1e-12);
    }

    /// A free body falls as [`gravity_share`] says, with the cloth's
    /// impulse as a force on top: the monolithic master's prediction of
    /// rapier's step; the user's own force is kept.
    #[test]
    fn a_free_body_ends_where_the_gravity_share_puts_it() {
        for substeps in [1, 4, 7] {
            let mut world = PhysicsWorld { gravity: vec_to_rapier(Vec3::new(0.0, 0.0, -9.81)), ..Default::default() };
            world.integration_parameters.dt = 0.01;
            world.integration_parameters.num_solver_iterations = substeps;
            let body = world.bodies.insert(RigidBodyBuilder::dynamic().linvel(vec_to_rapier(Vec3::new(0.3, 0.0, 1.0))));
            let collider = ColliderBuilder::ball(0.1).density(500.0);
            let (bodies, colliders) = (&mut world.bodies, &mut world.colliders);
            colliders.insert_with_parent(collider, body, bodies);
            let j = Vec3::new(0.0, 0.2, 0.5);
            let rb = &world.bodies[body];
            let (x0, v0, m) = (vec_from_rapier(rb.center_of_mass()), vec_from_rapier(rb.linvel()), rb.mass());
            let share = gravity_share(&world, rb);
            let user = Vec3::new(0.1, 0.0, 0.0);
            world.bodies[body].add_force(vec_to_rapier(user), false);
            let impulse = BodyImpulse { linear: j, angular: Vec3::zeros() };
            let saved = apply_as_force(&mut world.bodies[body], &impulse, 0.01);
            world.step();
            restore_forces(&mut world.bodies[body], saved);
            let rb = &world.bodies[body];
            let moved = vec_from_rapier(rb.center_of_mass()) - x0;
            let dv = Vec3::new(0.0, 0.0, -9.81) * 0.01 + (j + user * 0.01) / m;
            let predicted = (v0 + dv * share) * 0.01;
            assert!((moved - predicted).norm() < 1e-15, "{substeps} substeps: {moved} vs {predicted}");
            // The end velocity takes the whole impulse; the user's force stays.
            assert!((vec_from_rapier(rb.linvel()) - (v0 + dv)).norm() < 1e-14);
            assert_eq!(vec_from_rapier(rb.user_force()), user);
        }
    }
}
