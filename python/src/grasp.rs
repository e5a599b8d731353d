//! Grasps: the particles within a radius of a point, held together by a
//! gripper that moves (a kinematic point) or by a rigid body. Each particle
//! keeps its offset from the gripper as it was when grasped, so the
//! gripper holds a patch of cloth as it lay; it is held through
//! [`cloth_core::Simulation::hold`], and the gripper feels the sum of the
//! held particles' reactions.

use cloth_core::{BodyPose, Simulation, Vec3};
use cloth_rapier::rapier3d_f64::prelude::RigidBodyHandle;
use nalgebra::UnitQuaternion;

/// Why a grasp was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum GraspError {
    /// The point or radius is not a finite point and a radius > 0.
    #[error("grasp at {point:?} with radius {radius_m} m: needs a finite point and a finite radius > 0")]
    Invalid { point: [f64; 3], radius_m: f64 },
    /// No free particle lies within the radius.
    #[error("no free particle within {radius_m} m of {point:?} (pinned and already grasped ones do not count)")]
    Nothing { point: [f64; 3], radius_m: f64 },
    /// No grasp of that id is held.
    #[error("grasp {id}: no such grasp is held")]
    NoSuchGrasp { id: usize },
    /// A target is not finite.
    #[error("grasp {id}: target {point:?} is not finite")]
    NonFinite { id: usize, point: [f64; 3] },
    /// The grasp is on a body: it moves with it.
    #[error("grasp {id} is on a body: it moves with the body")]
    OnBody { id: usize },
    /// Particles and offsets given for a grasp do not pair up.
    #[error("grasp of {particles} particles with {offsets} offsets: needs one offset a particle, and a particle")]
    Unpaired { particles: usize, offsets: usize },
    /// A particle given for a grasp is not one of the cloth's.
    #[error("particle {index}: the cloth has {count}")]
    NoSuchParticle { index: usize, count: usize },
    /// A particle given for a grasp is pinned, held by another grasp or
    /// given twice.
    #[error("particle {index} is not free to grasp (pinned, held by another grasp or given twice)")]
    NotFree { index: usize },
    /// The gripper's position given for a grasp is not finite.
    #[error("grasp at {point:?}: the gripper's position is not finite")]
    NonFiniteGripper { point: [f64; 3] },
    /// An offset given for a grasp is not finite.
    #[error("offset of particle {index} is not finite: {offset:?}")]
    NonFiniteOffset { index: usize, offset: [f64; 3] },
}

/// What holds a grasp's particles.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Gripper {
    /// A point moved from outside.
    Point,
    /// A rapier body: a `[[bodies]]` entry or a rig link (offsets in its
    /// frame).
    Body(RigidBodyHandle),
}

/// One grasp.
#[derive(Debug, Clone)]
pub(crate) struct Grasp {
    pub(crate) particles: Vec<usize>,
    /// Each particle's offset from the gripper: world axes for a point,
    /// the body's frame for a body, m.
    offsets: Vec<Vec3>,
    pub(crate) gripper: Gripper,
}

impl Grasp {
    /// Each particle's offset from the gripper (world axes for a point,
    /// the body's frame for a body), m, in the order of `particles`.
    pub(crate) fn offsets(&self) -> &[Vec3] {
        &self.offsets
    }

    /// Holds the particles at their offsets from the gripper at `pose`, by
    /// the end of the next step. The particles are free and the pose
    /// finite (checked when grasped and moved): `hold` cannot refuse.
    fn place(&self, sim: &mut Simulation, pose: &BodyPose) {
        for (&i, &offset) in self.particles.iter().zip(&self.offsets) {
            let _ = sim.hold(i, pose.position + pose.rotation * offset);
        }
    }

    /// The mean force the cloth exerted on the gripper over the last step,
    /// N, and its torque about `about` (m), N m.
    pub(crate) fn pull(&self, sim: &Simulation, about: Vec3) -> (Vec3, Vec3) {
        let mut total = (Vec3::zeros(), Vec3::zeros());
        for &i in &self.particles {
            let f = sim.hold_reaction(i).unwrap_or_default();
            total.0 += f;
            total.1 += (sim.state().x[i] - about).cross(&f);
        }
        total
    }
}

/// The grasps of one simulation, by id (ids are not reused).
#[derive(Debug, Clone, Default)]
pub(crate) struct Grasps {
    slots: Vec<Option<Grasp>>,
}

