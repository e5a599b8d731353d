//! A cloth [`Simulation`] as a co-simulation [`Unit`].
//!
//! Variables (all `Float64`, SI):
//! - inputs, per externally driven pin `k`: `pin{k}.target.{x,y,z}`, where
//!   the pin is at the communication point (m), and
//!   `pin{k}.target_rate.{x,y,z}` (m/s, the target's derivative, also set
//!   by [`Unit::set_input_derivative`]). Over a step of `h` the pin moves
//!   linearly to `target + rate h`, where `rate` is the one set since the
//!   last step; when none was, it is the target's slope from the previous
//!   communication point, `(target - previous) / h_previous` (0 at the
//!   first step). So a master that knows only the values at the
//!   communication points (FMI 3.0's) drives a pin moving at constant
//!   velocity exactly from the second step on, and one that gives rates
//!   drives any piecewise-linear motion exactly;
//! - inputs, per externally driven solid `k`: `solid{k}.position.{x,y,z}`
//!   (m) and `solid{k}.rotation.{x,y,z}` (rotation vector, rad) at the
//!   communication point, and `solid{k}.velocity.{x,y,z}` (m/s) and
//!   `solid{k}.angular_velocity.{x,y,z}` (rad/s) over the step: the solid
//!   moves on from that pose at those velocities. A unit fed by a
//!   rigid-body unit stepped before it (a Gauss-Seidel or iterated master
//!   over rapier) takes the pose at the end of the step instead
//!   ([`ClothUnit::with_solids_at_step_end`]): the solid reaches it moving
//!   at the velocities, as a symplectic Euler step does;
//! - inputs, when the scene's wind is external (`[wind] profile = { kind =
//!   "external" }`): `wind.velocity.{x,y,z}`, the air velocity over the
//!   step (m/s);
//! - outputs, per solid `k`: `solid{k}.force.{x,y,z}` (N) and
//!   `solid{k}.torque.{x,y,z}` (N m, about the solid's frame origin at the
//!   start of the step): the mean the cloth exerted over the last step;
//! - outputs, per pin `k`: `pin{k}.reaction.{x,y,z}` (N), the mean force the
//!   cloth exerted on it;
//! - outputs, per `[[pins]]` entry `s` (an attachment: a clamp, a hanger):
//!   `attachment{s}.force.{x,y,z}` (N), its pins' reactions summed, and
//!   `attachment{s}.moment.{x,y,z}` (N m) about their centroid;
//! - outputs: `lowest_z` (m), `max_stretch` (longest link over its rest length);
//! - tunable parameters, which may change between steps: `gravity.{x,y,z}`
//!   (m/s^2, from the scene's; a change acts as the force `m_i (g - g_scene)`
//!   on every particle, a constant load the step takes like any other), and,
//!   when the scene has wind, `wind_scale` (1: a factor on the air's
//!   velocity, an outside field), and, for a unit that can rebuild its
//!   model ([`ClothUnit::with_tunable_damping`]), `damping` (N s/m, the
//!   material's `damping_n_s_m`): a change puts the model rebuilt with it
//!   in place before the next step ([`Simulation::replace_model`]), so
//!   the run goes on as one built with that damping from there.
//!
//! A step longer than the unit's largest internal step
//! ([`ClothUnit::with_max_step`]; none by default) is taken as equal
//! substeps no longer than it: the pins move linearly to their targets
//! over them, the solids follow their given motion, and the outputs are
//! the means over the whole step. So the cloth's motion at the
//! communication points does not depend on the master's step.
//!
//! A step that fails in the solver or goes non-finite is discarded: the
//! cloth stays at the start of the step, as FMI's `fmi3Discard` asks
//! (also when a later substep fails).

use crate::unit::{Causality, StepOutcome, Unit, UnitError, UnitState, ValueRef, Variable, bytes, settable};
use cloth_core::{BodyPose, ClothModel, Simulation, Snapshot, SolidMotion, Vec3, WindProfile};
use nalgebra::UnitQuaternion;

