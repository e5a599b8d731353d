//! The hard-case suite: scenes built to break a cloth
//! simulator (extreme steps, stiffness ratios and scales, violent pins,
//! crumpling, a fast solid, coincident particles, light and heavy coupled
//! bodies). Each case states what must hold and what it measured;
//! [`run_suite`] runs them all and judges each row. `cloth study
//! stability` writes the table; this crate's `stability` tests run each
//! of [`GROUPS`] on its own (two at a time on two cores) and fail on any
//! failed verdict, so the suite runs in CI.
//!
//! The scenes are written here, not in `fixtures/`, because each case
//! varies one thing of one small base scene: a 1 m square of the hang
//! fixture's cotton, 21 x 21 particles.

mod bodies;
mod cases;

use bodies::*;
use cases::*;
use cloth_core::scene::{Scene, SceneErrorKind};
use cloth_core::{EnergyBuffers, elastic_energy};
use cloth_core::{Simulation, StepError, StepReport, Vec3};
use std::time::Instant;

/// The base scene: the hang fixture's material on a 21 x 21 grid (5 cm
/// links), BDF2 at Choi & Ko's 1/90 s, 2 s; no pins (see [`CORNERS`]).
const BASE: &str = r#"
[simulation]
integrator = "bdf2"
dt_s = 0.011111111111111112
duration_s = 2.0
effects = ["gravity", "bending", "damping"]

[solver]
rel_tol = 1e-4
max_iter = 1000

[material]
areal_density_kg_m2 = 0.1
tensile_stiffness_n_m = 200.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 200.0
damping_n_s_m = 0.02

[[panels]]
particles = [21, 21]
size_m = [1.0, 1.0]
origin_m = [-0.5, -0.5, 1.0]
"#;

/// The stretch the base scene reaches at h = 1/90 s, with a margin: its
/// pinned corners peak at 1.15-1.18 in the first second (Choi & Ko's
/// arc-path law, whose boundary links stand for the half cell they border;
/// the pair law's full-cell boundary links: 1.14, Volino: 1.13).
const USUAL_STRETCH: f64 = 1.2;

/// The base scene's usual pins: the two corners of its far edge.
const CORNERS: &str = r#"
[[pins]]
nodes = [[0, 20], [20, 20]]
motion = { kind = "fixed" }
"#;

/// Rest link length of the base grid, m.
const LINK_M: f64 = 0.05;
/// Gravity of the base scene, m/s^2.
const G: f64 = 9.81;

/// A verdict: `Ok(what was measured)` or `Err(why the requirement fails)`.
pub type Verdict = Result<String, String>;

/// One row of the suite: a case run with one integrator and model.
#[derive(Debug, Clone)]
pub struct Row {
    /// The case.
    pub case: &'static str,
    /// What varies within the case (step, ratio, scale...).
    pub variant: String,
    /// Integrator (with the Newton iterations when more than one solve).
    pub integrator: String,
    /// Cloth model.
    pub model: String,
    /// What must hold.
    pub requirement: String,
    /// "ran N steps", or the typed error that stopped the run.
    pub outcome: String,
    /// Largest type-1 link stretch at any step (NaN when nothing ran).
    pub worst_stretch: f64,
    /// Deepest penetration into a solid at any step, m.
    pub penetration_m: f64,
    /// Mean CG iterations per step.
    pub cg_per_step: f64,
    /// Wall time of the steps, s.
    pub wall_s: f64,
    /// Whether the requirement holds, with what was measured.
    pub verdict: Verdict,
    /// A failure that is known and explained (and still open): the row is
    /// expected to fail; the suite fails when it holds (remove the note).
    pub known_defect: Option<&'static str>,
}

impl Row {
    /// Whether the row is as expected: holds, or fails as a known defect.
    pub fn as_expected(&self) -> bool {
        self.verdict.is_ok() == self.known_defect.is_none()
    }
}

/// What stepping a simulation measured.
struct Probe {
    steps: u64,
    cg: u64,
    worst_stretch: f64,
    penetration: f64,
    wall_s: f64,
    error: Option<StepError>,
}

impl Probe {
    fn new() -> Self {
        Probe { steps: 0, cg: 0, worst_stretch: 1.0, penetration: 0.0, wall_s: 0.0, error: None }
    }

    fn outcome(&self) -> String {
        match &self.error {
            None => format!("ran {} steps", self.steps),
            Some(e) => format!("stopped: {e}"),
        }
    }

