//! Scene files: TOML descriptions of a cloth, its material, pins, the
//! integrator and the effects to compute.
//!
//! Every key is checked: unknown keys, missing fields, NaN or negative
//! values and impossible pins are errors that name the file and the field.
//! An effect the scene does not list in `simulation.effects` is not
//! computed at all.
//!
//! ```toml
//! [simulation]
//! model = "choi-ko"           # or "provot", "volino"
//! bending_law = "arc-path"     # choi-ko only (default): flexural rigidity that holds
//!                              # at every spacing; "arc-chord": the paper's pair law
//! integrator = "bdf2"          # backward-euler, backward-euler-fixed-cg, forward-euler,
//!                              # symplectic-euler, midpoint, rk4, dopri5, vbd, quasi-newton
//! dt_s = 0.011111111111111112  # s
//! duration_s = 2.0             # s
//! effects = ["gravity", "bending", "damping"]   # also "strain-limit", "drag", "wind", "aerodynamics"
//! gravity_m_s2 = [0.0, 0.0, -9.81]
//!
//! [solver]                     # optional, these are the defaults
//! rel_tol = 1e-4
//! max_iter = 1000
//! preconditioner = "multigrid"   # or "block-jacobi" (Choi & Ko), "diagonal", "none"
//! accept_unconverged = true
//! fixed_cg_iterations = 4      # backward-euler-fixed-cg only
//! energy_guard = true          # bdf2 retakes a step that creates energy as backward Euler
//! blow_up_stretch = 100.0      # a step leaving a link longer than this x its rest length fails
//!
//! [solver.newton]              # backward-euler and bdf2
//! iterations = 1               # most linear solves per step (1: the single linearised step)
//! tolerance_m = 1e-6           # Newton stops at this residual (as a distance, m)
//! trigger = 0.0                # Newton only on steps whose linearised tension is off by more (share of k_s L; 0: always)
//! auto_trigger = 0.5           # iterations = 1: a step off by more is large for the material; Newton from it on (0: never)
//! auto_iterations = 10         # the iterations taken then
//!
//! [solver.contacts]            # backward-euler and bdf2 with solids
//! max_passes = 30              # most re-solves of a step's contact set (fewer: faster, friction beyond Coulomb)
//! settling_iterations = 4      # CG cap of the solves while the contact set settles (0: each to rel_tol)
//!
//! [solver.adaptive]            # dopri5 only
//! error_tolerance = 1e-4
//! max_substeps = 100000
//!
//! [solver.vbd]                 # vbd only: Vertex Block Descent's sweeps
//! iterations = 10              # sweeps over every colour per step
//! tolerance_m = 0.0            # stop earlier once no particle moves farther in a sweep (0: always all)
//! chebyshev_rho = 0.0          # Chebyshev acceleration's spectral radius estimate (0: off)
//! line_search = true           # halve a local step until the particle's potential falls
//!
//! [solver.quasi_newton]        # quasi-newton only: L-BFGS on backward Euler's potential
//! iterations = 50              # most iterations (line searches) per step
//! history = 5                  # (s, y) pairs kept; the history restarts each step
//! tolerance_m = 1e-6           # stop once the gradient, as a distance (|g| h^2 / m), is below
//!
//! [material]
//! areal_density_kg_m2 = 0.1
//! tensile_stiffness_n_m = 200.0
//! flexural_rigidity_n_m = 1e-5
//! buckling_stiffness_n_m = 200.0
//! damping_n_s_m = 0.02
//!
//! [[panels]]
//! particles = [41, 41]
//! size_m = [1.0, 1.0]
//! origin_m = [-0.5, -0.5, 1.0]
//!
//! [[pins]]
//! nodes = [[0, 40], [40, 40]]
//! motion = { kind = "fixed" }
//!
//! [[seams]]                    # any number: two runs of edge nodes sewn node for node
//! a = { panel = 1, edge = "i_min" }                    # range = [0, 1]: the whole edge
//! b = { panel = 0, edge = "j_min", range = [0.1, 0.2] } # fractions of the edge's length
//! reverse = false              # pair a's first node with b's last
//! stiffness_n_m = 2000.0       # a closed stitch; default 10 x tensile_stiffness_n_m
//! pull_n = 4.0                 # a closed stitch's strength, N; default E x the finer spacing
//! sewing_pull_n = 1.3          # an open stitch's pull, N; default pull_n / 4
//! closing_speed_m_s = 0.5      # an open stitch closes at about this speed
//!
//! [wind]                       # needed by "wind" and "aerodynamics"
//! profile = { kind = "gust", mean_m_s = [5.0, 0.0, 0.0], amplitude_m_s = [2.0, 0.0, 0.0], frequency_hz = 0.5 }
//! fluid_coefficient_n_s_m3 = 0.5   # Provot's C_v
//! air_density_kg_m3 = 1.2
//! drag_coefficient = 1.0
//! lift_coefficient = 0.5
//!
//! [constraints]                # optional; used with the "strain-limit" effect
//! max_strain = 0.1
//! passes = 10
//! projections = 0              # fast projections before the passes (0: passes alone)
//!
//! [collision]                  # optional; cloth-solid contact settings
//! thickness_m = 0.005          # distance kept from solid surfaces, m
//! allow_start_inside = false   # cloth starting inside a solid: an error naming it
//!
//! [[colliders]]                # any number; none: no narrow phase runs
//! shape = { kind = "ball", radius_m = 0.3 }
//! # or { kind = "cuboid", half_extents_m = [..] }, { kind = "capsule" | "cylinder",
//! # half_length_m, radius_m } (axis: local z), { kind = "convex-hull", points_m = [[..], ..] },
//! # { kind = "mesh", obj = "../meshes/pillow.obj", scale = 1.0 } (relative to this file),
//! # { kind = "half-space", normal = [0, 0, 1] }
//! position_m = [0.0, 0.0, 0.0]
//! rotation_deg = [0.0, 0.0, 0.0]   # about x, then y, then z (fixed axes)
//! friction = 0.3                   # Coulomb coefficient
//! motion = { kind = "fixed" }      # or linear / oscillate / keyframes, as pins, or "external"
//!                                  # (moved by the program each step; held in place by `cloth run`)
//! spin_deg_s = [0.0, 0.0, 0.0]     # angular velocity about the frame origin
//!
//! [self_collision]             # optional; absent: no spatial hash is built
//! thickness_m = 0.01
//! stiffness_n_m = 200.0        # default: material.tensile_stiffness_n_m
//! point_triangle = true
//! continuous = true            # no particle or edge passes through the cloth in a step
//! ```
//!
//! Self-collision needs an implicit integrator with an assembled matrix
//! (`bdf2` or `backward-euler`). Colliders work with every integrator: the
//! assembled ones hold contacts as constraints in the solve, the others
//! respond after the step (projection, inelastic impulse, Coulomb friction).

