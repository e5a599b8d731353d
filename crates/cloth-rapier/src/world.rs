//! What the coupling needs from a rapier world: the solids a cloth meets
//! (rapier colliders as external cloth solids), the bodies' motion over a
//! step, momentum, and a snapshot for repeating a step.

use crate::convert::{pose_from_rapier, rotation_from_rapier, vec_from_rapier};
use cloth_collide::SolidShape;
use cloth_core::{BodyPose, ClothModel, Collider, ModelError, SolidMotion, Vec3};
use nalgebra::{Matrix3, UnitQuaternion};
use rapier3d_f64::math::Pose;
use rapier3d_f64::prelude::{
    BroadPhaseBvh, CCDSolver, ColliderHandle, ColliderSet, ImpulseJointSet, InteractionGroups, IslandManager,
    MultibodyJointSet, NarrowPhase, PhysicsWorld, RigidBody, RigidBodyHandle, RigidBodySet, SoftBodySet,
};

/// Which of the world's colliders a cloth collides with. Sensors never.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum CollideWith {
    /// Every collider in the world when the cloth is inserted (default).
    #[default]
    All,
    /// Only these.
    Only(Vec<ColliderHandle>),
    /// All but these (a body the cloth is attached to, say).
    AllExcept(Vec<ColliderHandle>),
}

impl CollideWith {
    fn admits(&self, handle: ColliderHandle) -> bool {
        match self {
            CollideWith::All => true,
            CollideWith::Only(list) => list.contains(&handle),
            CollideWith::AllExcept(list) => !list.contains(&handle),
        }
    }
}

/// A cloth solid that stands for a rapier collider.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldSolid {
    /// Index of the solid among the cloth model's colliders.
    pub solid: usize,
    /// The rapier collider.
    pub collider: ColliderHandle,
    /// Its body (`None`: a collider without a parent never moves).
    pub body: Option<RigidBodyHandle>,
}

/// Adds the admitted colliders of `world` to `model` as externally driven
/// solids: the solid's frame is the body's frame (the collider's own pose
/// for a parentless collider), the shape sits at the collider's position
/// relative to its body, and the cloth-solid friction is the collider's;
/// dynamic bodies' colliders are [yielding](cloth_core::Collider::yielding).
/// Returns the model and which solid stands for which collider, in the
/// collider set's (deterministic) order.
pub fn import_colliders(
    model: ClothModel,
    world: &PhysicsWorld,
    which: &CollideWith,
) -> Result<(ClothModel, Vec<WorldSolid>), ModelError> {
    let (solids, links) = admitted_colliders(&model, world, (which, InteractionGroups::all()), |_| true);
    Ok((model.with_solids(solids)?, links))
}

/// The world's colliders a cloth with collision groups `groups` meets
/// (sensors and disabled colliders never; a collider whose groups and the
/// cloth's do not test each other, neither) among those `fresh` picks, as
/// solids numbered after `model`'s, and which solid stands for which.
pub(crate) fn admitted_colliders(
    model: &ClothModel,
    world: &PhysicsWorld,
    (which, groups): (&CollideWith, InteractionGroups),
    fresh: impl Fn(ColliderHandle) -> bool,
) -> (Vec<Collider>, Vec<WorldSolid>) {
    let first = model.colliders().len();
    let mut links = Vec::new();
    let mut solids = Vec::new();
    for (handle, collider) in world.colliders.iter() {
        let meets = collider.collision_groups().test(groups);
        if collider.is_sensor() || !collider.is_enabled() || !which.admits(handle) || !meets || !fresh(handle) {
            continue;
        }
        let body = collider.parent();
        let parent = body.and_then(|b| world.bodies.get(b));
        let (frame, local) = match parent {
            Some(rb) => (*rb.position(), collider.position_wrt_parent().copied().unwrap_or(Pose::IDENTITY)),
            None => (*collider.position(), Pose::IDENTITY),
        };
        let shape = SolidShape::from_parry(collider.shared_shape().clone(), local);
        // A dynamic body gives way; fixed and kinematic ones hold the cloth.
        let dynamic = parent.is_some_and(|rb| rb.is_dynamic());
        solids.push(Collider::external(shape, pose_from_rapier(&frame), collider.friction()).with_yielding(dynamic));
        links.push(WorldSolid { solid: first + links.len(), collider: handle, body });
    }
    (solids, links)
}

/// How a body moves over one step, as the cloth sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BodyStart {
    /// The body frame's pose at the start of the step.
    pub pose: BodyPose,
    /// Centre of mass at the start, m.
    pub com: Vec3,
    /// What drives it.
    pub kind: Drive,
}

/// What moves a body during a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Drive {
    /// Fixed, sleeping, disabled or absent: does not move.
    Still,
    /// Kinematic: to the pose its user set for the end of the step.
    Kinematic(BodyPose),
    /// Dynamic: velocities come from the coupling's guess.
    Dynamic,
}

