//! Cloths next to a rapier `RigidBodySet`: a [`ClothSet`] of
//! [`ClothHandle`]s, built with [`ClothBuilder`].

use crate::convert::pose_from_rapier;
use crate::world::{CollideWith, Momentum, WorldSnapshot, WorldSolid, admitted_colliders, bodies_momentum};
use cloth_core::{ClothModel, IntegratorKind, ModelError, Simulation, Snapshot, SolverParams, StepError, Vec3};
use rapier3d_f64::prelude::{InteractionGroups, PhysicsWorld, RigidBodyHandle};

/// A cloth pin held at a point of a rigid body; the cloth's pull on the pin
/// goes back to the body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attachment {
    /// Index of the pin in the model's [`ClothModel::pins`]; the pin must be
    /// declared externally driven (`PinMotion::External`).
    pub pin: usize,
    /// The body.
    pub body: RigidBodyHandle,
    /// The point in the body's frame, m.
    pub local_point: Vec3,
}

/// A cloth in a [`ClothSet`]: its simulation and what ties it to the world.
#[derive(Debug)]
pub struct CoupledCloth {
    pub(crate) sim: Simulation,
    pub(crate) solids: Vec<WorldSolid>,
    pub(crate) attachments: Vec<Attachment>,
    /// Which colliders it meets, and its collision groups.
    collide: CollideWith,
    groups: InteractionGroups,
}

impl CoupledCloth {
    /// The cloth's simulation (state, contacts, pin reactions of the last step).
    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    /// The simulation, to set external forces or read more; do not step it
    /// directly, or the bodies will not feel it.
    pub fn simulation_mut(&mut self) -> &mut Simulation {
        &mut self.sim
    }

    /// The cloth solids that stand for the world's colliders.
    pub fn world_solids(&self) -> &[WorldSolid] {
        &self.solids
    }

    /// The pins held by bodies.
    pub fn attachments(&self) -> &[Attachment] {
        &self.attachments
    }

    /// Takes in the colliders added to `world` since the cloth last looked
    /// (each step does), as new solids of its model.
    pub(crate) fn sync_colliders(&mut self, world: &PhysicsWorld) -> Result<(), CouplingError> {
        let known = |h| self.solids.iter().any(|s| s.collider == h);
        let (solids, links) = admitted_colliders(self.sim.model(), world, (&self.collide, self.groups), |h| !known(h));
        if !solids.is_empty() {
            self.sim.add_solids(solids)?;
            self.solids.extend(links);
        }
        Ok(())
    }
}

/// Why a cloth cannot join a world, or a coupled step failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CouplingError {
    /// The cloth model's gravity differs from the world's: bodies and cloth
    /// would fall differently.
    #[error("gravity: the cloth model has {cloth:?} m/s^2, the rapier world {world:?} m/s^2")]
    Gravity {
        /// The model's gravity (`None`: off).
        cloth: Option<[f64; 3]>,
        /// The world's.
        world: [f64; 3],
    },
    /// The world's colliders could not be added to the model.
    #[error("collider: {0}")]
    Collider(#[from] ModelError),
    /// An attachment names a pin that does not exist or is not external.
    #[error("attachment of pin {pin}: {message}")]
    Attachment {
        /// The pin.
        pin: usize,
        /// Why.
        message: String,
    },
    /// The handle names no cloth of this set.
    #[error("no cloth with this handle")]
    NoSuchCloth,
    /// A rig could not be posed (a motion value that is not finite).
    #[error("rig: {0}")]
    Rig(#[from] crate::rig::RigError),
    /// A cloth step failed (the world and every cloth are back at the start of the step).
    #[error("cloth {cloth} at t = {time_s} s: {message}")]
    Cloth {
        /// Index of the cloth in the set.
        cloth: usize,
        /// Start of the step, s.
        time_s: f64,
        /// The solver's error.
        message: String,
    },
    /// A body's motion went non-finite in rapier's step.
    #[error("body {body:?} at t = {time_s} s: its velocity is not finite after the rigid-body step")]
    NonFiniteBody {
        /// The body.
        body: RigidBodyHandle,
        /// Start of the step, s.
        time_s: f64,
    },
    /// The iterated coupling did not converge (everything is back at the start of the step).
    #[error(
        "coupling at t = {time_s} s: not converged after {iterations} iterations (residual {residual:.3e} of the tolerance)"
    )]
    NotConverged {
        /// Start of the step, s.
        time_s: f64,
        /// Iterations made.
        iterations: usize,
        /// Largest residual over its tolerance.
        residual: f64,
    },
    /// A coupling parameter is out of range.
    #[error("coupling.{field}: {message}")]
    Params {
        /// The field.
        field: &'static str,
        /// Why.
        message: String,
    },
}