use crate::{
    BendingLaw, ClothModel, ColliderSpec, CollisionSpec, Effect, EffectValues, Effects, FieldError, GridPanel,
    IntegratorKind, Material, ModelKind, ModelSpec, PinSpec, SeamSpec, SelfCollisionSpec, SolverParams, StrainLimit,
    Vec3, Wind,
};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole scene file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Time stepping and effects.
    pub simulation: SimulationSection,
    /// Solver settings (`[solver]`; every key optional).
    #[serde(default)]
    pub solver: SolverParams,
    /// The fabric.
    pub material: Material,
    /// Cloth grid panels (`[[panels]]`).
    #[serde(default)]
    pub panels: Vec<GridPanel>,
    /// Cloth mesh panels (`[[meshes]]`): an OBJ file or triangles listed
    /// in place; their particles follow the grid panels'.
    #[serde(default)]
    pub meshes: Vec<crate::MeshPanel>,
    /// Pinned nodes.
    #[serde(default)]
    pub pins: Vec<PinSpec>,
    /// Seams sewing panels together.
    #[serde(default)]
    pub seams: Vec<SeamSpec>,
    /// Provot's deformation constraints (used when `strain-limit` is listed).
    #[serde(default)]
    pub constraints: StrainLimit,
    /// The air (used by the `wind` and `aerodynamics` effects).
    #[serde(default)]
    pub wind: Option<Wind>,
    /// Solids the cloth collides with; none means no narrow phase runs.
    #[serde(default)]
    pub colliders: Vec<ColliderSpec>,
    /// Cloth-solid contact settings.
    #[serde(default)]
    pub collision: Option<CollisionSection>,
    /// Self-collision; off when absent (no spatial hash is built).
    #[serde(default)]
    pub self_collision: Option<SelfCollisionSpec>,
    /// Directory of the scene file: relative mesh paths start here.
    #[serde(skip)]
    pub base_dir: PathBuf,
}

