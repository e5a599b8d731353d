//! Output writers: OBJ frames and the run summary.

use cloth_core::{ClothModel, Vec3};
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// Writes positions and the model's triangles as a Wavefront OBJ file.
pub fn write_obj(path: &Path, model: &ClothModel, x: &[Vec3]) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    write_vertex_lines(&mut w, x)?;
    for t in model.triangles() {
        writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    w.flush()
}

/// Writes positions alone as a Wavefront OBJ file (vertices only, full
/// precision: each coordinate reads back to the same bits), after a
/// comment line `header`.
pub fn write_vertices(path: &Path, header: &str, x: &[Vec3]) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "# {header}")?;
    write_vertex_lines(&mut w, x)?;
    w.flush()
}

/// `v x y z` per position, full precision (`{}` of an `f64` reads back to
/// the same bits).
fn write_vertex_lines(w: &mut impl Write, x: &[Vec3]) -> std::io::Result<()> {
    for p in x {
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    Ok(())
}

/// Wall time per stage over the whole run, s.
#[derive(Debug, Default, Serialize)]
pub struct StageWall {
    /// Interaction laws on links (forces and Jacobian blocks).
    pub forces: f64,
    /// Matrix and right-hand side gather, pin constraints.
    pub assembly: f64,
    /// PCG.
    pub solve: f64,
    /// State update, friction and finiteness checks.
    pub update: f64,
    /// Cloth-solid narrow phase.
    pub collision: f64,
    /// Self-collision: spatial hash, pair tests, repulsion.
    pub self_collision: f64,
    /// Frame output.
    pub output: f64,
    /// The tangle check after each step: crossings of the cloth through
    /// itself, particles through a solid.
    pub tangle: f64,
}

impl StageWall {
    /// Every stage times `factor` (per step, per frame...).
    pub fn scaled(&self, factor: f64) -> StageWall {
        StageWall {
            forces: self.forces * factor,
            assembly: self.assembly * factor,
            solve: self.solve * factor,
            update: self.update * factor,
            collision: self.collision * factor,
            self_collision: self.self_collision * factor,
            output: self.output * factor,
            tangle: self.tangle * factor,
        }
    }

    /// All stages together, s.
    pub fn total(&self) -> f64 {
        self.forces
            + self.assembly
            + self.solve
            + self.update
            + self.collision
            + self.self_collision
            + self.output
            + self.tangle
    }
}

/// The cloth's hem and top along the character's up axis, in the frame of
/// its root link (the pelvis or hips: origin at its joint), m, negative
/// below: a skirt that slides down or a hem that rides up shows here.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct GarmentHeights {
    /// The lowest particle at the end.
    pub hem_m: f64,
    /// The highest particle at the end.
    pub top_m: f64,
    /// The lowest the hem was after the first step.
    pub hem_lowest_m: f64,
    /// The highest the hem rose after the first step.
    pub hem_highest_m: f64,
    /// The lowest the top sank after the first step.
    pub top_lowest_m: f64,
}

impl GarmentHeights {
    /// Heights `(hem, top)` at the end of a step, folded into the extremes.
    pub fn add(this: Option<Self>, (hem, top): (f64, f64)) -> Option<Self> {
        let seen =
            this.unwrap_or(Self { hem_m: hem, top_m: top, hem_lowest_m: hem, hem_highest_m: hem, top_lowest_m: top });
        Some(Self {
            hem_m: hem,
            top_m: top,
            hem_lowest_m: seen.hem_lowest_m.min(hem),
            hem_highest_m: seen.hem_highest_m.max(hem),
            top_lowest_m: seen.top_lowest_m.min(top),
        })
    }
}

