//! Inputs to a built scene from outside, step by step (a controller, a
//! learning loop, the Python module): forces and torques on dynamic
//! bodies, poses of kinematic bodies, joint positions of the rig; and what
//! the cloth did to each body over the last step.

use crate::convert::{pose_from_rapier, vec_from_rapier, vec_to_rapier};
use crate::rig::{JointKind, JointValue};
use crate::scene::{BodyKind, CoupledRun, SceneBody};
use cloth_core::{BodyPose, Vec3};

/// Why an input to a [`CoupledRun`] was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RunControlError {
    /// No `[[bodies]]` entry of that index.
    #[error("body {index}: the scene has {count} bodies")]
    NoSuchBody {
        /// The index asked for.
        index: usize,
        /// How many bodies the scene has.
        count: usize,
    },
    /// The body is not of the kind the input needs.
    #[error("body {name:?} is {kind}: {needs}")]
    WrongBodyKind {
        /// The body's name.
        name: String,
        /// Its kind (`dynamic`, `kinematic`, `fixed`).
        kind: &'static str,
        /// What the input needs.
        needs: &'static str,
    },
    /// A value is NaN or infinite.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which value.
        what: String,
    },
    /// The scene has no `[rig]`.
    #[error("the scene has no [rig]")]
    NoRig,
    /// The rig has no joint of that name.
    #[error("the rig has no joint {name:?}")]
    NoSuchJoint {
        /// The name asked for.
        name: String,
    },
    /// The value does not fit the joint's kind.
    #[error("joint {name:?} is {kind}: {expected}")]
    WrongJointValue {
        /// The joint's name.
        name: String,
        /// Its kind.
        kind: &'static str,
        /// What it takes.
        expected: &'static str,
    },
}

/// What the cloth did to a body over the last step: the mean force, N, and
/// torque about the body's centre of mass, N m, through its contacts and
/// the pins attached to it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ClothLoad {
    /// Mean force over the step, N.
    pub force_n: Vec3,
    /// Mean torque about the centre of mass, N m.
    pub torque_n_m: Vec3,
    /// Contacts that carried it.
    pub contacts: usize,
}

fn kind_name(kind: BodyKind) -> &'static str {
    match kind {
        BodyKind::Dynamic => "dynamic",
        BodyKind::Kinematic => "kinematic",
        BodyKind::Fixed => "fixed",
    }
}

fn finite(v: &Vec3, what: impl FnOnce() -> String) -> Result<(), RunControlError> {
    if v.iter().all(|c| c.is_finite()) { Ok(()) } else { Err(RunControlError::NonFinite { what: what() }) }
}

fn joint_kind_name(kind: &JointKind) -> &'static str {
    match kind {
        JointKind::Fixed => "fixed",
        JointKind::Revolute { .. } => "revolute",
        JointKind::Continuous => "continuous",
        JointKind::Prismatic { .. } => "prismatic",
        JointKind::Spherical => "spherical",
        JointKind::Floating => "floating",
    }
}

impl CoupledRun {
    fn scene_body(&self, index: usize) -> Result<&SceneBody, RunControlError> {
        self.bodies.get(index).ok_or(RunControlError::NoSuchBody { index, count: self.bodies.len() })
    }

    fn body_checked(&self, index: usize, kind: BodyKind, needs: &'static str) -> Result<usize, RunControlError> {
        let b = self.scene_body(index)?;
        if b.spec.kind != kind {
            return Err(RunControlError::WrongBodyKind { name: b.name.clone(), kind: kind_name(b.spec.kind), needs });
        }
        Ok(index)
    }

    /// Adds a force (N, through the centre of mass) and a torque (N m) to
    /// dynamic body `index` for the next step only.
    pub fn apply_force(&mut self, index: usize, force_n: Vec3, torque_n_m: Vec3) -> Result<(), RunControlError> {
        let k = self.body_checked(index, BodyKind::Dynamic, "forces move dynamic bodies only")?;
        finite(&force_n, || format!("body {:?} force", self.bodies[k].name))?;
        finite(&torque_n_m, || format!("body {:?} torque", self.bodies[k].name))?;
        let rb = &mut self.world.bodies[self.bodies[k].handle];
        rb.add_force(vec_to_rapier(force_n), true);
        rb.add_torque(vec_to_rapier(torque_n_m), true);
        Ok(())
    }

