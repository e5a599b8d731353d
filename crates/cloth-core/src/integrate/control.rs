//! Per-step inputs set from outside the model, and what the cloth did to
//! the outside in a step (Newton's `Control` beside `Model` and `State`).
//!
//! Inputs ([`Control`], set on a [`crate::Simulation`] before a step):
//! - the motion of each externally driven solid (a collider whose scene
//!   `motion` is `{ kind = "external" }`): its pose at the start of the step
//!   and its linear and angular velocity over the step ([`SolidMotion`]);
//! - the position at the end of the step of each externally driven pin;
//! - particles held by hand ([`Control::hold`]): any free particle, moved
//!   to a target as if pinned until let go (a mouse grabbing the cloth);
//! - external forces per particle, N, held constant over the step.
//!
//! Outputs (read after a step): per solid, the impulse and angular impulse
//! the cloth exerted on it over the step ([`SolidImpulse`]); per pin, the
//! force the cloth exerted on it ([`crate::Simulation::pin_reaction`]).
//!
//! Inputs persist from step to step until changed or cleared, as a motor
//! command would: set them only when they change.

use crate::bodies::{BodyError, BodyInSolve};
use crate::{ClothModel, Vec3};
use cloth_collide::BodyPose;
use nalgebra::UnitQuaternion;

/// The motion of a solid over one step: its pose at `time_s` and constant
/// velocities, so `pose(t)` moves the frame origin at `linear_velocity`
/// and turns it at `angular_velocity` (world axes, about the origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolidMotion {
    /// When `pose` holds, s.
    pub time_s: f64,
    /// The solid frame's pose at `time_s`.
    pub pose: BodyPose,
    /// Velocity of the frame origin, m/s.
    pub linear_velocity: Vec3,
    /// Angular velocity, rad/s, world axes.
    pub angular_velocity: Vec3,
}

impl SolidMotion {
    /// A solid at rest at `pose`.
    pub fn at_rest(time_s: f64, pose: BodyPose) -> Self {
        Self { time_s, pose, linear_velocity: Vec3::zeros(), angular_velocity: Vec3::zeros() }
    }

    /// The motion that takes the solid from `start` at `time_s` to `end`
    /// at `time_s + h` with constant velocities (the rotation about the
    /// shortest axis).
    pub fn between(time_s: f64, start: BodyPose, end: BodyPose, h: f64) -> Self {
        let turn = end.rotation * start.rotation.inverse();
        Self {
            time_s,
            pose: start,
            linear_velocity: (end.position - start.position) / h,
            angular_velocity: turn.scaled_axis() / h,
        }
    }

    /// Pose at time `t` (s): `p(t) = p_0 + v (t - t_0)`, `R(t) = exp(omega (t - t_0)) R_0`.
    pub fn pose_at(&self, t: f64) -> BodyPose {
        let dt = t - self.time_s;
        BodyPose {
            position: self.pose.position + self.linear_velocity * dt,
            rotation: UnitQuaternion::from_scaled_axis(self.angular_velocity * dt) * self.pose.rotation,
        }
    }

    /// Velocity of the solid's material point at `point` (m) at time `t`, m/s:
    /// `v + omega x (point - origin(t))`.
    pub fn velocity_at(&self, t: f64, point: Vec3) -> Vec3 {
        let origin = self.pose.position + self.linear_velocity * (t - self.time_s);
        self.linear_velocity + self.angular_velocity.cross(&(point - origin))
    }

    fn is_finite(&self) -> bool {
        let p = &self.pose;
        [p.position, self.linear_velocity, self.angular_velocity].iter().all(|v| v.iter().all(|c| c.is_finite()))
            && p.rotation.coords.iter().all(|c| c.is_finite())
            && self.time_s.is_finite()
    }
}

/// The impulse a solid received from the cloth over one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SolidImpulse {
    /// Linear impulse, N s (the step's mean contact force times the step).
    pub linear: Vec3,
    /// Angular impulse about the point the caller named, N m s.
    pub angular: Vec3,
    /// Contacts that carried it.
    pub contacts: usize,
}