/// `[collision]`: cloth-solid contact settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionSection {
    /// Distance kept between particles and solid surfaces, m (default 0.005).
    #[serde(default = "default_thickness")]
    pub thickness_m: f64,
    /// Start even if some of the cloth is inside a solid (a warning lists
    /// it); by default that is an error naming the particles and solids.
    #[serde(default)]
    pub allow_start_inside: bool,
}

fn default_thickness() -> f64 {
    crate::colliders::DEFAULT_THICKNESS_M
}

/// Particles listed by name in a report of cloth inside solids; the rest are counted.
const INSIDE_LISTED: usize = 5;

/// `particle 12 in "thigh_l" by 13.2 mm, ...; 40 particles in all`: the
/// deepest first. `name` names a solid by its index.
pub fn describe_inside(inside: &[crate::contacts::Inside], name: impl Fn(usize) -> String) -> String {
    let mut sorted = inside.to_vec();
    sorted.sort_by(|a, b| b.depth_m.total_cmp(&a.depth_m).then(a.particle.cmp(&b.particle)));
    let listed: Vec<String> = sorted
        .iter()
        .take(INSIDE_LISTED)
        .map(|i| format!("particle {} in {:?} by {:.1} mm", i.particle, name(i.solid), i.depth_m * 1e3))
        .collect();
    format!("{}; {} particles in all", listed.join(", "), inside.len())
}

/// The check of a scene's start: cloth inside a solid is an error naming
/// the particles and solids (field `collision.allow_start_inside`), or,
/// when `allow`ed, a warning returned.
pub fn check_start_outside(
    inside: &[crate::contacts::Inside],
    allow: bool,
    name: impl Fn(usize) -> String,
) -> Result<Option<String>, SceneErrorKind> {
    if inside.is_empty() {
        return Ok(None);
    }
    let what = describe_inside(inside, name);
    if allow {
        return Ok(Some(format!("the cloth starts inside solids: {what}")));
    }
    Err(SceneErrorKind::Invalid {
        field: "collision.allow_start_inside".into(),
        message: format!(
            "the cloth starts inside solids: {what}; move the cloth or the solids (or the rig's settle pose), \
             or set collision.allow_start_inside = true"
        ),
    })
}

/// `[simulation]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSection {
    /// Integrator.
    pub integrator: IntegratorKind,
    /// Discretisation of the fabric (default `choi-ko`).
    #[serde(default)]
    pub model: ModelKind,
    /// `choi-ko` only: `arc-path` (the default: bending read against the
    /// path through the middle particle, a flexural rigidity that holds at
    /// every grid spacing) or `arc-chord` (the paper's pair law).
    #[serde(default)]
    pub bending_law: Option<BendingLaw>,
    /// Time step, s.
    pub dt_s: f64,
    /// Simulated duration, s.
    pub duration_s: f64,
    /// Effects to compute; anything not listed is not computed.
    pub effects: Vec<Effect>,
    /// Gravitational acceleration, m/s^2 (used when `gravity` is listed).
    #[serde(default = "default_gravity")]
    pub gravity_m_s2: [f64; 3],
    /// Random displacement of each free particle at the start, up to this
    /// many metres per component (deterministic; default 0). Perfect
    /// symmetry hides instabilities: a perfectly flat cloth in free fall
    /// has no internal force to go unstable.
    #[serde(default)]
    pub initial_jitter_m: f64,
}

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

/// How to run a scene: everything but the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunConfig {
    /// Integrator.
    pub integrator: IntegratorKind,
    /// Time step, s.
    pub dt_s: f64,
    /// Number of steps (`duration_s / dt_s`, rounded).
    pub steps: u64,
    /// Solver settings.
    pub solver: SolverParams,
    /// Amplitude of the initial position jitter, m (0: start exactly at rest).
    pub initial_jitter_m: f64,
}