/// Builds a cloth for a [`ClothSet`].
#[derive(Debug, Clone)]
pub struct ClothBuilder {
    model: ClothModel,
    integrator: IntegratorKind,
    solver: SolverParams,
    attach: Vec<(usize, RigidBodyHandle)>,
    collide: CollideWith,
    groups: InteractionGroups,
}

impl ClothBuilder {
    /// A cloth of `model` (its gravity must equal the world's), backward
    /// Euler with default solver parameters, colliding with every collider.
    pub fn new(model: ClothModel) -> Self {
        Self {
            model,
            integrator: IntegratorKind::BackwardEuler,
            solver: SolverParams::default(),
            attach: Vec::new(),
            collide: CollideWith::All,
            groups: InteractionGroups::all(),
        }
    }

    /// The integrator.
    pub fn integrator(mut self, integrator: IntegratorKind) -> Self {
        self.integrator = integrator;
        self
    }

    /// The solver parameters.
    pub fn solver(mut self, solver: SolverParams) -> Self {
        self.solver = solver;
        self
    }

    /// Holds external pin `pin` at the body point where the pin is now.
    pub fn attach(mut self, pin: usize, body: RigidBodyHandle) -> Self {
        self.attach.push((pin, body));
        self
    }

    /// Which colliders the cloth meets.
    pub fn collide_with(mut self, which: CollideWith) -> Self {
        self.collide = which;
        self
    }

    /// The cloth's collision groups (default all): it meets a collider
    /// only when the collider's groups and these test each other, as two
    /// rapier colliders do (`InteractionGroups::test`).
    pub fn collision_groups(mut self, groups: InteractionGroups) -> Self {
        self.groups = groups;
        self
    }

    fn build(self, world: &PhysicsWorld) -> Result<CoupledCloth, CouplingError> {
        let g = world.gravity;
        let world_g = [g.x, g.y, g.z];
        let cloth_g = self.model.effects().gravity.map(|c| [c.x, c.y, c.z]);
        if cloth_g.unwrap_or([0.0; 3]) != world_g {
            return Err(CouplingError::Gravity { cloth: cloth_g, world: world_g });
        }
        let mut attachments = Vec::new();
        for (pin, body) in self.attach {
            let fail = |message: String| CouplingError::Attachment { pin, message };
            let p = self.model.pins().get(pin).ok_or_else(|| fail("no such pin".into()))?;
            if !p.is_external() {
                return Err(fail("declare the pin's motion external to attach it".into()));
            }
            if attachments.iter().any(|a: &Attachment| a.pin == pin) {
                return Err(fail("attached twice".into()));
            }
            let rb = world.bodies.get(body).ok_or_else(|| fail(format!("no body {body:?} in the world")))?;
            let frame = pose_from_rapier(rb.position());
            let local_point = frame.rotation.inverse() * (p.anchor - frame.position);
            attachments.push(Attachment { pin, body, local_point });
        }
        let (new, solids) = admitted_colliders(&self.model, world, (&self.collide, self.groups), |_| true);
        let model = self.model.with_solids(new)?;
        let sim = Simulation::new(model, self.integrator, self.solver);
        Ok(CoupledCloth { sim, solids, attachments, collide: self.collide, groups: self.groups })
    }
}

/// The state of a world and its cloths ([`ClothSet::save`]).
#[derive(Debug, Clone)]
pub struct CoupledSnapshot {
    world: WorldSnapshot,
    cloths: Vec<Option<Snapshot>>,
}

/// A handle to a cloth in a [`ClothSet`], stale once the cloth is removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClothHandle {
    index: u32,
    generation: u32,
}

#[derive(Debug)]
struct Slot {
    generation: u32,
    cloth: Option<CoupledCloth>,
}

/// The cloths of a world, next to its `RigidBodySet`. Step them with the
/// bodies through [`ClothSet::step`].
#[derive(Debug, Default)]
pub struct ClothSet {
    slots: Vec<Slot>,
}

impl ClothSet {
    /// No cloths.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a cloth built against `world`: it meets the colliders in the
    /// world now, and those added later from the next step on. (A removed
    /// collider's solid stays where it was last seen; a collider's shape
    /// or collision groups changed later are not seen.)
    pub fn insert(&mut self, builder: ClothBuilder, world: &PhysicsWorld) -> Result<ClothHandle, CouplingError> {
        let cloth = builder.build(world)?;
        let index = match self.slots.iter().position(|s| s.cloth.is_none()) {
            Some(i) => i,
            None => {
                self.slots.push(Slot { generation: 0, cloth: None });
                self.slots.len() - 1
            }
        };
        let slot = &mut self.slots[index];
        slot.cloth = Some(cloth);
        Ok(ClothHandle { index: index as u32, generation: slot.generation })
    }