/// Why a control input was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControlError {
    /// No collider with this index.
    #[error("solid {index}: the model has {count} colliders")]
    NoSuchSolid {
        /// The index given.
        index: usize,
        /// Colliders in the model.
        count: usize,
    },
    /// The collider follows a path from its scene; only `motion = { kind = "external" }` ones are driven.
    #[error("solid {index}: its motion comes from the scene; declare motion = {{ kind = \"external\" }} to drive it")]
    SolidNotExternal {
        /// The collider.
        index: usize,
    },
    /// No pin with this index.
    #[error("pin {index}: the model has {count} pinned particles")]
    NoSuchPin {
        /// The index given.
        index: usize,
        /// Pins in the model.
        count: usize,
    },
    /// The pin follows a path from its scene.
    #[error("pin {index}: its motion comes from the scene; declare motion = {{ kind = \"external\" }} to drive it")]
    PinNotExternal {
        /// The pin.
        index: usize,
    },
    /// No particle with this index.
    #[error("particle {index}: the model has {count} particles")]
    NoSuchParticle {
        /// The index given.
        index: usize,
        /// Particles in the model.
        count: usize,
    },
    /// The particle is pinned by the scene; only free particles are held.
    #[error("particle {index}: pinned by the scene, so it cannot be held")]
    ParticlePinned {
        /// The particle.
        index: usize,
    },
    /// The model has no wind, or its wind follows a profile from the scene.
    #[error("wind: the model's air velocity is not external; declare [wind] profile = {{ kind = \"external\" }}")]
    WindNotExternal,
    /// A wind scale for a model without wind.
    #[error("wind scale: the model has no wind; declare [wind] and the wind effect")]
    NoWind,
    /// A wind scale that is negative or not finite.
    #[error("wind scale {0}: must be finite and >= 0")]
    WindScale(f64),
    /// A force array of the wrong length.
    #[error("external forces: {got} given for {expected} particles")]
    ForceCount {
        /// Particles in the model.
        expected: usize,
        /// Forces given.
        got: usize,
    },
    /// A body set to join the solve was refused.
    #[error(transparent)]
    Body(#[from] BodyError),
    /// A value is NaN or infinite.
    #[error("{what}: not finite")]
    NonFinite {
        /// Which input.
        what: String,
    },
}

/// Per-step inputs from outside the model. Build with
/// [`Control::for_model`]; a [`crate::Simulation`] owns one.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Control {
    solids: Vec<Option<SolidMotion>>,
    /// Whether each solid's motion is prescribed (exact), not a guess.
    prescribed_solids: Vec<bool>,
    pins: Vec<Option<Vec3>>,
    /// Held particles and their targets, sorted by particle.
    holds: Vec<(usize, Vec3)>,
    forces: Vec<Vec3>,
    has_forces: bool,
    wind: Option<Vec3>,
    /// Factor on the wind's air velocity (`None`: 1).
    wind_scale: Option<f64>,
    /// Rigid bodies that join the solve.
    bodies: Vec<BodyInSolve>,
}

impl Control {
    /// No inputs: externally driven solids and pins stay where they are.
    pub fn for_model(model: &ClothModel) -> Self {
        Self {
            solids: vec![None; model.colliders().len()],
            prescribed_solids: vec![false; model.colliders().len()],
            pins: vec![None; model.pins().len()],
            holds: Vec::new(),
            forces: Vec::new(),
            has_forces: false,
            wind: None,
            wind_scale: None,
            bodies: Vec::new(),
        }
    }

    /// Lets `bodies` join the next steps' solves (monolithic coupling, see
    /// [`crate::BodyInSolve`]): each drives some external solids and pins, whose
    /// motions and targets (set as usual) are its predicted motion. Replaces
    /// the bodies set before; an empty list makes every solid and pin
    /// prescribed again. Only the assembled implicit integrators take
    /// bodies ([`crate::StepError::BodiesNeedMatrix`]).
    pub fn set_bodies(&mut self, model: &ClothModel, bodies: Vec<BodyInSolve>) -> Result<(), ControlError> {
        crate::bodies::check_bodies(model, &bodies)?;
        self.bodies = bodies;
        Ok(())
    }

    /// Makes room for solids added to the model (none set, not prescribed).
    pub(crate) fn grow_solids(&mut self, model: &ClothModel) {
        self.solids.resize(model.colliders().len(), None);
        self.prescribed_solids.resize(model.colliders().len(), false);
    }

    /// The bodies in the solve.
    pub fn bodies(&self) -> &[BodyInSolve] {
        &self.bodies
    }

    /// Whether solid `index` is a shape of a body in the solve.
    pub fn is_solid_in_solve(&self, index: usize) -> bool {
        self.bodies.iter().any(|b| b.solids.contains(&index))
    }

    /// Sets the motion of externally driven solid `index` (its index among
    /// the model's colliders) as a guess: a co-simulation master's
    /// estimate of a body that the cloth pushes back, so the cloth's
    /// friction on it is decided after the solve (stuck to a guessed
    /// velocity, a light body gains energy: `contacts::FrictionMode`).
    pub fn set_solid_motion(
        &mut self,
        model: &ClothModel,
        index: usize,
        motion: SolidMotion,
    ) -> Result<(), ControlError> {
        self.set_solid(model, index, motion, false)
    }

