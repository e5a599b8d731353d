//! Collision detection and response (Choi & Ko 2002 §5 with Baraff &
//! Witkin's 1998 constraints):
//!
//! - Cloth-solid, implicit step: a particle whose predicted position
//!   `x + h (2v - v_prev)` comes within the thickness of a solid gets the
//!   normal component of its unknown prescribed (two components against
//!   two solids), so it ends the step on the offset surface, moving with
//!   the solid. After a solve, the constraint force is read from the
//!   unfiltered residual: contacts that pull are released, free particles
//!   that ended inside are added, and the system is solved again
//!   ([`release_pulling`], [`add_penetrating`]); [`project_out`] is the
//!   last safety net. Friction then removes tangential velocity relative
//!   to the solid, at most `mu |f_n| tau / m` (Coulomb), all of it when
//!   that suffices (the static regime) ([`apply_friction`]).
//! - Cloth-solid in Newton iterations (`solver.newton_iterations > 1`):
//!   after the first solve the solids act as a stiff penalty energy
//!   ([`contact_penalty`], [`penalty_contacts`]) and their friction as a
//!   smoothed Coulomb dissipation potential ([`smoothed_friction`]), both
//!   inside the minimisation (see the `newton` module); [`apply_friction`]
//!   then only stops the smoothing's creep.
//! - Cloth-solid without an assembled matrix (explicit, fixed-CG):
//!   [`collide_after_step`].
//! - Self-collision: particle-particle and particle-triangle repulsion
//!   ([`laws::repulsion`]) found through the voxel hash at the start of the
//!   step, applied with its Jacobian along the repelling direction only,
//!   and [`separate_self_contacts`] after the step.
//!
//! Everything is evaluated in a fixed particle order (or reduced exactly),
//! so results do not depend on the number of threads.

use crate::colliders::SelfCollision;
use crate::control::{Control, SolidMotion};
use crate::laws::{self, pair_stiffness};
use crate::{ClothModel, ClothState, Mat3, Vec3};
use cloth_collide::{BodyPose, SurfacePoint, VoxelHash, closest_point_on_triangle};
use cloth_linalg::{BlockSparseMatrix, Constraint, ConstraintFilter, ROW_CHUNK};
use rayon::prelude::*;

/// A particle held on a solid's surface during one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolidContact {
    /// The particle.
    pub particle: u32,
    /// Index of the solid in the model's colliders.
    pub collider: u32,
    /// Closest point of the solid's surface at `t + h`, m.
    pub point: Vec3,
    /// Signed distance of the particle's predicted position from the
    /// surface, m (negative inside).
    pub distance_m: f64,
    /// Unit outward normal of the solid at the contact.
    pub normal: Vec3,
    /// Normal displacement over the step that puts the particle on the
    /// offset surface at `t + h`, m.
    pub normal_travel_m: f64,
    /// Velocity of the solid at `t + h`, m/s.
    pub solid_velocity: Vec3,
    /// Coulomb coefficient.
    pub friction: f64,
    /// Force the constraint exerts along the normal, N (>= 0 once solved).
    pub normal_force_n: f64,
    /// Impulse the solid gave the particle over the step, N s: the normal
    /// force times the step plus friction (the solid received the opposite).
    pub impulse_n_s: Vec3,
    /// False once released because it pulled.
    pub active: bool,
    /// Squeezed: the particle is also held by a solid on the opposite side
    /// (a cloth between a box and a table). It cannot be held by both, so
    /// this one presses with [`squeeze_force`] instead of a constraint;
    /// `normal_force_n` is that force.
    pub pressed: bool,
    /// Friction inside the implicit solve, of a squeezed particle
    /// ([`linearise_squeeze_friction`]) or of a held one in Newton
    /// iterations ([`linearise_contact_friction`]), linearised as
    /// `f = e - C v`: `C`, N s/m, ...
    pub solve_damping: Mat3,
    /// ... `e`, N, ...
    pub solve_constant_n: Vec3,
    /// The force it exerted at the solved velocity, N
    /// ([`squeeze_friction_forces`]); [`apply_friction`] settles the rest
    /// within the Coulomb bound.
    pub solve_friction_n: Vec3,
    /// The bound `mu N` of the last [`linearise_contact_friction`], N (the
    /// line search's dissipation uses the same one).
    pub solve_limit_n: f64,
    /// Where this contact's friction is decided (see [`FrictionMode`]).
    pub friction_mode: FrictionMode,
    /// For [`FrictionMode::Stick`]: the tangential travel of the solid's
    /// surface over the step, `h (I - n n^T) v_solid`, m.
    pub tangent_travel_m: Vec3,
    /// Whether this step's passes already turned it back from sliding to
    /// sticking once ([`stick_or_slide`]).
    pub turned_back: bool,
}

/// Where a contact's Coulomb friction is decided in an implicit step.
///
/// After the solve ([`apply_friction`]) the particle alone meets the
/// friction: its slip is stopped when `mu N tau / m` suffices. That is
/// right for a particle on its own, but a particle linked to the rest of
/// the cloth slips under the force of a whole stiff cluster, so its slip
/// speed understates the force to be resisted and it sticks where
/// Coulomb would let it slide: where the cloth's own tension presses it
/// onto a solid (the pole of a ball pushing through a curtain: `N` from the
/// wrapped tension, the particle held while the cloth around it
/// stretches to twice its length). In the solve, the decision is made on
/// the force: the contact first holds the particle on the moving surface
/// (a full constraint), and where the tangential part of the constraint
/// force exceeds `mu N` it slides instead, the friction `mu N` pointing
/// along that force (implicit Coulomb friction: the force needed to
/// stick, projected onto the friction cone). Baraff & Witkin 1998 hold
/// contacts the same way, with constraints in the filtered solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FrictionMode {
    /// [`apply_friction`] after the solve: particles squeezed between two
    /// solids or held by two, solids whose motion from outside is a guess
    /// (see [`stick_frictional_contacts`]), integrators without a matrix,
    /// Newton iterations (which smooth friction into their potential).
    #[default]
    AfterSolve,
    /// In the solve, stuck: the particle moves with the surface.
    Stick,
    /// In the solve, sliding: the normal constrained, and a constant
    /// force `mu N` (`solve_constant_n`) in the right-hand side.
    Slide,
}

impl SolidContact {
    /// A contact of `particle` held on solid `collider` at the surface
    /// `point` (m) with outward `normal`, the solid moving at
    /// `solid_velocity` (m/s), Coulomb `friction`: active, on the surface
    /// (no distance or travel), no force or impulse yet, nothing in the
    /// solve.
    pub fn new(
        particle: usize,
        collider: usize,
        point: Vec3,
        normal: Vec3,
        solid_velocity: Vec3,
        friction: f64,
    ) -> Self {
        Self {
            particle: particle as u32,
            collider: collider as u32,
            point,
            distance_m: 0.0,
            normal,
            normal_travel_m: 0.0,
            solid_velocity,
            friction,
            normal_force_n: 0.0,
            impulse_n_s: Vec3::zeros(),
            active: true,
            pressed: false,
            solve_damping: Mat3::zeros(),
            solve_constant_n: Vec3::zeros(),
            solve_friction_n: Vec3::zeros(),
            solve_limit_n: 0.0,
            friction_mode: FrictionMode::AfterSolve,
            tangent_travel_m: Vec3::zeros(),
            turned_back: false,
        }
    }
}

/// A pair of cloth pieces closer than the self-collision thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelfContact {
    /// The particle pushed along `direction`.
    pub particle: u32,
    /// The other side: a particle (weights `[1, 0, 0]`) or a triangle's corners.
    pub others: [u32; 3],
    /// Barycentric weights of the closest point on the other side.
    pub weights: [f64; 3],
    /// Unit direction from the other side to the particle.
    pub direction: Vec3,
    /// Distance, m.
    pub distance_m: f64,
    /// Whether it exerts a repulsion force (particle pairs, and each
    /// particle's nearest triangle); all pairs are kept apart after the step.
    pub repels: bool,
}

/// What collision handling did in one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactStats {
    /// Cloth-solid contacts held at the end of the step.
    pub contacts: usize,
    /// Contacts released because their force pulled.
    pub released: usize,
    /// Contacts added after a solve left a free particle inside a solid.
    pub added: usize,
    /// Particles moved out of a solid after the step (see [`project_out`]).
    pub projected: usize,
    /// Contacts held by static friction (no tangential slip).
    pub sticking: usize,
    /// Deepest particle inside a solid at the start of the step, m (0 when none).
    pub max_penetration_m: f64,
    /// Self-collision pairs closer than the thickness (particle-particle
    /// plus particle-triangle).
    pub self_contacts: usize,
    /// Pairs pushed apart after the step by [`separate_self_contacts`].
    pub self_separations: usize,
    /// Narrow-phase point queries against solids.
    pub narrow_phase_queries: usize,
    /// Spatial hash rebuilds (self-collision broad phase).
    pub hash_builds: usize,
}

impl std::ops::AddAssign for ContactStats {
    /// Sums counters; keeps the larger penetration.
    fn add_assign(&mut self, o: Self) {
        self.contacts += o.contacts;
        self.released += o.released;
        self.added += o.added;
        self.projected += o.projected;
        self.sticking += o.sticking;
        self.max_penetration_m = self.max_penetration_m.max(o.max_penetration_m);
        self.self_contacts += o.self_contacts;
        self.self_separations += o.self_separations;
        self.narrow_phase_queries += o.narrow_phase_queries;
        self.hash_builds += o.hash_builds;
    }
}

/// Scratch space of collision handling, sized once per model.
#[derive(Debug, Clone, Default)]
pub struct ContactBuffers {
    /// Cloth-solid contacts of the current step, sorted by particle; a
    /// particle touching two solids (a corner, overlapping solids) has two
    /// consecutive entries.
    pub solid: Vec<SolidContact>,
    /// Solids a Newton correction would carry a particle into (see
    /// [`penalty_watch`]): the line search's penalty sees them too.
    pub watch: Vec<SolidContact>,
    /// Self-collision pairs of the current step.
    pub self_pairs: Vec<SelfContact>,
    /// Per-particle candidates of the narrow phase (before compaction).
    candidate: Vec<[Option<SolidContact>; 2]>,
    /// Per-particle penetration depth and query count.
    probe: Vec<(f64, u32)>,
    /// First entry of each particle in `solid`, or `u32::MAX`.
    first_entry: Vec<u32>,
    /// Per particle, what was last learnt of its distance to the solids at
    /// the end of the current step: set from its predicted position by
    /// [`detect_solid_contacts`], then by each [`add_penetrating`] that
    /// measures it again.
    clearance: Vec<Clearance>,
    /// Per particle, whether `candidate` holds what the last
    /// [`detect_solid_contacts`] or [`add_penetrating`] found for it: they
    /// write (and read back) only the candidates of particles that have
    /// one, a contact being a few hundred bytes.
    has_candidate: Vec<bool>,
    /// The solids at the start and at the end of the current step.
    now: SolidFrames,
    next: SolidFrames,
    /// Motions of externally driven solids for the current step.
    external: Vec<Option<SolidMotion>>,
    hash: Option<VoxelHash>,
    corners: Vec<[Vec3; 3]>,
    /// Broad-phase output, reused.
    candidate_pairs: Vec<(u32, u32)>,
    /// Per chunk of the hash's cell table: the point pairs found from it.
    pair_chunks: Vec<Vec<(u32, u32)>>,
    /// Per chunk of triangles: broad-phase candidates and the pairs found.
    triangle_chunks: Vec<TriangleChunk>,
    /// CSR, built once per model: for each triangle, the sorted particles
    /// it never repels (its corners and every particle linked to one).
    excluded_ptr: Vec<u32>,
    excluded: Vec<u32>,
    /// Self-collision forces, N.
    pub self_force: Vec<Vec3>,
    /// Self-collision stiffness on the diagonal, `-df_i/dx_i`, N/m.
    pub self_stiffness: Vec<Mat3>,
    /// Friction of squeezed particles as damping on the diagonal,
    /// `-df_i/dv_i`, N s/m ([`linearise_squeeze_friction`]).
    pub friction_damping: Vec<Mat3>,
    /// Per particle, its nearest triangle's entry in `self_pairs` (or `u32::MAX`).
    nearest: Vec<u32>,
}

/// A predicted position closer than `(1 + CONTACT_MARGIN)` times the
/// thickness makes a contact. A particle resting on the offset surface is
/// predicted exactly at the thickness: without a margin it would drop out
/// of contact (and out of static friction) every other step. A wider
/// margin costs more: contacts that would pull must be released, one more
/// solve each time (measured: 0.5 doubled the CG iterations of the drape).
const CONTACT_MARGIN: f64 = 0.05;

/// Two contact normals closer than this (cosine) constrain one direction.
const PARALLEL_COS: f64 = 0.98;

/// Two contact normals further apart than this (cosine below its
/// negative, more than 120 degrees) squeeze the particle between their
/// solids: one holds it, the other presses ([`squeeze_force`]). Holding
/// it with both would lock it in the plane of the two normals: a cloth
/// pulled under a resting box's edge (whose normal turns from the bottom
/// face's as the particle passes) would push the box instead of sliding.
/// Between the two bounds the normals make a crease, both hold.
const OPPOSED_COS: f64 = 0.5;

/// Keeps the deepest solid and the deepest other one whose normal is not
/// parallel to it, from up to four solids in reach.
struct Nearest {
    found: [(f64, Option<SolidContact>); 4],
}

impl Nearest {
    fn new() -> Self {
        Self { found: [(f64::INFINITY, None); 4] }
    }

    fn offer(&mut self, distance: f64, contact: SolidContact) {
        // Replace the shallowest kept candidate if this one is deeper.
        let (slot, worst) = self
            .found
            .iter()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |acc, (k, (d, _))| if *d > acc.1 { (k, *d) } else { acc });
        if distance < worst {
            self.found[slot] = (distance, Some(contact));
        }
    }

    /// The deepest contact and a second one: a crease, or a solid on the
    /// opposite side (`pressed`). `yielding` tells whether a contact's
    /// solid gives way ([`crate::Collider::yielding`]).
    fn pick(&self, yielding: impl Fn(&SolidContact) -> bool) -> [Option<SolidContact>; 2] {
        // By reference: a contact is a few hundred bytes, and copying
        // candidates through the fold was 7% of a garment's step.
        let deepest = |skip: &dyn Fn(&SolidContact) -> bool| {
            self.found
                .iter()
                .filter_map(|(d, c)| c.as_ref().filter(|c| !skip(c)).map(|c| (*d, c)))
                .fold(None, |best: Option<(f64, &SolidContact)>, (d, c)| match best {
                    Some((bd, bc)) if bd < d || (bd == d && bc.collider <= c.collider) => Some((bd, bc)),
                    _ => Some((d, c)),
                })
                .map(|(_, c)| *c)
        };
        let first = deepest(&|_| false);
        let crease = first.and_then(|f| {
            deepest(&|c| c.collider == f.collider || !(-OPPOSED_COS..=PARALLEL_COS).contains(&f.normal.dot(&c.normal)))
        });
        if crease.is_some() {
            return [first, crease];
        }
        let opposite =
            first.and_then(|f| deepest(&|c| c.collider == f.collider || f.normal.dot(&c.normal) >= -OPPOSED_COS));
        match (first, opposite) {
            // Squeezed: a solid that gives way presses, the other holds
            // (the deeper one when both or neither give way).
            (Some(f), Some(o)) => {
                let (hold, mut press) = if yielding(&f) && !yielding(&o) { (o, f) } else { (f, o) };
                press.pressed = true;
                [Some(hold), Some(press)]
            }
            _ => [first, None],
        }
    }
}

