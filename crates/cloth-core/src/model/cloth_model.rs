//! The immutable cloth model (particles, links grouped by law, pins, the
//! effects a scene asked for, the system matrix's sparsity pattern), and
//! the interface of the force terms that act on it: a model holds the
//! terms added from outside, and a term reads the model ([`ForceTerm`]).
//! The model is built in `build.rs` and answers in `queries.rs`.

use super::assembly::{Row, SystemTerms};
use super::layout::{MeshRange, PanelRange};
use super::links::{BendLink, Incidence, StretchLink};
use super::spec::{Effects, ModelKind, StrainLimit};
use crate::colliders::{Collider, SelfCollision};
use crate::elements::{ElementBuffers, ElementSet};
use crate::seams::Stitch;
use crate::{Mat3, Material, Pin, Vec3, Wind};
use cloth_linalg::BlockPattern;
use std::any::Any;
use std::sync::Arc;

/// An immutable cloth model. Build one with [`ClothModel::build`].
#[derive(Debug, Clone)]
pub struct ClothModel {
    pub(super) colliders: Vec<Collider>,
    pub(super) contact_thickness: f64,
    pub(super) self_collision: Option<SelfCollision>,
    pub(super) mass: Vec<f64>,
    /// The largest `k_s / m` of a stretch link (its lighter end), 1/s^2.
    pub(super) stiffest_per_mass: f64,
    pub(super) rest_positions: Vec<Vec3>,
    pub(super) stretch: Vec<StretchLink>,
    pub(super) bend: Vec<BendLink>,
    pub(super) stitches: Vec<Stitch>,
    pub(super) pins: Vec<Pin>,
    pub(super) pinned: Vec<bool>,
    pub(super) effects: Effects,
    pub(super) material: Material,
    pub(super) kind: ModelKind,
    pub(super) strain_limit: Option<StrainLimit>,
    pub(super) wind: Option<Wind>,
    pub(super) panels: Vec<PanelRange>,
    pub(super) meshes: Vec<MeshRange>,
    pub(super) triangles: Vec<[u32; 3]>,
    /// The triangles of each particle, in triangle order: `tri_of[tri_ptr[i]..tri_ptr[i + 1]]`.
    pub(super) tri_ptr: Vec<usize>,
    pub(super) tri_of: Vec<u32>,
    /// Each sewn particle's group (the particles stitches join it to,
    /// directly or through others, itself included; empty if unsewn):
    /// `sewn[sewn_ptr[i]..sewn_ptr[i + 1]]`.
    pub(super) sewn_ptr: Vec<usize>,
    pub(super) sewn: Vec<u32>,
    pub(super) elements: ElementSet,
    pub(super) drag: Vec<f64>,
    pub(super) inc_ptr: Vec<usize>,
    pub(super) inc: Vec<Incidence>,
    pub(super) pattern: BlockPattern,
    pub(super) diag_local: Vec<u32>,
    /// Force terms added from outside ([`ClothModel::with_force_term`]).
    pub(super) extra_terms: Vec<Arc<dyn ForceTerm>>,
}

/// Scratch for [`crate::forces::forces_into`], sized once per model.
#[derive(Debug, Clone)]
pub struct ForceBuffers {
    pub(crate) link: Vec<Vec3>,
    pub(crate) elements: ElementBuffers,
    /// The particles' area-weighted normals (the wind's fluid force).
    pub(crate) normals: Vec<Vec3>,
}

impl ForceBuffers {
    /// Buffers for `model`.
    pub fn new(model: &ClothModel) -> Self {
        Self {
            link: vec![Vec3::zeros(); model.link_count()],
            elements: ElementBuffers::forces_only(model.elements()),
            normals: Self::normals_for(model),
        }
    }

    /// Buffers for `model`'s external terms only ([`ForceTerm::external`]).
    pub fn external(model: &ClothModel) -> Self {
        Self {
            link: Vec::new(),
            elements: ElementBuffers::forces_only(&Default::default()),
            normals: Self::normals_for(model),
        }
    }