    /// Sends kinematic body `index` to `pose` by the end of the next step and
    /// keeps it there: the pose replaces the scene's scripted motion.
    pub fn set_kinematic_target(&mut self, index: usize, pose: BodyPose) -> Result<(), RunControlError> {
        let k = self.body_checked(index, BodyKind::Kinematic, "targets move kinematic bodies only")?;
        let quaternion = pose.rotation.coords;
        finite(&pose.position, || format!("body {:?} target position", self.bodies[k].name))?;
        if !quaternion.iter().all(|c| c.is_finite()) {
            return Err(RunControlError::NonFinite { what: format!("body {:?} target rotation", self.bodies[k].name) });
        }
        self.bodies[k].target = Some(pose);
        Ok(())
    }

    /// Body `index`'s pose now (its frame origin, m, and rotation), and its
    /// linear (m/s, of the centre of mass) and angular (rad/s) velocity.
    pub fn body_state(&self, index: usize) -> Result<(BodyPose, Vec3, Vec3), RunControlError> {
        let b = self.scene_body(index)?;
        let rb = &self.world.bodies[b.handle];
        Ok((pose_from_rapier(rb.position()), vec_from_rapier(rb.linvel()), vec_from_rapier(rb.angvel())))
    }

    /// What the cloth did to body `index` over the last step (zero before
    /// the first): its contacts' and attached pins' mean force and torque.
    pub fn cloth_load(&self, index: usize) -> Result<ClothLoad, RunControlError> {
        let b = self.scene_body(index)?;
        let rb = &self.world.bodies[b.handle];
        let com = vec_from_rapier(rb.center_of_mass());
        let cloth = &self.cloths[self.cloth];
        let sim = cloth.simulation();
        let h = self.config.dt_s;
        let mut load = ClothLoad::default();
        for s in cloth.world_solids().iter().filter(|s| s.body == Some(b.handle)) {
            let impulse = sim.solid_impulse(s.solid, com);
            load.force_n += impulse.linear / h;
            load.torque_n_m += impulse.angular / h;
            load.contacts += impulse.contacts;
        }
        let pins = sim.model().pins();
        for a in cloth.attachments().iter().filter(|a| a.body == b.handle) {
            // The pin's reaction is the cloth's pull on what holds it.
            let f = sim.pin_reaction(a.pin);
            load.force_n += f;
            load.torque_n_m += (sim.state().x[pins[a.pin].particle] - com).cross(&f);
        }
        Ok(load)
    }

    /// The rig's joint values now (the pose it was last driven to), by
    /// joint, in [`crate::Rig::joints`] order.
    pub fn joint_positions(&self) -> Result<Vec<(String, JointValue)>, RunControlError> {
        let rig = self.rig.as_ref().ok_or(RunControlError::NoRig)?;
        let t = self.cloths[self.cloth].simulation().time();
        let pose = rig.pose_at(t);
        Ok(rig.rig.joints.iter().zip(pose.joints).map(|(j, v)| (j.name.clone(), v)).collect())
    }

    /// Sets the named joints of the rig (the others keep their values now)
    /// for the end of the next step and holds the pose from then on, in
    /// place of the scene's motion. Revolute and continuous joints take
    /// [`JointValue::Angle`] (rad), prismatic ones [`JointValue::Offset`]
    /// (m), spherical ones [`JointValue::Rotation`]. Nothing is set when
    /// one value is refused.
    pub fn set_joint_positions(&mut self, values: &[(String, JointValue)]) -> Result<(), RunControlError> {
        let t = self.cloths[self.cloth].simulation().time();
        let rig = self.rig.as_mut().ok_or(RunControlError::NoRig)?;
        let mut pose = rig.pose_at(t);
        for (name, value) in values {
            let k = rig.rig.joint(name).ok_or_else(|| RunControlError::NoSuchJoint { name: name.clone() })?;
            let kind = &rig.rig.joints[k].kind;
            let wrong = |expected| RunControlError::WrongJointValue {
                name: name.clone(),
                kind: joint_kind_name(kind),
                expected,
            };
            let fits = match (kind, value) {
                (JointKind::Revolute { .. } | JointKind::Continuous, JointValue::Angle(a)) => a.is_finite(),
                (JointKind::Prismatic { .. }, JointValue::Offset(d)) => d.is_finite(),
                (JointKind::Spherical, JointValue::Rotation(q)) => q.coords.iter().all(|c| c.is_finite()),
                (JointKind::Revolute { .. } | JointKind::Continuous, _) => return Err(wrong("an angle, rad")),
                (JointKind::Prismatic { .. }, _) => return Err(wrong("an offset, m")),
                (JointKind::Spherical, _) => return Err(wrong("a rotation")),
                (JointKind::Fixed | JointKind::Floating, _) => return Err(wrong("no value set from outside")),
            };
            if !fits {
                return Err(RunControlError::NonFinite { what: format!("joint {name:?} value") });
            }
            pose.joints[k] = *value;
        }
        rig.held_pose = Some(pose);
        Ok(())
    }
}
