//! Scene files with rigid bodies: a cloth scene (see `cloth_core::scene`)
//! plus these sections, every key checked.
//!
//! ```toml
//! [[bodies]]                   # rapier rigid bodies; the cloth meets their colliders
//! name = "ball"                # unique; attachments and summaries use it
//! kind = "dynamic"             # or "kinematic" (follows `motion` and `spin_deg_s`), "fixed"
//! shape = { kind = "ball", radius_m = 0.1 }   # any collider shape but "mesh" and
//!                              # "half-space" for dynamic bodies
//! position_m = [0.0, 0.0, 1.0]
//! rotation_deg = [0.0, 0.0, 0.0]   # about x, then y, then z (fixed axes)
//! velocity_m_s = [0.0, 0.0, 0.0]   # dynamic bodies: initial velocity of the centre of mass
//! angular_velocity_deg_s = [0.0, 0.0, 0.0]
//! density_kg_m3 = 1000.0       # or mass_kg = 2.0 (not both); default density 1000
//! friction = 0.5               # Coulomb coefficient, cloth-body and body-body
//! restitution = 0.0
//! linear_damping_1_s = 0.0     # dynamic bodies: rapier's damping, 1/s
//! angular_damping_1_s = 0.0    # (a body in a fluid)
//! motion = { kind = "fixed" }  # kinematic bodies: path of the frame origin, as pins
//! spin_deg_s = [0.0, 0.0, 0.0] # kinematic bodies: angular velocity
//!
//! [[attachments]]              # a [[pins]] entry (external motion) held by a body
//! pins = 0                     # index of the [[pins]] entry
//! body = "post"
//!
//! [coupling]                   # optional, these are the defaults
//! master = "monolithic"        # or "iterated", "staggered"; "iterated" is
//!                              # the default for integrators without a
//!                              # linear solve (vbd, explicit)
//! max_iterations = 20          # most passes a step (monolithic: solves of
//!                              # the cloths, 1 or 2; default 2)
//! abs_tol_m_s = 1e-6           # iterated: agreement of the bodies' mean
//! rel_tol = 1e-6               # velocities, m/s and rad/s
//! tol_m = 1e-3                 # monolithic: agreement of the points where
//!                              # cloth meets body at the step's end, m
//!                              # (default a fifth of the contact layer)
//! relaxation = "quasi-newton"  # or "fixed"
//! omega = 0.5                  # fixed relaxation, or the quasi-Newton's first step
//! accept_unconverged = true   # keep the best pass when contacts keep switching
//! ```
//!
//! A `[rig]` section adds a URDF character driven by a motion (see
//! [`crate::rig_scene`]). The rapier world steps with the scene's `dt_s`
//! and, with the `gravity` effect, its gravity (else none).

use crate::cloth_set::{ClothBuilder, ClothHandle, ClothSet, CouplingError};
use crate::convert::{pose_to_rapier, vec_to_rapier};
use crate::coupling::{CouplingReport, IteratedCoupling, Master, MonolithicCoupling};
use crate::rig_scene::{RigSection, SceneRig};
use cloth_collide::{BodyPose, ShapeSpec, SolidShape};
use cloth_core::rotation_from_degrees;
use cloth_core::scene::{RunConfig, Scene, SceneError, SceneErrorKind, check_start_outside};
use cloth_core::{FieldError, PinMotion, Vec3};
use cloth_cosim::Relaxation;
use nalgebra::UnitQuaternion;
use rapier3d_f64::prelude::{ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// What moves a body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BodyKind {
    /// Moved by forces, contacts and the cloth.
    Dynamic,
    /// Follows its `motion` and `spin_deg_s`; pushes but is not pushed.
    Kinematic,
    /// Never moves.
    Fixed,
}

fn fixed() -> PinMotion {
    PinMotion::Fixed
}

fn half() -> f64 {
    0.5
}