/// What a variable of the cloth unit stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Quantity {
    PinTarget,
    PinRate,
    WindVelocity,
    SolidPosition,
    SolidRotation,
    SolidVelocity,
    SolidAngularVelocity,
    SolidForce,
    SolidTorque,
    PinReaction,
    AttachmentForce,
    AttachmentMoment,
    LowestZ,
    MaxStretch,
    Gravity,
    WindScale,
    Damping,
}

/// Builds the unit's model again with another material damping (N s/m).
pub type ModelWithDamping = Box<dyn Fn(f64) -> Result<ClothModel, String> + Send>;

/// The tunable damping: how to rebuild, and the damping the simulation's
/// model was built with.
struct TunableDamping {
    rebuild: ModelWithDamping,
    built_n_s_m: f64,
}

impl std::fmt::Debug for TunableDamping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TunableDamping").field("built_n_s_m", &self.built_n_s_m).finish_non_exhaustive()
    }
}

/// A variable's quantity, for pin or solid `item`, component `axis` (0 for scalars).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Role {
    quantity: Quantity,
    item: usize,
    axis: usize,
}

/// A cloth simulation as a co-simulation unit.
#[derive(Debug)]
pub struct ClothUnit {
    name: String,
    sim: Simulation,
    vars: Vec<Variable>,
    roles: Vec<Role>,
    /// Current value of every variable (inputs as set, outputs after the last step).
    values: Vec<f64>,
    /// Per variable: a rate input set since the last step.
    given: Vec<bool>,
    /// Per variable: its value at the previous communication point (NaN
    /// before the first step), for the pins' slopes.
    previous: Vec<f64>,
    /// Length of the last step, s (NaN before the first).
    previous_h: f64,
    /// Per particle, the load of gravity beyond the scene's, N.
    loads: Vec<Vec3>,
    /// Largest internal step, s ([`ClothUnit::with_max_step`]).
    max_step_s: f64,
    /// Solid poses are the step's end ([`ClothUnit::with_solids_at_step_end`]).
    solids_at_step_end: bool,
    /// The `damping` parameter's model ([`ClothUnit::with_tunable_damping`]).
    damping: Option<TunableDamping>,
}

const AXES: [&str; 3] = ["x", "y", "z"];
const TAG: &[u8; 8] = b"clothunt";