    /// Finite and not stopped.
    fn ran(&self) -> Result<(), String> {
        self.error.as_ref().map_or(Ok(()), |e| Err(format!("stopped: {e}")))
    }

    fn stretch_at_most(&self, limit: f64) -> Verdict {
        self.ran()?;
        let s = self.worst_stretch;
        if s <= limit { Ok(format!("stretch {s:.3}")) } else { Err(format!("stretch {s:.3} > {limit}")) }
    }
}

/// One variant of a case: the base scene plus `extra` TOML and overrides.
struct Case {
    case: &'static str,
    variant: String,
    extra: String,
    overrides: Vec<String>,
    requirement: &'static str,
    known_defect: Option<&'static str>,
}

impl Case {
    fn new(case: &'static str, variant: impl Into<String>, requirement: &'static str) -> Self {
        Self {
            case,
            variant: variant.into(),
            extra: CORNERS.into(),
            overrides: Vec::new(),
            requirement,
            known_defect: None,
        }
    }

    fn known_defect(mut self, why: Option<&'static str>) -> Self {
        self.known_defect = why;
        self
    }

    fn extra(mut self, extra: impl Into<String>) -> Self {
        self.extra = extra.into();
        self
    }

    fn set(mut self, key: &str, value: impl std::fmt::Display) -> Self {
        self.overrides.push(format!("{key}={value}"));
        self
    }

    fn integrator(self, name: &str) -> Self {
        self.set("simulation.integrator", name)
    }

    fn model(self, name: &str) -> Self {
        self.set("simulation.model", format!("\"{name}\""))
    }

    /// The scene built into a simulation, with its step and step count.
    fn build(&self) -> Result<(Simulation, f64, u64), SceneErrorKind> {
        let (model, cfg) = Scene::parse(&format!("{BASE}{}", self.extra), &self.overrides)?.build()?;
        Ok((cfg.simulation(model), cfg.dt_s, cfg.steps))
    }

    /// Builds, lets `prepare` set the start, steps (calling `each` after
    /// every step) and returns the probe and the final simulation.
    fn run(
        &self,
        prepare: impl FnOnce(&mut Simulation),
        each: impl FnMut(&Simulation, &StepReport),
    ) -> Result<(Probe, Simulation), String> {
        let (mut sim, h, steps) = self.build().map_err(|e| format!("the scene does not build: {e}"))?;
        prepare(&mut sim);
        let p = probe(&mut sim, h, steps, each);
        Ok((p, sim))
    }

    /// Runs from the scene's own start and judges the result.
    fn judge(self, judge: impl FnOnce(&Probe, &Simulation) -> Verdict) -> Row {
        match self.run(|_| {}, |_, _| {}) {
            Ok((p, sim)) => {
                let verdict = judge(&p, &sim);
                self.row(Some(&p), verdict)
            }
            Err(e) => self.row(None, Err(e)),
        }
    }

    /// The last override of `key`, unquoted, or `default`.
    fn value(&self, key: &str, default: &str) -> String {
        let prefix = format!("{key}=");
        self.overrides
            .iter()
            .rev()
            .find_map(|o| o.strip_prefix(&prefix).map(|v| v.trim_matches('"').to_string()))
            .unwrap_or_else(|| default.to_string())
    }

    fn row(&self, p: Option<&Probe>, verdict: Verdict) -> Row {
        let mut integrator = self.value("simulation.integrator", "bdf2");
        let newton = self.value("solver.newton.iterations", "1");
        if newton != "1" {
            integrator = format!("{integrator} + Newton {newton}");
            let trigger = self.value("solver.newton.trigger", "0");
            if trigger != "0" {
                integrator = format!("{integrator} where off by {trigger}");
            }
        }
        Row {
            case: self.case,
            variant: self.variant.clone(),
            integrator,
            model: self.value("simulation.model", "choi-ko"),
            requirement: self.requirement.into(),
            outcome: p.map_or_else(|| "did not build".into(), Probe::outcome),
            worst_stretch: p.map_or(f64::NAN, |p| p.worst_stretch),
            penetration_m: p.map_or(0.0, |p| p.penetration),
            cg_per_step: p.map_or(0.0, |p| p.cg as f64 / p.steps.max(1) as f64),
            wall_s: p.map_or(0.0, |p| p.wall_s),
            verdict,
            known_defect: self.known_defect,
        }
    }
}