/// Stiffness of a squeezed contact per unit particle mass and per `1/h^2`:
/// the pressing solid meets a particle `SQUEEZE` times stiffer than the
/// particle's own inertia over one step (`m / h^2`). Any value gives the
/// same forces once a coupled step converges (the overlap adjusts); this
/// one keeps the overlap below a thousandth of the load's free-fall
/// distance over a step and an explicitly coupled body of the particle's
/// mass stable (`k h^2 / m < 4` fails only for bodies 25 times lighter
/// than the particles they press).
const SQUEEZE: f64 = 100.0;

/// Force with which a solid presses a particle that a solid on the other
/// side holds (N, >= 0): a penalty `f = k max(0, e - g)` on the particle's
/// gap `g` (m) to the pressing solid below the thickness `e` (m), with
/// `k = SQUEEZE m / h^2` (N/m) for particle mass `m` (kg) and step `h`
/// (s). Choi & Ko (2002, §5) hold particles on solids with constraints;
/// a particle between two solids (their normals opposite) can only be
/// held by one, and the other's push must be a force the holding solid
/// carries (Baraff & Witkin 1998 filter one direction once).
pub fn squeeze_force(gap_m: f64, thickness_m: f64, mass_kg: f64, h: f64) -> f64 {
    SQUEEZE * mass_kg / (h * h) * (thickness_m - gap_m).max(0.0)
}

/// The overlap (m) behind a squeezed contact's force `force_n` (N) on a
/// particle of mass `mass_kg` (kg) at step `h` (s): [`squeeze_force`]'s
/// `max(0, e - g)` back from its force.
fn squeeze_overlap(force_n: f64, mass_kg: f64, h: f64) -> f64 {
    force_n.max(0.0) * h * h / (SQUEEZE * mass_kg)
}

/// A solid's pose, motion and world bounding box at one instant.
#[derive(Debug, Clone, Copy)]
struct SolidPose {
    /// The pose at this instant (`motion.pose`) and the velocities through it.
    motion: SolidMotion,
    lo: Vec3,
    hi: Vec3,
}

impl SolidPose {
    /// The solid frame's pose at this instant.
    fn pose(&self) -> &BodyPose {
        &self.motion.pose
    }

    /// Whether `p` is within `margin` of the bounding box.
    fn near(&self, p: &Vec3, margin: f64) -> bool {
        (0..3).all(|a| p[a] >= self.lo[a] - margin && p[a] <= self.hi[a] + margin)
    }

    /// Distance from `p` to the bounding box (0 inside it), m: a lower
    /// bound on `p`'s distance to the solid.
    fn box_distance(&self, p: &Vec3) -> f64 {
        Vec3::from_fn(|a, _| (self.lo[a] - p[a]).max(p[a] - self.hi[a]).max(0.0)).norm()
    }

    /// Velocity of the solid's material point at `point` (m), m/s.
    fn velocity_at(&self, point: Vec3) -> Vec3 {
        self.motion.velocity_at(self.motion.time_s, point)
    }
}

/// Every solid's pose and bounding box at one time, computed once per time
/// rather than per particle (a spinning solid's pose takes a quaternion
/// exponential, a mesh's box a transform).
#[derive(Debug, Clone, Default)]
struct SolidFrames {
    time: Option<f64>,
    solids: Vec<SolidPose>,
}

impl SolidFrames {
    /// The solids of `model` at `time` (s), recomputed only when the time
    /// changes: path-driven ones from their path, external ones from
    /// `external` (held at their anchor when not set).
    fn at(&mut self, model: &ClothModel, external: &[Option<SolidMotion>], time: f64) -> &[SolidPose] {
        if self.time != Some(time) || self.solids.len() != model.colliders().len() {
            self.solids.clear();
            self.solids.extend(model.colliders().iter().enumerate().map(|(k, c)| {
                let motion = match external.get(k).copied().flatten() {
                    Some(m) if c.is_external() => SolidMotion { time_s: time, pose: m.pose_at(time), ..m },
                    _ => SolidMotion {
                        time_s: time,
                        pose: c.pose(time),
                        linear_velocity: c.motion.velocity(time),
                        angular_velocity: c.spin_rad_s,
                    },
                };
                let (lo, hi) = c.shape.aabb(&motion.pose);
                SolidPose { motion, lo, hi }
            }));
            self.time = Some(time);
        }
        &self.solids
    }
}

impl ContactBuffers {
    /// Takes the motions of externally driven solids for the next step
    /// from `control` (and forgets solid poses computed before, since a
    /// repeated step may move them differently).
    pub(crate) fn set_external(&mut self, control: &Control) {
        self.external.clear();
        self.external.extend_from_slice(control.solid_motions());
        self.now.time = None;
        self.next.time = None;
    }
}

/// Finds cloth-solid contacts for the step from `t` to `t + h` into
/// `bufs.solid`. The end of the step is predicted with the velocity
/// extrapolated from the last step, `x + h (2 v - v_prev)`, so
/// accelerating particles are caught before they pass the surface.
pub fn detect_solid_contacts(
    model: &ClothModel,
    state: &ClothState,
    h: f64,
    bufs: &mut ContactBuffers,
) -> ContactStats {
    let (x, v, t) = (&state.x, &state.v, state.time_s);
    let v_prev = if state.has_history { &state.v_prev } else { &state.v };
    let n = x.len();
    bufs.candidate.resize(n, [None; 2]);
    bufs.probe.resize(n, (0.0, 0));
    // The solids are at a new time: what was learnt of them is void, and
    // the predictions below measure them anew.
    bufs.clearance.clear();
    bufs.clearance.resize(n, Clearance::UNKNOWN);
    bufs.has_candidate.resize(n, false);
    let thickness = model.contact_thickness();
    let reach = thickness * (1.0 + CONTACT_MARGIN);
    let (colliders, masses) = (model.colliders(), model.masses());
    let (solids_now, solids_next) = (bufs.now.at(model, &bufs.external, t), bufs.next.at(model, &bufs.external, t + h));
    let per_particle = bufs.candidate.par_iter_mut().zip(bufs.probe.par_iter_mut());
    let per_particle = per_particle.zip(bufs.clearance.par_iter_mut().zip(bufs.has_candidate.par_iter_mut()));
    per_particle.enumerate().for_each(|(i, ((cand, probe), (clearance, has)))| {
        *probe = (0.0, 0);
        *has = false;
        if model.is_pinned(i) {
            return;
        }
        let predicted = x[i] + (v[i] * 2.0 - v_prev[i]) * h;
        let mut beyond = f64::INFINITY;
        let mut nearest: Option<Nearest> = None;
        for (k, (c, (now, next))) in colliders.iter().zip(solids_now.iter().zip(solids_next)).enumerate() {
            let mut here = None;
            if now.near(&x[i], reach) {
                let s = c.shape.closest(now.pose(), x[i]);
                probe.0 = probe.0.max(-s.distance_m);
                probe.1 += 1;
                here = Some(s);
            }
            let lipschitz = c.shape.distance_is_lipschitz();
            if !next.near(&predicted, reach) {
                if lipschitz {
                    beyond = beyond.min(next.box_distance(&predicted));
                }
                continue;
            }
            let s = c.shape.closest(next.pose(), predicted);
            probe.1 += 1;
            if lipschitz {
                beyond = beyond.min(s.distance_m);
            }
            if s.distance_m < reach {
                // The side the particle comes from: a prediction deep inside
                // a thin solid is closest to its far face.
                let surface = if c.is_moving() {
                    let mut queries = 0;
                    let side = side_of(c, (next, h), x[i], s, &mut queries);
                    probe.1 += queries as u32;
                    side
                } else {
                    here.filter(|f| f.distance_m > 0.0).unwrap_or(s)
                };
                let travel = normal_travel(surface.normal.dot(&(x[i] - surface.point)), thickness, reach);
                let found = contact(i, k, c, &surface, s.distance_m, travel, next);
                nearest.get_or_insert_with(Nearest::new).offer(s.distance_m, found);
            }
        }
        *clearance = Clearance { from: predicted, distance_m: beyond };
        let Some(nearest) = nearest else { return };
        (*cand, *has) = (nearest.pick(|c| colliders[c.collider as usize].yielding), true);
        if let [Some(held), Some(pressed)] = cand
            && pressed.pressed
        {
            // The particle ends the step where the holding solid puts it.
            let end = x[i] + held.normal * held.normal_travel_m;
            let gap = pressed.normal.dot(&(end - pressed.point));
            pressed.normal_force_n = squeeze_force(gap, thickness, masses[i], h);
        }
    });
    bufs.solid.clear();
    let mut stats = ContactStats::default();
    for ((cand, probe), has) in bufs.candidate.iter().zip(&bufs.probe).zip(&bufs.has_candidate) {
        stats.max_penetration_m = stats.max_penetration_m.max(probe.0);
        stats.narrow_phase_queries += probe.1 as usize;
        if *has {
            bufs.solid.extend(cand.iter().flatten());
        }
    }
    stats.contacts = bufs.solid.len();
    stats
}

fn contact(
    i: usize,
    k: usize,
    c: &crate::Collider,
    s: &SurfacePoint,
    distance: f64,
    travel: f64,
    next: &SolidPose,
) -> SolidContact {
    let held = SolidContact::new(i, k, s.point, s.normal, next.velocity_at(s.point), c.friction);
    SolidContact { distance_m: distance, normal_travel_m: travel, ..held }
}

/// What [`reach_surface`] found of solid `c` from a particle's new
/// position `to`.
enum Reach {
    /// Closer than the limit: the closest point to `to` and the surface
    /// point to push back to.
    Within(SurfacePoint, SurfacePoint),
    /// Not closer than the limit; `to`'s signed distance is at least
    /// `distance_m` (its bounding box's distance, or the query's).
    Beyond { distance_m: f64 },
}

impl Reach {
    /// A lower bound on `to`'s signed distance, m (within reach: the
    /// closest point's distance itself).
    fn distance_at_least(&self) -> f64 {
        match self {
            Reach::Within(at, _) => at.distance_m,
            Reach::Beyond { distance_m } => *distance_m,
        }
    }

    /// The two surface points when within reach.
    fn within(self) -> Option<(SurfacePoint, SurfacePoint)> {
        match self {
            Reach::Within(at, side) => Some((at, side)),
            Reach::Beyond { .. } => None,
        }
    }
}

/// Whether `to` (a particle's new position) is closer than `limit` to
/// solid `c` (posed as `next` at the end of a step of `h` s): if so the
/// closest point to `to` and the surface point to push back to
/// ([`side_of`], with the closest point to `to` as the fallback), else how
/// far it is at least. Point queries made are added to `queries`.
fn reach_surface(
    c: &crate::Collider,
    (next, h): (&SolidPose, f64),
    from: Vec3,
    to: Vec3,
    limit: f64,
    queries: &mut usize,
) -> Reach {
    if !next.near(&to, limit) {
        return Reach::Beyond { distance_m: next.box_distance(&to) };
    }
    let at = c.shape.closest(next.pose(), to);
    *queries += 1;
    if at.distance_m >= limit {
        return Reach::Beyond { distance_m: at.distance_m };
    }
    Reach::Within(at, side_of(c, (next, h), from, at, queries))
}

/// The surface point of solid `c` (posed `next` at the end of a step of
/// `h` s) that a particle at `from` (its position at the start of the
/// step) goes back to: the closest to `from` when `from` is outside (the
/// side it comes from: a thin solid is then not crossed), else
/// `fallback` (the point nearest where it ends). When a moving solid swept
/// over `from`, the face closest to where the particle sat relative to the
/// solid at the start (`from + h v_solid(from)` in the new pose: the face
/// that swept it) if that is the shorter way out: the fallback pushed a skirt particle of
/// the Table-1 dress, swept over by a striding thigh and carried deep
/// into it by the solve, 5 cm out through the thigh's far end in one
/// step. Only the solid's pose and velocity at the end of the step are
/// used, as a co-simulation master gives them.
fn side_of(
    c: &crate::Collider,
    (next, h): (&SolidPose, f64),
    from: Vec3,
    fallback: SurfacePoint,
    queries: &mut usize,
) -> SurfacePoint {
    let side = c.shape.closest(next.pose(), from);
    *queries += 1;
    if side.distance_m > 0.0 {
        return side;
    }
    if !c.is_moving() {
        return fallback;
    }
    // The solid moved by about `h v` since: relative to it, the particle
    // sat `h v` further along.
    let swept = c.shape.closest(next.pose(), from + next.velocity_at(from) * h);
    *queries += 1;
    // How far `from` must move along each normal to reach each surface.
    let way_out = |s: &SurfacePoint| s.normal.dot(&(s.point - from));
    if swept.distance_m > 0.0 && way_out(&swept) < way_out(&fallback) { swept } else { fallback }
}

/// The entries of `contacts` (sorted by particle) that belong to one
/// particle each, in order.
fn groups(contacts: &[SolidContact]) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
    contacts.chunk_by(same_particle).scan(0, |start, group| {
        let range = *start..*start + group.len();
        *start = range.end;
        Some(range)
    })
}