/// One `[[bodies]]` entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    /// Unique name.
    pub name: String,
    /// Dynamic, kinematic or fixed.
    pub kind: BodyKind,
    /// The collider's shape in the body's frame.
    pub shape: ShapeSpec,
    /// Frame origin at the start, m.
    #[serde(default)]
    pub position_m: [f64; 3],
    /// Orientation: about x, then y, then z (fixed axes), degrees.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// Initial velocity of the centre of mass (dynamic), m/s.
    #[serde(default)]
    pub velocity_m_s: [f64; 3],
    /// Initial angular velocity (dynamic), degrees/s.
    #[serde(default)]
    pub angular_velocity_deg_s: [f64; 3],
    /// Density, kg/m^3 (default 1000 unless `mass_kg` is given).
    #[serde(default)]
    pub density_kg_m3: Option<f64>,
    /// Mass, kg (instead of a density).
    #[serde(default)]
    pub mass_kg: Option<f64>,
    /// Coulomb coefficient (default 0.5).
    #[serde(default = "half")]
    pub friction: f64,
    /// Restitution of body-body contacts (default 0).
    #[serde(default)]
    pub restitution: f64,
    /// Dynamic bodies: rapier's linear damping, 1/s (the velocity decays
    /// as `exp(-c t)` without other forces; a body in a fluid). Default 0.
    #[serde(default)]
    pub linear_damping_1_s: f64,
    /// Dynamic bodies: rapier's angular damping, 1/s. Default 0.
    #[serde(default)]
    pub angular_damping_1_s: f64,
    /// Path of a kinematic body's frame origin, as an offset from `position_m`.
    #[serde(default = "fixed")]
    pub motion: PinMotion,
    /// Angular velocity of a kinematic body about its frame origin, degrees/s.
    #[serde(default)]
    pub spin_deg_s: [f64; 3],
}

/// One `[[attachments]]` entry.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttachmentSpec {
    /// Index of the `[[pins]]` entry; its motion must be external.
    pub pins: usize,
    /// Name of the body.
    pub body: String,
}

/// The coupling master by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum MasterName {
    /// One pass per step.
    Staggered,
    /// Passes until the bodies' end velocities agree.
    #[default]
    Iterated,
    /// The bodies inside the cloth's solve, one pass per step.
    Monolithic,
}

/// Relaxation by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RelaxationName {
    /// `u += omega r`.
    Fixed,
    /// IQN-ILS after a first step of `omega`.
    #[default]
    QuasiNewton,
}

/// `[coupling]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CouplingSection {
    /// Master; unset: monolithic when the integrator has a linear solve
    /// for bodies to join, else iterated.
    pub master: Option<MasterName>,
    /// Most passes per step; for the monolithic master its solves of the
    /// cloths, 1 or 2 (unset: the master's default).
    pub max_iterations: Option<usize>,
    /// Absolute velocity tolerance, m/s (and rad/s) (unset: the master's default).
    pub abs_tol_m_s: Option<f64>,
    /// Relative tolerance (unset: the master's default).
    pub rel_tol: Option<f64>,
    /// Monolithic master: agreement of the points where cloth meets body, m.
    pub tol_m: Option<f64>,
    /// Guess update.
    pub relaxation: RelaxationName,
    /// Relaxation factor, (0, 1].
    pub omega: f64,
    /// Keep the last pass when not converged.
    pub accept_unconverged: bool,
}

impl Default for CouplingSection {
    fn default() -> Self {
        let d = IteratedCoupling::default();
        Self {
            master: None,
            max_iterations: None,
            abs_tol_m_s: None,
            rel_tol: None,
            tol_m: None,
            relaxation: RelaxationName::QuasiNewton,
            omega: 0.5,
            accept_unconverged: d.accept_unconverged,
        }
    }
}