    /// Sets the motion of externally driven solid `index` as prescribed:
    /// exactly how it moves over the step, whatever the cloth does (a
    /// kinematic body, a character's link). The cloth's friction on it is
    /// then decided in the solve, as on the scene's own moving solids.
    pub fn set_solid_motion_prescribed(
        &mut self,
        model: &ClothModel,
        index: usize,
        motion: SolidMotion,
    ) -> Result<(), ControlError> {
        self.set_solid(model, index, motion, true)
    }

    fn set_solid(
        &mut self,
        model: &ClothModel,
        index: usize,
        motion: SolidMotion,
        prescribed: bool,
    ) -> Result<(), ControlError> {
        let count = model.colliders().len();
        let c = model.colliders().get(index).ok_or(ControlError::NoSuchSolid { index, count })?;
        if !c.is_external() {
            return Err(ControlError::SolidNotExternal { index });
        }
        if !motion.is_finite() {
            return Err(ControlError::NonFinite { what: format!("solid {index} motion") });
        }
        self.solids[index] = Some(motion);
        self.prescribed_solids[index] = prescribed;
        Ok(())
    }

    /// Sets where externally driven pin `index` (its index in
    /// [`ClothModel::pins`]) is at the end of the next step, m. Within the
    /// step it moves on a straight line from where its particle is.
    pub fn set_pin_target(&mut self, model: &ClothModel, index: usize, position: Vec3) -> Result<(), ControlError> {
        let count = model.pins().len();
        let pin = model.pins().get(index).ok_or(ControlError::NoSuchPin { index, count })?;
        if !pin.is_external() {
            return Err(ControlError::PinNotExternal { index });
        }
        if !position.iter().all(|c| c.is_finite()) {
            return Err(ControlError::NonFinite { what: format!("pin {index} target") });
        }
        self.pins[index] = Some(position);
        Ok(())
    }

    /// Holds free particle `particle` and moves it to `target` (m) by the
    /// end of the next step, on a straight line from where it is; it stays
    /// held there, as if pinned, until moved again or let go
    /// ([`Control::let_go`]). Particles pinned by the scene are refused.
    pub fn hold(&mut self, model: &ClothModel, particle: usize, target: Vec3) -> Result<(), ControlError> {
        let count = model.particle_count();
        if particle >= count {
            return Err(ControlError::NoSuchParticle { index: particle, count });
        }
        if model.is_pinned(particle) {
            return Err(ControlError::ParticlePinned { index: particle });
        }
        if !target.iter().all(|c| c.is_finite()) {
            return Err(ControlError::NonFinite { what: format!("particle {particle} hold target") });
        }
        match self.find_hold(particle) {
            Ok(k) => self.holds[k].1 = target,
            Err(k) => self.holds.insert(k, (particle, target)),
        }
        Ok(())
    }

    /// Lets held particle `particle` go (it keeps its velocity); whether
    /// it was held.
    pub fn let_go(&mut self, particle: usize) -> bool {
        self.find_hold(particle).map(|k| self.holds.remove(k)).is_ok()
    }

    /// The held particles and their targets (m), sorted by particle.
    pub fn holds(&self) -> &[(usize, Vec3)] {
        &self.holds
    }

    /// Where `particle` is in [`Control::holds`], if held.
    pub fn hold_index(&self, particle: usize) -> Option<usize> {
        self.find_hold(particle).ok()
    }

    /// Whether `particle` is held.
    pub fn is_held(&self, particle: usize) -> bool {
        self.find_hold(particle).is_ok()
    }

    /// The hold of `particle` (`Ok`) or where it would go (`Err`).
    fn find_hold(&self, particle: usize) -> Result<usize, usize> {
        self.holds.binary_search_by_key(&particle, |h| h.0)
    }

    /// Sets external forces on every particle, N, constant over each step
    /// until changed.
    pub fn set_forces(&mut self, model: &ClothModel, forces: &[Vec3]) -> Result<(), ControlError> {
        let expected = model.particle_count();
        if forces.len() != expected {
            return Err(ControlError::ForceCount { expected, got: forces.len() });
        }
        if let Some(i) = forces.iter().position(|f| !f.iter().all(|c| c.is_finite())) {
            return Err(ControlError::NonFinite { what: format!("external force on particle {i}") });
        }
        self.forces.clear();
        self.forces.extend_from_slice(forces);
        self.has_forces = forces.iter().any(|f| *f != Vec3::zeros());
        Ok(())
    }

    /// Adds the external forces, if any, to `force` (N per particle).
    pub(crate) fn add_forces_to(&self, force: &mut [Vec3]) {
        if let Some(applied) = self.forces() {
            force.iter_mut().zip(applied).for_each(|(f, a)| *f += a);
        }
    }

    /// Sets the air velocity of an external wind (`[wind] profile = { kind
    /// = "external" }`), m/s, constant over each step until changed.
    pub fn set_wind(&mut self, model: &ClothModel, velocity: Vec3) -> Result<(), ControlError> {
        if !model.wind().is_some_and(|w| w.profile == crate::wind::WindProfile::External) {
            return Err(ControlError::WindNotExternal);
        }
        if !velocity.iter().all(|c| c.is_finite()) {
            return Err(ControlError::NonFinite { what: "wind velocity".into() });
        }
        self.wind = Some(velocity);
        Ok(())
    }