/// Whether two contact entries belong to the same particle (entries are
/// sorted by particle, so a particle's entries are consecutive).
fn same_particle(a: &SolidContact, b: &SolidContact) -> bool {
    a.particle == b.particle
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
struct Clearance {
    from: Vec3,
    distance_m: f64,
}

impl Clearance {
    /// Nothing learnt yet.
    const UNKNOWN: Self = Self { from: Vec3::new(0.0, 0.0, 0.0), distance_m: f64::NEG_INFINITY };

    /// Slack on the bound, m, for the rounding of two distance queries
    /// (about 1e-16 of the coordinates): with it, a skipped query would
    /// have answered "beyond" however it rounds.
    const SLACK_M: f64 = 1e-9;

    /// Whether every Lipschitz solid is surely not closer than `limit` to
    /// `p`: the distance at `from`, less how far `p` is from there, is
    /// still beyond the limit (a distance changes no faster than its point
    /// moves).
    fn clears(&self, p: &Vec3, limit: f64) -> bool {
        self.distance_m - (p - self.from).norm() > limit + Self::SLACK_M
    }
}

/// After a solve: a particle whose new position `new_x` ends closer than
/// half the thickness to a solid at `t_next` becomes a contact if it was
/// free (not pinned, not released this step), or gains a second contact
/// direction if it touched one other solid with a different normal. The
/// new constraints go into `filter` with `value(target, i)`. Returns how
/// many contacts were added (the system must then be solved again).
#[allow(clippy::too_many_arguments)]
pub fn add_penetrating(
    model: &ClothModel,
    x: &[Vec3],
    new_x: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut ContactBuffers,
    filter: &mut ConstraintFilter,
    value: impl Fn(Vec3, usize) -> Vec3,
) -> usize {
    let thickness = model.contact_thickness();
    let colliders = model.colliders();
    bufs.first_entry.clear();
    bufs.first_entry.resize(x.len(), u32::MAX);
    for range in groups(&bufs.solid) {
        bufs.first_entry[bufs.solid[range.start].particle as usize] = range.start as u32;
    }
    let solids_next = bufs.next.at(model, &bufs.external, t + h);
    bufs.clearance.resize(x.len(), Clearance::UNKNOWN);
    let (solid, first_entry) = (&bufs.solid, &bufs.first_entry);
    let limit = 0.5 * thickness;
    let all_lipschitz = colliders.iter().all(|c| c.shape.distance_is_lipschitz());
    // Clearing and scanning every particle's candidate each pass was most
    // of a pass: see `has_candidate`.
    bufs.has_candidate.resize(x.len(), false);
    let candidates =
        bufs.candidate.par_iter_mut().zip(bufs.clearance.par_iter_mut()).zip(bufs.has_candidate.par_iter_mut());
    candidates.enumerate().for_each(|(i, ((cand, clearance), has))| {
        *has = false;
        if model.is_pinned(i) {
            return;
        }
        // The one solid this particle already touches, if exactly one.
        let existing = match first_entry[i] {
            u32::MAX => None,
            e => {
                let mine = solid[e as usize..].iter().take_while(|c| c.particle as usize == i);
                let (count, all_active) = mine.fold((0, true), |(n, a), c| (n + 1, a && c.active));
                if count != 1 || !all_active {
                    return;
                }
                Some(solid[e as usize])
            }
        };
        // Clear of every solid with a Lipschitz distance since the last
        // pass: those queries would all answer "beyond".
        let clear = clearance.clears(&new_x[i], limit);
        if clear && all_lipschitz {
            return;
        }
        let mut beyond = f64::INFINITY;
        // Made at the first solid within reach (most particles meet none:
        // four empty candidates a particle a pass were most of the pass).
        let mut nearest: Option<Nearest> = None;
        for (k, (c, next)) in colliders.iter().zip(solids_next).enumerate() {
            let lipschitz = c.shape.distance_is_lipschitz();
            if clear && lipschitz {
                continue;
            }
            let reach = reach_surface(c, (next, h), x[i], new_x[i], limit, &mut 0);
            if lipschitz {
                beyond = beyond.min(reach.distance_at_least());
            }
            let Some((s, surface)) = reach.within() else { continue };
            let distinct = existing.is_none_or(|e| {
                e.collider as usize != k && (-OPPOSED_COS..=PARALLEL_COS).contains(&e.normal.dot(&surface.normal))
            });
            if distinct {
                let travel = normal_travel(surface.normal.dot(&(x[i] - surface.point)), thickness, thickness);
                let found = contact(i, k, c, &surface, s.distance_m, travel, next);
                nearest.get_or_insert_with(Nearest::new).offer(s.distance_m, found);
            }
        }
        if let Some(found) = nearest.and_then(|nearest| nearest.pick(|_| false)[0]) {
            (cand[0], *has) = (Some(found), true);
        }
        if !clear {
            *clearance = Clearance { from: new_x[i], distance_m: beyond };
        }
    });
    let before = bufs.solid.len();
    let found = bufs.has_candidate.iter().zip(&bufs.candidate).filter(|(has, _)| **has);
    bufs.solid.extend(found.filter_map(|(_, c)| c[0].as_ref()));
    let added = bufs.solid.len() - before;
    if added > 0 {
        bufs.solid.sort_unstable_by_key(|c| (c.particle, c.collider));
        for range in groups(&bufs.solid) {
            if bufs.has_candidate[bufs.solid[range.start].particle as usize] {
                constrain_particle(&bufs.solid[range], x, filter, &value);
            }
        }
    }
    added
}

/// The safety net after the active set: particles that still end closer
/// than half the thickness to a solid at `t_next` are moved back to the
/// thickness along the normal of the side they came from, and lose their
/// velocity into the solid (relative to it). Only particles released this
/// step are checked, or every particle when `all` (the active set ran out
/// of passes with contacts still being added: large steps). Positions move
/// without a matching velocity, so this is a projection, not a force; in
/// ordinary steps it finds nothing. Returns the number of particles moved.
pub fn project_out(
    model: &ClothModel,
    x: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut ContactBuffers,
    all: bool,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) -> usize {
    let thickness = model.contact_thickness();
    let solids_next = bufs.next.at(model, &bufs.external, t + h);
    let mut moved = 0;
    let mut fix = |i: usize| {
        let mut changed = false;
        for (c, next) in model.colliders().iter().zip(solids_next) {
            let Some((_, surface)) = reach_surface(c, (next, h), x[i], new_x[i], 0.5 * thickness, &mut 0).within()
            else {
                continue;
            };
            let n = surface.normal;
            let gap = n.dot(&(new_x[i] - surface.point));
            if gap < thickness {
                new_x[i] += n * (thickness - gap);
                let inward = n.dot(&(new_v[i] - next.velocity_at(surface.point)));
                if inward < 0.0 {
                    new_v[i] -= n * inward;
                }
                changed = true;
            }
        }
        changed
    };
    if all {
        for i in (0..x.len()).filter(|&i| !model.is_pinned(i)) {
            moved += usize::from(fix(i));
        }
    } else {
        for c in bufs.solid.iter().filter(|c| !c.active) {
            moved += usize::from(fix(c.particle as usize));
        }
    }
    moved
}

/// Collision response for integrators without an assembled matrix (the
/// explicit ones and the fixed-iteration matrix-free backward Euler), after
/// the step, as in Provot (1995) and Bridson et al. (2002): a particle
/// ending closer than the thickness to a solid (at `t_next`) is moved back
/// to it along the normal of the side it came from, its velocity into the
/// solid is removed (an inelastic impulse `dv_n`), and its tangential
/// velocity relative to the solid loses at most `mu dv_n`, all of it when
/// that suffices (static friction: under gravity `dv_n = h g cos(theta)`
/// per step, so this is Coulomb's `mu m g cos(theta)`); the position moves
/// back by `h` times the tangential velocity removed. `x` are the
/// positions at the start of the step, at time `t`; the step is `h`. The
/// reported penetration is that of the start positions, as for the
/// implicit integrators.
pub fn collide_after_step(
    model: &ClothModel,
    x: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut ContactBuffers,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) -> ContactStats {
    let thickness = model.contact_thickness();
    let t_next = t + h;
    bufs.candidate.resize(x.len(), [None; 2]);
    let (solids_now, solids_next) =
        (bufs.now.at(model, &bufs.external, t), bufs.next.at(model, &bufs.external, t_next));
    let masses = model.masses();
    // Particles are independent; the counters add and the depth is a
    // maximum, so the parallel reduction is exact in any order.
    let stats = new_x
        .par_iter_mut()
        .zip(new_v.par_iter_mut())
        .zip(bufs.candidate.par_iter_mut())
        .enumerate()
        .with_min_len(ROW_CHUNK)
        .map(|(i, ((xi, vi), cand))| {
            let mut stats = ContactStats::default();
            *cand = [None; 2];
            if model.is_pinned(i) {
                return stats;
            }
            let mut slot = 0;
            for (k, (c, (now, next))) in model.colliders().iter().zip(solids_now.iter().zip(solids_next)).enumerate() {
                let Some((_, surface)) =
                    reach_surface(c, (next, h), x[i], *xi, thickness, &mut stats.narrow_phase_queries).within()
                else {
                    continue;
                };
                let before = c.shape.closest(now.pose(), x[i]);
                stats.max_penetration_m = stats.max_penetration_m.max(-before.distance_m);
                stats.narrow_phase_queries += 1;
                let n = surface.normal;
                let gap = n.dot(&(*xi - surface.point));
                if gap < thickness {
                    *xi += n * (thickness - gap);
                }
                let solid_v = next.velocity_at(surface.point);
                let rel = *vi - solid_v;
                let inward = n.dot(&rel);
                let v_before = *vi;
                if inward < 0.0 {
                    let tangential = rel - n * inward;
                    let speed = tangential.norm();
                    let budget = c.friction * -inward;
                    let slip = if speed <= budget { Vec3::zeros() } else { tangential * (1.0 - budget / speed) };
                    stats.sticking += usize::from(speed <= budget && c.friction > 0.0);
                    *vi = solid_v + slip;
                    // The step moved the particle with the velocity before
                    // friction: take back that part of the slide (x' = x + h v').
                    *xi += (slip - tangential) * h;
                }
                if slot < 2 {
                    let mut contact = contact(i, k, c, &surface, gap, 0.0, next);
                    contact.impulse_n_s = (*vi - v_before) * masses[i];
                    contact.normal_force_n = n.dot(&contact.impulse_n_s) / h;
                    cand[slot] = Some(contact);
                    slot += 1;
                }
                stats.contacts = 1;
            }
            stats
        })
        .reduce(ContactStats::default, |mut a, b| {
            a += b;
            a
        });
    bufs.solid.clear();
    bufs.solid.extend(bufs.candidate.iter().flatten().flatten());
    stats
}

/// Deepest any particle at positions `x` is inside a solid at time `t`, m
/// (0 when none is inside), with externally driven solids where `control`
/// puts them. A diagnostic: it queries every particle near every solid.
pub fn max_penetration(model: &ClothModel, control: &Control, x: &[Vec3], t: f64) -> f64 {
    let mut deepest: f64 = 0.0;
    let mut frames = SolidFrames::default();
    for (c, s) in model.colliders().iter().zip(frames.at(model, control.solid_motions(), t)) {
        for p in x.iter().filter(|p| s.near(p, 0.0)) {
            deepest = deepest.max(-c.shape.closest(s.pose(), *p).distance_m);
        }
    }
    deepest
}

/// The normal displacement over the step of a contact particle now at
/// distance `d` (m) from the solid's surface at `t + h`: particles closer
/// than the thickness go to it, particles arriving from beyond `reach`
/// land on it, and particles already within `(thickness, reach]` keep
/// their distance. Pulling those down to the thickness would take an
/// attractive force, so they would be released and re-solved every step;
/// holding them lets the cloth hover by at most the margin (0.25 mm for
/// a 5 mm thickness).
fn normal_travel(d: f64, thickness: f64, reach: f64) -> f64 {
    let target = if d > reach { thickness } else { d.max(thickness) };
    target - d
}

/// Solves `[1 c; c 1] (a, b) = (p, q)` with `c = n . m`: the coefficients
/// of the vector in span{n, m} whose components along unit `n` and `m`
/// are `p` and `q`.
fn two_direction_coefficients(n: &Vec3, m: &Vec3, p: f64, q: f64) -> (f64, f64) {
    let c = n.dot(m);
    let det = 1.0 - c * c;
    ((p - c * q) / det, (q - c * p) / det)
}

/// Constrains one particle from its contact entries: one active entry
/// prescribes the normal component, two prescribe both (motion stays free
/// along the crease), none frees the particle.
fn constrain_particle(
    group: &[SolidContact],
    x: &[Vec3],
    filter: &mut ConstraintFilter,
    value: &impl Fn(Vec3, usize) -> Vec3,
) {
    let i = group[0].particle as usize;
    let mut active = group.iter().filter(|c| c.active && !c.pressed);
    // A non-finite value is caught as a non-finite state after the step.
    let _ = match (active.next(), active.next()) {
        (None, _) => filter.set(i, Constraint::Free, Vec3::zeros()),
        (Some(c), None) if c.friction_mode == FrictionMode::Stick => {
            let z = value(x[i] + c.normal * c.normal_travel_m + c.tangent_travel_m, i);
            filter.set(i, Constraint::Fixed, z)
        }
        (Some(c), None) => {
            let z = value(x[i] + c.normal * c.normal_travel_m, i);
            filter.set(i, Constraint::OneDirection { normal: c.normal }, z)
        }
        (Some(a), Some(b)) => {
            let (p, q) = two_direction_coefficients(&a.normal, &b.normal, a.normal_travel_m, b.normal_travel_m);
            let z = value(x[i] + a.normal * p + b.normal * q, i);
            filter.set(i, Constraint::TwoDirections { n: a.normal, m: b.normal }, z)
        }
    };
}

/// Adds the contacts of `contacts` (sorted by particle) to `filter`: the
/// normal components of particle `i`'s unknown become those of
/// `value(target, i)`, where `target` is the position that ends the step
/// on the offset surface(s). Released contacts are skipped.
pub fn constrain_contacts(
    contacts: &[SolidContact],
    x: &[Vec3],
    filter: &mut ConstraintFilter,
    value: impl Fn(Vec3, usize) -> Vec3,
) {
    for range in groups(contacts) {
        if contacts[range.clone()].iter().any(|c| c.active) {
            constrain_particle(&contacts[range], x, filter, &value);
        }
    }
}

/// Puts the friction of every particle held by one solid alone (not
/// squeezed, not `prescribed` (pinned or held), with `mu > 0`, its
/// friction not yet in the solve) into the solve: a resting one starts
/// stuck ([`FrictionMode::Stick`]), moving with the surface over the step
/// `h` (s); a landing one (moving more than `LANDING_TRAVEL_M`, 1 mm, towards
/// the surface this step) starts sliding with no friction, which
/// [`stick_or_slide`] sets against its slip after the first solve (or
/// sticks it when it barely slips). Returns how many (constrain them
/// again, [`constrain_contacts`]).
/// Contacts found during the step's passes join too.
///
/// Solids whose motion from outside is a guess (`driven(collider)`:
/// [`crate::Control::set_solid_motion`], rapier's dynamic and fixed
/// bodies; not prescribed motions such as rig links, which are exact) keep
/// the friction after the solve. Their velocity over the step is the
/// co-simulation master's guess; a particle stuck to it hands the
/// body the whole cloth's tangential pull at once (up to `mu N`, with `N`
/// carrying the cloth's tension), and a body lighter than the cloth is
/// thrown by it between passes (`cloth study stability`, a ball of 1e-3
/// the cloth's mass: its energy rose 27% of the energy in play, 0 with the
/// friction after the solve).
pub fn stick_frictional_contacts(
    contacts: &mut [SolidContact],
    h: f64,
    prescribed: impl Fn(usize) -> bool,
    driven: impl Fn(usize) -> bool,
) -> usize {
    let mut stuck = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        let [c] = group else { continue };
        let eligible = c.active && !c.pressed && c.friction > 0.0 && c.friction_mode == FrictionMode::AfterSolve;
        if eligible && !driven(c.collider as usize) && !prescribed(c.particle as usize) {
            let n = c.normal;
            c.tangent_travel_m = (c.solid_velocity - n * n.dot(&c.solid_velocity)) * h;
            // A landing particle slides first (its friction set from its
            // slip after the first solve): stopped dead on landing it
            // would drag on its neighbours still in the air.
            let landing = c.normal_travel_m < -LANDING_TRAVEL_M;
            c.friction_mode = if landing { FrictionMode::Slide } else { FrictionMode::Stick };
            c.solve_constant_n = Vec3::zeros();
            stuck += 1;
        }
    }
    stuck
}

