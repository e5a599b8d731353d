//! Character rigs read from URDF, posed by forward kinematics.
//!
//! A [`Rig`] is a tree of links joined by joints, each link carrying its
//! collision shapes, read with `urdf-rs` and checked here (every error
//! names the file, the link or joint, and the field: [`RigError`]). A
//! [`RigPose`] holds one value per joint and the root's pose; [`Rig::link_poses`]
//! turns it into every link's pose in the world, SI units, Z up.
//!
//! Rigs as tools export them: Y-up or Z-up files ([`UpAxis`]: a Y-up file
//! is turned +90 degrees about X so its up becomes the world's Z), a
//! global scale (centimetre rigs: 0.01), CRLF line ends, links without
//! inertials (a driven rig needs none), meshes by path relative to the
//! file. Joints: the URDF kinds `fixed`, `revolute`, `continuous`,
//! `prismatic` and `floating`, and `spherical` (not in the URDF standard,
//! common in humanoid rigs: a ball joint). `planar` is refused.
//!
//! Joint limits are read but not enforced: a driven rig follows its
//! motion, which is the authority on where the character is.

use cloth_collide::ShapeSpec;
use cloth_core::FieldError;
use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion};
use std::path::{Path, PathBuf};

type Vec3 = nalgebra::Vector3<f64>;

/// Which axis of the file points up (`"z"` or `"y"` in scene files).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// Z up, as URDF and the cloth's world (no change).
    #[default]
    Z,
    /// Y up (common in character tools): the rig is turned +90 degrees
    /// about X, taking the file's +Y to the world's +Z.
    Y,
}

/// How to read a rig file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigOptions {
    /// The file's up axis. Default Z.
    pub up_axis: UpAxis,
    /// Metres per file length unit (0.01 for a rig in centimetres).
    /// Scales joint origins, shape origins, shape sizes and prismatic
    /// offsets. Default 1.
    pub scale: f64,
}

impl UpAxis {
    /// As scene files spell it.
    pub fn name(self) -> &'static str {
        match self {
            UpAxis::Z => "z",
            UpAxis::Y => "y",
        }
    }

    /// The turn that takes this up axis to the world's Z.
    pub fn turn(self) -> UnitQuaternion<f64> {
        match self {
            UpAxis::Z => UnitQuaternion::identity(),
            UpAxis::Y => UnitQuaternion::from_axis_angle(&Vec3::x_axis(), std::f64::consts::FRAC_PI_2),
        }
    }
}

impl Default for RigOptions {
    fn default() -> Self {
        Self { up_axis: UpAxis::Z, scale: 1.0 }
    }
}

/// A collision shape of a link, in its shape frame, m.
#[derive(Debug, Clone, PartialEq)]
pub enum RigGeometry {
    /// A box, cylinder, capsule or ball as the cloth's solids take them
    /// (cylinders and capsules along the shape frame's Z, URDF's
    /// convention; a capsule's `length` in URDF 1.1 is its cylinder's).
    Solid(ShapeSpec),
    /// A closed triangle mesh from an OBJ file, resolved against the rig
    /// file's folder, with its per-axis scale (the rig's scale included).
    /// Kept apart from [`ShapeSpec::Mesh`], which scales alike on every
    /// axis: URDF meshes scale per axis.
    Mesh {
        /// The mesh file.
        path: PathBuf,
        /// Scale per axis.
        scale: Vec3,
    },
}

/// One collision shape of a link.
#[derive(Debug, Clone, PartialEq)]
pub struct RigShape {
    /// The shape's frame in the link's frame (m).
    pub origin: Isometry3<f64>,
    /// The shape.
    pub geometry: RigGeometry,
}

/// A rigid part of the character.
#[derive(Debug, Clone, PartialEq)]
pub struct RigLink {
    /// The URDF name.
    pub name: String,
    /// Its collision shapes (may be none).
    pub shapes: Vec<RigShape>,
}