impl Grasps {
    /// Grasps the free particles within `radius_m` of `point` (not pinned,
    /// not held by another grasp) with `gripper`, whose pose now is `pose`
    /// (the identity for a point gripper at `point`). Returns the id.
    pub(crate) fn grasp(
        &mut self,
        sim: &mut Simulation,
        point: Vec3,
        radius_m: f64,
        (gripper, pose): (Gripper, BodyPose),
    ) -> Result<usize, GraspError> {
        if !(point.iter().all(|c| c.is_finite()) && radius_m.is_finite() && radius_m > 0.0) {
            return Err(GraspError::Invalid { point: point.into(), radius_m });
        }
        let model = sim.model().clone();
        let x = &sim.state().x;
        let free = |i: &usize| !model.is_pinned(*i) && !sim.control().is_held(*i);
        let particles: Vec<usize> = (0..x.len()).filter(|&i| (x[i] - point).norm() <= radius_m).filter(free).collect();
        if particles.is_empty() {
            return Err(GraspError::Nothing { point: point.into(), radius_m });
        }
        let inverse = pose.rotation.inverse();
        let offsets: Vec<Vec3> = particles.iter().map(|&i| inverse * (x[i] - pose.position)).collect();
        Ok(self.push(sim, Grasp { particles, offsets, gripper }, &pose))
    }

    /// Grasps `particles` at `offsets` (m, in the gripper's frame) from
    /// `gripper`, whose pose now is `pose`: a grasp taken again as
    /// [`Grasp::offsets`] recorded it (after a restore, the particles in
    /// reach and their offsets recomputed from the positions would differ
    /// by a rounding). Each particle must be free; nothing is held when
    /// one is refused. Returns the id.
    pub(crate) fn grasp_at_offsets(
        &mut self,
        sim: &mut Simulation,
        particles: Vec<usize>,
        offsets: Vec<Vec3>,
        (gripper, pose): (Gripper, BodyPose),
    ) -> Result<usize, GraspError> {
        if !pose.position.iter().all(|c| c.is_finite()) {
            return Err(GraspError::NonFiniteGripper { point: pose.position.into() });
        }
        if particles.len() != offsets.len() || particles.is_empty() {
            return Err(GraspError::Unpaired { particles: particles.len(), offsets: offsets.len() });
        }
        let count = sim.model().particle_count();
        let mut seen = vec![false; count];
        for (&index, offset) in particles.iter().zip(&offsets) {
            if index >= count {
                return Err(GraspError::NoSuchParticle { index, count });
            }
            if seen[index] || sim.model().is_pinned(index) || sim.control().is_held(index) {
                return Err(GraspError::NotFree { index });
            }
            seen[index] = true;
            if !offset.iter().all(|c| c.is_finite()) {
                return Err(GraspError::NonFiniteOffset { index, offset: (*offset).into() });
            }
        }
        Ok(self.push(sim, Grasp { particles, offsets, gripper }, &pose))
    }

    /// Holds `grasp`'s particles where `pose` puts them and keeps it;
    /// returns its id.
    fn push(&mut self, sim: &mut Simulation, grasp: Grasp, pose: &BodyPose) -> usize {
        grasp.place(sim, pose);
        self.slots.push(Some(grasp));
        self.slots.len() - 1
    }

    pub(crate) fn get(&self, id: usize) -> Result<&Grasp, GraspError> {
        self.slots.get(id).and_then(Option::as_ref).ok_or(GraspError::NoSuchGrasp { id })
    }

    /// Moves point grasp `id` to `point` (m) by the end of the next step.
    pub(crate) fn move_to(&mut self, sim: &mut Simulation, id: usize, point: Vec3) -> Result<(), GraspError> {
        let g = self.slots.get_mut(id).and_then(Option::as_mut).ok_or(GraspError::NoSuchGrasp { id })?;
        if !point.iter().all(|c| c.is_finite()) {
            return Err(GraspError::NonFinite { id, point: point.into() });
        }
        if matches!(g.gripper, Gripper::Body(_)) {
            return Err(GraspError::OnBody { id });
        }
        g.place(sim, &BodyPose { position: point, rotation: UnitQuaternion::identity() });
        Ok(())
    }

    /// Sets the targets of every body grasp from its body's pose at the
    /// end of the next step, `pose_of(body)`.
    pub(crate) fn follow_bodies(&self, sim: &mut Simulation, pose_of: impl Fn(RigidBodyHandle) -> BodyPose) {
        for g in self.slots.iter().flatten() {
            if let Gripper::Body(b) = g.gripper {
                g.place(sim, &pose_of(b));
            }
        }
    }

    /// The mean force the cloth exerted on grasp `id`'s gripper over the
    /// last step, N.
    pub(crate) fn force(&self, sim: &Simulation, id: usize) -> Result<Vec3, GraspError> {
        Ok(self.get(id)?.pull(sim, Vec3::zeros()).0)
    }

    /// Lets grasp `id`'s particles go (they keep their velocities).
    pub(crate) fn release(&mut self, sim: &mut Simulation, id: usize) -> Result<(), GraspError> {
        let g = self.slots.get_mut(id).and_then(Option::take).ok_or(GraspError::NoSuchGrasp { id })?;
        for i in g.particles {
            sim.let_go(i);
        }
        Ok(())
    }

    /// The body grasps, with their bodies.
    pub(crate) fn on_bodies(&self) -> impl Iterator<Item = (RigidBodyHandle, &Grasp)> {
        self.slots.iter().flatten().filter_map(|g| match g.gripper {
            Gripper::Body(b) => Some((b, g)),
            Gripper::Point => None,
        })
    }
}
