//! What the cloth collides with: solids (static or moving on a path) and
//! itself. These are the scene-facing descriptions and their checked,
//! built form; detection and response live in [`crate::contacts`].

use crate::FieldError;
use crate::keyframes::finite3;
use crate::{PinMotion, Vec3};
use cloth_collide::{BodyPose, ShapeSpec, SolidShape};
use nalgebra::UnitQuaternion;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The scene files' orientation (`rotation_deg`): rotations about x, then
/// y, then z (fixed axes) by `deg` degrees, `Rz Ry Rx`.
pub fn rotation_from_degrees(deg: [f64; 3]) -> UnitQuaternion<f64> {
    let [rx, ry, rz] = deg.map(f64::to_radians);
    UnitQuaternion::from_axis_angle(&Vec3::z_axis(), rz)
        * UnitQuaternion::from_axis_angle(&Vec3::y_axis(), ry)
        * UnitQuaternion::from_axis_angle(&Vec3::x_axis(), rx)
}

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
    /// Path of the solid's frame, as an offset from `position_m` (default:
    /// fixed).
    #[serde(default = "fixed")]
    pub motion: PinMotion,
    /// Constant angular velocity about the solid's frame origin, world
    /// axes, degrees per second (default: no spin).
    #[serde(default)]
    pub spin_deg_s: [f64; 3],
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
    /// After each step, test every particle-triangle and edge-edge pair
    /// along its path through the step, and move the particles of pairs
    /// that would pass through each other as rigid impact zones
    /// (default true): repulsion and separation only see pairs that start
    /// close, so a fast fold could cross the cloth otherwise.
    #[serde(default = "yes")]
    pub continuous: bool,
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
    /// Angular velocity, rad/s (world axes).
    pub spin_rad_s: Vec3,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Whether the solid gives way to the cloth's push (a dynamic rigid
    /// body's collider): a particle squeezed between it and a solid that
    /// does not give way is held by the other one and pressed by this one
    /// (see `contacts::squeeze_force`). Prescribed solids do not.
    pub yielding: bool,
}

impl Collider {
    /// A solid driven from outside ([`crate::Control::set_solid_motion`]),
    /// starting at `anchor`, with Coulomb coefficient `friction` (>= 0);
    /// not yielding (see [`Collider::yielding`]).
    pub fn external(shape: SolidShape, anchor: BodyPose, friction: f64) -> Self {
        Self { shape, anchor, motion: PinMotion::External, spin_rad_s: Vec3::zeros(), friction, yielding: false }
    }

    /// The same solid, giving way to the cloth's push or not (see
    /// [`Collider::yielding`]).
    pub fn with_yielding(self, yielding: bool) -> Self {
        Self { yielding, ..self }
    }

    /// Pose at time `t` (s): the anchor moved along the path and turned by
    /// the spin, `R(t) = exp(omega t) R_0`.
    pub fn pose(&self, t: f64) -> BodyPose {
        let turn = UnitQuaternion::from_scaled_axis(self.spin_rad_s * t);
        BodyPose { position: self.anchor.position + self.motion.offset(t), rotation: turn * self.anchor.rotation }
    }

    /// Velocity of the solid's material point at `point` (m) at time `t`,
    /// m/s: `v(t) + omega x (point - origin(t))`.
    pub fn velocity_at(&self, t: f64, point: Vec3) -> Vec3 {
        let origin = self.anchor.position + self.motion.offset(t);
        self.motion.velocity(t) + self.spin_rad_s.cross(&(point - origin))
    }

    /// Whether the solid moves at all.
    pub fn is_moving(&self) -> bool {
        self.motion != PinMotion::Fixed || self.spin_rad_s != Vec3::zeros()
    }

    /// Whether the solid is driven from outside ([`crate::Control::set_solid_motion`]).
    pub fn is_external(&self) -> bool {
        self.motion == PinMotion::External
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
    /// Whether crossings during the step are prevented (impact zones).
    pub continuous: bool,
    /// Voxel edge of the spatial hash, m: at least the thickness, and the
    /// mean rest link length so a triangle touches few voxels.
    pub voxel_m: f64,
}

fn non_negative(field: String, v: f64) -> Result<f64, FieldError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(FieldError::new(field, format!("must be finite and >= 0, got {v}")))
    }
}