/// How a joint lets its child move relative to its parent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointKind {
    /// No motion.
    Fixed,
    /// A rotation about the axis, rad, within limits (not enforced).
    Revolute {
        /// Lower limit, rad.
        lower: f64,
        /// Upper limit, rad.
        upper: f64,
    },
    /// A rotation about the axis, rad, unlimited.
    Continuous,
    /// A translation along the axis, m (after scaling), within limits (not enforced).
    Prismatic {
        /// Lower limit, m.
        lower: f64,
        /// Upper limit, m.
        upper: f64,
    },
    /// Any rotation (a ball joint).
    Spherical,
    /// Any rigid motion.
    Floating,
}

/// A joint between two links.
#[derive(Debug, Clone, PartialEq)]
pub struct RigJoint {
    /// The URDF name.
    pub name: String,
    /// What motion it allows.
    pub kind: JointKind,
    /// Index of the parent link.
    pub parent: usize,
    /// Index of the child link.
    pub child: usize,
    /// The joint frame in the parent's frame at zero motion (m).
    pub origin: Isometry3<f64>,
    /// The unit axis in the joint frame (revolute, continuous, prismatic).
    pub axis: Unit<Vec3>,
}

/// The value of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointValue {
    /// A rotation about the axis, rad (revolute, continuous).
    Angle(f64),
    /// A translation along the axis, m (prismatic).
    Offset(f64),
    /// A rotation of the child in the joint frame (spherical).
    Rotation(UnitQuaternion<f64>),
    /// A rigid motion of the child in the joint frame, m (floating).
    Motion(Isometry3<f64>),
    /// No value (fixed).
    None,
}

/// Joint values and the root's pose: everything that places the rig.
#[derive(Debug, Clone, PartialEq)]
pub struct RigPose {
    /// The root link's pose in the world (after the up-axis turn), m.
    pub root: Isometry3<f64>,
    /// One value per joint, in [`Rig::joints`] order.
    pub joints: Vec<JointValue>,
}

/// What went wrong reading or posing a rig.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RigError {
    /// The file could not be read or is not URDF.
    #[error("{file}: {message}")]
    Read {
        /// The file.
        file: PathBuf,
        /// Why.
        message: String,
    },
    /// A value in the file is impossible.
    #[error("{file}: {element} {name:?}: {field}: {message}")]
    Invalid {
        /// The file.
        file: PathBuf,
        /// `link`, `joint` or `robot`.
        element: &'static str,
        /// The link's or joint's name.
        name: String,
        /// The attribute or child element.
        field: String,
        /// Why.
        message: String,
    },
    /// A pose that does not fit the rig.
    #[error("pose: {message}")]
    Pose {
        /// Why.
        message: String,
    },
}

/// A character rig: links, joints in parent-before-child order, the root.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// The robot's name in the file.
    pub name: String,
    /// Links in file order.
    pub links: Vec<RigLink>,
    /// Joints ordered so that a joint's parent link is placed before it.
    pub joints: Vec<RigJoint>,
    /// The root link (the one no joint moves).
    pub root: usize,
    /// The up-axis turn applied before the root's pose, world from file.
    pub up: UnitQuaternion<f64>,
}