/// Travel towards a solid over a step beyond which a contact is landing,
/// not resting, m. A landing particle starts sliding: stuck at once it
/// stopped dead while its neighbours, not yet in contact, fell on (the
/// sphere drape's landing step stretched links to 1.46; sliding first,
/// 1.14, frictionless 1.13).
const LANDING_TRAVEL_M: f64 = 1e-3;

/// Slip along the friction over a step below which a sliding contact is
/// not taken as turned back (m): solver noise (the PCG's relative
/// tolerance of the step's motion), not motion.
const REVERSAL_SLIP_M: f64 = 1e-6;

/// Settles the friction in the solve after a solve (and after
/// [`release_pulling`] read the normal forces), from the solved new
/// positions `new_x`: a stuck contact whose tangential constraint force
/// `f_t` (the unfiltered residual) exceeds `mu N` slides from now on,
/// with the friction `mu N f_t / |f_t|` added to `rhs` (times
/// `force_coefficient`) and only its normal constrained; a sliding one
/// whose slip over the step (relative to the surface) went along its
/// friction was turned back by it, so it sticks, once a step: turned back
/// and then over its bound again it is at the bound (`|f_t| = mu N` with
/// next to no slip, where sticking and sliding meet), and it slides on
/// from then (in the Table-1 garments contacts went stick, slide, stick,
/// slide, stick pass after pass; allowed to turn back every time, the
/// passes never settled). One sliding on keeps its
/// direction (that of the force that would have stuck it: implicit
/// Coulomb friction) at the new `mu N`; a landed one takes `mu N` against
/// its slip (or sticks if it barely slipped); a released one, or one whose
/// particle now touches a second solid, goes back to the friction after
/// the solve. Returns how many changed between sticking and sliding (a
/// re-solve is due; the caller caps the passes).
#[allow(clippy::too_many_arguments)]
pub fn stick_or_slide(
    contacts: &mut [SolidContact],
    matrix: &BlockSparseMatrix,
    rhs: &mut [Vec3],
    (unknown, force_coefficient): (&[Vec3], f64),
    x: &[Vec3],
    new_x: &[Vec3],
    filter: &mut ConstraintFilter,
    value: impl Fn(Vec3, usize) -> Vec3,
) -> usize {
    let mut changed = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        let alone = group.len() == 1;
        for c in group.iter_mut().filter(|c| c.friction_mode != FrictionMode::AfterSolve) {
            let i = c.particle as usize;
            let (n, limit) = (c.normal, c.friction * c.normal_force_n.max(0.0));
            let before = c.friction_mode;
            let old = if c.friction_mode == FrictionMode::Slide { c.solve_constant_n } else { Vec3::zeros() };
            let friction = match c.friction_mode {
                // Released, or the particle now touches a second solid.
                _ if !c.active || !alone => {
                    rhs[i] -= old * force_coefficient;
                    (c.friction_mode, c.solve_constant_n) = (FrictionMode::AfterSolve, Vec3::zeros());
                    continue;
                }
                FrictionMode::Stick => {
                    let force = (matrix.row_times(i, unknown) - rhs[i]) / force_coefficient;
                    let tangential = force - n * n.dot(&force);
                    if tangential.norm() <= limit {
                        c.solve_constant_n = tangential;
                        continue;
                    }
                    c.friction_mode = FrictionMode::Slide;
                    tangential * (limit / tangential.norm())
                }
                FrictionMode::Slide => {
                    let moved = new_x[i] - x[i] - c.tangent_travel_m;
                    let slip = moved - n * n.dot(&moved);
                    match old.try_normalize(0.0) {
                        // Landed: against its slip, or stuck when it barely slips.
                        None if slip.norm() <= REVERSAL_SLIP_M => {
                            c.friction_mode = FrictionMode::Stick;
                            Vec3::zeros()
                        }
                        None => -slip.normalize() * limit,
                        Some(d) if slip.dot(&d) > REVERSAL_SLIP_M && !c.turned_back => {
                            (c.friction_mode, c.turned_back) = (FrictionMode::Stick, true);
                            Vec3::zeros()
                        }
                        Some(d) => d * limit,
                    }
                }
                FrictionMode::AfterSolve => unreachable!("filtered out"),
            };
            rhs[i] += (friction - old) * force_coefficient;
            c.solve_constant_n = friction;
            if before != c.friction_mode {
                constrain_particle(std::slice::from_ref(c), x, filter, &value);
            }
            if before != c.friction_mode || (old == Vec3::zeros() && friction != Vec3::zeros()) {
                changed += 1;
            }
        }
    }
    changed
}

/// Reads each contact's normal force from the unfiltered residual,
/// `f_c = (A u - b)_i / force_coefficient` (split along both normals for
/// a two-solid contact), and releases those that pull; the particle is
/// then re-constrained with what remains, through `value` as in
/// [`constrain_contacts`]. Returns how many were released.
#[allow(clippy::too_many_arguments)]
pub fn release_pulling(
    contacts: &mut [SolidContact],
    matrix: &BlockSparseMatrix,
    rhs: &[Vec3],
    unknown: &[Vec3],
    force_coefficient: f64,
    x: &[Vec3],
    filter: &mut ConstraintFilter,
    value: impl Fn(Vec3, usize) -> Vec3,
) -> usize {
    let mut released = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        let i = group[0].particle as usize;
        let mut active = (0..group.len()).filter(|&k| group[k].active && !group[k].pressed);
        let (first, second) = (active.next(), active.next());
        let Some(a) = first else { continue };
        // A squeezed particle's holding contact also carries the push of
        // the solid pressing from the other side (not part of the solve).
        let pressing: Vec3 = group.iter().filter(|c| c.active && c.pressed).map(|c| c.normal * c.normal_force_n).sum();
        let force = (matrix.row_times(i, unknown) - rhs[i]) / force_coefficient - pressing;
        match second {
            None => group[a].normal_force_n = group[a].normal.dot(&force),
            Some(b) => {
                let (na, nb) = (group[a].normal, group[b].normal);
                let (p, q) = two_direction_coefficients(&na, &nb, na.dot(&force), nb.dot(&force));
                (group[a].normal_force_n, group[b].normal_force_n) = (p, q);
            }
        }
        let mut changed = false;
        for k in [Some(a), second].into_iter().flatten() {
            let c = &mut group[k];
            if c.normal_force_n < 0.0 {
                (c.active, c.normal_force_n, changed) = (false, 0.0, true);
                released += 1;
            }
        }
        if changed && !group.iter().any(|c| c.active && !c.pressed) {
            // The holding solid let go: the pressing one holds instead.
            for c in group.iter_mut().filter(|c| c.active && c.pressed) {
                (c.pressed, c.normal_force_n) = (false, 0.0);
            }
        }
        if changed {
            constrain_particle(group, x, filter, &value);
        }
    }
    released
}

/// Slip speed above which a squeezed particle's friction goes into the
/// solve (m/s); slower ones stick or slip under [`apply_friction`] alone.
/// Sliding friction linearised near the point of sticking overshoots and
/// reverses: on the tablecloth fixture pulled slowly (0.1 m/s), a
/// threshold of 1 cm/s let the box alternate between slipping forwards
/// and back and lag 3 cm after 1 s; at 5 cm/s it follows within 5 mm.
const SLIDE_SPEED: f64 = 5e-2;

/// Coulomb friction of a sliding contact (Choi & Ko 2002, §5): the force
/// `f = -mu N u` against the slip direction `u = w / |w|` (`w` the slip
/// velocity in the tangent plane, m/s), with `limit = mu N` (N).
pub fn sliding_friction(slip: Vec3, limit_n: f64) -> Vec3 {
    -slip * (limit_n / slip.norm())
}

/// `-d f / d w` of [`sliding_friction`] within the tangent plane `P`
/// (projector), N s/m: `limit / |w| (P - u u^T)`. The force keeps its
/// magnitude and only turns with the slip.
fn sliding_friction_damping(slip: Vec3, limit_n: f64, tangent: &Mat3) -> Mat3 {
    let speed = slip.norm();
    let u = slip / speed;
    (tangent - u * u.transpose()) * (limit_n / speed)
}

/// Stiffness of a solid's penalty on a particle in Newton iterations, per
/// unit particle mass and per `1/h^2`: a particle meets the solid this
/// many times stiffer than its own inertia over one step (`m / h^2`). At
/// rest under its weight it sinks `g h^2 / CONTACT_PENALTY` into the
/// thickness: 0.4 mm at `h = 0.2 s`, a micrometre at 1/90 s. The
/// penalty adds `(4/9) CONTACT_PENALTY` times the mass to the matrix
/// diagonal (BDF2), which the block preconditioner takes in its stride.
const CONTACT_PENALTY: f64 = 1e3;

/// The penalty stiffness `k = CONTACT_PENALTY m / h^2` of a solid on a
/// particle of mass `m` (kg) in a step `h` (s), N/m.
pub fn contact_penalty_stiffness(mass_kg: f64, h: f64) -> f64 {
    CONTACT_PENALTY * mass_kg / (h * h)
}

/// A solid's penalty on a particle at gap `g` (m) from its surface, below
/// the contact thickness `e` (m): energy `k/2 (e - g)^2` (J), force
/// `k (e - g)` along the outward normal (N); zero beyond `e`. A penalty in
/// an implicit step's incremental potential, where Choi & Ko (2002, §5)
/// hold particles with constraints (see the `newton` module for why).
pub fn contact_penalty(gap_m: f64, thickness_m: f64, stiffness_n_m: f64) -> (f64, f64) {
    let depth = (thickness_m - gap_m).max(0.0);
    (0.5 * stiffness_n_m * depth * depth, stiffness_n_m * depth)
}

/// The contacts of a Newton iterate at positions `x_iter` (from `x` at the
/// start of the step) into `bufs.solid`, in particle order: each particle
/// (not pinned) closer than the thickness to a solid at `t_next` gets one
/// entry per such solid, on the solid's tangent plane at the closest point
/// of the iterate (of the start of the step, the side it came from, when
/// the iterate is inside), with `normal_force_n` its [`contact_penalty`]
/// force for the step `h`.
pub fn penalty_contacts(
    model: &ClothModel,
    x: &[Vec3],
    x_iter: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut ContactBuffers,
) {
    let thickness = model.contact_thickness();
    let (colliders, masses) = (model.colliders(), model.masses());
    let solids_next = bufs.next.at(model, &bufs.external, t + h);
    bufs.candidate.resize(x.len(), [None; 2]);
    bufs.candidate.par_iter_mut().enumerate().for_each(|(i, cand)| {
        *cand = [None; 2];
        if model.is_pinned(i) {
            return;
        }
        let mut found = 0;
        for (k, (c, next)) in colliders.iter().zip(solids_next).enumerate() {
            // No sweep (`h = 0`): the penalty acts on each iterate, and
            // choosing the face a solid swept over the start position
            // stretched the ball-through-curtain's Newton steps to 1.153
            // (1.109 with the face nearest the iterate).
            let Some((at, side)) = reach_surface(c, (next, 0.0), x[i], x_iter[i], thickness, &mut 0).within() else {
                continue;
            };
            let plane = if at.distance_m >= 0.0 { at } else { side };
            let gap = plane.normal.dot(&(x_iter[i] - plane.point));
            let (_, force) = contact_penalty(gap, thickness, contact_penalty_stiffness(masses[i], h));
            if force > 0.0 && found < 2 {
                let mut entry = contact(i, k, c, &plane, gap, 0.0, next);
                entry.normal_force_n = force;
                cand[found] = Some(entry);
                found += 1;
            }
        }
    });
    bufs.solid.clear();
    bufs.solid.extend(bufs.candidate.iter().flatten().flatten());
}

/// The solids a Newton correction `p` (unknown; positions move by `a p`)
/// would carry particles into, from the iterate `x_iter` whose contacts
/// [`penalty_contacts`] found: into `bufs.watch`, one entry per particle
/// whose full-step position `x_iter + a p` is closer than the thickness to
/// a solid it has no contact with, on the solid's tangent plane at the
/// point nearest the iterate (where the particle comes from, so its
/// penalty there is zero: the line's potential keeps the residual as its
/// slope). Without them the line search saw only the iterate's contacts:
/// an iterate just off a heavy ball moving into the cloth stepped its
/// particles deep into the ball (nothing to stop a full step), the next
/// pushed them out past the thickness, and Newton alternated between the
/// two for all 30 corrections, handing the coupling a 70 N penalty.
pub fn penalty_watch(model: &ClothModel, x_iter: &[Vec3], p: &[Vec3], a: f64, t_next: f64, bufs: &mut ContactBuffers) {
    let thickness = model.contact_thickness();
    let colliders = model.colliders();
    let solids_next = bufs.next.at(model, &bufs.external, t_next);
    bufs.watch.clear();
    for i in 0..x_iter.len() {
        if model.is_pinned(i) || p[i] == Vec3::zeros() {
            continue;
        }
        let end = x_iter[i] + p[i] * a;
        for (k, (c, next)) in colliders.iter().zip(solids_next).enumerate() {
            let touching = bufs.candidate[i].iter().flatten().any(|e| e.collider as usize == k);
            if touching {
                continue;
            }
            let Some((_, side)) = reach_surface(c, (next, 0.0), x_iter[i], end, thickness, &mut 0).within() else {
                continue;
            };
            let gap = side.normal.dot(&(x_iter[i] - side.point));
            bufs.watch.push(contact(i, k, c, &side, gap, 0.0, next));
        }
    }
}

/// The penalty energy of `contacts` ([`penalty_contacts`]) with particle
/// `i` at `x_i + beta p_i`, each on its frozen tangent plane, J.
pub fn contact_penalty_energy(
    contacts: &[SolidContact],
    model: &ClothModel,
    h: f64,
    x: &[Vec3],
    p: &[Vec3],
    beta: f64,
) -> f64 {
    let (thickness, masses) = (model.contact_thickness(), model.masses());
    contacts
        .iter()
        .map(|c| {
            let i = c.particle as usize;
            let gap = c.normal.dot(&(x[i] + p[i] * beta - c.point));
            contact_penalty(gap, thickness, contact_penalty_stiffness(masses[i], h)).0
        })
        .sum()
}

/// Slip speed below which [`smoothed_friction`] turns viscous, m/s. A
/// particle held by static friction creeps at most half of it while the
/// Newton iterations run; [`apply_friction`] then stops it exactly.
pub const FRICTION_SMOOTHING_M_S: f64 = 1e-3;

