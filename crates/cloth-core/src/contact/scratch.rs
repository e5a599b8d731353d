//! The data the contact algorithms keep from step to step inside
//! [`super::contacts::Contacts`]: solids' poses at an instant, what was
//! learnt of each particle's clearance, the crossing test's and the
//! self-collision broad phase's buffers, each particle's surroundings.
//! Their methods live with the algorithms that use them.

use crate::Vec3;
use crate::control::SolidMotion;
use cloth_collide::{Aabb, BoxGrid};

/// A solid's pose, motion and world bounding box at one instant.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SolidPose {
    /// The pose at this instant (`motion.pose`) and the velocities through it.
    pub(crate) motion: SolidMotion,
    pub(crate) lo: Vec3,
    pub(crate) hi: Vec3,
}

/// Every solid's pose and bounding box at one time, computed once per time
/// rather than per particle (a spinning solid's pose takes a quaternion
/// exponential, a mesh's box a transform).
#[derive(Debug, Clone, Default)]
pub(crate) struct SolidFrames {
    pub(crate) time: Option<f64>,
    pub(crate) solids: Vec<SolidPose>,
}

/// What a step's contact detection or a contact pass learnt of a
/// particle's distance to the solids at the end of the step: at `from` it
/// was at least `distance_m` from every solid whose distance is
/// 1-Lipschitz ([`cloth_collide::SolidShape::distance_is_lipschitz`]). The
/// passes of a step move most particles by far less than their distance
/// to the nearest solid; a particle still clear of them by the limit
/// needs no query at all (the Table-1 dress's particles sit inside the
/// torso's bounding box: each pass queried the torso for every one).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Clearance {
    pub(crate) from: Vec3,
    pub(crate) distance_m: f64,
}

/// Scratch of one chunk of the crossing test: triangle pairs whose boxes
/// overlap, and the meetings found among their vertices and edges.
pub(crate) type MeetingChunk = (Vec<(u32, u32)>, Vec<[u32; 4]>);

/// Scratch of the crossing test, built on its first use.
#[derive(Debug, Clone, Default)]
pub(crate) struct CrossingBuffers {
    /// Per triangle, the vertices and edges it tests (`owned_features`).
    pub(crate) owned: Vec<[u8; 2]>,
    /// Edge pairs owned by triangles round one vertex (`ring_edge_pairs`).
    pub(crate) ring: Vec<[u32; 4]>,
    /// The triangles' swept boxes, and their grid.
    pub(crate) boxes: Vec<Aabb>,
    /// Per triangle, its box at the start of the step, its corners' mean
    /// displacement and their largest departure from it, m.
    pub(crate) starts: Vec<(Aabb, Vec3, f64)>,
    pub(crate) extents: Vec<f64>,
    pub(crate) grid: BoxGrid,
    /// Triangles with a corner that moves, and those without (`find_meetings`).
    pub(crate) moving: Vec<u32>,
    pub(crate) resting: Vec<u32>,
    /// Per chunk: broad-phase candidates and the meetings found.
    pub(crate) chunks: Vec<MeetingChunk>,
    /// The particles of each meeting of the current round.
    pub(crate) meetings: Vec<[u32; 4]>,
    /// The step's end positions before any zone moved them.
    pub(crate) end: Vec<Vec3>,
    /// Union-find parents of the particles.
    pub(crate) parent: Vec<u32>,
    /// Particles in a zone, `(zone root, particle)`, sorted.
    pub(crate) members: Vec<(u32, u32)>,
    /// Particles that zones must not move this step: those a solid pushed
    /// out after the step (see [`CrossingBuffers::hold_projected`]).
    pub(crate) held: Vec<bool>,
    /// Positions before the last projection out of the solids.
    pub(crate) before: Vec<Vec3>,
    /// The step's end before the deformation constraints corrected it.
    pub(crate) uncorrected: Vec<Vec3>,
}

/// A solid's surface near a particle, linearised at the closest point
/// found: the particle's gap is `g(x) = n . (x - p)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Plane {
    /// Index of the solid in the model's colliders.
    pub collider: u32,
    /// Closest point of the solid at the end of the step, m.
    pub point: Vec3,
    /// Unit outward normal there.
    pub normal: Vec3,
    /// Velocity of the solid's material point there, m/s.
    pub solid_velocity: Vec3,
    /// Coulomb coefficient.
    pub friction: f64,
    /// The penalty's force at the start of the current iteration, N: the
    /// lagged normal force of the friction (IPC's lagged `lambda`).
    pub lagged_normal_n: f64,
}

/// What detection found around one particle: up to two solid surfaces
/// and a ball the particle may move in without reaching any other solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Surroundings {
    pub planes: [Option<Plane>; 2],
    /// Centre of the ball, m.
    pub centre: Vec3,
    /// Radius of the ball, m (infinite with no solid near).
    pub radius_m: f64,
}

/// What the projection out of the solids last saw in the step's finish,
/// where it runs between every few constraint passes against the same
/// solids and the same step start: a particle whose position has not
/// changed since and that it did not move then would come out the same,
/// so it is not looked at again.
#[derive(Debug, Clone, Default)]
pub(crate) struct ProjectionMemo {
    /// Whether the finish is under way (the memo may be used).
    pub(crate) active: bool,
    /// Whether `at` and `pushed` hold the last projection's outcome.
    pub(crate) valid: bool,
    /// Each particle's position after the last projection, m.
    pub(crate) at: Vec<Vec3>,
    /// Whether the last projection moved it.
    pub(crate) pushed: Vec<bool>,
}

impl ProjectionMemo {
    /// Starts (`true`) or ends a step's finish; either forgets.
    pub(crate) fn set_active(&mut self, active: bool) {
        self.active = active;
        self.valid = false;
    }
}
