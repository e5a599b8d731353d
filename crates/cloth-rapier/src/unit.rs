//! A rapier world as a co-simulation [`Unit`], to couple with a
//! [`cloth_cosim::ClothUnit`] (or any unit) through `cloth-cosim`'s masters.
//!
//! Variables, per body `k` of the list given to [`RapierUnit::new`] (all
//! `Float64`, SI):
//! - inputs `body{k}.force.{x,y,z}` (N) and `body{k}.torque.{x,y,z}` (N m,
//!   about the body frame's origin at the start of the step): the mean
//!   external load over the next step, applied as the impulse `h F` at the
//!   origin at the start of the step (an impulse at any point is a force
//!   and a torque about the origin);
//! - outputs `body{k}.position.{x,y,z}` (m) and `body{k}.rotation.{x,y,z}`
//!   (rotation vector, rad) of the frame at the end of the step, and
//!   `body{k}.velocity.{x,y,z}` (m/s) and `body{k}.angular_velocity.{x,y,z}`
//!   (rad/s), the mean over the step (displacement and turn over `h`).
//!
//! These match the cloth unit's `solid{k}` inputs (end pose, velocity over
//! the step) and outputs (force and torque about the frame origin), so
//! connecting them name by name couples a body to a cloth solid.
//! States can be saved and restored; serialising them is not supported
//! (rapier is built without serde to keep the build lean).

use crate::convert::{pose_from_rapier, vec_from_rapier, vec_to_rapier};
use crate::world::WorldSnapshot;
use cloth_core::Vec3;
use cloth_cosim::unit::{Causality, StepOutcome, Unit, UnitError, UnitState, ValueRef, Variable, settable};
use rapier3d_f64::prelude::{PhysicsWorld, RigidBodyHandle};

const AXES: [&str; 3] = ["x", "y", "z"];

/// The six 3-vectors of a body, in variable order.
const FIELDS: [(&str, Causality, &str, &str); 6] = [
    ("force", Causality::Input, "N", "mean external force over the step, at the frame origin"),
    ("torque", Causality::Input, "N.m", "mean external torque over the step, about the frame origin"),
    ("position", Causality::Output, "m", "frame origin at the end of the step"),
    ("rotation", Causality::Output, "rad", "orientation (rotation vector) at the end of the step"),
    ("velocity", Causality::Output, "m/s", "mean velocity of the frame origin over the step"),
    ("angular_velocity", Causality::Output, "rad/s", "mean angular velocity over the step"),
];

/// A rapier world as a co-simulation unit.
pub struct RapierUnit {
    name: String,
    world: PhysicsWorld,
    bodies: Vec<RigidBodyHandle>,
    vars: Vec<Variable>,
    values: Vec<f64>,
    time_s: f64,
}

impl std::fmt::Debug for RapierUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RapierUnit").field("name", &self.name).field("bodies", &self.bodies).finish_non_exhaustive()
    }
}

/// The unit's saved state.
struct Saved {
    world: WorldSnapshot,
    values: Vec<f64>,
    time_s: f64,
}

impl RapierUnit {
    /// Wraps `world`; `bodies` become `body0`, `body1`, ... Errors if a
    /// handle names no body.
    pub fn new(name: impl Into<String>, world: PhysicsWorld, bodies: Vec<RigidBodyHandle>) -> Result<Self, UnitError> {
        let name = name.into();
        let mut vars = Vec::new();
        for (k, &h) in bodies.iter().enumerate() {
            let rb = world.bodies.get(h).ok_or_else(|| UnitError::InvalidValue {
                unit: name.clone(),
                name: format!("body{k}"),
                value: f64::NAN,
                message: format!("no body {h:?} in the world"),
            })?;
            let pose = pose_from_rapier(rb.position());
            let starts = [Vec3::zeros(), Vec3::zeros(), pose.position, pose.rotation.scaled_axis()];
            for (f, (field, causality, unit, description)) in FIELDS.iter().enumerate() {
                let start = starts.get(f).copied().unwrap_or_else(Vec3::zeros);
                for (a, axis) in AXES.iter().enumerate() {
                    let var = Variable::new(format!("body{k}.{field}.{axis}"), *causality, unit, *description);
                    // The body's state after the step: no feedthrough.
                    let var = if *causality == Causality::Output { var.with_dependencies(vec![]) } else { var };
                    vars.push(var.with_start(start[a]));
                }
            }
        }
        let values = vars.iter().map(|v| v.start).collect();
        Ok(Self { name, world, bodies, vars, values, time_s: 0.0 })
    }

