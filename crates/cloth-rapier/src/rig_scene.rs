//! The `[rig]` section of a scene: a URDF character as kinematic rapier
//! bodies, driven by a BVH or keyframe motion (see [`crate::motion`]).
//!
//! ```toml
//! [rig]
//! urdf = "../rigs/mannequin.urdf"   # relative to the scene file
//! up_axis = "z"                     # the URDF's up axis: "z" or "y"
//! scale = 1.0                       # metres per URDF length unit
//! friction = 0.3                    # Coulomb coefficient, cloth on every link
//! position_m = [0.0, 0.0, 0.0]      # where the character stands
//! rotation_deg = [0.0, 0.0, 0.0]    # about x, then y, then z (fixed axes)
//! settle_s = 0.5                    # at the settle pose first (the garment settles)
//! settle_pose = "rest"              # or "first-frame" (the motion's first pose), or
//!                                   # { joints = { elbow_l = 30.0, shoulder_l = [0.0, 0.0, -60.0] } }
//! blend_s = 0.3                     # then blends into the motion's first pose
//! looping = true                    # loop the motion, carrying the root's displacement
//! motion = { kind = "bvh", file = "../motions/walk.bvh", root = "Hips",
//!            joints = { hip_l = "LeftUpLeg", knee_l = "LeftLeg" }, up_axis = "y", scale = 0.01 }
//! # or { kind = "keyframes", file = "../motions/wave.toml" }, or { kind = "rest" } (default)
//! ```
//!
//! `[[attachments]]` may name a link (`body = "pelvis"`): the pins then
//! follow it. Link names must differ from `[[bodies]]` names.

use crate::bvh::Bvh;
use crate::character::RigBodies;
use crate::motion::{BvhMap, Clip, Playback, RigMotion, joints_from_values, unit_scale, y_up};
use crate::rig::{Rig, RigOptions, RigPose, UpAxis};
use cloth_core::FieldError;
use cloth_core::rotation_from_degrees;
use nalgebra::{Isometry3, Translation3};
use rapier3d_f64::prelude::PhysicsWorld;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What moves the rig.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum RigMotionSpec {
    /// The rest pose throughout.
    #[default]
    Rest,
    /// A BVH file retargeted through a name table.
    Bvh {
        /// The BVH file, relative to the scene file.
        file: PathBuf,
        /// The BVH joint that places the rig's root link.
        root: String,
        /// Rig joint -> BVH joint.
        joints: BTreeMap<String, String>,
        /// The BVH's up axis (default "y", as motion capture).
        #[serde(default = "y_up")]
        up_axis: UpAxis,
        /// Metres per BVH length unit (default 1; 0.01 for centimetres).
        #[serde(default = "unit_scale")]
        scale: f64,
    },
    /// A keyframe file of joint values.
    Keyframes {
        /// The file, relative to the scene file.
        file: PathBuf,
    },
}

fn yes() -> bool {
    true
}

/// A named settle pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum SettlePoseName {
    /// The URDF's zero joint values.
    #[default]
    Rest,
    /// The motion's first pose.
    FirstFrame,
}

/// The pose the character holds while the garment settles (`settle_s`),
/// before it blends into the motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum SettlePose {
    /// `"rest"` or `"first-frame"`.
    Named(SettlePoseName),
    /// `{ joints = { elbow_l = 30.0, shoulder_l = [0.0, 0.0, -60.0] } }`:
    /// joint values over the rest pose, degrees, as in keyframe files.
    Joints {
        /// Rig joint -> value.
        joints: BTreeMap<String, toml::Value>,
    },
}

impl Default for SettlePose {
    fn default() -> Self {
        SettlePose::Named(SettlePoseName::Rest)
    }
}

fn default_friction() -> f64 {
    0.3
}

/// `[rig]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigSection {
    /// The URDF file, relative to the scene file.
    pub urdf: PathBuf,
    /// The URDF's up axis.
    #[serde(default)]
    pub up_axis: UpAxis,
    /// Metres per URDF length unit.
    #[serde(default = "unit_scale")]
    pub scale: f64,
    /// Cloth-link Coulomb coefficient (default 0.3).
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// Where the character stands, m.
    #[serde(default)]
    pub position_m: [f64; 3],
    /// Its heading: about x, then y, then z (fixed axes), degrees.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// Time at the settle pose before the motion, s.
    #[serde(default)]
    pub settle_s: f64,
    /// The pose held while settling (default the rest pose).
    #[serde(default)]
    pub settle_pose: SettlePose,
    /// Time to blend into the motion, s.
    #[serde(default)]
    pub blend_s: f64,
    /// Loop the motion (default true).
    #[serde(default = "yes")]
    pub looping: bool,
    /// The motion.
    #[serde(default)]
    pub motion: RigMotionSpec,
}

