//! Motion for a [`Rig`]: clips of poses from BVH or keyframe files,
//! sampled with interpolation (slerp for rotations), and a playback that
//! holds the rest pose while a garment settles, blends into the clip as it
//! starts playing, looping with the root's displacement carried from
//! cycle to cycle.
//!
//! A keyframe file (TOML, every key checked):
//!
//! ```toml
//! [[keys]]
//! time_s = 0.0
//! root_position_m = [0.0, 0.0, 0.92]   # the root link's frame (default: origin)
//! root_rotation_deg = [0.0, 0.0, 0.0]  # about x, then y, then z (fixed axes)
//! joints = { knee_l = 20.0, hip_l = [0.0, -15.0, 0.0] }
//! # revolute / continuous: degrees; prismatic: metres; spherical: [x, y, z]
//! # degrees (fixed axes); floating: { position_m = [..], rotation_deg = [..] }.
//! # A joint a key does not list is at rest in that key.
//! ```
//!
//! BVH ([`crate::bvh`]) is retargeted through a name table (rig joint ->
//! BVH joint): each mapped rig joint turns its child link so that the
//! link's orientation in the world changes from the rig's rest pose as
//! the BVH joint's does from the BVH's rest pose. So the BVH's zero pose
//! must be the rig's rest pose (both standing, arms down for the
//! mannequin); BVH joints between mapped ones are accounted for (their
//! rotations are in the world orientations); rig joints not in the table
//! stay at rest; a revolute joint takes the twist about its axis. The
//! root link takes the root BVH joint's position (file units times the
//! scale, the file's up turned to Z) and orientation.

use crate::bvh::Bvh;
use crate::rig::{JointKind, JointValue, Rig, RigPose, UpAxis};
use cloth_core::FieldError;
use cloth_core::rotation_from_degrees;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

type Vec3 = nalgebra::Vector3<f64>;

/// Why a motion could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MotionError {
    /// The BVH file is malformed.
    #[error(transparent)]
    Bvh(#[from] crate::bvh::BvhError),
    /// A value in a motion file or a name table is impossible.
    #[error("{file}: {field}: {message}")]
    Invalid {
        /// The file.
        file: PathBuf,
        /// The field (`keys[2].joints.knee_l`, `joints.hip_l`).
        field: String,
        /// Why.
        message: String,
    },
}

/// Poses at increasing times.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    /// Times, s, strictly increasing from 0.
    pub times_s: Vec<f64>,
    /// One pose per time.
    pub poses: Vec<RigPose>,
}

/// The shorter spherical interpolation from `a` (w = 0) to `b` (w = 1).
fn slerp(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, w: f64) -> UnitQuaternion<f64> {
    // The ends exactly (slerp's trigonometry is off by an ulp or so there).
    if w <= 0.0 {
        return *a;
    }
    if w >= 1.0 {
        return *b;
    }
    // `try_slerp` flips to the shorter arc; it declines only for opposite
    // rotations, where any path is as short: keep `a` until halfway.
    a.try_slerp(b, w, 1e-12).unwrap_or(if w < 0.5 { *a } else { *b })
}

/// Rigid motions interpolated: translation linearly, rotation by slerp.
fn blend_isometry(a: &Isometry3<f64>, b: &Isometry3<f64>, w: f64) -> Isometry3<f64> {
    let t = a.translation.vector.lerp(&b.translation.vector, w);
    Isometry3::from_parts(Translation3::from(t), slerp(&a.rotation, &b.rotation, w))
}

/// `a` and `b` interpolated joint by joint (`w` in [0, 1]); both poses must
/// be of one rig, so every joint has the same kind of value.
pub fn blend(a: &RigPose, b: &RigPose, w: f64) -> RigPose {
    let joints = a
        .joints
        .iter()
        .zip(&b.joints)
        .map(|(x, y)| match (x, y) {
            (JointValue::Angle(p), JointValue::Angle(q)) => JointValue::Angle(p + (q - p) * w),
            (JointValue::Offset(p), JointValue::Offset(q)) => JointValue::Offset(p + (q - p) * w),
            (JointValue::Rotation(p), JointValue::Rotation(q)) => JointValue::Rotation(slerp(p, q, w)),
            (JointValue::Motion(p), JointValue::Motion(q)) => JointValue::Motion(blend_isometry(p, q, w)),
            _ => *x,
        })
        .collect();
    RigPose { root: blend_isometry(&a.root, &b.root, w), joints }
}