/// Steps `sim` `steps` times at `h`, measuring after every step and
/// calling `each`; stops at the first error.
fn probe(sim: &mut Simulation, h: f64, steps: u64, mut each: impl FnMut(&Simulation, &StepReport)) -> Probe {
    let mut p = Probe::new();
    let solids = !sim.model().colliders().is_empty();
    for _ in 0..steps {
        let t = Instant::now();
        let result = sim.step(h);
        p.wall_s += t.elapsed().as_secs_f64();
        let report = match result {
            Ok(r) => r,
            Err(e) => {
                p.error = Some(e);
                break;
            }
        };
        p.cg += report.cg_iterations as u64;
        p.steps += 1;
        p.worst_stretch = p.worst_stretch.max(sim.model().max_stretch_ratio(&sim.state().x));
        if solids {
            p.penetration = p.penetration.max(sim.max_penetration());
        }
        each(sim, &report);
    }
    p
}

/// Implicit integrators the cases run: Choi & Ko's BDF2 and backward Euler.
const IMPLICIT: [&str; 2] = ["bdf2", "backward-euler"];

fn integrators(quick: bool) -> &'static [&'static str] {
    if quick { &IMPLICIT[..1] } else { &IMPLICIT[..] }
}

/// Runs the whole suite; `quick` keeps one variant of each case.
pub fn run_suite(quick: bool) -> Vec<Row> {
    GROUPS.iter().flat_map(|g| (g.run)(quick)).collect()
}

/// A part of the suite that runs on its own: a name for it and the
/// function that runs its rows (`quick`: fewer integrators and steps).
pub struct Group {
    /// What the group varies.
    pub name: &'static str,
    /// Runs its rows.
    pub run: fn(bool) -> Vec<Row>,
}

/// The suite's groups, in the table's order.
pub const GROUPS: &[Group] = &[
    Group { name: "step sizes", run: step_sizes },
    Group { name: "explicit stability limit", run: explicit_stability_limit },
    Group { name: "stiffness ratios", run: stiffness_ratios },
    Group { name: "crumpled", run: crumpled },
    Group { name: "yanked", run: yanked },
    Group { name: "released from ten times", run: released_from_ten_times },
    Group { name: "shaken", run: shaken },
    Group { name: "ball through a curtain", run: ball_through_curtain },
    Group { name: "pulled across a table", run: pulled_across_a_table },
    Group { name: "scales", run: scales },
    Group { name: "coincident particles", run: |_| coincident_particles() },
    Group { name: "coupled mass ratios", run: coupled_mass_ratios },
    Group { name: "body resting on cloth", run: resting_box },
];

/// `cloth study stability`'s Markdown table.
pub fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| case | variant | integrator | model | must hold | outcome | worst stretch | penetration (mm) | \
         CG/step | wall (s) | verdict |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {:.3} | {:.2} | {:.1} | {:.2} | {} |\n",
            r.case,
            r.variant,
            r.integrator,
            r.model,
            r.requirement,
            r.outcome.replace('|', "/"),
            r.worst_stretch,
            r.penetration_m * 1e3,
            r.cg_per_step,
            r.wall_s,
            match (&r.verdict, r.known_defect) {
                (Ok(m), None) => format!("holds: {m}"),
                (Err(e), None) => format!("**fails**: {e}"),
                (Err(e), Some(why)) => format!("known defect: {e} ({why})"),
                (Ok(m), Some(_)) => format!("**holds although marked a known defect**: {m}"),
            }
        ));
    }
    s
}

/// Every row as CSV.
pub fn csv(rows: &[Row]) -> anyhow::Result<crate::table::CsvTable> {
    let mut table = crate::table::CsvTable::new(&[
        "case",
        "variant",
        "integrator",
        "model",
        "requirement",
        "outcome",
        "worst_stretch",
        "penetration_m",
        "cg_per_step",
        "wall_s",
        "holds",
        "measured",
    ]);
    for r in rows {
        let (holds, measured) = match &r.verdict {
            Ok(m) => (true, m),
            Err(e) => (false, e),
        };
        table.row([
            r.case.to_string(),
            r.variant.clone(),
            r.integrator.clone(),
            r.model.to_string(),
            r.requirement.clone(),
            r.outcome.clone(),
            format!("{:.4}", r.worst_stretch),
            format!("{:.3e}", r.penetration_m),
            format!("{:.1}", r.cg_per_step),
            format!("{:.3}", r.wall_s),
            holds.to_string(),
            measured.clone(),
        ])?;
    }
    Ok(table)
}