    /// Removes a cloth, returning its simulation.
    pub fn remove(&mut self, handle: ClothHandle) -> Option<Simulation> {
        let slot = self.slots.get_mut(handle.index as usize).filter(|s| s.generation == handle.generation)?;
        let cloth = slot.cloth.take()?;
        slot.generation += 1;
        Some(cloth.sim)
    }

    /// The cloth behind `handle`.
    pub fn get(&self, handle: ClothHandle) -> Option<&CoupledCloth> {
        self.slots.get(handle.index as usize).filter(|s| s.generation == handle.generation)?.cloth.as_ref()
    }

    /// The cloth behind `handle`, mutably.
    pub fn get_mut(&mut self, handle: ClothHandle) -> Option<&mut CoupledCloth> {
        self.slots.get_mut(handle.index as usize).filter(|s| s.generation == handle.generation)?.cloth.as_mut()
    }

    /// Every cloth with its handle, in insertion-slot order.
    pub fn iter(&self) -> impl Iterator<Item = (ClothHandle, &CoupledCloth)> {
        self.slots.iter().enumerate().filter_map(|(i, s)| {
            s.cloth.as_ref().map(|c| (ClothHandle { index: i as u32, generation: s.generation }, c))
        })
    }

    pub(crate) fn cloths_mut(&mut self) -> impl Iterator<Item = &mut CoupledCloth> {
        self.slots.iter_mut().filter_map(|s| s.cloth.as_mut())
    }

    /// Total momentum of every cloth (pinned particles included) and every
    /// dynamic body of `world`, about the world origin.
    pub fn momentum(&self, world: &PhysicsWorld) -> Momentum {
        let cloths = self.iter().fold(Momentum::default(), |acc, (_, c)| {
            let (model, state) = (c.sim.model(), c.sim.state());
            let cloth =
                model.masses().iter().zip(&state.x).zip(&state.v).fold(Momentum::default(), |m, ((mi, x), v)| {
                    m + Momentum { linear: v * *mi, angular: x.cross(&(v * *mi)) }
                });
            acc + cloth
        });
        cloths + bodies_momentum(&world.bodies)
    }

    /// A copy of the world's and every cloth's state, for rollback and
    /// replay ([`ClothSet::restore`] repeats the run bit for bit).
    pub fn save(&self, world: &PhysicsWorld) -> CoupledSnapshot {
        CoupledSnapshot {
            world: WorldSnapshot::take(world),
            cloths: self.slots.iter().map(|s| s.cloth.as_ref().map(|c| c.sim.snapshot())).collect(),
        }
    }

    /// Puts the world and the cloths back as saved. Cloths inserted since
    /// are left as they are; a removed cloth is not brought back. Every
    /// cloth's saved state is checked before anything is written, so a
    /// refusal leaves the world and every cloth as they were.
    pub fn restore(&mut self, snapshot: &CoupledSnapshot, world: &mut PhysicsWorld) -> Result<(), CouplingError> {
        let refused = |index: usize, saved: &Snapshot, e: StepError| CouplingError::Cloth {
            cloth: index,
            time_s: saved.state.time_s,
            message: e.to_string(),
        };
        for (index, (slot, saved)) in self.slots.iter().zip(&snapshot.cloths).enumerate() {
            if let (Some(c), Some(saved)) = (slot.cloth.as_ref(), saved) {
                c.sim.check_snapshot(saved).map_err(|e| refused(index, saved, e))?;
            }
        }
        snapshot.world.restore(world);
        for (index, (slot, saved)) in self.slots.iter_mut().zip(&snapshot.cloths).enumerate() {
            if let (Some(c), Some(saved)) = (slot.cloth.as_mut(), saved) {
                c.sim.restore(saved).map_err(|e| refused(index, saved, e))?;
            }
        }
        Ok(())
    }

    /// Number of cloths.
    pub fn len(&self) -> usize {
        self.slots.iter().filter(|s| s.cloth.is_some()).count()
    }

    /// Whether there is no cloth.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl std::ops::Index<ClothHandle> for ClothSet {
    type Output = CoupledCloth;
    fn index(&self, handle: ClothHandle) -> &CoupledCloth {
        self.get(handle).expect("stale or foreign cloth handle")
    }
}