impl Rig {
    /// Reads a URDF file; meshes resolve against its folder.
    pub fn load(path: &Path, options: RigOptions) -> Result<Self, RigError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| RigError::Read { file: path.to_path_buf(), message: e.to_string() })?;
        Self::parse(&text, path, options)
    }

    /// Reads URDF text; `file` names it in errors and locates meshes.
    pub fn parse(text: &str, file: &Path, options: RigOptions) -> Result<Self, RigError> {
        let file_buf = file.to_path_buf();
        let scale = options.scale;
        if !(scale.is_finite() && scale > 0.0) {
            return Err(RigError::Invalid {
                file: file_buf,
                element: "robot",
                name: String::new(),
                field: "scale".into(),
                message: format!("must be finite and > 0, got {scale}"),
            });
        }
        let robot = urdf_rs::read_from_string(text)
            .map_err(|e| RigError::Read { file: file_buf.clone(), message: format!("not valid URDF: {e}") })?;
        let invalid = |element: &'static str, name: &str, field: &str, message: String| RigError::Invalid {
            file: file_buf.clone(),
            element,
            name: name.to_string(),
            field: field.to_string(),
            message,
        };
        if robot.links.is_empty() {
            return Err(invalid("robot", &robot.name, "link", "the rig has no links".into()));
        }
        let dir = file.parent().unwrap_or(Path::new(""));
        let mut links = Vec::with_capacity(robot.links.len());
        for link in &robot.links {
            if links.iter().any(|l: &RigLink| l.name == link.name) {
                return Err(invalid("link", &link.name, "name", "used by two links".into()));
            }
            let mut shapes = Vec::with_capacity(link.collision.len());
            for (k, c) in link.collision.iter().enumerate() {
                let field = |f: &str| format!("collision[{k}].{f}");
                let origin = pose(&c.origin, scale).map_err(|m| invalid("link", &link.name, &field("origin"), m))?;
                let geometry = geometry(&c.geometry, scale, dir)
                    .map_err(|e| invalid("link", &link.name, &field(&format!("geometry.{}", e.path)), e.message))?;
                shapes.push(RigShape { origin, geometry });
            }
            links.push(RigLink { name: link.name.clone(), shapes });
        }
        let find = |name: &str| links.iter().position(|l| l.name == name);
        let mut joints = Vec::with_capacity(robot.joints.len());
        let mut parent_of: Vec<Option<usize>> = vec![None; links.len()];
        for (index, j) in robot.joints.iter().enumerate() {
            let bad = |field: &str, message: String| invalid("joint", &j.name, field, message);
            if robot.joints[..index].iter().any(|o| o.name == j.name) {
                return Err(bad("name", "used by two joints".into()));
            }
            let parent =
                find(&j.parent.link).ok_or_else(|| bad("parent.link", format!("no link named {:?}", j.parent.link)))?;
            let child =
                find(&j.child.link).ok_or_else(|| bad("child.link", format!("no link named {:?}", j.child.link)))?;
            if parent == child {
                return Err(bad("child.link", "is its own parent".into()));
            }
            if let Some(other) = parent_of[child] {
                return Err(bad(
                    "child.link",
                    format!("{:?} is already the child of joint {:?}", j.child.link, robot.joints[other].name),
                ));
            }
            parent_of[child] = Some(index);
            let origin = pose(&j.origin, scale).map_err(|m| bad("origin", m))?;
            let axis = Vec3::from(j.axis.xyz.0);
            let moving_axis = matches!(
                j.joint_type,
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous | urdf_rs::JointType::Prismatic
            );
            let axis = if moving_axis {
                if !(axis.iter().all(|a| a.is_finite()) && axis.norm() > 0.0) {
                    return Err(bad("axis.xyz", format!("must be finite and non-zero, got {:?}", j.axis.xyz.0)));
                }
                Unit::new_normalize(axis)
            } else {
                Vec3::x_axis()
            };
            let limits = |s: f64| -> Result<(f64, f64), RigError> {
                let (lo, hi) = (j.limit.lower * s, j.limit.upper * s);
                if lo.is_nan() || hi.is_nan() || lo > hi {
                    return Err(bad(
                        "limit",
                        format!("lower {} must not exceed upper {}", j.limit.lower, j.limit.upper),
                    ));
                }
                Ok((lo, hi))
            };
            let kind = match j.joint_type {
                urdf_rs::JointType::Fixed => JointKind::Fixed,
                urdf_rs::JointType::Revolute => {
                    let (lower, upper) = limits(1.0)?;
                    JointKind::Revolute { lower, upper }
                }
                urdf_rs::JointType::Continuous => JointKind::Continuous,
                urdf_rs::JointType::Prismatic => {
                    let (lower, upper) = limits(scale)?;
                    JointKind::Prismatic { lower, upper }
                }
                urdf_rs::JointType::Spherical => JointKind::Spherical,
                urdf_rs::JointType::Floating => JointKind::Floating,
                urdf_rs::JointType::Planar => {
                    return Err(bad("type", "planar joints are not supported (use floating)".into()));
                }
            };
            joints.push(RigJoint { name: j.name.clone(), kind, parent, child, origin, axis });
        }
        let roots: Vec<usize> = (0..links.len()).filter(|&l| parent_of[l].is_none()).collect();
        let &[root] = roots.as_slice() else {
            let names: Vec<&str> = roots.iter().map(|&l| links[l].name.as_str()).collect();
            let message = if names.is_empty() {
                "the joints form a cycle: no root link".to_string()
            } else {
                format!(
                    "{} links are not moved by any joint ({}): the rig must be one tree",
                    names.len(),
                    names.join(", ")
                )
            };
            return Err(invalid("robot", &robot.name, "joint", message));
        };
        // Parent before child: a depth-first walk from the root.
        let mut ordered = Vec::with_capacity(joints.len());
        let mut frontier = vec![root];
        while let Some(link) = frontier.pop() {
            for j in joints.iter().filter(|j| j.parent == link) {
                frontier.push(j.child);
                ordered.push(j.clone());
            }
        }
        if ordered.len() != joints.len() {
            return Err(invalid("robot", &robot.name, "joint", "the joints form a cycle".into()));
        }
        Ok(Self { name: robot.name, links, joints: ordered, root, up: options.up_axis.turn() })
    }

    /// The pose with every joint at zero and the root at the origin.
    pub fn rest_pose(&self) -> RigPose {
        let joints = self
            .joints
            .iter()
            .map(|j| match j.kind {
                JointKind::Fixed => JointValue::None,
                JointKind::Revolute { .. } | JointKind::Continuous => JointValue::Angle(0.0),
                JointKind::Prismatic { .. } => JointValue::Offset(0.0),
                JointKind::Spherical => JointValue::Rotation(UnitQuaternion::identity()),
                JointKind::Floating => JointValue::Motion(Isometry3::identity()),
            })
            .collect();
        RigPose { root: Isometry3::identity(), joints }
    }

    /// Index of the joint named `name`.
    pub fn joint(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Index of the link named `name`.
    pub fn link(&self, name: &str) -> Option<usize> {
        self.links.iter().position(|l| l.name == name)
    }

    /// Every link's pose in the world for `pose`, into `out` (one per
    /// link, in [`Rig::links`] order): the root at `pose.root` after the
    /// up-axis turn, each child at `parent * origin * motion(value)`.
    pub fn link_poses(&self, pose: &RigPose, out: &mut Vec<Isometry3<f64>>) -> Result<(), RigError> {
        if pose.joints.len() != self.joints.len() {
            return Err(RigError::Pose {
                message: format!("{} joint values for {} joints", pose.joints.len(), self.joints.len()),
            });
        }
        out.clear();
        out.resize(self.links.len(), Isometry3::identity());
        out[self.root] = pose.root * Isometry3::from_parts(Translation3::identity(), self.up);
        for (j, value) in self.joints.iter().zip(&pose.joints) {
            let motion = joint_motion(j, value)?;
            out[j.child] = out[j.parent] * j.origin * motion;
        }
        Ok(())
    }
}