impl Clip {
    /// The clip's length, s.
    pub fn duration_s(&self) -> f64 {
        self.times_s.last().copied().unwrap_or(0.0)
    }

    /// The pose at `t` s: interpolated between the keys around it, the
    /// first key before the start and the last after the end.
    pub fn sample(&self, t: f64) -> RigPose {
        let k = self.times_s.partition_point(|&tk| tk <= t);
        if k == 0 {
            return self.poses[0].clone();
        }
        if k == self.times_s.len() {
            return self.poses[k - 1].clone();
        }
        let w = (t - self.times_s[k - 1]) / (self.times_s[k] - self.times_s[k - 1]);
        blend(&self.poses[k - 1], &self.poses[k], w)
    }

    /// Reads a keyframe file (TOML; see the module docs).
    pub fn load_keyframes(path: &Path, rig: &Rig) -> Result<Self, MotionError> {
        let invalid =
            |field: String, message: String| MotionError::Invalid { file: path.to_path_buf(), field, message };
        let text = std::fs::read_to_string(path).map_err(|e| invalid(String::new(), e.to_string()))?;
        Self::parse_keyframes(&text, path, rig)
    }

    /// Reads keyframe text; `file` names it in errors.
    pub fn parse_keyframes(text: &str, file: &Path, rig: &Rig) -> Result<Self, MotionError> {
        let invalid =
            |field: String, message: String| MotionError::Invalid { file: file.to_path_buf(), field, message };
        let parsed: KeyframeFile = toml::from_str(text).map_err(|e| invalid(String::new(), e.to_string()))?;
        if parsed.keys.is_empty() {
            return Err(invalid("keys".into(), "needs at least one key".into()));
        }
        let mut times_s = Vec::with_capacity(parsed.keys.len());
        let mut poses = Vec::with_capacity(parsed.keys.len());
        for (k, key) in parsed.keys.iter().enumerate() {
            let field = |f: &str| format!("keys[{k}].{f}");
            let previous = times_s.last().copied().unwrap_or(-1.0);
            if !(key.time_s.is_finite() && key.time_s > previous) || (k == 0 && key.time_s != 0.0) {
                return Err(invalid(
                    field("time_s"),
                    format!("times must start at 0 and increase, got {}", key.time_s),
                ));
            }
            let finite = |name: &str, v: &[f64; 3]| {
                if v.iter().all(|c| c.is_finite()) {
                    Ok(())
                } else {
                    Err(invalid(field(name), format!("must be finite, got {v:?}")))
                }
            };
            finite("root_position_m", &key.root_position_m)?;
            finite("root_rotation_deg", &key.root_rotation_deg)?;
            let mut pose = rig.rest_pose();
            pose.root = Isometry3::from_parts(
                Translation3::from(Vec3::from(key.root_position_m)),
                rotation_from_degrees(key.root_rotation_deg),
            );
            let unknown: Vec<FieldError> = key
                .joints
                .keys()
                .filter(|name| rig.joint(name).is_none())
                .map(|name| {
                    let names = rig.joints.iter().map(|j| j.name.as_str());
                    FieldError::new(field(&format!("joints.{name}")), crate::names::unknown("rig joint", name, names))
                })
                .collect();
            if let Some(e) = crate::names::combined(unknown, field("joints")) {
                return Err(invalid(e.path, e.message));
            }
            for (name, value) in &key.joints {
                let field = field(&format!("joints.{name}"));
                let j = rig.joint(name).expect("unknown joints are refused above");
                pose.joints[j] = joint_value(rig.joints[j].kind, value).map_err(|m| invalid(field, m))?;
            }
            times_s.push(key.time_s);
            poses.push(pose);
        }
        Ok(Self { times_s, poses })
    }