impl RunConfig {
    /// The simulation a scene describes, in its initial state.
    pub fn simulation(&self, model: ClothModel) -> crate::Simulation {
        crate::Simulation::builder(model)
            .integrator(self.integrator)
            .solver(self.solver)
            .initial_jitter(self.initial_jitter_m)
            .build()
    }
}

/// A scene error: the file and what is wrong with it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {kind}", file.display())]
pub struct SceneError {
    /// The scene file.
    pub file: PathBuf,
    /// What went wrong.
    pub kind: SceneErrorKind,
}

/// What is wrong with a scene.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneErrorKind {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(String),
    /// Not valid TOML, an unknown key, a missing field or a wrong type.
    #[error("{0}")]
    Parse(String),
    /// A `--set key=value` override could not be applied.
    #[error("--set {arg}: {message}")]
    Override {
        /// The override as given.
        arg: String,
        /// Why it failed.
        message: String,
    },
    /// A value is out of range.
    #[error("{field}: {message}")]
    Invalid {
        /// Dotted path of the field.
        field: String,
        /// Why it is invalid.
        message: String,
    },
}

impl From<FieldError> for SceneErrorKind {
    fn from(e: FieldError) -> Self {
        SceneErrorKind::Invalid { field: e.path, message: e.message }
    }
}

impl Scene {
    /// Whether `[collision] allow_start_inside` is set.
    pub fn allows_start_inside(&self) -> bool {
        self.collision.is_some_and(|c| c.allow_start_inside)
    }

    /// Reads `path`, applies `overrides` (`a.b=value`, array elements by
    /// index: `panels.0.particles=[75, 75]`), parses and validates.
    pub fn load(path: &Path, overrides: &[String]) -> Result<Self, SceneError> {
        let scene = Self::parse_file(path, overrides)?;
        scene.validate().map_err(|kind| SceneError { file: path.to_path_buf(), kind })?;
        Ok(scene)
    }

    /// Reads and parses `path` with overrides, without range checks (call
    /// [`Scene::build`], which checks everything, next).
    pub fn parse_file(path: &Path, overrides: &[String]) -> Result<Self, SceneError> {
        let err = |kind| SceneError { file: path.to_path_buf(), kind };
        let text = std::fs::read_to_string(path).map_err(|e| err(SceneErrorKind::Io(e.to_string())))?;
        let mut scene = Self::parse(&text, overrides).map_err(err)?;
        scene.base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Ok(scene)
    }

    /// Parses scene text with overrides (no range checks; see [`Scene::validate`]).
    pub fn parse(text: &str, overrides: &[String]) -> Result<Self, SceneErrorKind> {
        if overrides.is_empty() {
            return toml::from_str(text).map_err(|e| SceneErrorKind::Parse(e.to_string()));
        }
        Self::parse_with_extensions(text, overrides, &[]).map(|(scene, _)| scene)
    }

    /// Parses scene text with overrides, taking the top-level `extensions`
    /// keys (sections another crate reads, such as rigid bodies) out first:
    /// returns the scene and a table of the extension keys present.
    /// Overrides may address extension keys too.
    pub fn parse_with_extensions(
        text: &str,
        overrides: &[String],
        extensions: &[&str],
    ) -> Result<(Self, toml::Table), SceneErrorKind> {
        let mut table: toml::Table = toml::from_str(text).map_err(|e| SceneErrorKind::Parse(e.to_string()))?;
        for arg in overrides {
            apply_override(&mut table, arg)
                .map_err(|message| SceneErrorKind::Override { arg: arg.clone(), message })?;
        }
        let mut taken = toml::Table::new();
        for key in extensions {
            if let Some(value) = table.remove(*key) {
                taken.insert((*key).to_string(), value);
            }
        }
        let rewritten = toml::to_string(&table).map_err(|e| SceneErrorKind::Parse(e.to_string()))?;
        let scene = toml::from_str(&rewritten).map_err(|e| {
            let after = if overrides.is_empty() { "" } else { "after --set overrides: " };
            SceneErrorKind::Parse(format!("{after}{e}"))
        })?;
        Ok((scene, taken))
    }

    /// Range checks that the types cannot express, naming the field
    /// (this builds the model once to check panels, material and pins).
    pub fn validate(&self) -> Result<(), SceneErrorKind> {
        self.build().map(|_| ())
    }