    /// The world.
    pub fn world(&self) -> &PhysicsWorld {
        &self.world
    }

    fn vector(&self, body: usize, field: usize) -> Vec3 {
        let at = 18 * body + 3 * field;
        Vec3::new(self.values[at], self.values[at + 1], self.values[at + 2])
    }

    fn set_vector(&mut self, body: usize, field: usize, v: Vec3) {
        let at = 18 * body + 3 * field;
        self.values[at..at + 3].copy_from_slice(v.as_slice());
    }
}

impl Unit for RapierUnit {
    fn name(&self) -> &str {
        &self.name
    }

    fn variables(&self) -> &[Variable] {
        &self.vars
    }

    fn set(&mut self, vr: ValueRef, value: f64) -> Result<(), UnitError> {
        settable(&self.name, &self.vars, vr, value)?;
        self.values[vr] = value;
        Ok(())
    }

    fn set_input_derivative(&mut self, _vr: ValueRef, _du: f64) -> Result<(), UnitError> {
        Err(UnitError::Unsupported { unit: self.name.clone(), what: "input derivatives" })
    }

    fn get(&self, vr: ValueRef) -> Result<f64, UnitError> {
        self.values.get(vr).copied().ok_or(UnitError::NoSuchVariable {
            unit: self.name.clone(),
            vr,
            count: self.vars.len(),
        })
    }

    fn do_step(&mut self, t: f64, h: f64) -> Result<StepOutcome, UnitError> {
        if (t - self.time_s).abs() > 1e-9 * t.abs().max(1.0) || !(h.is_finite() && h > 0.0) {
            return Err(UnitError::StepFailed {
                unit: self.name.clone(),
                time_s: t,
                message: format!("the world is at t = {} s; steps must be finite and > 0 (got {h})", self.time_s),
            });
        }
        let saved = WorldSnapshot::take(&self.world);
        self.world.integration_parameters.dt = h;
        let mut starts = Vec::with_capacity(self.bodies.len());
        for (k, &handle) in self.bodies.iter().enumerate() {
            let (force, torque) = (self.vector(k, 0), self.vector(k, 1));
            let rb = &mut self.world.bodies[handle];
            let start = pose_from_rapier(rb.position());
            let com = vec_from_rapier(rb.center_of_mass());
            let impulse = force * h;
            let angular = torque * h + (start.position - com).cross(&impulse);
            rb.apply_impulse(vec_to_rapier(impulse), true);
            rb.apply_torque_impulse(vec_to_rapier(angular), true);
            starts.push(start);
        }
        self.world.step();
        for (k, start) in starts.iter().enumerate() {
            let end = pose_from_rapier(self.world.bodies[self.bodies[k]].position());
            let velocity = (end.position - start.position) / h;
            let turn = (end.rotation * start.rotation.inverse()).scaled_axis() / h;
            let outputs = [end.position, end.rotation.scaled_axis(), velocity, turn];
            if outputs.iter().any(|v| !v.iter().all(|c| c.is_finite())) {
                saved.restore(&mut self.world);
                return Ok(StepOutcome::Discarded {
                    last_time_s: t,
                    reason: format!("body{k} went non-finite in the rigid-body step"),
                });
            }
            for (f, v) in outputs.into_iter().enumerate() {
                self.set_vector(k, 2 + f, v);
            }
        }
        self.time_s = t + h;
        Ok(StepOutcome::Completed)
    }

    fn get_state(&self) -> UnitState {
        UnitState(Box::new(Saved {
            world: WorldSnapshot::take(&self.world),
            values: self.values.clone(),
            time_s: self.time_s,
        }))
    }

    fn set_state(&mut self, state: &UnitState) -> Result<(), UnitError> {
        let saved: &Saved = state.downcast(&self.name, "rapier unit")?;
        saved.world.restore(&mut self.world);
        self.values.clone_from(&saved.values);
        self.time_s = saved.time_s;
        Ok(())
    }

    fn serialize_state(&self, _state: &UnitState) -> Result<Vec<u8>, UnitError> {
        Err(UnitError::Unsupported { unit: self.name.clone(), what: "state serialisation (rapier without serde)" })
    }

    fn deserialize_state(&self, _data: &[u8]) -> Result<UnitState, UnitError> {
        Err(UnitError::Unsupported { unit: self.name.clone(), what: "state serialisation (rapier without serde)" })
    }
}