/// A rig built into a world.
#[derive(Debug, Clone)]
pub struct SceneRig {
    /// The rig.
    pub rig: Rig,
    /// Its link bodies.
    pub bodies: RigBodies,
    /// What moves it.
    pub motion: RigMotion,
    /// The URDF file.
    pub file: PathBuf,
    /// The up axis and scale it was read with.
    pub options: RigOptions,
    /// The rig joints the motion drives (the others stay at rest), by name.
    pub driven: Vec<String>,
    /// A pose set from outside ([`crate::CoupledRun::set_joint_positions`]),
    /// replacing the motion from then on.
    pub(crate) held_pose: Option<RigPose>,
}

/// What a scene's rig is, as `cloth validate` prints it.
#[derive(Debug, Clone, PartialEq)]
pub struct RigSummary {
    /// The robot's name in the URDF.
    pub name: String,
    /// The URDF file.
    pub file: PathBuf,
    /// Links and joints.
    pub links: usize,
    /// Joints.
    pub joints: usize,
    /// The joints the motion drives.
    pub driven: Vec<String>,
    /// The character's extent at the start: along z (its height when it
    /// stands) and the largest horizontal one, m.
    pub height_m: f64,
    /// See `height_m`.
    pub length_m: f64,
    /// The up axis and scale used.
    pub options: RigOptions,
}

/// A standing character's height is within this range, m.
pub const PLAUSIBLE_HEIGHT_M: [f64; 2] = [0.3, 3.0];

impl std::fmt::Display for RigSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let driven = if self.driven.is_empty() { "none".to_string() } else { self.driven.join(", ") };
        write!(
            f,
            "rig {:?} from {}: {} links, {} joints; {:.3} m tall, {:.3} m across at the start \
             (up axis {}, scale {} m per unit); the motion drives {}",
            self.name,
            self.file.display(),
            self.links,
            self.joints,
            self.height_m,
            self.length_m,
            self.options.up_axis.name(),
            self.options.scale,
            driven
        )
    }
}

impl RigSummary {
    /// What looks wrong: a height outside [`PLAUSIBLE_HEIGHT_M`] (the scale),
    /// or a character longer than tall (the up axis), each naming the key.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        let [low, high] = PLAUSIBLE_HEIGHT_M;
        if !(low..=high).contains(&self.height_m) {
            out.push(format!(
                "{}: the character is {:.2} m tall, outside {low}-{high} m: set rig.scale \
                 (metres per URDF unit, now {})",
                self.file.display(),
                self.height_m,
                self.options.scale
            ));
        }
        if self.length_m > 1.5 * self.height_m {
            out.push(format!(
                "{}: the character is {:.2} m across and {:.2} m tall: it lies on its side; set rig.up_axis \
                 (now \"{}\")",
                self.file.display(),
                self.length_m,
                self.height_m,
                self.options.up_axis.name()
            ));
        }
        out
    }
}

impl SceneRig {
    /// The rig's pose at `t`, s
    /// (the pose set from outside, once one is).
    pub fn pose_at(&self, t: f64) -> RigPose {
        self.held_pose.clone().unwrap_or_else(|| self.motion.pose_at(t))
    }

    /// Sends the link bodies to their poses at `t` (the end of the next step).
    pub fn drive(&mut self, world: &mut PhysicsWorld, t: f64) -> Result<(), crate::RigError> {
        let pose = self.pose_at(t);
        self.bodies.drive(&self.rig, world, &pose)
    }

    /// The body of the link named `name`.
    pub fn body(&self, name: &str) -> Option<rapier3d_f64::prelude::RigidBodyHandle> {
        self.rig.link(name).map(|l| self.bodies.handles[l])
    }

    /// The name of the link whose body is `handle`.
    pub fn link_of(&self, handle: rapier3d_f64::prelude::RigidBodyHandle) -> Option<&str> {
        let k = self.bodies.handles.iter().position(|&h| h == handle)?;
        Some(&self.rig.links[k].name)
    }

    /// The rig as it stands in `world` now (its links' colliders' bounds).
    pub fn summary(&self, world: &PhysicsWorld) -> RigSummary {
        let (mut lo, mut hi) = (nalgebra::Vector3::repeat(f64::INFINITY), nalgebra::Vector3::repeat(f64::NEG_INFINITY));
        for &h in &self.bodies.handles {
            for &c in world.bodies[h].colliders() {
                let aabb = world.colliders[c].compute_aabb();
                lo = lo.inf(&crate::convert::vec_from_rapier(aabb.mins));
                hi = hi.sup(&crate::convert::vec_from_rapier(aabb.maxs));
            }
        }
        let size = if lo.x.is_finite() { hi - lo } else { nalgebra::Vector3::zeros() };
        RigSummary {
            name: self.rig.name.clone(),
            file: self.file.clone(),
            links: self.rig.links.len(),
            joints: self.rig.joints.len(),
            driven: self.driven.clone(),
            height_m: size.z,
            length_m: size.x.max(size.y),
            options: self.options,
        }
    }
}