/// `summary.json`.
#[derive(Debug, Serialize)]
pub struct Summary {
    pub scene: String,
    pub particles: usize,
    pub stretch_links: usize,
    pub bend_links: usize,
    pub effects: Vec<String>,
    /// The discretisation (`choi-ko`, `provot` or `volino`).
    pub model: String,
    pub integrator: String,
    pub threads: usize,
    pub steps: u64,
    pub dt_s: f64,
    pub sim_time_s: f64,
    pub wall_s: f64,
    /// Processor time of the steps, all threads, s (Linux, to 10 ms; absent elsewhere).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu_s: Option<f64>,
    /// Median wall time of one step, s.
    pub step_wall_s_median: f64,
    /// Force evaluations (implicit methods: one force and Jacobian evaluation per step).
    pub force_evaluations_total: u64,
    /// Accepted substeps (adaptive integrator; otherwise equal to `steps`).
    pub substeps_total: u64,
    /// Rejected substeps of the adaptive integrator.
    pub rejected_steps_total: u64,
    pub cg_iterations_total: u64,
    pub cg_iterations_max: usize,
    pub cg_iterations_mean: f64,
    pub unconverged_steps: u64,
    /// Largest type-1 length / rest length at the end.
    pub max_stretch_ratio: f64,
    /// Largest type-1 length / rest length at any step (and at the start).
    pub peak_stretch_ratio: f64,
    /// The seams' stitches (`[[seams]]`) and how closed they are at the
    /// end. Absent without seams.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seams: Option<SeamSummary>,
    /// Newton iterations (`solver.newton.iterations > 1`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub newton: Option<NewtonSummary>,
    /// The energy monitor (implicit integrators with an assembled matrix).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy: Option<EnergySummary>,
    pub min_z_m: f64,
    pub max_speed_m_s: f64,
    pub finite: bool,
    /// Solids the cloth can touch (colliders, rapier bodies' colliders, rig links).
    pub solids: usize,
    /// Triangles of the mesh solids among them (Choi & Ko's Table 1 column).
    pub solid_triangles: usize,
    /// Most cloth-solid contacts held in one step.
    pub contacts_max: usize,
    /// Deepest any particle was inside a solid, over all steps and the final state, m.
    pub max_penetration_m: f64,
    /// The force the cloth pulls its pins with, summed over the pins and
    /// averaged over the run's last 0.5 s, N (none without pins). At rest,
    /// the weight the pins carry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pin_load_n: Option<[f64; 3]>,
    /// Most self-collision pairs in one step.
    pub self_contacts_max: usize,
    /// Contacts released because they pulled.
    pub released_contacts_total: u64,
    /// Narrow-phase point queries against solids (0 without colliders).
    pub narrow_phase_queries_total: u64,
    /// Spatial-hash rebuilds (0 without self-collision).
    pub hash_builds_total: u64,
    /// Steps in which the cloth would have passed through itself, kept
    /// apart by impact zones (`self_collision.continuous`); absent when none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crossings: Option<CrossingSummary>,
    /// Whether the cloth tangled: through itself or through a solid.
    pub tangle: TangleSummary,
    /// Whether the deformation constraints held their limit (scenes with
    /// the `strain-limit` effect).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub strain_limit: Option<StrainLimitSummary>,
    /// The error that stopped the run, if any.
    pub error: Option<String>,
    /// What looked wrong before the first step (a character of an
    /// implausible height, or lying on its side); absent when nothing did.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub warnings: Vec<String>,
    pub stage_wall_s: StageWall,
    /// Where the cloth hangs on a rigged character (scenes with `[rig]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub garment: Option<GarmentHeights>,
    /// Rigid bodies at the end (scenes with `[[bodies]]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bodies: Option<Vec<BodySummary>>,
    /// Cloth-body coupling counters (scenes with `[[bodies]]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coupling: Option<CouplingSummary>,
}

/// Crossings of the cloth through itself met during a run.
#[derive(Debug, Serialize)]
pub struct CrossingSummary {
    /// Steps with a point-triangle or edge-edge pair meeting.
    pub steps: u64,
    /// Such pairs found, summed over the steps.
    pub meetings_total: u64,
    /// Pairs still meeting after the impact zones (a start already
    /// tangled, or zones held by pins), summed over the steps.
    pub left_total: u64,
}

/// Whether the cloth tangled, from the state after each step: its mesh
/// edges through its own triangles (stitched and adjacent elements left
/// out) and its particles deeper inside a solid than the contact thickness.
#[derive(Debug, Default, Serialize)]
pub struct TangleSummary {
    /// Most crossings of the cloth through itself after a step.
    pub self_crossings_max: usize,
    /// Crossings after the last step.
    pub self_crossings_end: usize,
    /// Steps after which the cloth crossed itself.
    pub self_crossing_steps: u64,
    /// Most particles deeper inside a solid than the contact thickness after a step.
    pub deep_in_solids_max: usize,
    /// Such particles after the last step.
    pub deep_in_solids_end: usize,
    /// The deepest a particle was inside a solid after any step, m.
    pub deepest_in_solids_m: f64,
    /// The first crossing that lasted (`cloth_core::LASTING_STEPS` steps), in words.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lasting_crossing: Option<String>,
    /// The first step that left cloth through a solid, in words.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub through_solid: Option<String>,
    /// When the first lasting crossing began, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lasting_crossing_from_s: Option<f64>,
    /// When cloth was first left through a solid, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub through_solid_at_s: Option<f64>,
}

/// Whether the deformation constraints held their limit, from the state
/// after each step (`cloth_core::over_stretched`): links left longer than
/// `StrainLimit::reported_ratio` times their rest length.
#[derive(Debug, Default, Serialize)]
pub struct StrainLimitSummary {
    /// The limit's length over the rest length, `1 + max_strain`.
    pub limit_ratio: f64,
    /// Steps after which a link was past the limit.
    pub steps_over: u64,
    /// The longest a link was over its rest length after such a step (the
    /// limit when none was past it).
    pub worst_ratio: f64,
    /// The first step that left a link past the limit, in words.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_over: Option<String>,
    /// When that was, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_over_at_s: Option<f64>,
}

