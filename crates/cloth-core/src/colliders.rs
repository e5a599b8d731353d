//! What the cloth collides with: solids (static or moving on a path) and
//! itself. These are the scene-facing descriptions and their checked,
//! built form; detection and response live in [`crate::contacts`].

use crate::keyframes::finite3;
use crate::{PinMotion, Vec3};
use cloth_collide::{BodyPose, ShapeSpec, SolidShape};
use nalgebra::UnitQuaternion;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// One solid, `[[colliders]]` in a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColliderSpec {
    /// The shape in the solid's own frame.
    pub shape: ShapeSpec,
    /// Where the solid's frame starts, m.
    #[serde(default)]
    pub position_m: [f64; 3],
    /// Orientation: rotations about x, then y, then z (fixed axes), degrees.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// Coulomb friction coefficient between cloth and this solid (>= 0).
    #[serde(default)]
    pub friction: f64,
    /// Path of the solid's frame, as an offset from `position_m` (the
    /// solid translates; default: fixed).
    #[serde(default = "fixed")]
    pub motion: PinMotion,
}

fn fixed() -> PinMotion {
    PinMotion::Fixed
}

/// Cloth self-collision, `[self_collision]` in a scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SelfCollisionSpec {
    /// Distance below which two pieces of cloth repel, m.
    pub thickness_m: f64,
    /// Repulsion stiffness `k_r`, N/m (default: the material's tensile stiffness).
    #[serde(default)]
    pub stiffness_n_m: Option<f64>,
    /// Also repel particles from triangles, not only from particles
    /// (default true): with a thickness below the particle spacing, pairs
    /// alone let a particle slip through the middle of a quad.
    #[serde(default = "yes")]
    pub point_triangle: bool,
}

fn yes() -> bool {
    true
}

/// Everything the cloth collides with.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CollisionSpec {
    /// Solids.
    pub colliders: Vec<ColliderSpec>,
    /// Distance kept between the cloth's particles and solid surfaces, m
    /// (`[collision] thickness_m`, default 0.005).
    pub thickness_m: Option<f64>,
    /// Self-collision, off when `None`.
    pub self_collision: Option<SelfCollisionSpec>,
    /// Directory that relative mesh paths are resolved against.
    pub base_dir: PathBuf,
}

/// Default cloth-solid thickness, m.
pub const DEFAULT_THICKNESS_M: f64 = 0.005;

/// A built solid.
#[derive(Debug, Clone)]
pub struct Collider {
    /// The shape, ready for queries.
    pub shape: SolidShape,
    /// Pose at time 0.
    pub anchor: BodyPose,
    /// Translation path relative to the anchor.
    pub motion: PinMotion,
    /// Coulomb friction coefficient.
    pub friction: f64,
}

impl Collider {
    /// Pose at time `t` (s).
    pub fn pose(&self, t: f64) -> BodyPose {
        BodyPose { position: self.anchor.position + self.motion.offset(t), rotation: self.anchor.rotation }
    }

    /// Velocity of the solid (it translates only) at time `t`, m/s.
    pub fn velocity(&self, t: f64) -> Vec3 {
        self.motion.velocity(t)
    }
}

/// Self-collision parameters of a built model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelfCollision {
    /// Repulsion distance, m.
    pub thickness_m: f64,
    /// Repulsion stiffness, N/m.
    pub stiffness_n_m: f64,
    /// Whether particle-triangle pairs are tested too.
    pub point_triangle: bool,
    /// Voxel edge of the spatial hash, m: at least the thickness, and the
    /// mean rest link length so a triangle touches few voxels.
    pub voxel_m: f64,
}

/// Why the collision set-up is invalid: the field path (as in the scene) and why.
pub type CollisionError = (String, String);

fn non_negative(field: String, v: f64) -> Result<f64, CollisionError> {
    if v.is_finite() && v >= 0.0 { Ok(v) } else { Err((field, format!("must be finite and >= 0, got {v}"))) }
}

fn positive(field: String, v: f64) -> Result<f64, CollisionError> {
    if v.is_finite() && v > 0.0 { Ok(v) } else { Err((field, format!("must be finite and > 0, got {v}"))) }
}

impl CollisionSpec {
    /// The cloth-solid thickness, m.
    pub fn thickness(&self) -> f64 {
        self.thickness_m.unwrap_or(DEFAULT_THICKNESS_M)
    }

    /// Checks and builds the solids (loading meshes).
    pub fn build_colliders(&self) -> Result<Vec<Collider>, CollisionError> {
        positive("collision.thickness_m".into(), self.thickness())?;
        let mut out = Vec::with_capacity(self.colliders.len());
        for (k, c) in self.colliders.iter().enumerate() {
            let field = |name: &str| format!("colliders[{k}].{name}");
            let shape = SolidShape::build(&c.shape, &self.base_dir).map_err(|e| {
                let text = e.to_string();
                let (f, m) = text.split_once(": ").unwrap_or(("", &text));
                (field(&format!("shape.{f}")), m.to_string())
            })?;
            finite3("position_m", &c.position_m).map_err(|(f, m)| (field(f), m))?;
            finite3("rotation_deg", &c.rotation_deg).map_err(|(f, m)| (field(f), m))?;
            c.motion.validate().map_err(|(f, m)| (field(&format!("motion.{f}")), m))?;
            let friction = non_negative(field("friction"), c.friction)?;
            let [rx, ry, rz] = c.rotation_deg.map(f64::to_radians);
            let rotation = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), rz)
                * UnitQuaternion::from_axis_angle(&Vec3::y_axis(), ry)
                * UnitQuaternion::from_axis_angle(&Vec3::x_axis(), rx);
            let anchor = BodyPose { position: Vec3::from(c.position_m), rotation };
            out.push(Collider { shape, anchor, motion: c.motion.clone(), friction });
        }
        Ok(out)
    }

    /// Checks the self-collision set-up; `default_stiffness` (N/m) and
    /// `mean_link_m` (m) come from the model.
    pub fn build_self_collision(
        &self,
        default_stiffness: f64,
        mean_link_m: f64,
    ) -> Result<Option<SelfCollision>, CollisionError> {
        let Some(s) = self.self_collision else { return Ok(None) };
        let thickness_m = positive("self_collision.thickness_m".into(), s.thickness_m)?;
        let stiffness_n_m =
            positive("self_collision.stiffness_n_m".into(), s.stiffness_n_m.unwrap_or(default_stiffness))?;
        let voxel_m = thickness_m.max(mean_link_m);
        Ok(Some(SelfCollision { thickness_m, stiffness_n_m, point_triangle: s.point_triangle, voxel_m }))
    }
}
