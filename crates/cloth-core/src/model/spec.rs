//! What a model is built from: [`ModelSpec`] (panels, material, pins,
//! effects, the discretisation), its parts, and why a build can fail.

use crate::colliders::CollisionSpec;
use crate::seams::SeamSpec;
use crate::{Edge, FieldError, GridPanel, Material, MeshPanel, PinMotion, Vec3, Wind};
use serde::{Deserialize, Serialize};

/// Effects computed by a model. An effect that is off costs nothing: no
/// links are built and no loop runs for it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Effects {
    /// Uniform gravitational acceleration, m/s^2 (`None`: no gravity).
    pub gravity: Option<Vec3>,
    /// Directional damping along type-1 links (Choi & Ko Eq. 13).
    pub damping: bool,
    /// Type-2 interlaced buckling links (bending and compression resistance).
    pub bending: bool,
    /// Viscous drag on every particle, `f_i = -c_i v_i` with
    /// `c_i = material.drag_n_s_m3 x` the particle's area (Provot's
    /// "viscous damping" `-C_dis v`).
    pub drag: bool,
    /// Provot's viscous fluid (wind) force on particles; needs [`ModelSpec::wind`].
    pub wind: bool,
    /// Aerodynamic drag and lift on triangles; needs [`ModelSpec::wind`].
    pub aerodynamics: bool,
}

/// A set of pinned grid nodes or mesh vertices and the path they follow.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinSpec {
    /// Panel index (default 0).
    #[serde(default)]
    pub panel: usize,
    /// Grid nodes `[i, j]` to pin.
    #[serde(default)]
    pub nodes: Vec<[usize; 2]>,
    /// A whole edge to pin (in addition to `nodes`).
    #[serde(default)]
    pub edge: Option<Edge>,
    /// A mesh panel index (`[[meshes]]`): pins its `vertices` instead of
    /// a grid panel's nodes.
    #[serde(default)]
    pub mesh: Option<usize>,
    /// The mesh's vertices to pin (0-based, in the mesh's order).
    #[serde(default)]
    pub vertices: Vec<usize>,
    /// A pattern mesh's outline edges to pin whole (edge `k` from outline
    /// corner `k` to the next), in addition to `vertices`.
    #[serde(default)]
    pub outline_edges: Vec<usize>,
    /// The path (default: fixed).
    #[serde(default = "fixed")]
    pub motion: PinMotion,
}

fn fixed() -> PinMotion {
    PinMotion::Fixed
}

impl Default for PinSpec {
    /// Pins nothing yet, on panel 0, fixed.
    fn default() -> Self {
        Self {
            panel: 0,
            nodes: Vec::new(),
            edge: None,
            mesh: None,
            vertices: Vec::new(),
            outline_edges: Vec::new(),
            motion: PinMotion::Fixed,
        }
    }
}

/// Everything needed to build a [`crate::ClothModel`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelSpec {
    /// The cloth's grid panels (particles are numbered panel after panel,
    /// `j * nx + i` within one).
    pub panels: Vec<GridPanel>,
    /// The cloth's mesh panels (their particles follow the grid panels',
    /// in each mesh's vertex order).
    pub meshes: Vec<MeshPanel>,
    /// The fabric, shared by all panels.
    pub material: Material,
    /// Pinned nodes.
    pub pins: Vec<PinSpec>,
    /// Effects to compute.
    pub effects: Effects,
    /// The discretisation.
    pub kind: ModelKind,
    /// How Choi & Ko's type-2 interactions read bending (`choi-ko` only;
    /// None: [`BendingLaw::ArcPath`]).
    pub bending_law: Option<BendingLaw>,
    /// Deformation constraints, if any.
    pub strain_limit: Option<StrainLimit>,
    /// The air's motion and coefficients, for the wind effects.
    pub wind: Option<Wind>,
    /// Solids and self-collision (none by default).
    pub collision: CollisionSpec,
    /// Seams sewing panels together (none by default).
    pub seams: Vec<SeamSpec>,
}