/// How closed the seams are at the end of a run.
#[derive(Debug, Serialize)]
pub struct SeamSummary {
    /// Stitches (sewn node pairs).
    pub stitches: usize,
    /// Stitches closed at the end (a closed stitch holds with the seam's
    /// strength, an open one pulls with its sewing pull).
    pub closed: usize,
    /// Widest gap of a stitch at the end, m.
    pub max_gap_m: f64,
}

/// What the Newton iterations did over a run.
#[derive(Debug, Serialize)]
pub struct NewtonSummary {
    /// Steps whose Newton iterations the run engaged itself, its steps
    /// being large for its material (`solver.newton.auto_trigger`).
    pub automatic_steps: u64,
    /// The end of the first of them, s (none: never).
    pub engaged_at_s: Option<f64>,
    /// Steps that took Newton iterations alone because their single
    /// linearised step misjudged a link's tension
    /// (`solver.newton.auto_step_trigger`: a solid striking the cloth).
    pub struck_steps: u64,
    /// Newton corrections after each step's first linear solve.
    pub corrections_total: u64,
    pub corrections_max: usize,
    pub corrections_mean: f64,
    /// Halvings of a correction by the line search.
    pub backtracks_total: u64,
    /// Steps that ended with the residual above `solver.newton.tolerance_m`.
    pub unconverged_steps: u64,
    /// Largest final residual of a step, as a distance, m.
    pub residual_max_m: f64,
}

/// The energy balance over a run, J (see `cloth_core::EnergyReport`).
#[derive(Debug, Serialize)]
pub struct EnergySummary {
    /// Energies at the end.
    pub kinetic_j: f64,
    pub elastic_j: f64,
    pub gravitational_j: f64,
    /// Work of pins, external forces and solids (through their contacts),
    /// and dissipation by dampers and drag, over the run.
    pub pin_work_total_j: f64,
    pub external_work_total_j: f64,
    pub contact_work_total_j: f64,
    pub dissipated_total_j: f64,
    /// Energy the steps created beyond their loads (negative: numerical dissipation).
    pub gain_total_j: f64,
    /// Largest gain of one step (explicit integrators: of one window of
    /// `cloth_core::ENERGY_WINDOW` steps, whose dissipation is not
    /// measured).
    pub gain_max_j: f64,
    /// Steps (explicit integrators: windows) whose growth (gain without
    /// the dissipation) exceeded the tolerance (`cloth_core::GAIN_TOLERANCE`
    /// of the energy in play).
    pub flagged_steps: u64,
    /// BDF2 steps retaken as backward Euler because they were flagged.
    pub retaken_as_backward_euler_steps: u64,
    /// `backward-euler` steps flagged as a single linearised step and
    /// retaken with Newton iterations (`solver.newton.auto_iterations`).
    pub retaken_with_newton_steps: u64,
}

/// A rigid body at the end of a run.
#[derive(Debug, Serialize)]
pub struct BodySummary {
    pub name: String,
    /// Frame origin, m.
    pub position_m: [f64; 3],
    /// Orientation quaternion (x, y, z, w).
    pub rotation_xyzw: [f64; 4],
    /// Velocity of the centre of mass, m/s.
    pub velocity_m_s: [f64; 3],
    /// Angular velocity, rad/s.
    pub angular_velocity_rad_s: [f64; 3],
}

/// What the cloth-body coupling did over a run.
#[derive(Debug, Serialize)]
pub struct CouplingSummary {
    /// `staggered`, `iterated` or `monolithic`.
    pub master: String,
    /// Cloth-plus-bodies passes over the run (1 per step when staggered;
    /// monolithic: the cloths' solves, 1 or 2 a step).
    pub passes_total: u64,
    pub passes_max: usize,
    pub passes_mean: f64,
    /// Steps whose residual stayed over 1: the iterated master's best pass
    /// unconverged; the monolithic master's bodies moved, where cloth
    /// meets them, more than its tolerance from what rapier's contacts saw.
    pub unconverged_steps: u64,
    /// The largest step residual over its tolerance
    /// (`cloth_rapier::CouplingReport::residual`).
    pub residual_max: f64,
    /// Change of the total linear momentum of cloth and dynamic bodies over
    /// the run, N s. Gravity, pins and fixed or kinematic bodies change it;
    /// in a free scene without gravity it is the coupling's drift.
    pub linear_momentum_change_n_s: [f64; 3],
    /// The same for angular momentum about the world origin, N m s.
    pub angular_momentum_change_n_m_s: [f64; 3],
}