impl CouplingSection {
    /// The master these settings describe, for an integrator that takes
    /// bodies into its solve (`takes_bodies`) or not.
    pub fn master(&self, takes_bodies: bool) -> Master {
        let default = if takes_bodies { MasterName::Monolithic } else { MasterName::Iterated };
        let (d, m) = (IteratedCoupling::default(), MonolithicCoupling::default());
        match self.master.unwrap_or(default) {
            MasterName::Staggered => Master::Staggered,
            MasterName::Monolithic => Master::Monolithic(MonolithicCoupling {
                max_solves: self.max_iterations.unwrap_or(m.max_solves),
                tol_m: self.tol_m.or(m.tol_m),
            }),
            MasterName::Iterated => Master::Iterated(IteratedCoupling {
                max_iterations: self.max_iterations.unwrap_or(d.max_iterations),
                abs_tol_m_s: self.abs_tol_m_s.unwrap_or(d.abs_tol_m_s),
                rel_tol: self.rel_tol.unwrap_or(d.rel_tol),
                relaxation: match self.relaxation {
                    RelaxationName::Fixed => Relaxation::Fixed(self.omega),
                    RelaxationName::QuasiNewton => Relaxation::QuasiNewton { initial: self.omega },
                },
                accept_unconverged: self.accept_unconverged,
            }),
        }
    }
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Extensions {
    #[serde(default)]
    bodies: Vec<BodySpec>,
    #[serde(default)]
    attachments: Vec<AttachmentSpec>,
    #[serde(default)]
    coupling: CouplingSection,
    #[serde(default)]
    rig: Option<RigSection>,
}

/// A scene with rigid bodies.
#[derive(Debug, Clone, PartialEq)]
pub struct CoupledScene {
    /// The cloth part.
    pub scene: Scene,
    /// `[[bodies]]`.
    pub bodies: Vec<BodySpec>,
    /// `[[attachments]]`.
    pub attachments: Vec<AttachmentSpec>,
    /// `[coupling]`.
    pub coupling: CouplingSection,
    /// `[rig]`.
    pub rig: Option<RigSection>,
}

/// The top-level keys this module reads.
const KEYS: [&str; 4] = ["bodies", "attachments", "coupling", "rig"];

/// Whether scene text declares rigid bodies (a `[[bodies]]` table or a `[rig]`).
pub fn has_bodies(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("bodies") || t.contains_key("rig"))
}

/// A body of a built scene.
#[derive(Debug, Clone)]
pub struct SceneBody {
    /// Its name in the scene.
    pub name: String,
    /// Its handle.
    pub handle: RigidBodyHandle,
    /// Its `[[bodies]]` entry.
    pub spec: BodySpec,
    anchor: BodyPose,
    /// A kinematic body's pose set from outside
    /// ([`CoupledRun::set_kinematic_target`]), replacing its scripted motion.
    pub(crate) target: Option<BodyPose>,
}

/// A built scene: the world, the cloth, and how to step them.
pub struct CoupledRun {
    /// The rapier world.
    pub world: PhysicsWorld,
    /// The cloth set (one cloth).
    pub cloths: ClothSet,
    /// The scene's cloth.
    pub cloth: ClothHandle,
    /// The bodies, in scene order.
    pub bodies: Vec<SceneBody>,
    /// The character, if the scene has a `[rig]`.
    pub rig: Option<SceneRig>,
    /// The master.
    pub master: Master,
    /// Time step, steps, integrator and solver.
    pub config: RunConfig,
    /// What the scene allowed that looks wrong (cloth starting inside a solid).
    allowed: Vec<String>,
}

impl std::fmt::Debug for CoupledRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CoupledRun").field("bodies", &self.bodies).field("master", &self.master).finish_non_exhaustive()
    }
}

impl CoupledScene {
    /// Reads `path` with `--set` overrides (which may address bodies too).
    pub fn load(path: &Path, overrides: &[String]) -> Result<Self, SceneError> {
        let err = |kind| SceneError { file: path.to_path_buf(), kind };
        let text = std::fs::read_to_string(path).map_err(|e| err(SceneErrorKind::Io(e.to_string())))?;
        let mut scene = Self::parse(&text, overrides).map_err(err)?;
        scene.scene.base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(scene)
    }