    /// Retargets `bvh` onto `rig` through `map` (see the module docs);
    /// `file` names the BVH file in errors.
    pub fn from_bvh(bvh: &Bvh, file: &Path, rig: &Rig, map: &BvhMap) -> Result<Self, MotionError> {
        let invalid =
            |field: String, message: String| MotionError::Invalid { file: file.to_path_buf(), field, message };
        if !(map.scale.is_finite() && map.scale > 0.0) {
            return Err(invalid("scale".into(), format!("must be finite and > 0, got {}", map.scale)));
        }
        // Every name that does not resolve, at once, with the nearest ones.
        let bvh_names = || bvh.joints.iter().map(|j| j.name.as_str());
        let rig_names = || rig.joints.iter().map(|j| j.name.as_str());
        let mut problems = Vec::new();
        let root = bvh.joint(&map.root);
        if root.is_none() {
            problems.push(FieldError::new("root", crate::names::unknown("BVH joint", &map.root, bvh_names())));
        }
        // (rig joint, BVH joint) in the rig's joint order.
        let mut pairs: Vec<Option<usize>> = vec![None; rig.joints.len()];
        for (rig_joint, bvh_joint) in &map.joints {
            let field = format!("joints.{rig_joint}");
            let (j, b) = (rig.joint(rig_joint), bvh.joint(bvh_joint));
            if j.is_none() {
                problems
                    .push(FieldError::new(field.clone(), crate::names::unknown("rig joint", rig_joint, rig_names())));
            }
            if b.is_none() {
                problems
                    .push(FieldError::new(field.clone(), crate::names::unknown("BVH joint", bvh_joint, bvh_names())));
            }
            let (Some(j), Some(b)) = (j, b) else { continue };
            if matches!(rig.joints[j].kind, JointKind::Fixed | JointKind::Prismatic { .. }) {
                let message = format!("{:?} joints do not turn: BVH rotations drive the others", rig.joints[j].kind);
                problems.push(FieldError::new(field, message));
                continue;
            }
            pairs[j] = Some(b);
        }
        if let Some(e) = crate::names::combined(problems, "joints") {
            return Err(invalid(e.path, e.message));
        }
        let root = root.expect("an unknown root is a problem above");
        let up = map.up_axis.turn();
        let mut rest = Vec::new();
        rig.link_poses(&rig.rest_pose(), &mut rest).map_err(|e| invalid(String::new(), e.to_string()))?;
        let (mut turns, mut places, mut link_turn) =
            (Vec::new(), Vec::new(), vec![UnitQuaternion::identity(); rig.links.len()]);
        let mut times_s = Vec::with_capacity(bvh.frames());
        let mut poses = Vec::with_capacity(bvh.frames());
        for frame in 0..bvh.frames() {
            bvh.global_rotations(frame, &mut turns);
            bvh.positions_from(frame, &turns, &mut places);
            // The BVH's orientations and positions in the world (Z up, m).
            let world_turn = |b: usize| up * turns[b] * up.inverse();
            let mut pose = rig.rest_pose();
            let root_turn = world_turn(root);
            pose.root = Isometry3::from_parts(Translation3::from(up * places[root] * map.scale), root_turn);
            link_turn[rig.root] = root_turn * rest[rig.root].rotation;
            for (j, joint) in rig.joints.iter().enumerate() {
                let frame_turn = link_turn[joint.parent] * joint.origin.rotation;
                if let Some(b) = pairs[j] {
                    let wanted = frame_turn.inverse() * world_turn(b) * rest[joint.child].rotation;
                    pose.joints[j] = match joint.kind {
                        JointKind::Spherical => JointValue::Rotation(wanted),
                        JointKind::Floating => {
                            JointValue::Motion(Isometry3::from_parts(Translation3::identity(), wanted))
                        }
                        _ => JointValue::Angle(twist_angle(&wanted, &joint.axis)),
                    };
                }
                let motion = match pose.joints[j] {
                    JointValue::Angle(a) => UnitQuaternion::from_axis_angle(&joint.axis, a),
                    JointValue::Rotation(q) => q,
                    JointValue::Motion(m) => m.rotation,
                    JointValue::Offset(_) | JointValue::None => UnitQuaternion::identity(),
                };
                link_turn[joint.child] = frame_turn * motion;
            }
            times_s.push(frame as f64 * bvh.frame_time_s);
            poses.push(pose);
        }
        Ok(Self { times_s, poses })
    }
}