impl BodyStart {
    pub(crate) fn of(body: &RigidBody) -> Self {
        let pose = pose_from_rapier(body.position());
        let com = vec_from_rapier(body.center_of_mass());
        let kind = if body.is_dynamic() && body.is_enabled() {
            Drive::Dynamic
        } else if body.is_kinematic() && body.is_enabled() {
            Drive::Kinematic(pose_from_rapier(body.next_position()))
        } else {
            Drive::Still
        };
        Self { pose, com, kind }
    }

    /// The frame's motion from `t` over `h`: the straight line (and the
    /// shortest turn) to [`Self::end_pose`], so the cloth sees the body end
    /// exactly where rapier puts it when the guess is right.
    pub(crate) fn motion(&self, t: f64, h: f64, v: Vec3, omega: Vec3) -> SolidMotion {
        match self.kind {
            Drive::Still => SolidMotion::at_rest(t, self.pose),
            _ => SolidMotion::between(t, self.pose, self.end_pose(h, v, omega), h),
        }
    }

    /// Where the frame is at the end of the step: for a dynamic body whose
    /// centre of mass moves by `h v` and which turns by `h omega` (mean
    /// velocities over the step), turned about the centre of mass.
    pub(crate) fn end_pose(&self, h: f64, v: Vec3, omega: Vec3) -> BodyPose {
        match self.kind {
            Drive::Still => self.pose,
            Drive::Kinematic(end) => end,
            Drive::Dynamic => {
                let turn = UnitQuaternion::from_scaled_axis(omega * h);
                let com = self.com + v * h;
                BodyPose { position: com + turn * (self.pose.position - self.com), rotation: turn * self.pose.rotation }
            }
        }
    }
}

/// The world inertia tensor of a body about its centre of mass, kg m^2.
pub(crate) fn world_inertia(body: &RigidBody) -> Matrix3<f64> {
    let local = body.mass_properties().local_mprops.reconstruct_inertia_matrix();
    let m = Matrix3::from_columns(&[
        vec_from_rapier(local.x_axis),
        vec_from_rapier(local.y_axis),
        vec_from_rapier(local.z_axis),
    ]);
    let r = rotation_from_rapier(*body.rotation()).to_rotation_matrix();
    r.matrix() * m * r.matrix().transpose()
}

/// Linear (N s) and angular (N m s, about the world origin) momentum.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Momentum {
    /// Linear momentum, kg m/s.
    pub linear: Vec3,
    /// Angular momentum about the world origin, kg m^2/s.
    pub angular: Vec3,
}

impl std::ops::Add for Momentum {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self { linear: self.linear + o.linear, angular: self.angular + o.angular }
    }
}

/// The momentum of the world's dynamic bodies.
pub fn bodies_momentum(bodies: &RigidBodySet) -> Momentum {
    bodies.iter().filter(|(_, b)| b.is_dynamic() && b.is_enabled()).fold(Momentum::default(), |acc, (_, b)| {
        let (com, v, w) =
            (vec_from_rapier(b.center_of_mass()), vec_from_rapier(b.linvel()), vec_from_rapier(b.angvel()));
        let p = v * b.mass();
        acc + Momentum { linear: p, angular: com.cross(&p) + world_inertia(b) * w }
    })
}

/// Everything of a rapier world that changes in a step, for repeating the
/// step (the pipeline keeps only scratch buffers and is not copied).
#[derive(Clone)]
pub struct WorldSnapshot {
    islands: IslandManager,
    broad_phase: BroadPhaseBvh,
    narrow_phase: NarrowPhase,
    bodies: RigidBodySet,
    colliders: ColliderSet,
    impulse_joints: ImpulseJointSet,
    multibody_joints: MultibodyJointSet,
    soft_bodies: SoftBodySet,
    ccd_solver: CCDSolver,
}

impl std::fmt::Debug for WorldSnapshot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WorldSnapshot").field("bodies", &self.bodies.len()).finish_non_exhaustive()
    }
}

impl WorldSnapshot {
    /// Copies the world's state.
    pub fn take(world: &PhysicsWorld) -> Self {
        Self {
            islands: world.islands.clone(),
            broad_phase: world.broad_phase.clone(),
            narrow_phase: world.narrow_phase.clone(),
            bodies: world.bodies.clone(),
            colliders: world.colliders.clone(),
            impulse_joints: world.impulse_joints.clone(),
            multibody_joints: world.multibody_joints.clone(),
            soft_bodies: world.soft_bodies.clone(),
            ccd_solver: world.ccd_solver.clone(),
        }
    }

    /// Puts the world back as it was when the snapshot was taken.
    pub fn restore(&self, world: &mut PhysicsWorld) {
        world.islands.clone_from(&self.islands);
        world.broad_phase.clone_from(&self.broad_phase);
        world.narrow_phase.clone_from(&self.narrow_phase);
        world.bodies.clone_from(&self.bodies);
        world.colliders.clone_from(&self.colliders);
        world.impulse_joints.clone_from(&self.impulse_joints);
        world.multibody_joints.clone_from(&self.multibody_joints);
        world.soft_bodies.clone_from(&self.soft_bodies);
        world.ccd_solver.clone_from(&self.ccd_solver);
    }
}