/// `F0(s)` of the smoothed Coulomb dissipation potential (Li et al. 2020,
/// "Incremental Potential Contact", §5.1), m/s: `s` for `s >= eps`,
/// `-s^3 / (3 eps^2) + s^2 / eps + eps / 3` below (C^1 at `eps`, convex).
fn smoothed_slip(s: f64, eps: f64) -> f64 {
    if s >= eps { s } else { -s * s * s / (3.0 * eps * eps) + s * s / eps + eps / 3.0 }
}

/// The dissipation potential of a contact's Coulomb friction, W:
/// `D(w) = mu N F0(|w|)` for the slip velocity `w` (m/s, in the tangent
/// plane) with `limit = mu N` (N). Its negative gradient is
/// [`smoothed_friction`]'s force.
pub fn smoothed_friction_potential(slip: Vec3, limit_n: f64, eps: f64) -> f64 {
    limit_n * smoothed_slip(slip.norm(), eps)
}

/// Coulomb friction smoothed at small slip (Li et al. 2020, §5.1):
/// `f = -mu N f1(s) w / s`, `s = |w|`, with `f1(s) = 1` for `s >= eps`
/// (Coulomb's sliding friction, [`sliding_friction`]) and
/// `2 s / eps - s^2 / eps^2` below (viscous at rest: `-2 mu N w / eps`).
/// Returns the force (N) and `C = -df/dv` within the tangent plane `P`
/// (projector), N s/m: `mu N [f1/s (P - u u^T) + f1' u u^T]`, `u = w / s`,
/// positive semidefinite. `limit = mu N`, N; `eps`, m/s.
pub fn smoothed_friction(slip: Vec3, limit_n: f64, eps: f64, tangent: &Mat3) -> (Vec3, Mat3) {
    let s = slip.norm();
    if s >= eps {
        return (sliding_friction(slip, limit_n), sliding_friction_damping(slip, limit_n, tangent));
    }
    let (f1_over_s, df1) = (2.0 / eps - s / (eps * eps), 2.0 / eps - 2.0 * s / (eps * eps));
    let uu = if s > 0.0 { slip * slip.transpose() / (s * s) } else { Mat3::zeros() };
    let damping = ((tangent - uu) * f1_over_s + uu * df1) * limit_n;
    (-slip * (limit_n * f1_over_s), damping)
}

/// Whether a contact's friction is a Newton iterate's smoothed friction:
/// active, holding (a pressed contact's friction is
/// [`linearise_squeeze_friction`]'s), with a coefficient.
fn holds_with_friction(c: &SolidContact) -> bool {
    c.active && !c.pressed && c.friction > 0.0
}

/// The holding contacts' [`smoothed_friction`] linearised about the
/// velocities `v` of a Newton iterate, each with the normal force
/// `normal_force(contact)` (N; lagged, Li et al. 2020 §5.2):
/// `f(v) ~ f(v_k) - C (v - v_k)`, `C` added to `damping` (N s/m) and
/// `f(v_k) + C v_k` to `external` (N), and kept on the contact
/// (`solve_damping`, `solve_constant_n`, `solve_limit_n`) so
/// [`contact_friction_potential`] and [`apply_friction`] know what the
/// solve applied.
pub fn linearise_contact_friction(
    contacts: &mut [SolidContact],
    v: &[Vec3],
    normal_force: impl Fn(&SolidContact) -> f64,
    damping: &mut [Mat3],
    external: &mut [Vec3],
) {
    for c in contacts.iter_mut().filter(|c| holds_with_friction(c)) {
        let i = c.particle as usize;
        let tangent = Mat3::identity() - c.normal * c.normal.transpose();
        let slip = tangent * (v[i] - c.solid_velocity);
        let limit = c.friction * normal_force(c).max(0.0);
        let (force, damp) = smoothed_friction(slip, limit, FRICTION_SMOOTHING_M_S, &tangent);
        // f(w_k) - C (w - w_k) with w = P (v - v_s) and C P = C.
        let constant = force + damp * v[i];
        damping[i] += damp;
        external[i] += constant;
        (c.solve_damping, c.solve_constant_n, c.solve_limit_n) = (damp, constant, limit);
    }
}

/// The holding contacts' friction dissipation
/// `sum mu N F0(|P (v + beta p - v_s)|)`, W ([`smoothed_friction_potential`]),
/// with the bounds `mu N` of the last [`linearise_contact_friction`].
pub fn contact_friction_potential(contacts: &[SolidContact], v: &[Vec3], p: &[Vec3], beta: f64) -> f64 {
    contacts
        .iter()
        .filter(|c| holds_with_friction(c))
        .map(|c| {
            let i = c.particle as usize;
            let w = v[i] + p[i] * beta - c.solid_velocity;
            let slip = w - c.normal * c.normal.dot(&w);
            smoothed_friction_potential(slip, c.solve_limit_n, FRICTION_SMOOTHING_M_S)
        })
        .sum()
}

/// Friction of squeezed particles that slide, inside the implicit solve:
/// [`sliding_friction`] linearised about the slip `w0 = P (v - v_s)` at
/// the start of the step, relative to the pressing solid (velocity `v_s`)
/// in the holding solid's tangent plane (`P = I - n n^T`), with `N` the
/// pressing force ([`squeeze_force`]): `f = f(w0) - C (w - w0)`, which is
/// `e - C v`; `C` is added to `damping` (N s/m) and `e` to `external`
/// (N). Only slips above [`SLIDE_SPEED`]. Why in the solve: a pressing
/// solid often rests on a few particles (a box on its leading edge), and
/// friction applied after the solve cannot exceed what stops that
/// particle alone (`m |w| / h`); in the solve its neighbours' links take
/// up the load and the full `mu N` reaches the cloth. A particle that
/// would stop within the step overshoots; [`apply_friction`] stops it. Returns whether any was added.
pub fn linearise_squeeze_friction(
    contacts: &mut [SolidContact],
    v: &[Vec3],
    damping: &mut [Mat3],
    external: &mut [Vec3],
) -> bool {
    let mut added = false;
    for group in contacts.chunk_by_mut(same_particle) {
        let Some(hold) = group.iter().find(|c| c.active && !c.pressed).map(|c| c.normal) else { continue };
        let tangent = Mat3::identity() - hold * hold.transpose();
        for c in group.iter_mut().filter(|c| c.pressed && c.friction > 0.0) {
            let i = c.particle as usize;
            let slip = tangent * (v[i] - c.solid_velocity);
            if slip.norm() <= SLIDE_SPEED {
                continue;
            }
            let limit = c.friction * c.normal_force_n;
            let damp = sliding_friction_damping(slip, limit, &tangent);
            // f(w0) - C (w - w0) with w = P (v - v_s), C P = C and C w0 = 0.
            let constant = sliding_friction(slip, limit) + damp * c.solid_velocity;
            damping[i] += damp;
            external[i] += constant;
            (c.solve_damping, c.solve_constant_n) = (damp, constant);
            added = true;
        }
    }
    added
}

/// The force each of [`linearise_squeeze_friction`]'s contacts exerted at
/// the solved velocities `v`, `e - C v`, N, into `solve_friction_n`.
pub fn squeeze_friction_forces(contacts: &mut [SolidContact], v: &[Vec3]) {
    for c in contacts.iter_mut() {
        c.solve_friction_n = c.solve_constant_n - c.solve_damping * v[c.particle as usize];
    }
}

/// The solids still holding each particle at the end of a step (active
/// constraint contacts, one or two; none for a squeezed particle, which
/// a penalty presses): `(first, second)` indices into `group`.
fn held_by(group: &[SolidContact]) -> Option<(usize, Option<usize>)> {
    if group.iter().any(|c| c.active && c.pressed) {
        return None;
    }
    let mut held = (0..group.len()).filter(|&k| group[k].active);
    held.next().map(|a| (a, held.next()))
}

/// The change `d` in span{`na`, `nb`} (`nb` only for a particle held by two
/// solids) with `na . d = p` and `nb . d = q`, as `(d_a, d_b)` along each.
fn along_normals(na: Vec3, nb: Option<Vec3>, p: f64, q: f64) -> (Vec3, Vec3) {
    match nb {
        None => (na * p, Vec3::zeros()),
        Some(nb) => {
            let (a, b) = two_direction_coefficients(&na, &nb, p, q);
            (na * a, nb * b)
        }
    }
}

/// No bounce off a holding solid: a particle that a solid still holds at
/// the end of a step (Choi & Ko 2002, §5: its displacement along the
/// normal prescribed) does not leave the step moving away from it; the
/// outward part of its normal velocity relative to the solid (to each
/// solid in a crease) is removed and the solid's impulse takes the change
/// of momentum `m dv` (N s). The constraint put the particle on the
/// surface, but the step's velocity differentiates across the impact:
/// BDF2's `(3 dx - delta) / (2h)` sent a particle pushed back 0.4 mm
/// after falling 0.4 mm the step before off at 70 mm/s (a restitution of
/// about a half), and it landed again two steps later: half the Table-1
/// one-piece's contacts and a quarter of the sphere drape's were made and
/// lost every other step, with friction every other step. An inward
/// velocity is left (the constraint holds the particle next step too):
/// stopped as well, a landing particle stopped dead while the cloth
/// behind it fell on, and the V-groove's landing stretched links to 1.28
/// (1.14 with the inward velocity left, 1.13 before).
/// See [`restart_history_at_contacts`].
pub fn stop_separation(contacts: &mut [SolidContact], masses: &[f64], new_v: &mut [Vec3]) {
    for group in contacts.chunk_by_mut(same_particle) {
        let Some((a, b)) = held_by(group) else { continue };
        let i = group[a].particle as usize;
        let leaving = |c: &SolidContact| c.normal.dot(&(new_v[i] - c.solid_velocity)).max(0.0);
        let (p, q) = (leaving(&group[a]), b.map_or(0.0, |b| leaving(&group[b])));
        if p == 0.0 && q == 0.0 {
            continue;
        }
        let (dv_a, dv_b) = along_normals(group[a].normal, b.map(|b| group[b].normal), -p, -q);
        new_v[i] += dv_a + dv_b;
        group[a].impulse_n_s += dv_a * masses[i];
        if let Some(b) = b {
            group[b].impulse_n_s += dv_b * masses[i];
        }
    }
}

/// Restarts BDF2's history along the normal(s) of each particle a solid
/// held over the step just committed (see [`stop_separation`]): its
/// previous position becomes `x - h v` and its previous velocity `v`
/// along them, as if it had moved at `v` all along. The two-step formula
/// otherwise carries the impact into the next step: the displacement
/// `delta` that pushed the particle out and the landing velocity in
/// `v_prev` make its free prediction `delta / 3 + h (8 v - 2 v_prev) / 9`
/// leave the surface again (a cloth dropped flat onto the floor, held
/// and stopped on landing, was off it entirely two steps later).
/// Tangential history is kept.
pub fn restart_history_at_contacts(
    contacts: &[SolidContact],
    h: f64,
    (x, v): (&[Vec3], &[Vec3]),
    (x_prev, v_prev): (&mut [Vec3], &mut [Vec3]),
) {
    for group in contacts.chunk_by(same_particle) {
        let Some((a, b)) = held_by(group) else { continue };
        let i = group[a].particle as usize;
        let (na, nb) = (group[a].normal, b.map(|b| group[b].normal));
        let along = |d: Vec3| {
            let (da, db) = along_normals(na, nb, na.dot(&d), nb.map_or(0.0, |nb| nb.dot(&d)));
            da + db
        };
        x_prev[i] += along(x[i] - v[i] * h - x_prev[i]);
        v_prev[i] += along(v[i] - v_prev[i]);
    }
}

/// Coulomb friction on the new state, per particle in contact: each solid
/// `k` it touches drags it towards the solid's velocity `v_k` in the
/// particle's free directions (the tangent plane; the crease for two
/// solids at an angle; the plane for a particle squeezed between two
/// opposite solids) by at most `mu_k f_k tau / m`, `f_k` the normal force
/// of that contact and `mu_k` its coefficient. With one solid the
/// relative velocity stops when that is enough (static regime) and loses
/// exactly that much otherwise. With two, the new velocity `w` minimises
/// `m/(2 tau) |w - v|^2 + sum_k mu_k f_k |w - v_k|` over the free
/// directions (implicit Coulomb friction against both surfaces), found by
/// projected Gauss-Seidel on the two changes ([`FRICTION_SWEEPS`] sweeps).
/// Positions move by `tau` times the change. `tau` is the time over which
/// a force changes the new velocity in the integrator (`h` for backward
/// Euler, `2h/3` for BDF2), so each friction force is exactly `mu_k f_k`
/// while sliding. Friction already applied in the solve
/// (`solve_friction_n`, see [`linearise_squeeze_friction`]) stays; its
/// contact may only stop a particle it pushed past the solid's velocity
/// (an overshoot). Each contact's `impulse_n_s` becomes its normal
/// force plus its own friction force, times the step `h`. Returns how
/// many particles stick to a solid.
pub fn apply_friction(
    contacts: &mut [SolidContact],
    masses: &[f64],
    (tau, h): (f64, f64),
    solved: bool,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) -> usize {
    let mut sticking = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        for c in group.iter_mut() {
            c.impulse_n_s = if c.active { c.normal * (c.normal_force_n * h) } else { Vec3::zeros() };
        }
        if let [c] = group
            && c.active
            && c.friction_mode != FrictionMode::AfterSolve
        {
            // Decided in the solve: the stuck contact's tangential
            // constraint force, or the sliding one's `mu N`.
            c.impulse_n_s += c.solve_constant_n * h;
            sticking += usize::from(c.friction_mode == FrictionMode::Stick);
            continue;
        }
        let mut active = group.iter().enumerate().filter(|(_, c)| c.active).map(|(k, _)| k);
        let Some(a) = active.next() else { continue };
        let b = active.next();
        let i = group[a].particle as usize;
        let squeezed = group[a].pressed || b.is_some_and(|b| group[b].pressed);
        let (na, nb) = (group[a].normal, b.map(|b| group[b].normal));
        let free = |u: Vec3| match nb {
            Some(nb) if !squeezed => {
                let crease = na.cross(&nb).normalize();
                crease * crease.dot(&u)
            }
            _ => u - na * na.dot(&u),
        };
        if squeezed {
            // The pressing force's part in the holding solid's tangent
            // plane moves the particle (its normal part the holding
            // solid carries, see `release_pulling`), as far as relieves
            // the overlap it was computed from and no further: as the
            // velocity change `f tau / m` of the particle alone, the
            // penalty's stiffness (`SQUEEZE m / h^2`) moved it 44 times
            // the overlap (a skirt particle of the Table-1 dress caught
            // where a thigh meets the pelvis: 10 cm in one step).
            for c in group.iter().filter(|c| c.active && c.pressed) {
                let push = free(c.normal);
                let overlap = squeeze_overlap(c.normal_force_n, masses[i], h);
                // Moving by `s push` changes the gap by `s |push|^2`.
                let relieving = overlap / push.norm_squared().max(f64::MIN_POSITIVE);
                let dx = push * (c.normal_force_n * tau * tau / masses[i]).min(relieving);
                new_v[i] += dx / tau;
                new_x[i] += dx;
            }
        }
        if group[a].friction <= 0.0 && b.is_none_or(|b| group[b].friction <= 0.0) {
            continue;
        }
        if solved && !squeezed {
            // Newton iterations solved this friction with the rest of the
            // cloth (the velocity change `f tau / m` would be that of the
            // particle alone: 100 m/s at h = 0.2 s). What remains is the
            // smoothing's creep below `FRICTION_SMOOTHING_M_S`: stopped.
            let slip = free(new_v[i] - group[a].solid_velocity);
            let stick = slip.norm() < FRICTION_SMOOTHING_M_S;
            let dv = if stick { -slip } else { Vec3::zeros() };
            new_v[i] += dv;
            new_x[i] += dv * tau;
            group[a].impulse_n_s += (group[a].solve_friction_n + dv * (masses[i] / tau)) * h;
            if let Some(b) = b {
                group[b].impulse_n_s += group[b].solve_friction_n * h;
            }
            sticking += usize::from(stick);
            continue;
        }
        // Each contact's bound on the change: `mu N tau / m`, or, for
        // friction the solve applied (`linearise_squeeze_friction`, kept
        // from the step's start when the particle is no longer squeezed),
        // only what stops an overshoot (the slip now runs along that
        // friction: the particle would have stopped within the step).
        // That friction is not taken out as the velocity change
        // `f tau / m` of the particle alone: the solve shared it with the
        // neighbours' links, and for a 26 mg particle of the Table-1 dress
        // `f tau / m` was 30 m/s (it jumped 22 cm in one step).
        let budget = |c: &SolidContact| {
            if c.solve_friction_n == Vec3::zeros() {
                return c.friction * c.normal_force_n.max(0.0) * tau / masses[i];
            }
            let slip = free(new_v[i] - c.solid_velocity);
            if slip.dot(&c.solve_friction_n) > 0.0 { slip.norm() } else { 0.0 }
        };
        // The change that would make the particle move with each solid.
        let to_a = free(group[a].solid_velocity - new_v[i]);
        let to_b = b.map(|b| free(group[b].solid_velocity - new_v[i]));
        let (budget_a, budget_b) = (budget(&group[a]), b.map_or(0.0, |b| budget(&group[b])));
        let clamp = |u: Vec3, limit: f64| if u.norm() <= limit { u } else { u * (limit / u.norm()) };
        let (mut dv_a, mut dv_b) = (clamp(to_a, budget_a), Vec3::zeros());
        if let Some(to_b) = to_b {
            for _ in 0..FRICTION_SWEEPS {
                dv_b = clamp(to_b - dv_a, budget_b);
                dv_a = clamp(to_a - dv_b, budget_a);
            }
        }
        let dv = dv_a + dv_b;
        new_v[i] += dv;
        new_x[i] += dv * tau;
        // A friction force is m dv / tau; over the step it gives h times that.
        let scale = masses[i] * h / tau;
        group[a].impulse_n_s += group[a].solve_friction_n * h + dv_a * scale;
        if let Some(b) = b {
            group[b].impulse_n_s += group[b].solve_friction_n * h + dv_b * scale;
        }
        let sticks = |dv: &Vec3, limit: f64| limit > 0.0 && dv.norm() < limit;
        sticking += usize::from(sticks(&dv_a, budget_a) || sticks(&dv_b, budget_b));
    }
    sticking
}