    /// Parses scene text with overrides.
    pub fn parse(text: &str, overrides: &[String]) -> Result<Self, SceneErrorKind> {
        let (scene, rest) = Scene::parse_with_extensions(text, overrides, &KEYS)?;
        let ext: Extensions = rest.try_into().map_err(|e: toml::de::Error| SceneErrorKind::Parse(e.to_string()))?;
        Ok(Self { scene, bodies: ext.bodies, attachments: ext.attachments, coupling: ext.coupling, rig: ext.rig })
    }

    /// Checks every field and builds the world and the cloth.
    pub fn build(&self) -> Result<CoupledRun, SceneErrorKind> {
        let invalid = |field: String, message: String| SceneErrorKind::Invalid { field, message };
        let (model, config) = self.scene.build()?;
        let mut world = PhysicsWorld::new();
        world.gravity = vec_to_rapier(model.effects().gravity.unwrap_or_else(Vec3::zeros));
        world.integration_parameters.dt = config.dt_s;
        let mut bodies = Vec::with_capacity(self.bodies.len());
        for (k, b) in self.bodies.iter().enumerate() {
            let field = |name: &str| format!("bodies[{k}].{name}");
            if bodies.iter().any(|o: &SceneBody| o.name == b.name) {
                return Err(invalid(field("name"), format!("{:?} is used twice", b.name)));
            }
            let (handle, anchor) =
                add_body(&mut world, b, &self.scene.base_dir).map_err(|e| e.within(&format!("bodies[{k}]")))?;
            bodies.push(SceneBody { name: b.name.clone(), handle, spec: b.clone(), anchor, target: None });
        }
        let rig = match &self.rig {
            Some(section) => {
                let built = section.build(&mut world, &self.scene.base_dir)?;
                if let Some(b) = bodies.iter().find(|b| built.rig.link(&b.name).is_some()) {
                    return Err(invalid("bodies".into(), format!("{:?} is also a link of the rig", b.name)));
                }
                Some(built)
            }
            None => None,
        };
        let takes_bodies = config.integrator.capabilities().bodies;
        self.check_coupling(takes_bodies)?;
        let mut builder = ClothBuilder::new(model.clone()).integrator(config.integrator).solver(config.solver);
        let body_of = |name: &str| {
            let scene_body = bodies.iter().find(|b| b.name == name).map(|b| b.handle);
            scene_body.or_else(|| rig.as_ref().and_then(|r| r.body(name)))
        };
        // Every attachment naming no body, at once, with the nearest names.
        let known: Vec<&str> = bodies
            .iter()
            .map(|b| b.name.as_str())
            .chain(rig.iter().flat_map(|r| r.rig.links.iter().map(|l| l.name.as_str())))
            .collect();
        let unknown: Vec<FieldError> = (self.attachments.iter().enumerate())
            .filter(|(_, a)| body_of(&a.body).is_none())
            .map(|(k, a)| {
                let message = crate::names::unknown("body or rig link", &a.body, known.clone());
                FieldError::new(format!("attachments[{k}].body"), message)
            })
            .collect();
        if let Some(e) = crate::names::combined(unknown, "attachments") {
            return Err(e.into());
        }
        for (k, a) in self.attachments.iter().enumerate() {
            let field = |name: &str| format!("attachments[{k}].{name}");
            let body = body_of(&a.body).expect("unknown bodies are refused above");
            let pins: Vec<usize> = (0..model.pins().len()).filter(|&p| model.pins()[p].spec == a.pins).collect();
            if pins.is_empty() {
                return Err(invalid(field("pins"), format!("no [[pins]] entry {}", a.pins)));
            }
            if !model.pins()[pins[0]].is_external() {
                return Err(invalid(
                    field("pins"),
                    format!("pins[{}] needs motion = {{ kind = \"external\" }}", a.pins),
                ));
            }
            for p in pins {
                builder = builder.attach(p, body);
            }
        }
        let mut cloths = ClothSet::new();
        let cloth = cloths.insert(builder, &world).map_err(|e| match e {
            CouplingError::Attachment { pin, message } => invalid(format!("attachments (model pin {pin})"), message),
            other => invalid("bodies".into(), other.to_string()),
        })?;
        if config.initial_jitter_m > 0.0 {
            let sim = config.simulation(model);
            let jittered = sim.snapshot();
            let own = cloths.get_mut(cloth).expect("just inserted").simulation_mut();
            own.restore(&jittered).map_err(|e| invalid("simulation.initial_jitter_m".into(), e.to_string()))?;
        }
        let master = self.coupling.master(takes_bodies);
        let mut run = CoupledRun { world, cloths, cloth, bodies, rig, master, config, allowed: Vec::new() };
        let names = run.solid_names();
        let inside = run.particles_inside();
        let allow = self.scene.allows_start_inside();
        run.allowed.extend(check_start_outside(&inside, allow, |k| names[k].clone())?);
        Ok(run)
    }