impl RigSection {
    /// Reads the rig and its motion (paths against `base_dir`) and adds the
    /// links to `world` at the pose of time 0. Errors name the field from the
    /// scene's root (`rig.settle_s`).
    pub fn build(&self, world: &mut PhysicsWorld, base_dir: &Path) -> Result<SceneRig, FieldError> {
        let field = |f: &str| format!("rig.{f}");
        for (name, v) in [("position_m", self.position_m), ("rotation_deg", self.rotation_deg)] {
            if !v.iter().all(|c| c.is_finite()) {
                return Err(FieldError::new(field(name), format!("must be finite, got {v:?}")));
            }
        }
        for (name, v) in [("settle_s", self.settle_s), ("blend_s", self.blend_s)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FieldError::new(field(name), format!("must be finite and >= 0, got {v}")));
            }
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(FieldError::new(field("friction"), format!("must be finite and >= 0, got {}", self.friction)));
        }
        let urdf = base_dir.join(&self.urdf);
        let options = RigOptions { up_axis: self.up_axis, scale: self.scale };
        let rig = Rig::load(&urdf, options).map_err(|e| FieldError::new(field("urdf"), e.to_string()))?;
        let (clip, file) = match &self.motion {
            RigMotionSpec::Rest => (Clip { times_s: vec![0.0], poses: vec![rig.rest_pose()] }, urdf.clone()),
            RigMotionSpec::Keyframes { file } => {
                let path = base_dir.join(file);
                (
                    Clip::load_keyframes(&path, &rig)
                        .map_err(|e| FieldError::new(field("motion.file"), e.to_string()))?,
                    path,
                )
            }
            RigMotionSpec::Bvh { file, root, joints, up_axis, scale } => {
                let path = base_dir.join(file);
                let bvh = Bvh::load(&path).map_err(|e| FieldError::new(field("motion.file"), e.to_string()))?;
                let map = BvhMap { root: root.clone(), joints: joints.clone(), up_axis: *up_axis, scale: *scale };
                (
                    Clip::from_bvh(&bvh, &path, &rig, &map)
                        .map_err(|e| FieldError::new(field("motion"), e.to_string()))?,
                    path,
                )
            }
        };
        // The rest "motion" is one pose: nothing to loop.
        let looping = self.looping && self.motion != RigMotionSpec::Rest;
        if looping && clip.duration_s() <= 0.0 {
            return Err(FieldError::new(field("looping"), "a motion of one pose cannot loop: set looping = false"));
        }
        let playback = Playback {
            settle_s: self.settle_s,
            blend_s: self.blend_s,
            looping,
            placement: Isometry3::from_parts(
                Translation3::from(nalgebra::Vector3::from(self.position_m)),
                rotation_from_degrees(self.rotation_deg),
            ),
        };
        let driven = driven_joints(&clip, &rig);
        let settle = match &self.settle_pose {
            SettlePose::Named(SettlePoseName::Rest) => None,
            SettlePose::Named(SettlePoseName::FirstFrame) => Some(clip.poses[0].joints.clone()),
            SettlePose::Joints { joints } => Some(joints_from_values(&rig, joints).map_err(|problems| {
                let problems = problems.into_iter().map(|e| e.within("rig.settle_pose")).collect();
                crate::names::combined(problems, field("settle_pose.joints")).expect("refused for a problem")
            })?),
        };
        let mut motion =
            RigMotion::new(clip, &rig, playback, &file).map_err(|e| FieldError::new(field("motion"), e.to_string()))?;
        if let Some(joints) = settle {
            motion = motion.settling_at(joints).map_err(|e| FieldError::new(field("settle_pose"), e.to_string()))?;
        }
        let bodies = RigBodies::insert(&rig, world, &motion.pose_at(0.0), self.friction, &urdf)
            .map_err(|e| FieldError::new(field("urdf"), e.to_string()))?;
        Ok(SceneRig { rig, bodies, motion, file: urdf, options, driven, held_pose: None })
    }
}

/// The joints `clip` moves away from the rest pose at some key, by name.
fn driven_joints(clip: &Clip, rig: &Rig) -> Vec<String> {
    let rest = rig.rest_pose();
    (rig.joints.iter().enumerate())
        .filter(|(j, _)| clip.poses.iter().any(|p| p.joints[*j] != rest.joints[*j]))
        .map(|(_, joint)| joint.name.clone())
        .collect()
}