/// Sweeps of [`apply_friction`]'s projected Gauss-Seidel for a particle
/// against two solids: two suffice when both slide or one sticks; the rest
/// settle the case where the particle's velocity lies between the two
/// solids'. Fixed, so results do not depend on a tolerance.
const FRICTION_SWEEPS: usize = 16;

/// Whether particles `a` and `b` share a link (they never repel).
fn linked(model: &ClothModel, a: usize, b: usize) -> bool {
    model.incidence(a).iter().any(|inc| inc.other as usize == b)
}

/// Finds self-collision pairs at positions `x` into `bufs.self_pairs` and
/// the repulsion forces and diagonal stiffness into `bufs.self_force` and
/// `bufs.self_stiffness`. Returns the particle at fault if a position is
/// not finite.
///
/// Pairs are gathered within 1.5 thicknesses plus the distance the two
/// particles cover towards each other at their speeds in the step `h`
/// (up to the voxel size), so
/// [`separate_self_contacts`] can still tell which side each particle
/// was on after the step. Particle pairs closer than the thickness repel
/// unless linked. With
/// `point_triangle`, each particle also finds its nearest triangle (not
/// containing it or a particle linked to it) whose closest point is inside
/// the triangle or on an edge (vertices are the particle pairs' job), so
/// a particle cannot slip through the middle of a quad.
pub fn detect_self_contacts(
    model: &ClothModel,
    sc: &SelfCollision,
    x: &[Vec3],
    v: &[Vec3],
    h: f64,
    bufs: &mut ContactBuffers,
) -> Result<ContactStats, usize> {
    let n = x.len();
    let fastest = v.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let radius = (SELF_SLACK * sc.thickness_m + 2.0 * h * fastest).min(sc.voxel_m);
    // Taken out of the buffers while they are filled; put back below.
    let mut hash = match bufs.hash.take() {
        Some(hash) => hash,
        None => VoxelHash::new(sc.voxel_m).map_err(|_| 0usize)?,
    };
    hash.insert_points(x).map_err(|e| match e {
        cloth_collide::BroadPhaseError::NonFinite { index, .. } => index,
        cloth_collide::BroadPhaseError::InvalidVoxelSize(_) => 0,
    })?;
    let th = sc.thickness_m;
    bufs.self_pairs.clear();
    // A pair is kept when it could close the gap to the thickness within
    // the step: its distance is below the thickness (with some slack for
    // accelerations) plus what the two particles travel at their speeds.
    let reach = |d: f64, speed: f64| d < SELF_SLACK * th + h * speed;
    // The cell table in fixed chunks, in parallel; the union sorted, so
    // the pairs do not depend on the number of threads.
    let slot_chunks = hash.table_slots().div_ceil(SLOT_CHUNK);
    bufs.pair_chunks.resize_with(slot_chunks, Vec::new);
    bufs.pair_chunks.par_iter_mut().enumerate().for_each(|(k, pairs)| {
        pairs.clear();
        let slots = k * SLOT_CHUNK..((k + 1) * SLOT_CHUNK).min(hash.table_slots());
        hash.pairs_from_slots(slots, radius, |a, b| linked(model, a as usize, b as usize), pairs);
    });
    bufs.candidate_pairs.clear();
    bufs.candidate_pairs.extend(bufs.pair_chunks.iter().flatten());
    bufs.candidate_pairs.sort_unstable();
    for &(a, b) in &bufs.candidate_pairs {
        let (a, b) = (a as usize, b as usize);
        let diff = x[a] - x[b];
        let d = diff.norm();
        if !reach(d, v[a].norm() + v[b].norm()) {
            continue;
        }
        let direction = if d > 1e-12 * th {
            diff / d
        } else {
            // Coincident: separate along the rest-shape direction.
            (model.rest_positions()[a] - model.rest_positions()[b]).normalize()
        };
        bufs.self_pairs.push(SelfContact {
            particle: a as u32,
            others: [b as u32; 3],
            weights: [1.0, 0.0, 0.0],
            direction,
            distance_m: d,
            repels: true,
        });
    }
    if sc.point_triangle {
        point_triangle_contacts(model, radius, x, &hash, bufs, |p, tri, d| {
            reach(d, v[p].norm() + tri.iter().map(|&c| v[c as usize].norm()).fold(0.0, f64::max))
        });
    }
    bufs.hash = Some(hash);
    bufs.self_force.resize(n, Vec3::zeros());
    bufs.self_stiffness.resize(n, Mat3::zeros());
    bufs.self_force.iter_mut().for_each(|f| *f = Vec3::zeros());
    bufs.self_stiffness.iter_mut().for_each(|k| *k = Mat3::zeros());
    for c in bufs.self_pairs.iter().filter(|c| c.repels) {
        let law = laws::repulsion(c.distance_m, th, sc.stiffness_n_m);
        // phi < 0: the particle is pushed along `direction`, the other side back.
        let f = c.direction * -law.phi;
        let block = pair_stiffness(&c.direction, c.distance_m, &law, false);
        let p = c.particle as usize;
        bufs.self_force[p] += f;
        bufs.self_stiffness[p] += block;
        for (&o, &w) in c.others.iter().zip(&c.weights) {
            if w != 0.0 {
                bufs.self_force[o as usize] -= f * w;
                bufs.self_stiffness[o as usize] += block * (w * w);
            }
        }
    }
    let touching = bufs.self_pairs.iter().filter(|c| c.repels && c.distance_m < th).count();
    Ok(ContactStats { self_contacts: touching, hash_builds: 1, ..Default::default() })
}

/// Self-collision pairs are gathered up to this many thicknesses (plus
/// the distance the pair can close in the step).
const SELF_SLACK: f64 = 1.5;

/// Fraction of the self-collision thickness below which
/// [`separate_self_contacts`] pushes pairs apart after a step.
pub const MIN_SELF_GAP: f64 = 0.75;

/// After a step: every self-collision pair found at the start whose gap,
/// measured along its start-of-step direction (so a particle that crossed
/// the other layer has a negative gap), fell below `MIN_SELF_GAP` times the
/// thickness is pushed apart to it, momentum-conserving with inverse-mass
/// weights (a few Gauss-Seidel passes), no particle by more than the gap's
/// deficit; velocities change by the position change over `tau`, as for
/// friction. This is the safety net behind the
/// repulsion forces for impacts faster than one step can resolve.
/// Returns the number of corrections.
pub fn separate_self_contacts(
    model: &ClothModel,
    sc: &SelfCollision,
    pairs: &[SelfContact],
    tau: f64,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) -> usize {
    const PASSES: usize = 4;
    let target = MIN_SELF_GAP * sc.thickness_m;
    let inv_mass = |i: usize| if model.is_pinned(i) { 0.0 } else { 1.0 / model.masses()[i] };
    let mut corrections = 0;
    for _ in 0..PASSES {
        let mut any = false;
        for c in pairs {
            let p = c.particle as usize;
            let other =
                c.others.iter().zip(&c.weights).fold(Vec3::zeros(), |acc, (&o, &w)| acc + new_x[o as usize] * w);
            let gap = (new_x[p] - other).dot(&c.direction);
            if gap >= target {
                continue;
            }
            let w_sum =
                inv_mass(p) + c.others.iter().zip(&c.weights).map(|(&o, &w)| w * w * inv_mass(o as usize)).sum::<f64>();
            if w_sum <= 0.0 {
                continue;
            }
            let deficit = target - gap;
            let lambda = deficit / w_sum;
            // No particle moves further than the gap it closes. This binds
            // only when the particle is pinned or more than 4 times as heavy
            // as a corner it pushes (w (1 - w) / m_o <= 1 / m_p otherwise):
            // then a triangle whose nearest corner is pinned moves its free
            // corners almost alone, and with their small weights w the
            // projection would throw them by deficit / w.
            let mut push = |i: usize, amount: f64| {
                let dx = c.direction * amount.clamp(-deficit, deficit);
                new_x[i] += dx;
                new_v[i] += dx / tau;
            };
            push(p, lambda * inv_mass(p));
            for (&o, &w) in c.others.iter().zip(&c.weights) {
                if w != 0.0 {
                    push(o as usize, -lambda * w * inv_mass(o as usize));
                }
            }
            corrections += 1;
            any = true;
        }
        if !any {
            break;
        }
    }
    corrections
}

/// Particle-triangle pairs within `radius` (see [`detect_self_contacts`])
/// kept when `keep(particle, triangle, distance)`; each particle's nearest
/// triangle repels it (one force per particle: a particle over an edge
/// would otherwise be pushed by both triangles), all are kept apart after
/// the step.
fn point_triangle_contacts(
    model: &ClothModel,
    radius: f64,
    x: &[Vec3],
    hash: &VoxelHash,
    bufs: &mut ContactBuffers,
    keep: impl Fn(usize, [u32; 3], f64) -> bool + Sync,
) {
    let triangles = model.triangles();
    if bufs.excluded_ptr.len() != triangles.len() + 1 {
        build_exclusions(model, &mut bufs.excluded_ptr, &mut bufs.excluded);
    }
    bufs.corners.clear();
    bufs.corners.extend(triangles.iter().map(|t| t.map(|k| x[k as usize])));
    let (excluded_ptr, excluded) = (&bufs.excluded_ptr, &bufs.excluded);
    // Triangles in fixed chunks, in parallel; each chunk keeps its own
    // buffers (reused across steps) and the chunks are merged in order, so
    // the result does not depend on the number of threads.
    let chunks = triangles.len().div_ceil(TRIANGLE_CHUNK);
    bufs.triangle_chunks.resize_with(chunks, Default::default);
    let corners = &bufs.corners;
    bufs.triangle_chunks.par_iter_mut().enumerate().for_each(|(k, (candidates, found))| {
        found.clear();
        let first = k * TRIANGLE_CHUNK;
        let mine = &corners[first..(first + TRIANGLE_CHUNK).min(corners.len())];
        if hash.point_triangle_candidates_into(mine, radius, candidates).is_err() {
            return;
        }
        for &(p, t_local) in candidates.iter() {
            let t = first + t_local as usize;
            let (p, tri) = (p as usize, triangles[t]);
            let never = &excluded[excluded_ptr[t] as usize..excluded_ptr[t + 1] as usize];
            if never.binary_search(&(p as u32)).is_ok() {
                continue;
            }
            let [a, b, c] = corners[t];
            let (q, w) = closest_point_on_triangle(x[p], a, b, c);
            let d = (x[p] - q).norm();
            let at_vertex = w.iter().any(|&wk| wk > 1.0 - 1e-9);
            if d >= radius || at_vertex || !keep(p, tri, d) {
                continue;
            }
            let normal = (b - a).cross(&(c - a));
            let direction = if d > 1e-12 * radius {
                (x[p] - q) / d
            } else if normal.norm() > 0.0 {
                normal.normalize()
            } else {
                continue;
            };
            found.push(SelfContact {
                particle: p as u32,
                others: tri,
                weights: w,
                direction,
                distance_m: d,
                repels: false,
            });
        }
    });
    bufs.nearest.clear();
    bufs.nearest.resize(x.len(), u32::MAX);
    for (_, found) in &bufs.triangle_chunks {
        for contact in found {
            let p = contact.particle as usize;
            let nearest = bufs.nearest[p] as usize;
            if bufs.self_pairs.get(nearest).is_none_or(|old| contact.distance_m < old.distance_m) {
                bufs.nearest[p] = bufs.self_pairs.len() as u32;
            }
            bufs.self_pairs.push(*contact);
        }
    }
    for &k in bufs.nearest.iter().filter(|&&k| k != u32::MAX) {
        bufs.self_pairs[k as usize].repels = true;
    }
}