    fn normals_for(model: &ClothModel) -> Vec<Vec3> {
        Vec::with_capacity(if model.wind().is_some() { model.particle_count() } else { 0 })
    }
}

/// Where the terms are evaluated: a model at positions `x` (m) and
/// velocities `v` (m/s), with its stitches' states and the air's velocity.
#[derive(Debug, Clone, Copy)]
pub struct At<'a> {
    /// The model.
    pub model: &'a ClothModel,
    /// Positions, m.
    pub x: &'a [Vec3],
    /// Velocities, m/s.
    pub v: &'a [Vec3],
    /// Of each stitch, whether it has closed ([`crate::ClothState::stitches_closed`]).
    pub stitches_closed: &'a [bool],
    /// The air's velocity, m/s: the wind's at this time
    /// ([`crate::WindProfile::velocity`]); `None` where no external term is
    /// evaluated.
    pub air_m_s: Option<Vec3>,
}

impl<'a> At<'a> {
    /// `model` at `(x, v)` with `stitches_closed`, in still air.
    pub fn new(model: &'a ClothModel, x: &'a [Vec3], v: &'a [Vec3], stitches_closed: &'a [bool]) -> Self {
        Self { model, x, v, stitches_closed, air_m_s: None }
    }

    /// The same point with the air at the model's wind velocity at time
    /// `t` (s), an external wind's from `set` (m/s), times `scale`.
    pub fn with_wind_at(self, t: f64, set: Option<Vec3>, scale: f64) -> Self {
        Self { air_m_s: self.model.wind().map(|w| w.profile.velocity(t, set) * scale), ..self }
    }
}

/// One particle's share of a term: what a vertex solver needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexBlock {
    /// Force on the particle, N.
    pub force: Vec3,
    /// `-df_i/dx_i`, N/m (the energy's Hessian block where the term has an
    /// energy; its positive semidefinite part where the law's is not).
    pub stiffness: Mat3,
    /// `-df_i/dv_i`, N s/m.
    pub damping: Mat3,
    /// The part of `force` that dissipates (dampers, drag), N: the rest
    /// of a term with [`ForceTerm::vertex_energy`] is minus that energy's
    /// gradient.
    pub dissipative: Vec3,
}

impl VertexBlock {
    /// No force, no blocks.
    pub fn zero() -> Self {
        Self { force: Vec3::zeros(), stiffness: Mat3::zeros(), damping: Mat3::zeros(), dissipative: Vec3::zeros() }
    }
}

impl std::ops::AddAssign for VertexBlock {
    fn add_assign(&mut self, o: Self) {
        self.force += o.force;
        self.stiffness += o.stiffness;
        self.damping += o.damping;
        self.dissipative += o.dissipative;
    }
}

/// One effect's forces on the cloth.
pub trait ForceTerm: Send + Sync + std::fmt::Debug {
    /// The effect's name.
    fn name(&self) -> &'static str;

    /// Whether `model` has this effect: an effect the model was not built
    /// with costs nothing.
    fn acts_on(&self, model: &ClothModel) -> bool;

    /// Potential energy at `at.x`, J (0 for a force without one). Reads
    /// positions only: `at.v` may be empty.
    fn energy(&self, at: &At<'_>) -> f64;

    /// Power the term dissipates at `at.v`, W (>= 0; 0 for a conservative
    /// term).
    fn dissipation(&self, _at: &At<'_>) -> f64 {
        0.0
    }

    /// Adds the force on every particle to `out`, N, in a fixed order per
    /// particle (the same bits for any thread count), with `scratch` sized
    /// for the model.
    fn add_forces(&self, at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]);

    /// Particle `i`'s force and blocks.
    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock;

    /// The energy of the term's parts that involve particle `i`, with `i`
    /// at `xi` and the others at `at.x`, J: what changes when `i` alone
    /// moves (a vertex solver's line search). `None` (the default) for a
    /// term without a potential: its force then counts as constant over
    /// a local step.
    fn vertex_energy(&self, _at: &At<'_>, _i: usize, _xi: Vec3) -> Option<f64> {
        None
    }