    fn check_coupling(&self, takes_bodies: bool) -> Result<(), SceneErrorKind> {
        let c = &self.coupling;
        let invalid =
            |field: &str, message: String| SceneErrorKind::Invalid { field: format!("coupling.{field}"), message };
        if c.master == Some(MasterName::Monolithic) && !takes_bodies {
            let message = "needs an integrator with a linear solve (bdf2, backward-euler); use \"iterated\"";
            return Err(invalid("master", message.into()));
        }
        if c.max_iterations == Some(0) {
            return Err(invalid("max_iterations", "must be >= 1".into()));
        }
        let monolithic = c.master.unwrap_or(if takes_bodies { MasterName::Monolithic } else { MasterName::Iterated })
            == MasterName::Monolithic;
        if monolithic {
            if let Some(n) = c.max_iterations.filter(|n| *n > 2) {
                return Err(invalid(
                    "max_iterations",
                    format!("the monolithic master solves the cloths 1 or 2 times a step, got {n}"),
                ));
            }
            for (name, set) in [("abs_tol_m_s", c.abs_tol_m_s.is_some()), ("rel_tol", c.rel_tol.is_some())] {
                if set {
                    return Err(invalid(name, "the monolithic master's agreement is coupling.tol_m (m)".into()));
                }
            }
        } else if c.tol_m.is_some() {
            return Err(invalid("tol_m", "only the monolithic master takes it".into()));
        }
        if let Some(t) = c.tol_m.filter(|t| !(t.is_finite() && *t > 0.0)) {
            return Err(invalid("tol_m", format!("must be finite and > 0, got {t}")));
        }
        let (abs, rel) = (c.abs_tol_m_s.unwrap_or(1.0), c.rel_tol.unwrap_or(1.0));
        for (name, v) in [("abs_tol_m_s", abs), ("rel_tol", rel)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(name, format!("must be finite and >= 0, got {v}")));
            }
        }
        if abs + rel == 0.0 {
            return Err(invalid("abs_tol_m_s", "abs_tol_m_s and rel_tol cannot both be 0".into()));
        }
        if !(c.omega > 0.0 && c.omega <= 1.0) {
            return Err(invalid("omega", format!("must be in (0, 1], got {}", c.omega)));
        }
        Ok(())
    }
}