    fn check_run_fields(&self) -> Result<(), SceneErrorKind> {
        let invalid = |field: &str, message: String| SceneErrorKind::Invalid { field: field.into(), message };
        let s = &self.simulation;
        if !(s.dt_s.is_finite() && s.dt_s > 0.0) {
            return Err(invalid("simulation.dt_s", format!("must be finite and > 0, got {}", s.dt_s)));
        }
        if !(s.duration_s.is_finite() && s.duration_s >= 0.0) {
            return Err(invalid("simulation.duration_s", format!("must be finite and >= 0, got {}", s.duration_s)));
        }
        if !(s.initial_jitter_m.is_finite() && s.initial_jitter_m >= 0.0) {
            return Err(invalid(
                "simulation.initial_jitter_m",
                format!("must be finite and >= 0, got {}", s.initial_jitter_m),
            ));
        }
        if s.duration_s / s.dt_s > 1e9 {
            return Err(invalid("simulation.duration_s", "more than 1e9 steps".into()));
        }
        for (k, e) in s.effects.iter().enumerate() {
            if s.effects[..k].contains(e) {
                return Err(invalid("simulation.effects", format!("{e:?} is listed twice")));
            }
        }
        self.solver.validate().map_err(|e| SceneErrorKind::from(e.within("solver")))?;
        // Checked even when the effect is not listed: a bad value is never silently kept.
        let c = &self.constraints;
        if !(c.max_strain.is_finite() && c.max_strain >= 0.0) {
            return Err(invalid("constraints.max_strain", format!("must be finite and >= 0, got {}", c.max_strain)));
        }
        if c.passes == 0 {
            return Err(invalid("constraints.passes", "must be >= 1".into()));
        }
        Ok(())
    }

    /// Whether the scene lists `effect`.
    pub fn has_effect(&self, effect: Effect) -> bool {
        self.simulation.effects.contains(&effect)
    }

    /// The model description: the scene's effects switched on from the
    /// effects table ([`Effect`]).
    pub fn model_spec(&self) -> ModelSpec {
        let mut spec = ModelSpec {
            panels: self.panels.clone(),
            meshes: self.meshes.clone(),
            material: self.material,
            pins: self.pins.clone(),
            seams: self.seams.clone(),
            effects: Effects::default(),
            wind: self.wind.clone(),
            collision: CollisionSpec {
                colliders: self.colliders.clone(),
                thickness_m: self.collision.map(|c| c.thickness_m),
                self_collision: self.self_collision,
                base_dir: self.base_dir.clone(),
            },
            kind: self.simulation.model,
            bending_law: self.simulation.bending_law,
            strain_limit: None,
        };
        let values =
            EffectValues { gravity_m_s2: Vec3::from(self.simulation.gravity_m_s2), strain_limit: self.constraints };
        for effect in &self.simulation.effects {
            effect.switch_on(&mut spec, &values);
        }
        spec
    }

    /// Checks every field and builds the model and the run configuration.
    /// Panels, material, pins and gravity are checked by the model builder,
    /// whose error paths (`panels[0].particles`) match the scene's keys.
    pub fn build(&self) -> Result<(ClothModel, RunConfig), SceneErrorKind> {
        self.check_run_fields()?;
        let model = ClothModel::build(&self.model_spec()).map_err(|e| SceneErrorKind::from(e.field_error()))?;
        let s = &self.simulation;
        if model.self_collision().is_some() && !s.integrator.handles_self_collision() {
            return Err(SceneErrorKind::Invalid {
                field: "simulation.integrator".into(),
                message: format!(
                    "{} does not handle self-collision: use backward-euler, bdf2 or vbd",
                    s.integrator.name()
                ),
            });
        }
        let config = RunConfig {
            integrator: s.integrator,
            dt_s: s.dt_s,
            steps: (s.duration_s / s.dt_s).round() as u64,
            initial_jitter_m: s.initial_jitter_m,
            solver: self.solver,
        };
        Ok((model, config))
    }
}