    /// [`ForceTerm::vertex`] and [`ForceTerm::vertex_energy`] at `at.x`
    /// together: a term that evaluates both from one law evaluation
    /// overrides it (a vertex solver's line search needs both every local
    /// step).
    fn vertex_with_energy(&self, at: &At<'_>, i: usize) -> (VertexBlock, Option<f64>) {
        (self.vertex(at, i), self.vertex_energy(at, i, at.x[i]))
    }

    /// The pairs of particles the term's force couples (each once, in
    /// either order): the system's sparsity pattern holds their blocks.
    /// None by default: a force on each particle alone.
    fn coupled_pairs(&self, _model: &ClothModel) -> Vec<[usize; 2]> {
        Vec::new()
    }

    /// The force on every particle at `at` and its Jacobian: into `out`,
    /// `f_i` (N), `-df_i/dx_j` (N/m) and `-df_i/dv_j` (N s/m) for each
    /// particle and each pair of [`ForceTerm::coupled_pairs`], in both
    /// orders. By default each particle's [`ForceTerm::vertex`] on the
    /// diagonal: exact for a force on each particle alone.
    fn jacobian(&self, at: &At<'_>, out: &mut Jacobian<'_>) {
        for i in 0..at.x.len() {
            let b = self.vertex(at, i);
            out.add_force(i, b.force);
            out.add_stiffness(i, i, &b.stiffness);
            out.add_damping(i, i, &b.damping);
        }
    }

    /// How the implicit steps assemble the term: its own assembly (the
    /// built-in terms', law by law), or `None` (the default): from
    /// [`ForceTerm::jacobian`] at the step's positions.
    fn assembly(&self) -> Option<&dyn TermAssembly> {
        None
    }

    /// Whether this is a force from outside the cloth (the wind's): every
    /// step takes it at the step's start, as given over the step, and
    /// the energy monitor counts its work as external work, not as
    /// potential or dissipation.
    fn external(&self) -> bool {
        false
    }
}

/// Scratch a term's own assembly keeps between its evaluation and its
/// rows (its per-link or per-element results), made once per model.
pub type TermScratch = Box<dyn Any + Send + Sync>;

/// A term's own assembly into an implicit step's linear system
/// `A = M - c_v D - c_x K`, `b = c_f f + ...` (see [`SystemTerms`]): a
/// parallel pass over its links or elements, then each row's share, read
/// back in a fixed order (the same bits for any thread count).
pub trait TermAssembly: Send + Sync {
    /// Its scratch for `model`.
    fn scratch(&self, model: &ClothModel) -> TermScratch;

    /// Evaluates the term's laws at `at.x` for the system's coefficients
    /// `c` into `scratch`; returns the energy it stores there, J (the
    /// links' and elements': 0 for gravity, whose potential the energy
    /// monitor counts apart, and for a force without one).
    fn evaluate(&self, at: &At<'_>, c: &SystemTerms<'_>, scratch: &mut TermScratch) -> f64;

    /// Adds row `i`'s right-hand side: `c_f f_i` and the terms `c` asks
    /// for (`a_k (K w_k)_i`, `a_d (D w_d)_i`).
    fn add_rhs(&self, at: &At<'_>, c: &SystemTerms<'_>, scratch: &TermScratch, i: usize, rhs: &mut Vec3);