/// Adds one body with its collider; errors name the field (relative to the entry).
fn add_body(
    world: &mut PhysicsWorld,
    b: &BodySpec,
    base_dir: &Path,
) -> Result<(RigidBodyHandle, BodyPose), FieldError> {
    let finite = |name: &str, v: &[f64; 3]| {
        if v.iter().all(|c| c.is_finite()) {
            Ok(())
        } else {
            Err(FieldError::new(name.to_string(), format!("must be finite, got {v:?}")))
        }
    };
    finite("position_m", &b.position_m)?;
    finite("rotation_deg", &b.rotation_deg)?;
    finite("velocity_m_s", &b.velocity_m_s)?;
    finite("angular_velocity_deg_s", &b.angular_velocity_deg_s)?;
    finite("spin_deg_s", &b.spin_deg_s)?;
    let non_negative = |name: &str, v: f64| {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(FieldError::new(name.to_string(), format!("must be finite and >= 0, got {v}")))
        }
    };
    non_negative("friction", b.friction)?;
    non_negative("restitution", b.restitution)?;
    non_negative("linear_damping_1_s", b.linear_damping_1_s)?;
    non_negative("angular_damping_1_s", b.angular_damping_1_s)?;
    for (name, damping) in
        [("linear_damping_1_s", b.linear_damping_1_s), ("angular_damping_1_s", b.angular_damping_1_s)]
    {
        if b.kind != BodyKind::Dynamic && damping > 0.0 {
            return Err(FieldError::new(name, "only dynamic bodies are damped"));
        }
    }
    b.motion.validate().map_err(|e| e.within("motion"))?;
    let moving = b.motion != PinMotion::Fixed || b.spin_deg_s != [0.0; 3];
    if b.kind != BodyKind::Kinematic && moving {
        return Err(FieldError::new("motion", "only kinematic bodies follow a motion or spin"));
    }
    if b.motion == PinMotion::External {
        return Err(FieldError::new("motion", "a scene body cannot be external: use a kinematic path"));
    }
    let dynamic = b.kind == BodyKind::Dynamic;
    if dynamic && matches!(b.shape, ShapeSpec::HalfSpace { .. } | ShapeSpec::Mesh { .. }) {
        return Err(FieldError::new(
            "shape",
            "a dynamic body needs a solid shape (not half-space or mesh; use convex-hull)",
        ));
    }
    let shape = SolidShape::build(&b.shape, base_dir).map_err(|e| FieldError::from(e).within("shape"))?;
    let (parry_shape, local) = shape.parts();
    let mut collider =
        ColliderBuilder::new(parry_shape.clone()).position(local).friction(b.friction).restitution(b.restitution);
    match (b.density_kg_m3, b.mass_kg) {
        (Some(_), Some(_)) => return Err(FieldError::new("mass_kg", "give density_kg_m3 or mass_kg, not both")),
        (_, Some(m)) if !(m.is_finite() && m > 0.0) => {
            return Err(FieldError::new("mass_kg", format!("must be finite and > 0, got {m}")));
        }
        (Some(d), _) if !(d.is_finite() && d > 0.0) => {
            return Err(FieldError::new("density_kg_m3", format!("must be finite and > 0, got {d}")));
        }
        (_, Some(m)) => collider = collider.mass(m),
        (d, None) => collider = collider.density(d.unwrap_or(1000.0)),
    }
    let anchor = BodyPose { position: Vec3::from(b.position_m), rotation: rotation_from_degrees(b.rotation_deg) };
    let builder = match b.kind {
        BodyKind::Dynamic => RigidBodyBuilder::dynamic()
            .linvel(vec_to_rapier(Vec3::from(b.velocity_m_s)))
            .angvel(vec_to_rapier(Vec3::from(b.angular_velocity_deg_s.map(f64::to_radians))))
            .linear_damping(b.linear_damping_1_s)
            .angular_damping(b.angular_damping_1_s),
        BodyKind::Kinematic => RigidBodyBuilder::kinematic_position_based(),
        BodyKind::Fixed => RigidBodyBuilder::fixed(),
    };
    let body = builder.pose(pose_to_rapier(&anchor)).build();
    let handle = world.bodies.insert(body);
    world.colliders.insert_with_parent(collider.build(), handle, &mut world.bodies);
    Ok((handle, anchor))
}

