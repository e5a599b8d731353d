//! The contact data a step carries: solid contacts, self contacts, the
//! per-step counters and the buffers reused from step to step.

use super::contacts::*;
use crate::control::{Control, SolidMotion};
use crate::{Mat3, Vec3};
use cloth_collide::VoxelHash;

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
    /// (`linearise_squeeze_friction`) or of a held one in Newton
    /// iterations (`linearise_contact_friction`), linearised as
    /// `f = e - C v`: `C`, N s/m, ...
    pub solve_damping: Mat3,
    /// ... `e`, N, ...
    pub solve_constant_n: Vec3,
    /// The force it exerted at the solved velocity, N
    /// (`squeeze_friction_forces`); `apply_friction` settles the rest
    /// within the Coulomb bound.
    pub solve_friction_n: Vec3,
    /// The bound `mu N` of the last `linearise_contact_friction`, N (the
    /// line search's dissipation uses the same one).
    pub solve_limit_n: f64,
    /// Where this contact's friction is decided (see [`FrictionMode`]).
    pub friction_mode: FrictionMode,
    /// For [`FrictionMode::Stick`]: the tangential travel of the solid's
    /// surface over the step, `h (I - n n^T) v_solid`, m.
    pub tangent_travel_m: Vec3,
    /// Whether this step's passes already turned it back from sliding to
    /// sticking once (`stick_or_slide`).
    pub turned_back: bool,
    /// How often this step's passes took it up again after it was
    /// released from a body (`add_penetrating`); after the second time it
    /// is not released again in the step (`release_pulling`).
    pub revivals: u8,
}

/// Where a contact's Coulomb friction is decided in an implicit step.
///
/// After the solve (`apply_friction`) the particle alone meets the
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
    /// `apply_friction` after the solve: particles squeezed between two
    /// solids or held by two, solids whose motion from outside is a guess
    /// (see `stick_frictional_contacts`), integrators without a matrix,
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
            revivals: 0,
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

/// Scratch of one chunk of the particle-triangle search: broad-phase
/// candidates `(particle, triangle within the chunk)` and the pairs found
/// with their triangle.
pub(crate) type TriangleChunk = (Vec<(u32, u32)>, Vec<(u32, SelfContact)>);

/// What collision handling did in one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactStats {
    /// Cloth-solid contacts held at the end of the step.
    pub contacts: usize,
    /// Contacts released because their force pulled.
    pub released: usize,
    /// Contacts added after a solve left a free particle inside a solid.
    pub added: usize,
    /// Particles moved out of a solid after the step (see `project_out`).
    pub projected: usize,
    /// Contacts held by static friction (no tangential slip).
    pub sticking: usize,
    /// Deepest particle inside a solid at the start of the step, m (0 when none).
    pub max_penetration_m: f64,
    /// Self-collision pairs closer than the thickness (particle-particle
    /// plus particle-triangle).
    pub self_contacts: usize,
    /// Pairs pushed apart after the step by `separate_self_contacts`.
    pub self_separations: usize,
    /// Point-triangle and edge-edge pairs of the cloth found meeting
    /// during the step, before impact zones kept them apart.
    pub self_crossings: usize,
    /// Such pairs still meeting after the impact zones (a start already
    /// tangled, or zones held by pins).
    pub crossings_left: usize,
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
        self.self_crossings += o.self_crossings;
        self.crossings_left += o.crossings_left;
        self.narrow_phase_queries += o.narrow_phase_queries;
        self.hash_builds += o.hash_builds;
    }
}