/// For each triangle, the sorted particles it never repels: its corners
/// and the particles linked to a corner.
fn build_exclusions(model: &ClothModel, ptr: &mut Vec<u32>, list: &mut Vec<u32>) {
    ptr.clear();
    list.clear();
    ptr.push(0);
    for tri in model.triangles() {
        let start = list.len();
        for &c in tri {
            list.push(c);
            list.extend(model.incidence(c as usize).iter().map(|inc| inc.other));
        }
        list[start..].sort_unstable();
        let mut unique = start;
        for k in start..list.len() {
            if k == start || list[k] != list[unique - 1] {
                list[unique] = list[k];
                unique += 1;
            }
        }
        list.truncate(unique);
        ptr.push(list.len() as u32);
    }
}

/// Scratch of one chunk of the particle-triangle search: broad-phase
/// candidates `(particle, triangle within the chunk)` and the pairs found.
type TriangleChunk = (Vec<(u32, u32)>, Vec<SelfContact>);

/// Triangles per parallel chunk of the particle-triangle search.
const TRIANGLE_CHUNK: usize = 256;

/// Slots of the spatial hash's cell table per parallel task of the point
/// pairs (the table has two to four slots a particle).
const SLOT_CHUNK: usize = 1024;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CollisionSpec, Effects, GridPanel, Material, ModelSpec, SelfCollisionSpec};

    /// Two parallel 3 x 3 sheets `gap` apart (z), self-collision on.
    fn two_sheets(gap: f64) -> (ClothModel, Vec<Vec3>) {
        let sheet = |z: f64| GridPanel {
            particles: [3, 3],
            size_m: [0.04, 0.04],
            origin_m: [0.0, 0.0, z],
            u_axis: [1.0, 0.0, 0.0],
            v_axis: [0.0, 1.0, 0.0],
            wrap_u: false,
        };
        let spec = ModelSpec {
            panels: vec![sheet(0.0), sheet(gap)],
            material: Material::default(),
            effects: Effects::default(),
            collision: CollisionSpec {
                self_collision: Some(SelfCollisionSpec {
                    thickness_m: 0.01,
                    stiffness_n_m: Some(50.0),
                    point_triangle: true,
                }),
                ..CollisionSpec::default()
            },
            ..ModelSpec::default()
        };
        let model = ClothModel::build(&spec).unwrap();
        let x = model.rest_positions().to_vec();
        (model, x)
    }

    /// The two sheets 6 mm apart, the top one shifted so particles sit over
    /// triangle interiors too, at rest, with their self-collision pairs.
    fn overlapping_sheets() -> (ClothModel, SelfCollision, Vec<Vec3>, ContactBuffers, ContactStats) {
        let (model, mut x) = two_sheets(0.006);
        for p in &mut x[9..] {
            *p += Vec3::new(0.006, 0.004, 0.0);
        }
        let sc = *model.self_collision().unwrap();
        let v = vec![Vec3::zeros(); x.len()];
        let mut bufs = ContactBuffers::default();
        let stats = detect_self_contacts(&model, &sc, &x, &v, 0.01, &mut bufs).unwrap();
        (model, sc, x, bufs, stats)
    }

    fn energy(model: &ClothModel, bufs: &ContactBuffers, x: &[Vec3]) -> f64 {
        let sc = model.self_collision().unwrap();
        let p = |c: &SelfContact| {
            let other = c.others.iter().zip(&c.weights).fold(Vec3::zeros(), |a, (&o, &w)| a + x[o as usize] * w);
            (x[c.particle as usize] - other).norm()
        };
        let repelling = bufs.self_pairs.iter().filter(|c| c.repels);
        repelling.map(|c| laws::repulsion(p(c), sc.thickness_m, sc.stiffness_n_m).energy).sum()
    }

    /// Repulsion forces are minus the gradient of the repulsion energy (pairs
    /// and barycentric weights held fixed), sum to zero (momentum), and the
    /// diagonal stiffness is the derivative along the repelling direction.
    #[test]
    fn self_repulsion_is_conservative_and_momentum_free() {
        let (model, sc, x, bufs, stats) = overlapping_sheets();
        assert!(stats.self_contacts > 4, "{stats:?}");
        assert!(bufs.self_pairs.iter().any(|c| c.weights[1] > 0.0), "no particle-triangle pair");
        let total: Vec3 = bufs.self_force.iter().sum();
        assert!(total.norm() < 1e-12, "net force {total}");
        let eps = 1e-7;
        for i in [0, 4, 9, 13] {
            for axis in 0..3 {
                let mut xp = x.clone();
                let mut xm = x.clone();
                xp[i][axis] += eps;
                xm[i][axis] -= eps;
                let fd = -(energy(&model, &bufs, &xp) - energy(&model, &bufs, &xm)) / (2.0 * eps);
                assert!((fd - bufs.self_force[i][axis]).abs() < 1e-6, "particle {i} axis {axis}: {fd}");
            }
        }
        // The kept stiffness, summed from the pairs as documented: each
        // touching pair adds `w^2 k_r u u^T` to each of its particles (weight
        // 1 for the particle, the barycentric weights for the others), with
        // nothing orthogonal to `u` (that part, `phi / d`, is negative).
        let mut expected = vec![Mat3::zeros(); x.len()];
        for c in bufs.self_pairs.iter().filter(|c| c.repels && c.distance_m < sc.thickness_m) {
            let uu = c.direction * c.direction.transpose() * sc.stiffness_n_m;
            expected[c.particle as usize] += uu;
            for (&o, &w) in c.others.iter().zip(&c.weights) {
                expected[o as usize] += uu * (w * w);
            }
        }
        let worst = (0..x.len()).map(|i| (bufs.self_stiffness[i] - expected[i]).norm()).fold(0.0, f64::max);
        assert!(worst < 1e-12 * sc.stiffness_n_m, "self-collision stiffness off the pairs' sum by {worst:e}");
        assert!(expected.iter().filter(|s| s.norm() > 0.0).count() > 8, "too few particles touch");
    }

    /// The push-apart after a step conserves linear momentum and the centre
    /// of mass (inverse-mass weights, barycentric weights summing to one)
    /// and leaves every pair it corrected at least `MIN_SELF_GAP` of the
    /// thickness apart along its direction (README: "momentum-conserving").
    /// Measured: the centre moves 3.7e-18 m and its velocity changes by
    /// 4.7e-17 m/s over 25 corrections, every pair exactly at the target.
    /// A push that moves only the particle and not the other side fails
    /// (8.7e-4 m, 8.7e-2 m/s).
    #[test]
    fn self_separation_conserves_momentum_and_restores_the_gap() {
        let (model, sc, x, bufs, _) = overlapping_sheets();
        // The step brought the top sheet 4 mm down and set everything moving.
        let mut new_x = x.clone();
        let mut new_v: Vec<Vec3> =
            (0..x.len()).map(|i| Vec3::new(0.1 * i as f64, -0.2, 0.05 * (i % 3) as f64)).collect();
        for p in &mut new_x[9..] {
            p.z -= 0.004;
        }
        let m = model.masses();
        let moments = |x: &[Vec3], v: &[Vec3]| -> (Vec3, Vec3) {
            (0..x.len()).fold((Vec3::zeros(), Vec3::zeros()), |(c, p), i| (c + x[i] * m[i], p + v[i] * m[i]))
        };
        let (c0, p0) = moments(&new_x, &new_v);
        let corrections = separate_self_contacts(&model, &sc, &bufs.self_pairs, 0.01, &mut new_x, &mut new_v);
        let (c1, p1) = moments(&new_x, &new_v);
        let mass: f64 = m.iter().sum();
        let (dc, dp) = ((c1 - c0).norm() / mass, (p1 - p0).norm() / mass);
        eprintln!("{corrections} corrections; centre moved {dc:.1e} m, velocity of the centre changed {dp:.1e} m/s");
        assert!(corrections > 4, "{corrections} corrections");
        assert!(dc < 1e-17 && dp < 1e-16, "centre moved {dc} m, its velocity changed by {dp} m/s");
        let target = MIN_SELF_GAP * sc.thickness_m;
        let closest = bufs.self_pairs.iter().fold(f64::INFINITY, |least, c| {
            let other = c.others.iter().zip(&c.weights).fold(Vec3::zeros(), |a, (&o, &w)| a + new_x[o as usize] * w);
            least.min((new_x[c.particle as usize] - other).dot(&c.direction))
        });
        assert!(closest >= target * (1.0 - 1e-9), "a pair at {closest} m");
    }

    /// Particle 0 held on solid 0 at the origin: outward `normal`, the
    /// solid moving at `solid_velocity` (m/s), Coulomb `friction`, normal
    /// force `normal_force_n` (N).
    fn touching(normal: Vec3, solid_velocity: Vec3, friction: f64, normal_force_n: f64) -> SolidContact {
        SolidContact { normal_force_n, ..SolidContact::new(0, 0, Vec3::zeros(), normal, solid_velocity, friction) }
    }

    /// The squeezed particle's friction in the solve, `e - C v`, is the
    /// sliding force at the start velocity and follows it to first order
    /// as the slip turns (C against central differences); a slip below
    /// `SLIDE_SPEED` adds nothing.
    #[test]
    fn squeeze_friction_linearisation_matches_the_law() {
        let mut hold = touching(Vec3::new(0.0, 0.6, 0.8), Vec3::zeros(), 0.3, 1.0);
        let mut press = hold;
        (press.collider, press.normal, press.pressed) = (1, -hold.normal, true);
        (press.solid_velocity, press.friction, press.normal_force_n) = (Vec3::new(0.2, -0.1, 0.3), 0.4, 2.5);
        hold.solid_velocity = Vec3::new(1.0, 2.0, 3.0);
        let v0 = Vec3::new(1.3, 0.4, -0.2);
        let mut contacts = [hold, press];
        let (mut damping, mut external) = ([Mat3::zeros()], [Vec3::new(0.5, 0.0, 0.0)]);
        assert!(linearise_squeeze_friction(&mut contacts, &[v0], &mut damping, &mut external));
        let n = hold.normal;
        let tangent = Mat3::identity() - n * n.transpose();
        let slip = |v: Vec3| tangent * (v - press.solid_velocity);
        let limit = 0.4 * 2.5;
        let linear = |v: Vec3| external[0] - Vec3::new(0.5, 0.0, 0.0) - damping[0] * v;
        assert!((linear(v0) - sliding_friction(slip(v0), limit)).norm() < 1e-15);
        assert!((sliding_friction(slip(v0), limit).norm() - limit).abs() < 1e-15);
        assert!(sliding_friction(slip(v0), limit).dot(&n).abs() < 1e-15);
        let eps = 1e-6;
        for d in [Vec3::x(), Vec3::y(), Vec3::z()] {
            let numeric = (sliding_friction(slip(v0 + d * eps), limit) - sliding_friction(slip(v0 - d * eps), limit))
                / (2.0 * eps);
            let analytic = -damping[0] * d;
            assert!((numeric - analytic).norm() < 1e-8, "{numeric} vs {analytic}");
        }
        squeeze_friction_forces(&mut contacts, &[v0]);
        assert!((contacts[1].solve_friction_n - sliding_friction(slip(v0), limit)).norm() < 1e-15);
        assert_eq!(contacts[0].solve_friction_n, Vec3::zeros());
        // Nearly moving with the box: left to `apply_friction`.
        let mut contacts = [hold, press];
        let slow = press.solid_velocity + tangent * Vec3::new(0.03, 0.0, 0.0);
        assert!(!linearise_squeeze_friction(&mut contacts, &[slow], &mut damping, &mut external));
    }

    /// A squeezed particle's push along the holding solid moves it as far
    /// as relieves the overlap behind the pressing force (to first order),
    /// however light it is; as `f tau / m` it went 44 times the overlap.
    #[test]
    fn a_squeezed_particle_is_pushed_no_further_than_relieves_its_overlap() {
        let (mass, h) = (2.6e-5, 1.0 / 90.0);
        let tau = 2.0 * h / 3.0;
        let overlap = 0.002;
        let hold = touching(Vec3::z(), Vec3::zeros(), 0.0, 0.0);
        let mut press = hold;
        (press.collider, press.normal, press.pressed) = (1, Vec3::new(0.6, 0.0, -0.8), true);
        press.normal_force_n = squeeze_force(0.005 - overlap, 0.005, mass, h);
        assert!((squeeze_overlap(press.normal_force_n, mass, h) - overlap).abs() < 1e-15);
        let (mut x, mut v) = (vec![Vec3::zeros()], vec![Vec3::zeros()]);
        apply_friction(&mut [hold, press], &[mass], (tau, h), false, &mut x, &mut v);
        // Along the holding plane, and the gap to the pressing solid opens by the overlap.
        assert_eq!(x[0].z, 0.0);
        assert!((press.normal.dot(&x[0]) - overlap).abs() < 1e-15, "{}", press.normal.dot(&x[0]));
        assert!((v[0] - x[0] / tau).norm() < 1e-12);
        // Solids nearly opposed (the push along the plane 0.1 of the force,
        // relieving 0.01 of its travel): the force's push, `44 * 0.1` overlaps.
        press.normal = Vec3::new(0.1, 0.0, -(0.99f64.sqrt()));
        let (mut x, mut v) = (vec![Vec3::zeros()], vec![Vec3::zeros()]);
        apply_friction(&mut [hold, press], &[mass], (tau, h), false, &mut x, &mut v);
        let force_push = Vec3::new(0.1, 0.0, 0.0) * (press.normal_force_n * tau * tau / mass);
        assert!((force_push.x / overlap - 100.0 * 4.0 / 9.0 * 0.1).abs() < 1e-12);
        assert!((x[0] - force_push).norm() < 1e-15, "{x:?} vs {force_push}");
    }

    /// Friction the solve applied (a squeezed particle's) stays, and is not
    /// taken out as the velocity change `f tau / m` of the particle alone:
    /// a light particle still sliding along it only gets the holding
    /// solid's friction after the solve, and one it pushed past the
    /// pressing solid's velocity stops there.
    #[test]
    fn friction_from_the_solve_is_not_taken_out_as_if_the_particle_were_alone() {
        let (mass, h) = (2.6e-5, 1.0 / 90.0);
        let tau = 2.0 * h / 3.0;
        let mut hold = touching(Vec3::z(), Vec3::zeros(), 0.3, 0.01);
        let mut press = touching(-Vec3::z(), Vec3::zeros(), 0.3, 0.05);
        (press.collider, press.pressed) = (1, true);
        press.solve_friction_n = Vec3::new(-0.1, 0.0, 0.0);
        // Sliding on along +x: the holding solid's budget (0.85 m/s) stops it.
        let budget = 0.3 * 0.01 * tau / mass;
        assert!(budget > 0.5 && 0.1 * tau / mass > 20.0);
        let (mut x, mut v) = (vec![Vec3::zeros()], vec![Vec3::new(0.5, 0.0, 0.0)]);
        apply_friction(&mut [hold, press], &[mass], (tau, h), false, &mut x, &mut v);
        assert!(v[0].norm() < 1e-15, "{v:?}");
        assert!((x[0] - Vec3::new(-0.5 * tau, 0.0, 0.0)).norm() < 1e-15);
        // Pushed past: reversed along the solve's friction, it stops.
        hold.friction = 0.0;
        let (mut x, mut v) = (vec![Vec3::zeros()], vec![Vec3::new(-0.2, 0.0, 0.0)]);
        apply_friction(&mut [hold, press], &[mass], (tau, h), false, &mut x, &mut v);
        assert!(v[0].norm() < 1e-15, "{v:?}");
        // Still sliding and no friction from the holding solid: kept.
        let (mut x, mut v) = (vec![Vec3::zeros()], vec![Vec3::new(0.2, 0.0, 0.0)]);
        apply_friction(&mut [hold, press], &[mass], (tau, h), false, &mut x, &mut v);
        assert_eq!(v[0], Vec3::new(0.2, 0.0, 0.0));
    }

    /// A box moving at 2 m/s sweeps over a particle 1 cm ahead of its
    /// leading face within a 10 ms step; the solve then carries the particle
    /// up inside it. The particle leaves by the leading face (in the box's
    /// new pose), not by the top face nearest where it ended.
    #[test]
    fn a_particle_swept_over_by_a_moving_solid_leaves_by_the_face_that_swept_it() {
        let shape = crate::ShapeSpec::Cuboid { half_extents_m: [0.05, 0.05, 0.05] };
        let collider = crate::Collider {
            shape: cloth_collide::SolidShape::build(&shape, std::path::Path::new("")).unwrap(),
            anchor: BodyPose { position: Vec3::zeros(), rotation: nalgebra::UnitQuaternion::identity() },
            motion: crate::PinMotion::Linear { velocity_m_s: [2.0, 0.0, 0.0] },
            spin_rad_s: Vec3::zeros(),
            friction: 0.0,
            yielding: false,
        };
        let posed = |t: f64| {
            let pose = collider.pose(t);
            let (lo, hi) = collider.shape.aabb(&pose);
            let motion = SolidMotion {
                time_s: t,
                pose,
                linear_velocity: Vec3::new(2.0, 0.0, 0.0),
                angular_velocity: Vec3::zeros(),
            };
            SolidPose { motion, lo, hi }
        };
        let (now, next) = (posed(0.0), posed(0.01));
        let (from, to) = (Vec3::new(0.06, 0.0, 0.035), Vec3::new(0.04, 0.0, 0.047));
        let (at, side) = reach_surface(&collider, (&next, 0.01), from, to, 0.0025, &mut 0).within().unwrap();
        assert!((at.normal - Vec3::z()).norm() < 1e-12, "the top face is nearest the end: {at:?}");
        assert!((side.normal - Vec3::x()).norm() < 1e-12, "{side:?}");
        assert!((side.point - Vec3::new(0.07, 0.0, 0.035)).norm() < 1e-12, "{side:?}");
        // A solid at rest never sweeps: a particle inside it keeps the nearest face.
        let still = crate::Collider { motion: crate::PinMotion::Fixed, ..collider.clone() };
        let (at, side) =
            reach_surface(&still, (&now, 0.01), Vec3::new(0.04, 0.0, 0.035), to, 0.0025, &mut 0).within().unwrap();
        assert_eq!(at, side);
    }

    /// A sliding contact whose slip went along its friction (the friction
    /// turned it back) sticks, once a step; turned back again it is at its
    /// bound and slides on with `mu N` (allowed to turn back every time,
    /// contacts of the Table-1 garments went stick, slide, stick, slide
    /// pass after pass).
    #[test]
    fn a_contact_turns_back_from_sliding_to_sticking_once_a_step() {
        let pattern = cloth_linalg::BlockPattern::from_pairs(1, []).unwrap();
        let mut matrix = BlockSparseMatrix::new(pattern);
        matrix.fill_rows(|_, row| row[0] = Mat3::identity() * 1e-3);
        let mut filter = ConstraintFilter::new(1);
        let limit = 0.3 * 0.01;
        let mut c = touching(Vec3::z(), Vec3::zeros(), 0.3, 0.01);
        let friction = Vec3::new(limit, 0.0, 0.0);
        (c.friction_mode, c.solve_constant_n) = (FrictionMode::Slide, friction);
        let (x, along) = ([Vec3::zeros()], [Vec3::new(1e-3, 0.0, 0.0)]);
        let mut rhs = [friction];
        let unknown = [Vec3::zeros()];
        let mut contacts = [c];
        let pass = |contacts: &mut [SolidContact], rhs: &mut [Vec3], filter: &mut ConstraintFilter| {
            stick_or_slide(contacts, &matrix, rhs, (&unknown, 1.0), &x, &along, filter, |v, _| v)
        };
        assert_eq!(pass(&mut contacts, &mut rhs, &mut filter), 1);
        assert_eq!(contacts[0].friction_mode, FrictionMode::Stick);
        assert!(contacts[0].turned_back && rhs[0] == Vec3::zeros());
        // Over its bound again it slides, and now stays sliding.
        (contacts[0].friction_mode, contacts[0].solve_constant_n, rhs[0]) = (FrictionMode::Slide, friction, friction);
        assert_eq!(pass(&mut contacts, &mut rhs, &mut filter), 0);
        assert_eq!((contacts[0].friction_mode, contacts[0].solve_constant_n), (FrictionMode::Slide, friction));
    }

    /// Coulomb friction: a tangential speed below mu f_n tau / m stops
    /// (static), above it loses exactly that much; normal velocity is kept.
    #[test]
    fn friction_sticks_below_the_budget_and_slides_above() {
        let contact = touching(Vec3::z(), Vec3::new(0.1, 0.0, 0.0), 0.5, 2.0);
        let (mass, tau) = (0.5, 0.01);
        let budget = 0.5 * 2.0 * tau / mass; // 0.02 m/s
        let mut x = vec![Vec3::zeros()];
        let mut v = vec![Vec3::new(0.1 + 0.015, 0.0, -0.3)];
        assert_eq!(apply_friction(&mut [contact], &[mass], (tau, tau), false, &mut x, &mut v), 1);
        assert!((v[0] - Vec3::new(0.1, 0.0, -0.3)).norm() < 1e-15);
        assert!((x[0] - Vec3::new(-0.015 * tau, 0.0, 0.0)).norm() < 1e-15);
        let mut v = vec![Vec3::new(0.1 + 0.05, 0.0, 0.2)];
        assert_eq!(apply_friction(&mut [contact], &[mass], (tau, tau), false, &mut x, &mut v), 0);
        assert!((v[0] - Vec3::new(0.1 + 0.05 - budget, 0.0, 0.2)).norm() < 1e-15);
    }

    #[test]
    fn two_direction_targets_have_both_prescribed_components() {
        let n = Vec3::z();
        let m = Vec3::new(1.0, 0.0, 1.0).normalize();
        let (a, b) = two_direction_coefficients(&n, &m, 0.3, -0.2);
        let t = n * a + m * b;
        assert!((t.dot(&n) - 0.3).abs() < 1e-15 && (t.dot(&m) + 0.2).abs() < 1e-15);
    }

    /// The smoothed Coulomb friction is the negative gradient of its
    /// dissipation potential, and its damping the Jacobian of the force
    /// (central differences, both regimes and at the smoothing speed);
    /// above it the force is Coulomb's `mu N`, below it shrinks to zero
    /// with the slip. A force with the sliding magnitude at every slip
    /// (the unsmoothed law) fails the first check near zero.
    #[test]
    fn smoothed_friction_is_the_gradient_of_its_potential() {
        let (limit, eps) = (0.02, FRICTION_SMOOTHING_M_S);
        let n = Vec3::new(0.2, -0.3, 1.0).normalize();
        let tangent = Mat3::identity() - n * n.transpose();
        let direction = tangent * Vec3::new(1.0, 0.4, 0.0);
        let direction = direction / direction.norm();
        let side = n.cross(&direction);
        let (mut worst_force, mut worst_damping) = (0.0_f64, 0.0_f64);
        for speed in [0.1 * eps, 0.5 * eps, 0.999 * eps, 1.001 * eps, 3.0 * eps, 100.0 * eps] {
            let slip = (direction * 0.8 + side * 0.6) * speed;
            let (force, damping) = smoothed_friction(slip, limit, eps, &tangent);
            let d = 1e-4 * speed;
            for axis in [direction, side] {
                let energy = |s: Vec3| smoothed_friction_potential(s, limit, eps);
                let gradient = (energy(slip + axis * d) - energy(slip - axis * d)) / (2.0 * d);
                worst_force = worst_force.max((force.dot(&axis) + gradient).abs() / limit);
                let jacobian = (smoothed_friction(slip + axis * d, limit, eps, &tangent).0
                    - smoothed_friction(slip - axis * d, limit, eps, &tangent).0)
                    / (2.0 * d);
                worst_damping = worst_damping.max((damping * axis + jacobian).norm() / (limit / eps));
            }
            let expected = if speed >= eps { limit } else { limit * (2.0 * speed / eps - speed * speed / (eps * eps)) };
            assert!((force.norm() - expected).abs() < 1e-15, "{speed}: |f| {} against {expected}", force.norm());
            assert!(
                force.dot(&n).abs() < 1e-15 && (damping * n).norm() < 1e-12 * limit / eps,
                "not in the tangent plane"
            );
        }
        eprintln!("worst force error {worst_force:.1e} (of mu N), damping error {worst_damping:.1e} (of mu N / eps)");
        assert!(worst_force < 5e-9, "force is not -grad D: {worst_force:e}");
        assert!(worst_damping < 6e-9, "damping is not -df/dw: {worst_damping:e}");
        // Coulomb's constant magnitude near rest has no potential of this shape.
        let slip = direction * (0.1 * eps);
        let d = 1e-5 * eps;
        let energy = |s: Vec3| smoothed_friction_potential(s, limit, eps);
        let gradient = (energy(slip + direction * d) - energy(slip - direction * d)) / (2.0 * d);
        assert!((sliding_friction(slip, limit).dot(&direction) + gradient).abs() > 0.5 * limit);
    }

    /// The penalty's force is the negative derivative of its energy in the
    /// gap, zero beyond the thickness, and its stiffness scales as
    /// `m / h^2`.
    #[test]
    fn contact_penalty_force_is_minus_the_energy_derivative() {
        let (e, k) = (0.005, contact_penalty_stiffness(6.25e-5, 0.2));
        assert!((k - 1e3 * 6.25e-5 / 0.04).abs() < 1e-12);
        for gap in [-0.002, 0.0, 0.001, 0.004, 0.0049] {
            let d = 1e-7;
            let slope = (contact_penalty(gap + d, e, k).0 - contact_penalty(gap - d, e, k).0) / (2.0 * d);
            let force = contact_penalty(gap, e, k).1;
            assert!((force + slope).abs() < 1e-9 * k, "gap {gap}: force {force} against -dE/dg {}", -slope);
            assert!((force - k * (e - gap)).abs() < 1e-15);
        }
        assert_eq!(contact_penalty(0.006, e, k), (0.0, 0.0));
    }

    /// A contact pass skips only the queries that would have found nothing:
    /// a sheet lowered pass by pass onto a ball, a rotated box, a spinning
    /// capsule and a mesh pillow (whose distance is not Lipschitz: always
    /// queried) gets the same contacts, in the same order, as passes that
    /// query every solid for every particle; and most particles are
    /// skipped once the first pass has measured them.
    #[test]
    fn contact_passes_skip_only_particles_clear_of_every_solid() {
        use crate::{ColliderSpec, PinMotion, ShapeSpec};
        let solid = |shape, position_m, rotation_deg, spin_deg_s| ColliderSpec {
            shape,
            position_m,
            rotation_deg,
            friction: 0.3,
            motion: PinMotion::Fixed,
            spin_deg_s,
        };
        let spec = ModelSpec {
            panels: vec![GridPanel {
                particles: [20, 20],
                size_m: [0.8, 0.8],
                origin_m: [-0.4, -0.4, 0.13],
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 1.0, 0.0],
                wrap_u: false,
            }],
            collision: CollisionSpec {
                colliders: vec![
                    solid(ShapeSpec::Ball { radius_m: 0.1 }, [-0.2, -0.2, 0.0], [0.0; 3], [0.0; 3]),
                    solid(
                        ShapeSpec::Cuboid { half_extents_m: [0.08; 3] },
                        [0.2, -0.2, -0.05],
                        [20.0, 30.0, 10.0],
                        [0.0; 3],
                    ),
                    solid(
                        ShapeSpec::Capsule { half_length_m: 0.05, radius_m: 0.04 },
                        [-0.2, 0.2, 0.0],
                        [90.0, 0.0, 0.0],
                        [0.0, 0.0, 90.0],
                    ),
                    solid(
                        ShapeSpec::Mesh { obj: "pillow.obj".into(), scale: 0.5 },
                        [0.2, 0.2, 0.0],
                        [0.0; 3],
                        [0.0; 3],
                    ),
                ],
                base_dir: std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes"),
                ..CollisionSpec::default()
            },
            ..ModelSpec::default()
        };
        let model = ClothModel::build(&spec).unwrap();
        let state = crate::ClothState::at_rest(&model);
        let (n, h) = (model.particle_count(), 0.01);
        let (mut cached, mut fresh) = (ContactBuffers::default(), ContactBuffers::default());
        detect_solid_contacts(&model, &state, h, &mut cached);
        detect_solid_contacts(&model, &state, h, &mut fresh);
        let (mut filter_cached, mut filter_fresh) = (ConstraintFilter::new(n), ConstraintFilter::new(n));
        let value = |target: Vec3, _: usize| target;
        let (mut added, mut skipped) = (0, 0);
        for pass in 1..=12 {
            // Down 1 cm a pass, with a wobble of a few millimetres.
            let new_x: Vec<Vec3> = (0..n)
                .map(|i| {
                    let wobble =
                        Vec3::new((i * pass) as f64, (3 * i + pass) as f64, (i + 7 * pass) as f64).map(f64::sin);
                    state.x[i] + Vec3::new(0.0, 0.0, -0.01 * pass as f64) + wobble * 0.003
                })
                .collect();
            fresh.clearance.clear();
            let a = add_penetrating(&model, &state.x, &new_x, (0.0, h), &mut cached, &mut filter_cached, value);
            let b = add_penetrating(&model, &state.x, &new_x, (0.0, h), &mut fresh, &mut filter_fresh, value);
            assert_eq!(a, b, "pass {pass}");
            assert_eq!(cached.solid, fresh.solid, "pass {pass}");
            added += a;
            // A particle measured this pass has its clearance from here.
            skipped += cached.clearance.iter().zip(&new_x).filter(|(c, x)| c.from != **x).count();
        }
        // Measured: 84 contacts; 3,760 of the 4,800 particle passes skipped.
        assert!(added > 80, "the sheet lands on the solids: {added} contacts");
        assert!(skipped > 3700, "{skipped} of {} particle passes skipped", 12 * n);
    }
}