fn positive(field: String, v: f64) -> Result<f64, FieldError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(FieldError::new(field, format!("must be finite and > 0, got {v}")))
    }
}

impl CollisionSpec {
    /// The cloth-solid thickness, m.
    pub fn thickness(&self) -> f64 {
        self.thickness_m.unwrap_or(DEFAULT_THICKNESS_M)
    }

    /// Checks and builds the solids (loading meshes).
    pub fn build_colliders(&self) -> Result<Vec<Collider>, FieldError> {
        positive("collision.thickness_m".into(), self.thickness())?;
        let mut out = Vec::with_capacity(self.colliders.len());
        for (k, c) in self.colliders.iter().enumerate() {
            let field = |name: &str| format!("colliders[{k}].{name}");
            let table = format!("colliders[{k}]");
            let shape = SolidShape::build(&c.shape, &self.base_dir)
                .map_err(|e| FieldError::from(e).within("shape").within(&table))?;
            finite3("position_m", &c.position_m).map_err(|e| e.within(&table))?;
            finite3("rotation_deg", &c.rotation_deg).map_err(|e| e.within(&table))?;
            finite3("spin_deg_s", &c.spin_deg_s).map_err(|e| e.within(&table))?;
            c.motion.validate().map_err(|e| e.within("motion").within(&table))?;
            if c.motion == PinMotion::External && c.spin_deg_s != [0.0; 3] {
                return Err(FieldError::new(
                    field("spin_deg_s"),
                    "an external solid's rotation is set from outside: leave spin out",
                ));
            }
            let friction = non_negative(field("friction"), c.friction)?;
            let anchor =
                BodyPose { position: Vec3::from(c.position_m), rotation: rotation_from_degrees(c.rotation_deg) };
            let spin_rad_s = Vec3::from(c.spin_deg_s.map(f64::to_radians));
            out.push(Collider { shape, anchor, motion: c.motion.clone(), spin_rad_s, friction, yielding: false });
        }
        Ok(out)
    }

    /// Checks the self-collision set-up; `default_stiffness` (N/m) and
    /// `mean_link_m` (m) come from the model.
    pub fn build_self_collision(
        &self,
        default_stiffness: f64,
        mean_link_m: f64,
    ) -> Result<Option<SelfCollision>, FieldError> {
        let Some(s) = self.self_collision else { return Ok(None) };
        let thickness_m = positive("self_collision.thickness_m".into(), s.thickness_m)?;
        let stiffness_n_m =
            positive("self_collision.stiffness_n_m".into(), s.stiffness_n_m.unwrap_or(default_stiffness))?;
        let voxel_m = thickness_m.max(mean_link_m);
        Ok(Some(SelfCollision {
            thickness_m,
            stiffness_n_m,
            point_triangle: s.point_triangle,
            continuous: s.continuous,
            voxel_m,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cloth_collide::ShapeSpec;

    /// The surface velocity is the time derivative of a material point of
    /// the moving, spinning solid.
    #[test]
    fn surface_velocity_is_the_derivative_of_a_material_point() {
        let spec = CollisionSpec {
            colliders: vec![ColliderSpec {
                shape: ShapeSpec::Ball { radius_m: 0.2 },
                position_m: [0.1, -0.2, 0.3],
                rotation_deg: [10.0, 20.0, 30.0],
                friction: 0.0,
                motion: PinMotion::Oscillate { amplitude_m: [0.05, 0.0, 0.02], frequency_hz: 1.3 },
                spin_deg_s: [40.0, -25.0, 90.0],
            }],
            ..CollisionSpec::default()
        };
        let c = &spec.build_colliders().unwrap()[0];
        let local = Vec3::new(0.05, 0.1, -0.15);
        let world = |t: f64| {
            let p = c.pose(t);
            p.position + p.rotation * local
        };
        for t in [0.0, 0.37, 1.9] {
            let eps = 1e-6;
            let fd = (world(t + eps) - world(t - eps)) / (2.0 * eps);
            assert!((fd - c.velocity_at(t, world(t))).norm() < 1e-7, "t = {t}");
        }
        assert!(c.is_moving());
    }
}