/// The rest pose of `rig` with `values` (keyframe notation: degrees, or
/// `[x, y, z]` degrees for ball joints) on the joints they name. Every
/// unknown name and bad value is reported, with the field `joints.<name>`.
pub fn joints_from_values(
    rig: &Rig,
    values: &BTreeMap<String, toml::Value>,
) -> Result<Vec<JointValue>, Vec<FieldError>> {
    let mut joints = rig.rest_pose().joints;
    let mut problems = Vec::new();
    for (name, value) in values {
        let field = format!("joints.{name}");
        let Some(j) = rig.joint(name) else {
            let names = rig.joints.iter().map(|j| j.name.as_str());
            problems.push(FieldError::new(field, crate::names::unknown("rig joint", name, names)));
            continue;
        };
        match joint_value(rig.joints[j].kind, value) {
            Ok(v) => joints[j] = v,
            Err(m) => problems.push(FieldError::new(field, m)),
        }
    }
    if problems.is_empty() { Ok(joints) } else { Err(problems) }
}

/// The angle of `q`'s twist about `axis` (swing-twist decomposition), rad, in (-pi, pi].
pub fn twist_angle(q: &UnitQuaternion<f64>, axis: &nalgebra::Unit<Vec3>) -> f64 {
    let along = q.imag().dot(axis);
    let a = 2.0 * along.atan2(q.w);
    // atan2 of (sin, cos) of the half angle: fold into (-pi, pi].
    if a > std::f64::consts::PI {
        a - std::f64::consts::TAU
    } else if a <= -std::f64::consts::PI {
        a + std::f64::consts::TAU
    } else {
        a
    }
}

/// A BVH name table: which BVH joint drives the rig's root and each rig joint.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BvhMap {
    /// The BVH joint that places the rig's root link.
    pub root: String,
    /// Rig joint -> BVH joint.
    pub joints: BTreeMap<String, String>,
    /// The BVH file's up axis (motion capture: usually Y).
    #[serde(default = "y_up")]
    pub up_axis: UpAxis,
    /// Metres per BVH length unit (0.01 for centimetres).
    #[serde(default = "unit_scale")]
    pub scale: f64,
}

pub(crate) fn y_up() -> UpAxis {
    UpAxis::Y
}

pub(crate) fn unit_scale() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeFile {
    keys: Vec<Key>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Key {
    time_s: f64,
    #[serde(default)]
    root_position_m: [f64; 3],
    #[serde(default)]
    root_rotation_deg: [f64; 3],
    #[serde(default)]
    joints: BTreeMap<String, toml::Value>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FloatingValue {
    #[serde(default)]
    position_m: [f64; 3],
    #[serde(default)]
    rotation_deg: [f64; 3],
}

/// A keyframe file's value for a joint of `kind`.
fn joint_value(kind: JointKind, value: &toml::Value) -> Result<JointValue, String> {
    let number = || {
        value
            .as_float()
            .or_else(|| value.as_integer().map(|i| i as f64))
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("a {kind:?} joint takes a finite number, got {value}"))
    };
    let triple = |v: &toml::Value| -> Result<[f64; 3], String> {
        let parsed: Result<[f64; 3], _> = v.clone().try_into();
        parsed
            .ok()
            .filter(|t| t.iter().all(|c| c.is_finite()))
            .ok_or_else(|| format!("needs three finite numbers, got {v}"))
    };
    Ok(match kind {
        JointKind::Fixed => return Err("a fixed joint takes no value".into()),
        JointKind::Revolute { .. } | JointKind::Continuous => JointValue::Angle(number()?.to_radians()),
        JointKind::Prismatic { .. } => JointValue::Offset(number()?),
        JointKind::Spherical => JointValue::Rotation(rotation_from_degrees(triple(value)?)),
        JointKind::Floating => {
            let f: FloatingValue =
                value.clone().try_into().map_err(|e| format!("needs {{ position_m, rotation_deg }}: {e}"))?;
            if !f.position_m.iter().chain(&f.rotation_deg).all(|c| c.is_finite()) {
                return Err(format!("position_m and rotation_deg must be finite, got {value}"));
            }
            JointValue::Motion(Isometry3::from_parts(
                Translation3::from(Vec3::from(f.position_m)),
                rotation_from_degrees(f.rotation_deg),
            ))
        }
    })
}

/// How a clip is played: rest, then the clip blended in from the rest
/// pose (looping, or holding its last pose).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Playback {
    /// Time at the rest pose first (the garment settles), s.
    pub settle_s: f64,
    /// Time over which the playing clip takes over from the rest pose, s.
    pub blend_s: f64,
    /// Loop the clip, carrying the root's displacement over each cycle
    /// (the clip's last pose is the next cycle's first); else hold the last pose.
    pub looping: bool,
    /// Where the character stands: applied to the root in every pose.
    pub placement: Isometry3<f64>,
}