/// The child's motion in the joint frame for `value` (rotation about or
/// translation along the axis; any rotation; any rigid motion).
fn joint_motion(joint: &RigJoint, value: &JointValue) -> Result<Isometry3<f64>, RigError> {
    let wrong =
        || RigError::Pose { message: format!("joint {:?} ({:?}) cannot take {value:?}", joint.name, joint.kind) };
    let finite = |x: f64| {
        if x.is_finite() {
            Ok(x)
        } else {
            Err(RigError::Pose { message: format!("joint {:?}: value {x} is not finite", joint.name) })
        }
    };
    Ok(match (joint.kind, value) {
        (JointKind::Fixed, JointValue::None) => Isometry3::identity(),
        (JointKind::Revolute { .. } | JointKind::Continuous, JointValue::Angle(a)) => {
            Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&joint.axis, finite(*a)?))
        }
        (JointKind::Prismatic { .. }, JointValue::Offset(d)) => {
            Isometry3::from_parts(Translation3::from(joint.axis.into_inner() * finite(*d)?), UnitQuaternion::identity())
        }
        (JointKind::Spherical, JointValue::Rotation(q)) => {
            finite(q.coords.norm())?;
            Isometry3::from_parts(Translation3::identity(), *q)
        }
        (JointKind::Floating, JointValue::Motion(m)) => {
            finite(m.translation.vector.norm() + m.rotation.coords.norm())?;
            *m
        }
        _ => return Err(wrong()),
    })
}