    /// Adds row `i`'s blocks `-c_x K_ij - c_v D_ij` to `row`.
    fn add_row(&self, at: &At<'_>, c: &SystemTerms<'_>, scratch: &TermScratch, i: usize, row: &mut Row<'_>);

    /// Adds row `i` of the coupling blocks applied to `w` scaled by `s`,
    /// `sum_j B_ij w_j s_j`, to `acc` (the matrix-free operator; the
    /// diagonal's mass and drag are the system's). Nothing by default.
    fn apply(&self, _at: &At<'_>, _scratch: &TermScratch, _i: usize, _w: &[Vec3], _s: &[f64], _acc: &mut Vec3) {}

    /// Whether [`TermAssembly::apply`] adds anything (false by default).
    fn couples(&self) -> bool {
        false
    }
}

/// A term's force and Jacobian at one configuration, evaluated apart from
/// any step ([`ForceTerm::jacobian`] into buffers of its own): to check a
/// term against finite differences, or to look at it.
#[derive(Debug, Clone)]
pub struct JacobianBlocks {
    pattern: BlockPattern,
    force: Vec<Vec3>,
    stiffness: Vec<Mat3>,
    damping: Vec<Mat3>,
}

impl JacobianBlocks {
    /// `term`'s force and Jacobian at `at`.
    pub fn of(term: &dyn ForceTerm, at: &At<'_>) -> Self {
        let n = at.x.len();
        let pairs = term.coupled_pairs(at.model).into_iter().map(|[i, j]| (i, j));
        let pattern = BlockPattern::from_pairs(n, pairs).expect("a term couples the model's particles");
        let nnz = pattern.nnz_blocks();
        let (mut force, mut stiffness, mut damping) =
            (vec![Vec3::zeros(); n], vec![Mat3::zeros(); nnz], vec![Mat3::zeros(); nnz]);
        let mut written = vec![false; nnz];
        let buffers = (&mut force[..], &mut stiffness[..], &mut damping[..], &mut written[..]);
        term.jacobian(at, &mut Jacobian::new(&pattern, term.name(), buffers));
        Self { pattern, force, stiffness, damping }
    }

    /// The force on particle `i`, N.
    pub fn force(&self, i: usize) -> Vec3 {
        self.force[i]
    }

    /// `-df_i/dx_j`, N/m (zero for a pair the term does not couple).
    pub fn stiffness(&self, i: usize, j: usize) -> Mat3 {
        self.pattern.slot(i, j).map_or_else(Mat3::zeros, |s| self.stiffness[s])
    }

    /// `-df_i/dv_j`, N s/m (zero for a pair the term does not couple).
    pub fn damping(&self, i: usize, j: usize) -> Mat3 {
        self.pattern.slot(i, j).map_or_else(Mat3::zeros, |s| self.damping[s])
    }
}

/// A term's force and Jacobian at one configuration ([`ForceTerm::jacobian`]),
/// stored by the system's sparsity pattern: what the implicit steps
/// assemble of a term without an assembly of its own.
#[derive(Debug)]
pub struct Jacobian<'p> {
    pattern: &'p BlockPattern,
    term: &'static str,
    force: &'p mut [Vec3],
    stiffness: &'p mut [Mat3],
    damping: &'p mut [Mat3],
    written: &'p mut [bool],
}

impl<'p> Jacobian<'p> {
    /// A Jacobian of the term named `term` into buffers sized for
    /// `pattern` (`force` per particle; the others per stored block).
    pub(crate) fn new(
        pattern: &'p BlockPattern,
        term: &'static str,
        (force, stiffness, damping, written): (&'p mut [Vec3], &'p mut [Mat3], &'p mut [Mat3], &'p mut [bool]),
    ) -> Self {
        Self { pattern, term, force, stiffness, damping, written }
    }

    /// Adds `f` (N) to the force on particle `i`.
    pub fn add_force(&mut self, i: usize, f: Vec3) {
        self.force[i] += f;
    }

    /// Adds `block` (N/m) to `-df_i/dx_j`. Panics when `(i, j)` is neither
    /// a diagonal block nor a pair the term couples
    /// ([`ForceTerm::coupled_pairs`]): the pattern has no room for it.
    pub fn add_stiffness(&mut self, i: usize, j: usize, block: &Mat3) {
        let s = self.slot(i, j);
        self.stiffness[s] += block;
    }

    /// Adds `block` (N s/m) to `-df_i/dv_j` (see [`Jacobian::add_stiffness`]).
    pub fn add_damping(&mut self, i: usize, j: usize, block: &Mat3) {
        let s = self.slot(i, j);
        self.damping[s] += block;
    }

    fn slot(&mut self, i: usize, j: usize) -> usize {
        let Some(s) = self.pattern.slot(i, j) else {
            panic!("force term {:?}: block ({i}, {j}) is not in the pattern: list the pair in coupled_pairs", self.term)
        };
        self.written[s] = true;
        s
    }
}