    /// The air velocity set for an external wind, m/s, if any.
    pub fn wind(&self) -> Option<Vec3> {
        self.wind
    }

    /// Scales the wind's air velocity (its profile's, or the external one
    /// set) by `scale` from the next step on: a gust stronger or weaker
    /// than the scene's. The air is an outside field, so changing it
    /// between steps is sound.
    pub fn set_wind_scale(&mut self, model: &ClothModel, scale: f64) -> Result<(), ControlError> {
        if model.wind().is_none() {
            return Err(ControlError::NoWind);
        }
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(ControlError::WindScale(scale));
        }
        self.wind_scale = Some(scale);
        Ok(())
    }

    /// The factor on the wind's air velocity (1 unless set).
    pub fn wind_scale(&self) -> f64 {
        self.wind_scale.unwrap_or(1.0)
    }

    /// Removes the external forces.
    pub fn clear_forces(&mut self) {
        self.forces.clear();
        self.has_forces = false;
    }

    /// The motion set for solid `index`, if any.
    pub fn solid_motion(&self, index: usize) -> Option<&SolidMotion> {
        self.solids.get(index).and_then(Option::as_ref)
    }

    /// Whether solid `index`'s motion was set as prescribed
    /// ([`Control::set_solid_motion_prescribed`]).
    pub fn is_solid_prescribed(&self, index: usize) -> bool {
        self.prescribed_solids.get(index).copied().unwrap_or(false)
    }

    /// The motion set for each of the model's solids (`None`: not set).
    pub(crate) fn solid_motions(&self) -> &[Option<SolidMotion>] {
        &self.solids
    }

    /// The target set for pin `index`, if any.
    pub fn pin_target(&self, index: usize) -> Option<Vec3> {
        self.pins.get(index).copied().flatten()
    }

    /// The external forces, when any is non-zero.
    pub fn forces(&self) -> Option<&[Vec3]> {
        self.has_forces.then_some(&self.forces[..])
    }
}

/// Where each prescribed particle is during one step from `t0` to
/// `t0 + h`: first the model's pins (index `k` = the pin's index), on their
/// scene path or, for an external pin, on the straight line from its
/// particle's position `x0` to the target (held in place without one); then
/// the control's held particles (`k = pins + j` for hold `j`), on the
/// straight line to their target.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PinPaths<'a> {
    model: &'a ClothModel,
    control: &'a Control,
    x0: &'a [Vec3],
    t0: f64,
    h: f64,
}

impl<'a> PinPaths<'a> {
    pub(crate) fn new(model: &'a ClothModel, control: &'a Control, x0: &'a [Vec3], t0: f64, h: f64) -> Self {
        Self { model, control, x0, t0, h }
    }

    /// How many particles are prescribed: pins, then held particles.
    pub(crate) fn count(&self) -> usize {
        self.model.pins().len() + self.control.holds.len()
    }

    /// The particle of prescribed entry `k`.
    pub(crate) fn particle(&self, k: usize) -> usize {
        let pins = self.model.pins();
        pins.get(k).map_or_else(|| self.control.holds[k - pins.len()].0, |p| p.particle)
    }

    /// The particles of every entry, in entry order.
    pub(crate) fn particles(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.count()).map(|k| self.particle(k))
    }

    /// Velocity of entry `k` moving on a straight line to its target over
    /// the step (or resting without one), m/s.
    fn straight_velocity(&self, k: usize) -> Vec3 {
        let pins = self.model.pins().len();
        let target = if k < pins { self.control.pin_target(k) } else { Some(self.control.holds[k - pins].1) };
        target.map_or(Vec3::zeros(), |target| (target - self.x0[self.particle(k)]) / self.h)
    }

    /// Whether entry `k` follows a scene path (else a straight line to a target).
    fn on_scene_path(&self, k: usize) -> bool {
        self.model.pins().get(k).is_some_and(|p| !p.is_external())
    }

    /// Position of entry `k` at time `t` (s), m.
    pub(crate) fn position(&self, k: usize, t: f64) -> Vec3 {
        if self.on_scene_path(k) {
            self.model.pins()[k].position(t)
        } else {
            self.x0[self.particle(k)] + self.straight_velocity(k) * (t - self.t0)
        }
    }

    /// Velocity of entry `k` at time `t` (s), m/s.
    pub(crate) fn velocity(&self, k: usize, t: f64) -> Vec3 {
        if self.on_scene_path(k) { self.model.pins()[k].velocity(t) } else { self.straight_velocity(k) }
    }
}