/// Sets `path=value` in a TOML table. `value` is parsed as a TOML value
/// (`1e-3`, `[75, 75]`, `"bdf2"`, `true`); bare words become strings.
/// Missing tables on the path are created; array elements are addressed by
/// index and must exist.
fn apply_override(table: &mut toml::Table, arg: &str) -> Result<(), String> {
    let (path, raw) = arg.split_once('=').ok_or("expected key.path=value")?;
    let keys: Vec<&str> = path.trim().split('.').collect();
    if keys.iter().any(|k| k.is_empty()) {
        return Err("empty key in the path".into());
    }
    let value = match toml::from_str::<toml::Table>(&format!("v = {}", raw.trim())) {
        Ok(mut t) => t.remove("v").expect("the key just parsed"),
        Err(_) => toml::Value::String(raw.trim().to_string()),
    };
    set_in_table(table, &keys, value)
}

fn set_in_table(t: &mut toml::Table, keys: &[&str], value: toml::Value) -> Result<(), String> {
    let (key, rest) = keys.split_first().expect("non-empty path");
    if rest.is_empty() {
        t.insert((*key).to_string(), value);
        return Ok(());
    }
    let child = t.entry(*key).or_insert_with(|| toml::Value::Table(toml::Table::new()));
    set_in_value(child, key, rest, value)
}