impl CoupledRun {
    /// The scene's cloth particles inside a solid now, with the solid each
    /// is deepest in (see [`cloth_core::Simulation::particles_inside`]),
    /// but for a pin inside the body it is attached to: held there by
    /// design.
    pub fn particles_inside(&self) -> Vec<cloth_core::Inside> {
        let c = &self.cloths[self.cloth];
        let pin_body = |particle: usize| {
            let pins = c.simulation().model().pins();
            c.attachments().iter().find(|a| pins[a.pin].particle == particle).map(|a| a.body)
        };
        let solid_body = |solid: usize| c.world_solids().iter().find(|s| s.solid == solid).and_then(|s| s.body);
        let held = |particle: usize, solid: usize| pin_body(particle).is_some_and(|b| solid_body(solid) == Some(b));
        c.simulation().particles_inside(held)
    }

    /// What looks wrong with the scene before its first step (a character
    /// of an implausible height or lying on its side, cloth allowed to
    /// start inside a solid), each naming the file or the key to set.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = self.rig.as_ref().map(|r| r.summary(&self.world).warnings()).unwrap_or_default();
        out.extend(self.allowed.iter().cloned());
        out
    }

    /// A name for each of the cloth's solids, in the model's order: its
    /// `[[bodies]]` name or rig link, or `colliders[k]` for the scene's own.
    pub fn solid_names(&self) -> Vec<String> {
        let cloth = &self.cloths[self.cloth];
        let n = cloth.simulation().model().colliders().len();
        let mut names: Vec<String> = (0..n).map(|k| format!("colliders[{k}]")).collect();
        for s in cloth.world_solids() {
            let Some(handle) = s.body else { continue };
            let scene_body = self.bodies.iter().find(|b| b.handle == handle).map(|b| b.name.as_str());
            let link = self.rig.as_ref().and_then(|r| r.link_of(handle));
            if let (Some(name), Some(slot)) = (scene_body.or(link), names.get_mut(s.solid)) {
                *slot = name.to_string();
            }
        }
        names
    }

    /// Steps cloth and bodies once with the scene's master.
    pub fn step(&mut self) -> Result<CouplingReport, CouplingError> {
        let master = self.master;
        self.step_with(&master)
    }

    /// Sends the kinematic bodies and the rig's links to their poses at the
    /// end of the next step (rapier's next kinematic positions), from their
    /// scripted motions or the targets and joint values set from outside.
    /// [`CoupledRun::step_with`] does this first; calling it before, to
    /// read where they will be, changes nothing.
    pub fn pose_kinematics(&mut self) -> Result<(), crate::RigError> {
        let h = self.config.dt_s;
        let t_end = self.cloths[self.cloth].simulation().time() + h;
        for b in self.bodies.iter().filter(|b| b.spec.kind == BodyKind::Kinematic) {
            let spin = UnitQuaternion::from_scaled_axis(Vec3::from(b.spec.spin_deg_s.map(f64::to_radians)) * t_end);
            let pose = b.target.unwrap_or_else(|| BodyPose {
                position: b.anchor.position + b.spec.motion.offset(t_end),
                rotation: spin * b.anchor.rotation,
            });
            let rb = &mut self.world.bodies[b.handle];
            rb.set_next_kinematic_position(pose_to_rapier(&pose));
        }
        if let Some(rig) = &mut self.rig {
            rig.drive(&mut self.world, t_end)?;
        }
        Ok(())
    }

    /// Steps cloth and bodies once with `master`: kinematic bodies and the
    /// rig's links are sent to their poses at the end of the step first
    /// ([`CoupledRun::pose_kinematics`]).
    pub fn step_with(&mut self, master: &Master) -> Result<CouplingReport, CouplingError> {
        self.pose_kinematics()?;
        let report = self.cloths.step(&mut self.world, master);
        // Forces and torques set from outside last one step.
        for b in &self.bodies {
            if let Some(rb) = self.world.bodies.get_mut(b.handle) {
                rb.reset_forces(false);
                rb.reset_torques(false);
            }
        }
        report
    }
}