/// Why a model could not be built. Field paths match the scene file's keys.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelError {
    /// The model has no panel.
    NoPanels,
    /// The paper's arc-chord law was asked of a model with mesh panels.
    MeshBendingLaw,
    /// A mesh panel is invalid.
    Mesh {
        /// Mesh index.
        mesh: usize,
        /// Offending field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A panel is invalid.
    Panel {
        /// Panel index.
        panel: usize,
        /// Offending field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The material is invalid.
    Material {
        /// Offending field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A pin is impossible.
    Pin {
        /// Pin index.
        pin: usize,
        /// Offending field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The wind is missing or invalid.
    Wind {
        /// Offending field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The deformation constraints are invalid.
    StrainLimit {
        /// Offending field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// Gravity is not finite.
    Gravity([f64; 3]),
    /// A bending law was asked of a model that does not have it.
    BendingLaw(&'static str, &'static str),
    /// A seam is invalid.
    Seam {
        /// Seam index.
        seam: usize,
        /// Offending field (`a.range`).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A collider or the self-collision set-up is invalid.
    Collision {
        /// Dotted path of the field (`colliders[0].shape.radius_m`).
        field: String,
        /// What is wrong.
        message: String,
    },
}

impl ModelError {
    /// The field at fault, by its path from a scene's root
    /// (`panels[0].size_m`, `material.shear_modulus_n_m`), and what is
    /// wrong with it: what the scene reports, and this error's text.
    pub fn field_error(&self) -> FieldError {
        let at = |table: String, field: &str, message: &str| FieldError::new(field, message).within(&table);
        match self {
            ModelError::NoPanels => FieldError::new("panels", "at least one panel or mesh is required"),
            ModelError::MeshBendingLaw => FieldError::new(
                "simulation.bending_law",
                "arc-chord reads a grid's type-2 links; mesh panels take arc-path (the default)",
            ),
            ModelError::Mesh { mesh, field, message } => at(format!("meshes[{mesh}]"), field, message),
            ModelError::Panel { panel, field, message } => at(format!("panels[{panel}]"), field, message),
            ModelError::Material { field, message } => at("material".into(), field, message),
            ModelError::Pin { pin, field, message } => at(format!("pins[{pin}]"), field, message),
            ModelError::Wind { field, message } => at("wind".into(), field, message),
            ModelError::StrainLimit { field, message } => at("constraints".into(), field, message),
            ModelError::Gravity(g) => FieldError::new("simulation.gravity_m_s2", format!("must be finite, got {g:?}")),
            ModelError::BendingLaw(law, kind) => {
                FieldError::new("simulation.bending_law", format!("{law} is a law of the choi-ko model, not of {kind}"))
            }
            ModelError::Seam { seam, field, message } => at(format!("seams[{seam}]"), field, message),
            ModelError::Collision { field, message } => FieldError::new(field.clone(), message.clone()),
        }
    }
}

impl std::fmt::Display for ModelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.field_error().fmt(f)
    }
}

impl std::error::Error for ModelError {}

/// Which discretisation of the fabric a model uses. Both take the same
/// [`Material`]; see [`Material`]'s docs for the constants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// Choi & Ko (2002): tension-only type-1 springs, type-2 buckling links
    /// (circular-arc law with the `c_b` ramp) on `i+2`, `j+2` and both
    /// skip-one diagonals.
    #[default]
    ChoiKo,
    /// Provot (1995): linear structural and shear springs (tension and
    /// compression) and linear flexion springs on `i+2`, `j+2`.
    Provot,
    /// Volino & Magnenat-Thalmann (2001), "accurate" model: a linear
    /// orthotropic membrane on the triangles and a bending element per triangle;
    /// the `damping` effect acts along the type-1 links.
    Volino,
}

impl ModelKind {
    /// Name as written in scene files.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::ChoiKo => "choi-ko",
            ModelKind::Provot => "provot",
            ModelKind::Volino => "volino",
        }
    }
}

/// How the `choi-ko` model's type-2 interactions read bending.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BendingLaw {
    /// The paper's pair law: the arc law on the chord against the rest
    /// length, capped by the ramp `c_b (L - d)` (Eq. 11), tension-only
    /// type-1 links, every link standing for a full cell. Its flexural
    /// rigidity depends on the grid (material docs).
    ArcChord,
    /// The default: the arc law on the chord against the path through the
    /// middle particle ([`crate::element_laws::bend_triple_with`]): bending
    /// only, with `k_b = (8/9) B a / L`, links along a boundary standing
    /// for the part of a cell they border, and the membrane's compression
    /// on the type-1 links. Flexural rigidity that holds at every grid
    /// spacing.
    #[default]
    ArcPath,
}

impl BendingLaw {
    /// Name as written in scene files.
    pub fn name(self) -> &'static str {
        match self {
            BendingLaw::ArcChord => "arc-chord",
            BendingLaw::ArcPath => "arc-path",
        }
    }
}

/// Provot's (1995) deformation constraints: after each step, every
/// structural and shear (type-1) link longer than `(1 + max_strain) L` is
/// shortened back to that length by moving its free ends (split equally
/// when both are free, never moving pinned ones), in link order, after
/// every closed stitch is shut the same way, for up to `passes` passes or
/// until none is too long or open. With `projections > 0`, fast
/// projections of every violated link at once (Goldenthal et al. 2007)
/// come before the passes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StrainLimit {
    /// Largest allowed strain `tau_c` (dimensionless; Provot: 0.1).
    pub max_strain: f64,
    /// Most passes over the links per step (with continuous
    /// self-collision, a few more where impact zones moved the corrected
    /// cloth: `docs/contacts.md`).
    pub passes: usize,
    /// Most fast projections before each run of passes (0: Provot's
    /// passes alone). A pass moves a correction one link along, so a
    /// chain of over-long links needs of the order of its length squared
    /// in passes; a projection corrects them all together, keeping the
    /// particles out of the solids near them in the same solve (see
    /// `docs/garments.md`).
    pub projections: usize,
}

impl Default for StrainLimit {
    fn default() -> Self {
        Self { max_strain: 0.1, passes: 10, projections: 0 }
    }
}