/// A URDF origin (`xyz` scaled, `rpy` fixed-axis roll-pitch-yaw: `Rz(y) Ry(p) Rx(r)`).
fn pose(p: &urdf_rs::Pose, scale: f64) -> Result<Isometry3<f64>, String> {
    let (xyz, rpy) = (p.xyz.0, p.rpy.0);
    if !xyz.iter().chain(&rpy).all(|v| v.is_finite()) {
        return Err(format!("xyz {xyz:?} and rpy {rpy:?} must be finite"));
    }
    Ok(Isometry3::from_parts(
        Translation3::from(Vec3::from(xyz) * scale),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    ))
}

/// A URDF collision geometry, scaled; errors name the field under `geometry`.
fn geometry(g: &urdf_rs::Geometry, scale: f64, dir: &Path) -> Result<RigGeometry, FieldError> {
    let positive = |field: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(v * scale)
        } else {
            Err(FieldError::new(field, format!("must be finite and > 0, got {v}")))
        }
    };
    Ok(match g {
        urdf_rs::Geometry::Box { size } => {
            let s = size.0;
            let half = |v: f64| positive("box.size", v).map(|v| v / 2.0);
            RigGeometry::Solid(ShapeSpec::Cuboid { half_extents_m: [half(s[0])?, half(s[1])?, half(s[2])?] })
        }
        urdf_rs::Geometry::Cylinder { radius, length } => RigGeometry::Solid(ShapeSpec::Cylinder {
            half_length_m: positive("cylinder.length", *length)? / 2.0,
            radius_m: positive("cylinder.radius", *radius)?,
        }),
        urdf_rs::Geometry::Capsule { radius, length } => RigGeometry::Solid(ShapeSpec::Capsule {
            half_length_m: positive("capsule.length", *length)? / 2.0,
            radius_m: positive("capsule.radius", *radius)?,
        }),
        urdf_rs::Geometry::Sphere { radius } => {
            RigGeometry::Solid(ShapeSpec::Ball { radius_m: positive("sphere.radius", *radius)? })
        }
        urdf_rs::Geometry::Mesh { filename, scale: mesh_scale } => {
            if filename.starts_with("package://") {
                return Err(FieldError::new(
                    "mesh.filename",
                    format!("{filename:?}: package:// paths need ROS; give a path relative to the rig file"),
                ));
            }
            let s = mesh_scale.map_or([1.0; 3], |s| s.0);
            let scale =
                Vec3::new(positive("mesh.scale", s[0])?, positive("mesh.scale", s[1])?, positive("mesh.scale", s[2])?);
            let path = dir.join(filename.strip_prefix("file://").unwrap_or(filename));
            if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")) {
                return Err(FieldError::new(
                    "mesh.filename",
                    format!("{filename:?}: only OBJ meshes are read (export STL or Collada meshes as OBJ)"),
                ));
            }
            if !path.is_file() {
                return Err(FieldError::new("mesh.filename", format!("{} does not exist", path.display())));
            }
            RigGeometry::Mesh { path, scale }
        }
    })
}