fn set_in_value(node: &mut toml::Value, name: &str, keys: &[&str], value: toml::Value) -> Result<(), String> {
    match node {
        toml::Value::Table(t) => set_in_table(t, keys, value),
        toml::Value::Array(a) => {
            let idx: usize = keys[0].parse().map_err(|_| format!("`{name}` is an array: index it with a number"))?;
            let len = a.len();
            let slot = a.get_mut(idx).ok_or_else(|| format!("`{name}` has {len} entries, no index {idx}"))?;
            if keys.len() == 1 {
                *slot = value;
                Ok(())
            } else {
                set_in_value(slot, keys[0], &keys[1..], value)
            }
        }
        _ => Err(format!("`{name}` is a value, not a table or an array")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BASE: &str = r#"
[simulation]
integrator = "bdf2"
dt_s = 0.01
duration_s = 0.1
effects = ["gravity"]

[material]
areal_density_kg_m2 = 0.1
tensile_stiffness_n_m = 100.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 100.0

[[panels]]
particles = [5, 4]
size_m = [1.0, 1.0]

[[pins]]
nodes = [[0, 3]]
"#;

    fn field_of(e: SceneErrorKind) -> String {
        match e {
            SceneErrorKind::Invalid { field, .. } => field,
            other => panic!("expected Invalid, got {other:?}"),
        }
    }

    fn check(text: &str, overrides: &[&str]) -> Result<Scene, SceneErrorKind> {
        let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        let s = Scene::parse(text, &o)?;
        s.validate()?;
        Ok(s)
    }

    #[test]
    fn base_scene_builds_and_counts_steps() {
        let (model, cfg) = check(BASE, &[]).unwrap().build().unwrap();
        assert_eq!(model.particle_count(), 20);
        assert_eq!(cfg.steps, 10);
        assert!(model.bend_links().is_empty(), "bending not listed, so no type-2 links");
        assert!(model.stretch_links().iter().all(|l| l.k_d == 0.0), "damping not listed");
    }

    #[test]
    fn overrides_set_nested_and_indexed_fields() {
        let s =
            check(BASE, &["panels.0.particles=[9, 7]", "solver.rel_tol=1e-6", "simulation.integrator=backward-euler"])
                .unwrap();
        assert_eq!(s.panels[0].particles, [9, 7]);
        assert_eq!(s.solver.rel_tol, 1e-6);
        assert_eq!(s.simulation.integrator, IntegratorKind::BackwardEuler);
        assert!(matches!(check(BASE, &["panels.3.particles=[9, 7]"]), Err(SceneErrorKind::Override { .. })));
        assert!(matches!(check(BASE, &["simulation.dt_s.x=1"]), Err(SceneErrorKind::Override { .. })));
        assert!(matches!(check(BASE, &["novalue"]), Err(SceneErrorKind::Override { .. })));
        // A misspelt key is an unknown field, not silently ignored.
        let e = check(BASE, &["solver.rel_toll=1e-6"]).unwrap_err();
        assert!(matches!(&e, SceneErrorKind::Parse(m) if m.contains("rel_toll")), "{e}");
    }

    #[test]
    fn bad_values_name_their_field() {
        let cases = [
            ("simulation.dt_s=-0.1", "simulation.dt_s"),
            ("simulation.duration_s=nan", "simulation.duration_s"),
            ("material.areal_density_kg_m2=-1.0", "material.areal_density_kg_m2"),
            ("material.tensile_stiffness_n_m=nan", "material.tensile_stiffness_n_m"),
            ("solver.rel_tol=2.0", "solver.rel_tol"),
            ("solver.adaptive.error_tolerance=0.0", "solver.adaptive.error_tolerance"),
            ("solver.adaptive.max_substeps=0", "solver.adaptive.max_substeps"),
            ("solver.newton.iterations=0", "solver.newton.iterations"),
            ("solver.newton.tolerance_m=-1e-6", "solver.newton.tolerance_m"),
            ("solver.newton.trigger=-0.25", "solver.newton.trigger"),
            ("solver.vbd.iterations=0", "solver.vbd.iterations"),
            ("solver.vbd.tolerance_m=-1.0", "solver.vbd.tolerance_m"),
            ("solver.vbd.chebyshev_rho=1.0", "solver.vbd.chebyshev_rho"),
            ("solver.quasi_newton.iterations=0", "solver.quasi_newton.iterations"),
            ("solver.quasi_newton.tolerance_m=nan", "solver.quasi_newton.tolerance_m"),
            ("constraints.max_strain=-0.1", "constraints.max_strain"),
            ("panels.0.particles=[1, 4]", "panels[0].particles"),
            ("panels.0.size_m=[1.0, inf]", "panels[0].size_m"),
            ("panels.0.size_m=[1e-200, 1e-200]", "panels[0].size_m"),
            ("pins.0.nodes=[[5, 0]]", "pins[0].nodes"),
            ("pins.0.panel=2", "pins[0].panel"),
            ("simulation.gravity_m_s2=[0.0, nan, 0.0]", "simulation.gravity_m_s2"),
            ("simulation.effects=[\"gravity\", \"gravity\"]", "simulation.effects"),
        ];
        for (o, field) in cases {
            assert_eq!(field_of(check(BASE, &[o]).unwrap_err()), field, "{o}");
        }
        for law in ["arc-path", "arc-chord"] {
            let set = format!("simulation.bending_law=\"{law}\"");
            assert_eq!(
                field_of(check(BASE, &["simulation.model=\"volino\"", &set]).unwrap_err()),
                "simulation.bending_law"
            );
            assert!(check(BASE, &[&set]).is_ok());
        }
        assert!(check(BASE, &["simulation.model=\"volino\""]).is_ok());
    }

    #[test]
    fn unknown_and_missing_keys_are_parse_errors() {
        let e = check(&BASE.replace("dt_s = 0.01", "dt = 0.01"), &[]).unwrap_err();
        assert!(matches!(&e, SceneErrorKind::Parse(m) if m.contains("dt")), "{e}");
        let e = check(&BASE.replace("effects = [\"gravity\"]", "effects = [\"gravty\"]"), &[]).unwrap_err();
        assert!(matches!(&e, SceneErrorKind::Parse(m) if m.contains("gravty")), "{e}");
        let e = check(&format!("{BASE}\n[extra]\nx = 1\n"), &[]).unwrap_err();
        assert!(matches!(&e, SceneErrorKind::Parse(m) if m.contains("extra")), "{e}");
    }

    #[test]
    fn every_effect_is_named_as_in_scene_files_and_switched_on_by_it() {
        for &e in Effect::ALL {
            let parsed: toml::Table = toml::from_str(&format!("e = \"{}\"", e.name())).unwrap();
            let back: Effect = parsed["e"].clone().try_into().unwrap();
            assert_eq!(back, e);
            let scene =
                Scene::parse(&BASE.replace("effects = [\"gravity\"]", &format!("effects = [\"{}\"]", e.name())), &[])
                    .unwrap();
            let spec = scene.model_spec();
            assert!(Effect::ALL.iter().all(|&o| o.is_on(&spec) == (o == e)), "{}", e.name());
        }
    }

    #[test]
    fn load_names_the_file() {
        let e = Scene::load(Path::new("/nonexistent/scene.toml"), &[]).unwrap_err();
        assert!(e.to_string().starts_with("/nonexistent/scene.toml: cannot read"), "{e}");
    }
}