/// The contacts of a step: the collision stage's product (as Newton's
/// `Contacts`), which every integrator reads and the response after its
/// solve completes. Found at the step's start for the integrators that
/// take contacts into their solve ([`crate::ContactHandling`]), at its end
/// for the others; with the scratch that finding them reuses from step
/// to step.
#[derive(Debug, Clone, Default)]
pub struct Contacts {
    /// Cloth-solid contacts of the current step, sorted by particle; a
    /// particle touching two solids (a corner, overlapping solids) has two
    /// consecutive entries.
    pub(crate) solid: Vec<SolidContact>,
    /// Solids a Newton correction would carry a particle into (see
    /// `penalty_watch`): the line search's penalty sees them too.
    pub(crate) watch: Vec<SolidContact>,
    /// Self-collision pairs of the current step.
    pub(crate) self_pairs: Vec<SelfContact>,
    /// Per particle, the solids around it
    /// ([`crate::ContactHandling::Penalties`]).
    pub(crate) around: Vec<Surroundings>,
    /// Per particle, the narrow-phase queries that found `around`.
    pub(crate) around_queries: Vec<u32>,
    /// Per particle, whether the step prescribes it (nothing around it).
    pub(crate) around_fixed: Vec<bool>,
    /// What the step's stages did with contacts so far.
    pub(crate) stats: ContactStats,
    /// Per-particle candidates of the narrow phase (before compaction).
    pub(crate) candidate: Vec<[Option<SolidContact>; 2]>,
    /// Per-particle penetration depth and query count.
    pub(crate) probe: Vec<(f64, u32)>,
    /// First entry of each particle in `solid`, or `u32::MAX`.
    pub(crate) first_entry: Vec<u32>,
    /// Per particle, what was last learnt of its distance to the solids at
    /// the end of the current step: set from its predicted position by
    /// `detect_solid_contacts`, then by each `add_penetrating` that
    /// measures it again.
    pub(crate) clearance: Vec<Clearance>,
    /// Per particle, whether `candidate` holds what the last
    /// `detect_solid_contacts` or `add_penetrating` found for it: they
    /// write (and read back) only the candidates of particles that have
    /// one, a contact being a few hundred bytes.
    pub(crate) has_candidate: Vec<bool>,
    /// The solids at the start and at the end of the current step.
    pub(crate) now: SolidFrames,
    pub(crate) next: SolidFrames,
    /// Motions of externally driven solids for the current step.
    pub(crate) external: Vec<Option<SolidMotion>>,
    /// Per model solid, the mass of the body in the solve that it belongs
    /// to this step (kg), 0 for a solid that is no such body's.
    pub(crate) body_mass: Vec<f64>,
    /// The particles held by hand this step ([`Control::hold`]), sorted:
    /// prescribed as pins are, so no solid contact takes them over.
    pub(crate) held: Vec<usize>,
    pub(crate) hash: Option<VoxelHash>,
    pub(crate) corners: Vec<[Vec3; 3]>,
    /// Broad-phase output, reused.
    pub(crate) candidate_pairs: Vec<(u32, u32)>,
    /// Per chunk of the hash's cell table: the point pairs found from it.
    pub(crate) pair_chunks: Vec<Vec<(u32, u32)>>,
    /// Per chunk of triangles: broad-phase candidates and the pairs found.
    pub(crate) triangle_chunks: Vec<TriangleChunk>,
    /// The pairs of all chunks as `(triangle, place, pair)`, sorted.
    pub(crate) triangle_found: Vec<(u32, u32, SelfContact)>,
    /// The particle-triangle search's order of the triangles, built once
    /// per model (`search_order`).
    pub(crate) triangle_order: Vec<u32>,
    /// CSR, built once per model: for each triangle, the sorted particles
    /// it never repels (its corners and every particle linked to one).
    pub(crate) excluded_ptr: Vec<u32>,
    pub(crate) excluded: Vec<u32>,
    /// Scratch of the continuous self-collision test.
    pub(crate) crossings: CrossingBuffers,
    /// The projection's last outcome in the step's finish.
    pub(crate) projection_memo: ProjectionMemo,
    /// Scratch of the deformation constraints' passes in the finish: a
    /// bit per stretch link that may need a correction.
    pub(crate) strain_dirty: Vec<u64>,
    /// The solids near the particles in a step's finish, as the
    /// deformation constraints' fast projection keeps them out of them;
    /// found by chunks of particles.
    pub(crate) solid_bounds: Vec<crate::model::fast_projection::SolidBound>,
    pub(crate) bound_chunks: Vec<Vec<crate::model::fast_projection::SolidBound>>,
    /// Scratch of the deformation constraints' fast projection.
    pub(crate) strain_projection: crate::model::fast_projection::ProjectionScratch,
    /// Self-collision forces, N.
    pub(crate) self_force: Vec<Vec3>,
    /// Self-collision stiffness on the diagonal, `-df_i/dx_i`, N/m.
    pub(crate) self_stiffness: Vec<Mat3>,
    /// The same contacts' stiffness between their particles, N/m: the
    /// blocks off the diagonal, which the solve adds to the matrix.
    pub(crate) self_couplings: cloth_linalg::Couplings,
    /// Friction of squeezed particles as damping on the diagonal,
    /// `-df_i/dv_i`, N s/m (`linearise_squeeze_friction`).
    pub(crate) friction_damping: Vec<Mat3>,
    /// Per particle, its nearest triangle's entry in `self_pairs` (or `u32::MAX`).
    pub(crate) nearest: Vec<u32>,
}

impl Contacts {
    /// The cloth-solid contacts of the last step (point, normal, solid
    /// velocity and the normal force each exerted), sorted by particle.
    pub fn solid(&self) -> &[SolidContact] {
        &self.solid
    }

    /// The self-collision pairs found at the last step's start.
    pub fn self_pairs(&self) -> &[SelfContact] {
        &self.self_pairs
    }

    /// What the last step did with contacts.
    pub fn stats(&self) -> ContactStats {
        self.stats
    }

    /// Takes the motions of externally driven solids for the next step
    /// from `control` (and forgets solid poses computed before, since a
    /// repeated step may move them differently).
    pub(crate) fn set_external(&mut self, control: &Control) {
        self.external.clear();
        self.external.extend_from_slice(control.solid_motions());
        self.body_mass.clear();
        self.body_mass.resize(self.external.len(), 0.0);
        for b in control.bodies() {
            for &s in &b.solids {
                if let Some(m) = self.body_mass.get_mut(s) {
                    *m = b.mass_kg;
                }
            }
        }
        self.held.clear();
        self.held.extend(control.holds().iter().map(|&(i, _)| i));
        self.now.time = None;
        self.next.time = None;
    }
}