/// The variables of one kind of 3-vector: quantity, name after the item
/// (`pin{k}.` or `solid{k}.`), causality, unit, description.
type VectorKind = (Quantity, &'static str, Causality, &'static str, &'static str);

const PIN_INPUTS: [VectorKind; 2] = [
    (Quantity::PinTarget, "target", Causality::Input, "m", "pin position at the communication point"),
    (
        Quantity::PinRate,
        "target_rate",
        Causality::Input,
        "m/s",
        "pin velocity over the next step; when not set, the target's slope since the previous communication point",
    ),
];
const WIND_INPUT: VectorKind =
    (Quantity::WindVelocity, "velocity", Causality::Input, "m/s", "air velocity over the step (external wind)");
const SOLID_INPUTS: [VectorKind; 4] = [
    (
        Quantity::SolidPosition,
        "position",
        Causality::Input,
        "m",
        "solid frame origin at the communication point (the step's end if so built)",
    ),
    (
        Quantity::SolidRotation,
        "rotation",
        Causality::Input,
        "rad",
        "solid orientation (rotation vector) at the communication point (the step's end if so built)",
    ),
    (Quantity::SolidVelocity, "velocity", Causality::Input, "m/s", "velocity of the solid frame origin"),
    (Quantity::SolidAngularVelocity, "angular_velocity", Causality::Input, "rad/s", "angular velocity of the solid"),
];
const SOLID_OUTPUTS: [VectorKind; 2] = [
    (Quantity::SolidForce, "force", Causality::Output, "N", "mean force of the cloth on the solid over the last step"),
    (
        Quantity::SolidTorque,
        "torque",
        Causality::Output,
        "N.m",
        "mean torque of the cloth on the solid about its frame origin",
    ),
];
const PIN_OUTPUTS: [VectorKind; 1] = [(
    Quantity::PinReaction,
    "reaction",
    Causality::Output,
    "N",
    "mean force of the cloth on the pin over the last step",
)];
const ATTACHMENT_OUTPUTS: [VectorKind; 2] = [
    (
        Quantity::AttachmentForce,
        "force",
        Causality::Output,
        "N",
        "mean force of the cloth on the pins of one [[pins]] entry over the last step, summed",
    ),
    (
        Quantity::AttachmentMoment,
        "moment",
        Causality::Output,
        "N.m",
        "moment of those forces about the pins' centroid at the end of the step",
    ),
];

impl ClothUnit {
    /// Wraps `sim`; its external pins, solids and wind become inputs.
    pub fn new(name: impl Into<String>, sim: Simulation) -> Self {
        let mut vars = Vec::new();
        let mut roles = Vec::new();
        let model = sim.model().clone();
        // Adds the x, y, z variables of `kind` for item `k` of `prefix`
        // (`{prefix}{k}.`; just `{prefix}.` for a single item, `k = None`), starting at `start`.
        let mut add_item = |prefix: &str, k: Option<usize>, kind: &VectorKind, start: Vec3| {
            let (quantity, field, causality, unit, description) = *kind;
            let item = k.map_or(String::new(), |k| k.to_string());
            for (axis, name) in AXES.iter().enumerate() {
                let var = Variable::new(format!("{prefix}{item}.{field}.{name}"), causality, unit, description);
                // Outputs change only in a step: no feedthrough.
                let var = if causality == Causality::Output { var.with_dependencies(vec![]) } else { var };
                vars.push(var.with_start(start[axis]));
                roles.push(Role { quantity, item: k.unwrap_or(0), axis });
            }
        };
        if model.wind().is_some_and(|w| w.profile == WindProfile::External) {
            add_item("wind", None, &WIND_INPUT, Vec3::zeros());
        }
        let mut add = |prefix: &str, k: usize, kind: &VectorKind, start: Vec3| add_item(prefix, Some(k), kind, start);
        for (k, pin) in model.pins().iter().enumerate().filter(|(_, p)| p.is_external()) {
            add("pin", k, &PIN_INPUTS[0], pin.anchor);
            add("pin", k, &PIN_INPUTS[1], Vec3::zeros());
        }
        for (k, c) in model.colliders().iter().enumerate().filter(|(_, c)| c.is_external()) {
            let starts = [c.anchor.position, c.anchor.rotation.scaled_axis(), Vec3::zeros(), Vec3::zeros()];
            for (kind, start) in SOLID_INPUTS.iter().zip(starts) {
                add("solid", k, kind, start);
            }
        }
        for k in 0..model.colliders().len() {
            for kind in &SOLID_OUTPUTS {
                add("solid", k, kind, Vec3::zeros());
            }
        }
        for k in 0..model.pins().len() {
            add("pin", k, &PIN_OUTPUTS[0], Vec3::zeros());
        }
        // One attachment per `[[pins]]` entry that pinned a particle.
        let mut entries: Vec<usize> = model.pins().iter().map(|p| p.spec).collect();
        entries.sort_unstable();
        entries.dedup();
        for s in entries {
            for kind in &ATTACHMENT_OUTPUTS {
                add("attachment", s, kind, Vec3::zeros());
            }
        }
        for (quantity, name, unit, description) in [
            (Quantity::LowestZ, "lowest_z", "m", "lowest particle height"),
            (Quantity::MaxStretch, "max_stretch", "1", "longest link over its rest length"),
        ] {
            vars.push(Variable::new(name, Causality::Output, unit, description).with_dependencies(vec![]));
            roles.push(Role { quantity, item: 0, axis: 0 });
        }
        let g = model.effects().gravity.unwrap_or_else(Vec3::zeros);
        for (axis, name) in AXES.iter().enumerate() {
            let description = "acceleration of gravity from the next step on (the scene's to start)";
            let var = Variable::new(format!("gravity.{name}"), Causality::Parameter, "m/s2", description);
            vars.push(var.tunable().with_start(g[axis]));
            roles.push(Role { quantity: Quantity::Gravity, item: 0, axis });
        }
        if model.wind().is_some() {
            let description = "factor on the wind's air velocity from the next step on";
            vars.push(Variable::new("wind_scale", Causality::Parameter, "1", description).tunable().with_start(1.0));
            roles.push(Role { quantity: Quantity::WindScale, item: 0, axis: 0 });
        }
        // Each pin's rates are its targets' derivatives.
        for v in 0..vars.len() {
            if roles[v].quantity == Quantity::PinRate {
                let target = Role { quantity: Quantity::PinTarget, ..roles[v] };
                let of = roles.iter().position(|r| *r == target).expect("a rate follows its target");
                vars[v] = vars[v].clone().derivative_of(of);
            }
        }
        let values = vars.iter().map(|v| v.start).collect();
        let (given, previous) = (vec![false; vars.len()], vec![f64::NAN; vars.len()]);
        let mut unit = Self {
            name: name.into(),
            sim,
            vars,
            roles,
            values,
            given,
            previous,
            previous_h: f64::NAN,
            loads: Vec::new(),
            max_step_s: f64::INFINITY,
            solids_at_step_end: false,
            damping: None,
        };
        unit.update_shape_outputs();
        unit
    }

    /// The same unit taking each step as equal substeps of at most
    /// `max_step_s` (s; a scene's `dt_s` is the natural choice), so that its
    /// motion does not depend on the master's step. Not finite and
    /// positive: no substeps.
    pub fn with_max_step(mut self, max_step_s: f64) -> Self {
        self.max_step_s = if max_step_s.is_finite() && max_step_s > 0.0 { max_step_s } else { f64::INFINITY };
        self
    }

    /// The same unit with the tunable parameter `damping` (N s/m), starting
    /// at `damping_n_s_m`, the damping its model was built with: `rebuild`
    /// builds the model again with another (the scene with its material's
    /// `damping_n_s_m` changed). A scene without the damping effect gets no
    /// parameter: its links have no dashpots to tune.
    pub fn with_tunable_damping(
        mut self,
        damping_n_s_m: f64,
        rebuild: impl Fn(f64) -> Result<ClothModel, String> + Send + 'static,
    ) -> Self {
        if !self.sim.model().effects().damping {
            return self;
        }
        let description = "the material's damping from the next step on (the scene's to start)";
        let var = Variable::new("damping", Causality::Parameter, "N.s/m", description).tunable();
        self.vars.push(var.with_start(damping_n_s_m));
        self.roles.push(Role { quantity: Quantity::Damping, item: 0, axis: 0 });
        self.values.push(damping_n_s_m);
        self.given.push(false);
        self.previous.push(f64::NAN);
        self.damping = Some(TunableDamping { rebuild: Box::new(rebuild), built_n_s_m: damping_n_s_m });
        self
    }

    /// The same unit taking each solid's pose inputs as where the solid is
    /// at the end of the step, not at the communication point: for a unit
    /// fed by a rigid-body unit that a master steps first (rapier under a
    /// Gauss-Seidel or iterated master), whose outputs are its end poses.
    pub fn with_solids_at_step_end(mut self) -> Self {
        self.solids_at_step_end = true;
        self
    }

    /// The largest internal step, s (infinite: none).
    pub fn max_step(&self) -> f64 {
        self.max_step_s
    }

    /// The wrapped simulation.
    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    /// Substeps of a step of `h` s: the fewest no longer than the largest
    /// internal step (a step a billionth longer still takes one).
    fn substeps(&self, h: f64) -> usize {
        ((h / self.max_step_s) * (1.0 - 1e-9)).ceil().max(1.0) as usize
    }

    /// Takes the step from `t` of `h` s as `n` substeps (inputs applied for
    /// the whole step, the pins moved on linearly), the outputs the means
    /// over it; on a failed substep everything goes back to `t`.
    fn substepped(&mut self, t: f64, h: f64, n: usize) -> Result<StepOutcome, UnitError> {
        let model = self.sim.model().clone();
        let saved = self.get_state();
        let pins = self.pin_paths(h);
        self.apply_inputs(t, h)?;
        let origins = self.solid_origins(t);
        let hs = h / n as f64;
        let mut impulses = vec![(Vec3::zeros(), Vec3::zeros()); origins.len()];
        let mut reactions = vec![Vec3::zeros(); model.pins().len()];
        for i in 1..=n {
            for &(k, start, end) in &pins {
                let target = if i == n { end } else { start + (end - start) * (i as f64 / n as f64) };
                self.sim.set_pin_target(k, target).map_err(|e| UnitError::StepFailed {
                    unit: self.name.clone(),
                    time_s: t,
                    message: e.to_string(),
                })?;
            }
            if let Err(e) = self.sim.step(hs) {
                self.set_state(&saved)?;
                let reason = format!("substep {i} of {n} ({hs} s each): {e}");
                return Ok(StepOutcome::Discarded { last_time_s: t, reason });
            }
            for (k, (origin, (linear, angular))) in origins.iter().zip(&mut impulses).enumerate() {
                let impulse = self.sim.solid_impulse(k, *origin);
                (*linear, *angular) = (*linear + impulse.linear, *angular + impulse.angular);
            }
            for (k, r) in reactions.iter_mut().enumerate() {
                *r += self.sim.pin_reaction(k) * hs;
            }
        }
        let means: Vec<Vec3> = reactions.iter().map(|r| r / h).collect();
        self.set_step_outputs(&impulses, &means, h);
        self.step_taken(h);
        Ok(StepOutcome::Completed)
    }

    /// Each external pin's path over a step of `h` s: the pin, its target
    /// at the communication point and at the end of the step.
    fn pin_paths(&self, h: f64) -> Vec<(usize, Vec3, Vec3)> {
        let mut paths: Vec<(usize, Vec3, Vec3)> = Vec::new();
        for (i, role) in self.roles.iter().enumerate().filter(|(_, r)| r.quantity == Quantity::PinRate) {
            let target = self.vars[i].derivative_of.expect("a pin's rate has its target");
            let (value, before) = (self.values[target], self.previous[target]);
            let rate = match (self.given[i], before.is_nan()) {
                (true, _) => self.values[i],
                (false, true) => 0.0,
                (false, false) => (value - before) / self.previous_h,
            };
            if paths.last().is_none_or(|p| p.0 != role.item) {
                paths.push((role.item, Vec3::zeros(), Vec3::zeros()));
            }
            let path = paths.last_mut().expect("pushed");
            (path.1[role.axis], path.2[role.axis]) = (value, value + rate * h);
        }
        paths
    }

    /// After a step of `h` s is taken: the inputs' values become the
    /// previous communication point's, and rates given for it are spent.
    fn step_taken(&mut self, h: f64) {
        self.previous.clone_from(&self.values);
        self.previous_h = h;
        self.given.fill(false);
    }

    /// Each solid's frame origin at time `t`, m (about which torques are given).
    fn solid_origins(&self, t: f64) -> Vec<Vec3> {
        let model = self.sim.model();
        (0..model.colliders().len())
            .map(|k| {
                self.sim
                    .control()
                    .solid_motion(k)
                    .map_or(model.colliders()[k].pose(t).position, |m| m.pose_at(t).position)
            })
            .collect()
    }

    fn update_shape_outputs(&mut self) {
        let state = self.sim.state();
        let lowest = state.x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        let stretch = self.sim.model().max_stretch_ratio(&state.x);
        for (role, value) in self.roles.iter().zip(&mut self.values) {
            match role.quantity {
                Quantity::LowestZ => *value = lowest,
                Quantity::MaxStretch => *value = stretch,
                _ => {}
            }
        }
    }

    /// The 3-vector input `quantity` of item `k`.
    fn input(&self, quantity: Quantity, k: usize) -> Vec3 {
        let mut value = Vec3::zeros();
        for (i, role) in self.roles.iter().enumerate() {
            if role.quantity == quantity && role.item == k {
                value[role.axis] = self.values[i];
            }
        }
        value
    }

    /// Puts the inputs into the simulation's control for a step from `t` of `h`.
    fn apply_inputs(&mut self, t: f64, h: f64) -> Result<(), UnitError> {
        let model = self.sim.model().clone();
        let refuse = |e: cloth_core::ControlError| UnitError::StepFailed {
            unit: self.name.clone(),
            time_s: t,
            message: e.to_string(),
        };
        for (k, _, end) in self.pin_paths(h) {
            self.sim.set_pin_target(k, end).map_err(refuse)?;
        }
        if self.roles.iter().any(|r| r.quantity == Quantity::WindVelocity) {
            self.sim.set_wind(self.input(Quantity::WindVelocity, 0)).map_err(refuse)?;
        }
        if let Some(k) = self.roles.iter().position(|r| r.quantity == Quantity::WindScale) {
            self.sim.set_wind_scale(self.values[k]).map_err(refuse)?;
        }
        if let (Some(k), Some(tunable)) =
            (self.roles.iter().position(|r| r.quantity == Quantity::Damping), self.damping.as_mut())
            && self.values[k].to_bits() != tunable.built_n_s_m.to_bits()
        {
            let failed = |message: String| UnitError::StepFailed { unit: self.name.clone(), time_s: t, message };
            let model = (tunable.rebuild)(self.values[k]).map_err(|e| failed(format!("damping: {e}")))?;
            self.sim.replace_model(model).map_err(|e| failed(format!("damping: {e}")))?;
            tunable.built_n_s_m = self.values[k];
        }
        // Gravity other than the scene's: the difference as a load m_i dg.
        let dg = self.input(Quantity::Gravity, 0) - model.effects().gravity.unwrap_or_else(Vec3::zeros);
        if dg == Vec3::zeros() {
            self.sim.clear_external_forces();
        } else {
            self.loads.clear();
            self.loads.extend(model.masses().iter().map(|&m| dg * m));
            self.sim.set_external_forces(&self.loads).map_err(refuse)?;
        }
        for k in (0..model.colliders().len()).filter(|&k| model.colliders()[k].is_external()) {
            let get = |quantity| self.input(quantity, k);
            let rotation = UnitQuaternion::from_scaled_axis(get(Quantity::SolidRotation));
            let pose = BodyPose { position: get(Quantity::SolidPosition), rotation };
            let motion = SolidMotion {
                time_s: if self.solids_at_step_end { t + h } else { t },
                pose,
                linear_velocity: get(Quantity::SolidVelocity),
                angular_velocity: get(Quantity::SolidAngularVelocity),
            };
            self.sim.set_solid_motion(k, motion).map_err(refuse)?;
        }
        Ok(())
    }

    /// Reads the step's outputs; `h` turns impulses into mean forces.
    fn read_outputs(&mut self, h: f64) {
        let origins = self.solid_origins(self.sim.time() - h);
        let impulses: Vec<(Vec3, Vec3)> = origins
            .iter()
            .enumerate()
            .map(|(k, o)| {
                let impulse = self.sim.solid_impulse(k, *o);
                (impulse.linear, impulse.angular)
            })
            .collect();
        let reactions: Vec<Vec3> = (0..self.sim.model().pins().len()).map(|k| self.sim.pin_reaction(k)).collect();
        self.set_step_outputs(&impulses, &reactions, h);
    }

    /// Every output after a step of `h` s: each solid's mean force and
    /// torque from its `impulses` (linear N s, angular N m s) over the
    /// step, the pins' and attachments' from their mean `reactions` (N),
    /// and the cloth's shape.
    fn set_step_outputs(&mut self, impulses: &[(Vec3, Vec3)], reactions: &[Vec3], h: f64) {
        for (i, role) in self.roles.iter().enumerate() {
            let (k, a) = (role.item, role.axis);
            self.values[i] = match role.quantity {
                Quantity::SolidForce => impulses[k].0[a] / h,
                Quantity::SolidTorque => impulses[k].1[a] / h,
                _ => continue,
            };
        }
        self.set_pin_outputs(reactions);
        self.update_shape_outputs();
    }

    /// The pins' outputs from their mean reactions `reactions` (N): each
    /// pin's, and each attachment's sum and moment about its pins'
    /// centroid where they are now.
    fn set_pin_outputs(&mut self, reactions: &[Vec3]) {
        let (model, x) = (self.sim.model(), &self.sim.state().x);
        for (i, role) in self.roles.iter().enumerate() {
            let (k, a) = (role.item, role.axis);
            let of_entry = || model.pins().iter().zip(reactions).filter(move |(p, _)| p.spec == k);
            self.values[i] = match role.quantity {
                Quantity::PinReaction => reactions[k][a],
                Quantity::AttachmentForce => of_entry().map(|(_, r)| r[a]).sum(),
                Quantity::AttachmentMoment => {
                    let count = of_entry().count() as f64;
                    let centroid = of_entry().map(|(p, _)| x[p.particle]).sum::<Vec3>() / count;
                    of_entry().map(|(p, r)| (x[p.particle] - centroid).cross(r)).sum::<Vec3>()[a]
                }
                _ => continue,
            };
        }
    }
}

/// The unit's complete state: the cloth's, every variable's value, which
/// rates were given, and the previous communication point's values.
#[derive(Debug, Clone, PartialEq)]
struct Saved {
    cloth: Snapshot,
    values: Vec<f64>,
    given: Vec<bool>,
    previous: Vec<f64>,
    previous_h: f64,
}

impl Unit for ClothUnit {
    fn name(&self) -> &str {
        &self.name
    }

    fn variables(&self) -> &[Variable] {
        &self.vars
    }

    /// A pin's rate, once set, holds for the next step only; a target set
    /// after it leaves it standing.
    fn set(&mut self, vr: ValueRef, value: f64) -> Result<(), UnitError> {
        settable(&self.name, &self.vars, vr, value)?;
        if self.roles[vr].quantity == Quantity::Damping && value < 0.0 {
            let (unit, name) = (self.name.clone(), self.vars[vr].name.clone());
            return Err(UnitError::InvalidValue { unit, name, value, message: "must be >= 0".into() });
        }
        self.values[vr] = value;
        self.given[vr] = self.roles[vr].quantity == Quantity::PinRate;
        Ok(())
    }

    /// Sets `pin{k}.target_rate` for `pin{k}.target`.
    fn set_input_derivative(&mut self, vr: ValueRef, du: f64) -> Result<(), UnitError> {
        settable(&self.name, &self.vars, vr, du)?;
        match self.vars.iter().position(|v| v.derivative_of == Some(vr)) {
            Some(rate) => self.set(rate, du),
            None => Err(UnitError::Unsupported {
                unit: self.name.clone(),
                what: "derivatives of inputs other than pin targets",
            }),
        }
    }

    fn get(&self, vr: ValueRef) -> Result<f64, UnitError> {
        self.values.get(vr).copied().ok_or(UnitError::NoSuchVariable {
            unit: self.name.clone(),
            vr,
            count: self.vars.len(),
        })
    }

    fn do_step(&mut self, t: f64, h: f64) -> Result<StepOutcome, UnitError> {
        let now = self.sim.time();
        if (t - now).abs() > 1e-9 * now.abs().max(1.0) {
            return Err(UnitError::StepFailed {
                unit: self.name.clone(),
                time_s: t,
                message: format!("the cloth is at t = {now} s"),
            });
        }
        if !(h.is_finite() && h > 0.0) {
            return Err(UnitError::InvalidValue {
                unit: self.name.clone(),
                name: "step".into(),
                value: h,
                message: "must be finite and > 0".into(),
            });
        }
        let n = self.substeps(h);
        if n > 1 {
            return self.substepped(t, h, n);
        }
        self.apply_inputs(t, h)?;
        match self.sim.step(h) {
            Ok(_) => {
                self.read_outputs(h);
                self.step_taken(h);
                Ok(StepOutcome::Completed)
            }
            Err(e) => Ok(StepOutcome::Discarded { last_time_s: now, reason: e.to_string() }),
        }
    }

    fn get_state(&self) -> UnitState {
        UnitState(Box::new(Saved {
            cloth: self.sim.snapshot(),
            values: self.values.clone(),
            given: self.given.clone(),
            previous: self.previous.clone(),
            previous_h: self.previous_h,
        }))
    }

    fn set_state(&mut self, state: &UnitState) -> Result<(), UnitError> {
        let bad = |message: String| UnitError::BadState { unit: self.name.clone(), message };
        let saved: &Saved = state.downcast(&self.name, "cloth unit")?;
        if saved.values.len() != self.values.len() {
            return Err(bad(format!("{} variables, this unit has {}", saved.values.len(), self.values.len())));
        }
        self.sim.restore(&saved.cloth).map_err(|e| bad(e.to_string()))?;
        self.values.clone_from(&saved.values);
        self.given.clone_from(&saved.given);
        self.previous.clone_from(&saved.previous);
        self.previous_h = saved.previous_h;
        Ok(())
    }

    /// Layout: tag, then the cloth's snapshot as [`Snapshot::values`]
    /// gives it (`time, steps, has_history, last_dt`, the integrator's
    /// memory: `newton_engaged` for the implicit integrators, `next_dt_s`
    /// for `dopri5`; `x, v, x_prev, v_prev`, the stitches' states), the
    /// variables' values, their given flags (1 given, 0 not) and previous
    /// values (NaN: none), the previous step.
    fn serialize_state(&self, state: &UnitState) -> Result<Vec<u8>, UnitError> {
        let saved: &Saved = state.downcast(&self.name, "cloth unit")?;
        let flag = |b: bool| f64::from(u8::from(b));
        let values = saved
            .cloth
            .values()
            .chain(saved.values.iter().copied())
            .chain(saved.given.iter().map(|&g| flag(g)))
            .chain(saved.previous.iter().copied())
            .chain([saved.previous_h]);
        Ok(bytes::pack(TAG, values))
    }

    fn deserialize_state(&self, data: &[u8]) -> Result<UnitState, UnitError> {
        let model = self.sim.model();
        let (n, stitches) = (model.particle_count(), model.stitches().len());
        let m = self.values.len();
        let memory = self.sim.integrator_memory();
        let cloth_values = Snapshot::value_count(n, stitches, memory.entries().len());
        let expected = cloth_values + 3 * m + 1;
        let bad = |why: String| UnitError::BadState {
            unit: self.name.clone(),
            message: format!("{} bytes are not a serialised state of this cloth unit: {why}", data.len()),
        };
        let values = bytes::unpack(TAG, data)
            .and_then(|v| {
                if v.len() == expected { Ok(v) } else { Err(format!("{} values where it holds {expected}", v.len())) }
            })
            .map_err(bad)?;
        let cloth =
            Snapshot::from_values(&values[..cloth_values], n, stitches, &memory).map_err(|e| bad(e.to_string()))?;
        let tail = &values[cloth_values..];
        Ok(UnitState(Box::new(Saved {
            cloth,
            values: tail[..m].to_vec(),
            given: tail[m..2 * m].iter().map(|&g| g != 0.0).collect(),
            previous: tail[2 * m..3 * m].to_vec(),
            previous_h: tail[3 * m],
        })))
    }
}