impl Default for Playback {
    fn default() -> Self {
        Self { settle_s: 0.0, blend_s: 0.0, looping: true, placement: Isometry3::identity() }
    }
}

/// A clip on a schedule: the rig's pose at any time.
#[derive(Debug, Clone, PartialEq)]
pub struct RigMotion {
    clip: Clip,
    playback: Playback,
    /// The rest pose with the clip's first root: held while settling.
    rest: RigPose,
    /// The root's displacement over one cycle, world frame.
    cycle: Isometry3<f64>,
}

impl RigMotion {
    /// Plays `clip` (of `rig`) as `playback` says; `file` names the clip in errors.
    pub fn new(clip: Clip, rig: &Rig, playback: Playback, file: &Path) -> Result<Self, MotionError> {
        let invalid = |field: &str, message: String| MotionError::Invalid {
            file: file.to_path_buf(),
            field: field.to_string(),
            message,
        };
        for (name, v) in [("settle_s", playback.settle_s), ("blend_s", playback.blend_s)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(name, format!("must be finite and >= 0, got {v}")));
            }
        }
        if clip.poses.iter().any(|p| p.joints.len() != rig.joints.len()) || clip.poses.len() != clip.times_s.len() {
            return Err(invalid("", "the clip was made for another rig".into()));
        }
        if playback.looping && clip.duration_s() <= 0.0 {
            return Err(invalid("looping", "a clip of one pose cannot loop".into()));
        }
        let first = &clip.poses[0];
        let mut rest = rig.rest_pose();
        rest.root = first.root;
        let last = clip.poses.last().unwrap_or(first);
        let cycle = last.root * first.root.inverse();
        Ok(Self { clip, playback, rest, cycle })
    }

    /// Holds `joints` (one value per rig joint) instead of the rest pose
    /// while settling and blends from them into the clip.
    pub fn settling_at(mut self, joints: Vec<JointValue>) -> Result<Self, MotionError> {
        if joints.len() != self.rest.joints.len() {
            let message = format!("{} joint values for a rig of {}", joints.len(), self.rest.joints.len());
            return Err(MotionError::Invalid { file: PathBuf::new(), field: "settle_pose".into(), message });
        }
        self.rest.joints = joints;
        Ok(self)
    }

    /// The clip.
    pub fn clip(&self) -> &Clip {
        &self.clip
    }

    /// The playback settings.
    pub fn playback(&self) -> &Playback {
        &self.playback
    }

    /// The pose at time `t`, s (from the start of the run): the settle pose
    /// (the rest pose unless [`RigMotion::settling_at`]) until `settle_s`; then the clip plays from its start, weighted
    /// against the rest pose by a smoothstep that reaches the clip after
    /// `blend_s`, so every joint and the root start from rest with zero
    /// velocity and reach the clip's own velocity without a jump.
    pub fn pose_at(&self, t: f64) -> RigPose {
        let Playback { settle_s, blend_s, looping, placement } = self.playback;
        let tau = (t - settle_s).max(0.0);
        let mut pose = if looping {
            let period = self.clip.duration_s();
            let cycles = (tau / period).floor();
            let mut pose = self.clip.sample(tau - cycles * period);
            for _ in 0..cycles as u64 {
                pose.root = self.cycle * pose.root;
            }
            pose
        } else {
            self.clip.sample(tau)
        };
        if tau < blend_s {
            pose = blend(&self.rest, &pose, smoothstep(tau / blend_s));
        } else if t < settle_s {
            // No blend: the settle pose until the clip starts.
            pose = self.rest.clone();
        }
        pose.root = placement * pose.root;
        pose
    }
}

/// `3 s^2 - 2 s^3` for `s` in [0, 1]: starts and ends with zero slope.
fn smoothstep(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}
