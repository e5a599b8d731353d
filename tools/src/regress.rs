//! `cloth regress`: every fixture scene and the Table-1 garments, each
//! shortened, against golden results committed under `fixtures/goldens/`.
//!
//! A case's golden is two files: `NAME.json` (how the case ran, the fields
//! of its `summary.json` that the physics decides, and the step time when
//! recorded, shown but never compared) and `NAME.final.obj` (the cloth's
//! positions after the last step, full precision, vertices only).
//!
//! What is compared, and how closely:
//! - the physics fields of the summary (counts, stretch, energies,
//!   contacts, penetration, bodies, errors) and the final positions: bit
//!   for bit. Determinism promises it for the same source on the same
//!   platform (with 1 or 2 threads, in test and release builds alike:
//!   checked on hang, skirt-walk, tablecloth and drape-sphere), so a single
//!   flipped bit is a change in what the code computes. On another
//!   platform (another libm, another compiler) the promise does not hold;
//!   `--rel-tol` then accepts floats within that relative tolerance and
//!   positions within it times the golden cloth's extent;
//! - timing (wall, CPU and stage seconds, threads, the scene's path):
//!   never compared; the step time is printed beside the golden's.

use crate::bench::GARMENTS;
use crate::output::write_vertices;
use crate::run::{SimulateOptions, simulate_steps};
use anyhow::{Context, Result, bail};
use cloth_collide::parse_obj_points;
use cloth_core::Vec3;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Steps a fixture runs (fewer when the scene has fewer): two thirds of a
/// second at Choi & Ko's 1/90 s, enough for contacts to form, seams to
/// start closing and rigs to move; all fixtures together take about 25 s
/// on 2 cores.
pub const FIXTURE_STEPS: u64 = 60;

/// Steps a Table-1 garment runs: six frames of 30 Hz animation.
pub const TABLE1_STEPS: u64 = 18;

/// Summary fields that measure time or name the machine's paths, never
/// compared.
const NOT_COMPARED: [&str; 6] = ["scene", "threads", "wall_s", "cpu_s", "step_wall_s_median", "stage_wall_s"];

/// Changes listed per case before "and N more".
const LISTED_CHANGES: usize = 12;

/// Options of `cloth regress`.
pub struct RegressArgs {
    /// The fixtures directory (with `scenes/`).
    pub fixtures: PathBuf,
    /// Where the goldens are (default `FIXTURES/goldens`).
    pub goldens: Option<PathBuf>,
    /// Rewrite the goldens of the cases that changed (or are new), delete
    /// goldens no case has.
    pub update: bool,
    /// Only these cases (all when empty).
    pub only: Vec<String>,
    /// Worker threads.
    pub threads: usize,
    /// Relative tolerance of floats and final positions (0: bit for bit).
    pub rel_tol: f64,
}

/// One regression case: a scene, its overrides and a step cap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Case {
    name: String,
    /// The scene file, relative to the fixtures directory.
    scene: String,
    overrides: Vec<String>,
    max_steps: u64,
}

/// `NAME.json`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Golden {
    case: Case,
    /// The summary without the fields in [`NOT_COMPARED`].
    summary: Map<String, Value>,
    /// Median wall time of a step when recorded, s (shown, not compared).
    step_wall_s_median: f64,
}

/// How a case compares with its golden.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    /// Bit for bit.
    Same,
    /// Within `--rel-tol`, not bit for bit.
    Close,
    Changed,
    /// No golden yet.
    New,
    /// A golden no case has.
    Stale,
    /// The case did not run (its scene does not load).
    Failed,
}

impl Outcome {
    fn passes(self) -> bool {
        matches!(self, Outcome::Same | Outcome::Close)
    }

    fn label(self, update: bool) -> &'static str {
        match (self, update) {
            (Outcome::Same, _) => "same",
            (Outcome::Close, _) => "within tolerance",
            (Outcome::Changed, false) => "CHANGED",
            (Outcome::New, false) => "NEW (no golden)",
            (Outcome::Stale, false) => "STALE golden (no such case)",
            (Outcome::Changed, true) => "changed: golden rewritten",
            (Outcome::New, true) => "new: golden written",
            (Outcome::Stale, true) => "stale: golden deleted",
            (Outcome::Failed, _) => "FAILED",
        }
    }
}

/// One difference from the golden.
#[derive(Debug, PartialEq)]
struct Change {
    field: String,
    golden: String,
    now: String,
}

/// What one case did.
struct Checked {
    name: String,
    outcome: Outcome,
    particles: Option<usize>,
    steps: Option<u64>,
    step_ms: Option<(Option<f64>, f64)>,
    changes: Vec<Change>,
}

/// Runs the cases, compares (or, with `update`, rewrites) their goldens,
/// prints the table; fails when a case differs from its golden.
pub fn regress(args: &RegressArgs) -> Result<()> {
    if !(args.rel_tol.is_finite() && args.rel_tol >= 0.0) {
        bail!("--rel-tol must be finite and >= 0, got {}", args.rel_tol);
    }
    let goldens = args.goldens.clone().unwrap_or_else(|| args.fixtures.join("goldens"));
    let all = cases(&args.fixtures)?;
    if let Some(unknown) = args.only.iter().find(|o| !all.iter().any(|c| &c.name == *o)) {
        let names: Vec<&str> = all.iter().map(|c| c.name.as_str()).collect();
        bail!("--only {unknown}: no such case (the cases: {})", names.join(", "));
    }
    let selected: Vec<&Case> = all.iter().filter(|c| args.only.is_empty() || args.only.contains(&c.name)).collect();
    if args.update {
        std::fs::create_dir_all(&goldens).with_context(|| format!("creating {}", goldens.display()))?;
    }
    println!("| case | particles | steps | ms/step golden -> now | result |");
    println!("|---|---|---|---|---|");
    let mut checked = Vec::new();
    for case in selected {
        let c = check(case, &args.fixtures, &goldens, args)?;
        print_row(&c, args.update);
        checked.push(c);
    }
    if args.only.is_empty() {
        for name in stale_goldens(&goldens, &all) {
            if args.update {
                for path in golden_paths(&goldens, &name) {
                    std::fs::remove_file(&path).with_context(|| format!("deleting {}", path.display()))?;
                }
            }
            let c =
                Checked { name, outcome: Outcome::Stale, particles: None, steps: None, step_ms: None, changes: vec![] };
            print_row(&c, args.update);
            checked.push(c);
        }
    }
    print_changes(&checked);
    let failed = checked.iter().filter(|c| c.outcome == Outcome::Failed).count();
    let differ = checked.iter().filter(|c| !c.outcome.passes() && c.outcome != Outcome::Failed).count();
    if failed > 0 {
        bail!("{failed} of {} cases did not run", checked.len());
    }
    if differ > 0 && !args.update {
        bail!(
            "{differ} of {} cases differ from their goldens in {} (after a deliberate change: cloth regress --update)",
            checked.len(),
            goldens.display()
        );
    }
    Ok(())
}

/// Every scene under `FIXTURES/scenes` (sorted by name), then the Table-1
/// garments at the paper's particle counts (`table1-NAME`).
fn cases(fixtures: &Path) -> Result<Vec<Case>> {
    let dir = fixtures.join("scenes");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .with_context(|| format!("reading {} (--fixtures)", dir.display()))?
        .filter_map(|e| e.ok())
        .filter_map(|e| e.file_name().to_str().and_then(|n| n.strip_suffix(".toml")).map(str::to_owned))
        .collect();
    names.sort();
    let mut cases: Vec<Case> = names
        .into_iter()
        .map(|name| Case { scene: format!("scenes/{name}.toml"), name, overrides: vec![], max_steps: FIXTURE_STEPS })
        .collect();
    for g in &GARMENTS {
        let file = Path::new(g.scene).file_name().and_then(|f| f.to_str()).expect("a Table-1 scene file name");
        cases.push(Case {
            name: format!("table1-{}", g.name),
            scene: format!("scenes/{file}"),
            overrides: g.overrides(),
            max_steps: TABLE1_STEPS,
        });
    }
    Ok(cases)
}

/// `NAME.json` and `NAME.final.obj` under `goldens`.
fn golden_paths(goldens: &Path, name: &str) -> [PathBuf; 2] {
    [goldens.join(format!("{name}.json")), goldens.join(format!("{name}.final.obj"))]
}

/// Names of the goldens no case has.
fn stale_goldens(goldens: &Path, cases: &[Case]) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(goldens) else { return vec![] };
    let mut stale: Vec<String> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| e.file_name().to_str().and_then(|n| n.strip_suffix(".json")).map(str::to_owned))
        .filter(|name| !cases.iter().any(|c| &c.name == name))
        .collect();
    stale.sort();
    stale
}

/// Runs one case and compares it with (or writes) its golden.
fn check(case: &Case, fixtures: &Path, goldens: &Path, args: &RegressArgs) -> Result<Checked> {
    let [json_path, obj_path] = golden_paths(goldens, &case.name);
    let golden = read_golden(&json_path, &obj_path)?;
    let opts = SimulateOptions { threads: args.threads, max_steps: Some(case.max_steps), ..Default::default() };
    let run = simulate_steps(&fixtures.join(&case.scene), &case.overrides, opts);
    let run = match run {
        Ok(run) => run,
        Err(e) => {
            let change = Change { field: "did not run".into(), golden: String::new(), now: format!("{e:#}") };
            return Ok(Checked {
                name: case.name.clone(),
                outcome: Outcome::Failed,
                particles: None,
                steps: None,
                step_ms: None,
                changes: vec![change],
            });
        }
    };
    let mut summary = match serde_json::to_value(&run.summary)? {
        Value::Object(map) => map,
        _ => unreachable!("a summary serialises to an object"),
    };
    for key in NOT_COMPARED {
        summary.remove(key);
    }
    let (outcome, changes, golden_ms) = match &golden {
        None => (Outcome::New, vec![], None),
        Some((g, x)) => {
            let mut changes = Vec::new();
            if g.case != *case {
                changes.push(Change {
                    field: "case".into(),
                    golden: serde_json::to_string(&g.case)?,
                    now: serde_json::to_string(case)?,
                });
            }
            let mut close = false;
            compare_maps("", &g.summary, &summary, args.rel_tol, &mut changes, &mut close);
            close |= compare_positions(x, &run.final_x, args.rel_tol, &mut changes);
            let outcome = match (changes.is_empty(), close) {
                (false, _) => Outcome::Changed,
                (true, true) => Outcome::Close,
                (true, false) => Outcome::Same,
            };
            (outcome, changes, Some(g.step_wall_s_median * 1e3))
        }
    };
    if args.update && matches!(outcome, Outcome::Changed | Outcome::New) {
        let golden = Golden { case: case.clone(), summary, step_wall_s_median: run.summary.step_wall_s_median };
        std::fs::write(&json_path, serde_json::to_string_pretty(&golden)? + "\n")
            .with_context(|| format!("writing {}", json_path.display()))?;
        let header = format!("cloth regress: {}, positions (m) after {} steps", case.name, run.summary.steps);
        write_vertices(&obj_path, &header, &run.final_x).with_context(|| format!("writing {}", obj_path.display()))?;
    }
    Ok(Checked {
        name: case.name.clone(),
        outcome,
        particles: Some(run.summary.particles),
        steps: Some(run.summary.steps),
        step_ms: Some((golden_ms, run.summary.step_wall_s_median * 1e3)),
        changes,
    })
}

/// A case's golden, if it has one.
fn read_golden(json_path: &Path, obj_path: &Path) -> Result<Option<(Golden, Vec<Vec3>)>> {
    if !json_path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(json_path).with_context(|| format!("reading {}", json_path.display()))?;
    let golden: Golden =
        serde_json::from_str(&text).with_context(|| format!("{}: not a golden", json_path.display()))?;
    let text = std::fs::read_to_string(obj_path).with_context(|| format!("reading {}", obj_path.display()))?;
    let frame = parse_obj_points(&text).with_context(|| obj_path.display().to_string())?;
    Ok(Some((golden, frame.vertices)))
}

/// Compares two summary values field by field, numbers bit for bit (or
/// within `rel_tol`, which sets `close`).
fn compare_values(path: &str, golden: &Value, now: &Value, rel_tol: f64, out: &mut Vec<Change>, close: &mut bool) {
    match (golden, now) {
        (Value::Object(g), Value::Object(n)) => compare_maps(path, g, n, rel_tol, out, close),
        (Value::Array(g), Value::Array(n)) if g.len() == n.len() => {
            for (i, (a, b)) in g.iter().zip(n).enumerate() {
                compare_values(&format!("{path}[{i}]"), a, b, rel_tol, out, close);
            }
        }
        (Value::Number(a), Value::Number(b)) if a.is_f64() || b.is_f64() => {
            let (a, b) = (a.as_f64().unwrap_or(f64::NAN), b.as_f64().unwrap_or(f64::NAN));
            if a.to_bits() != b.to_bits() {
                if (a - b).abs() <= rel_tol * a.abs().max(b.abs()) {
                    *close = true;
                } else {
                    out.push(Change { field: path.into(), golden: a.to_string(), now: b.to_string() });
                }
            }
        }
        (g, n) if g != n => out.push(Change { field: path.into(), golden: g.to_string(), now: n.to_string() }),
        _ => {}
    }
}

/// [`compare_values`] of two objects, key by key in sorted order (a key
/// on one side only is compared with "(absent)").
fn compare_maps(
    path: &str,
    golden: &Map<String, Value>,
    now: &Map<String, Value>,
    rel_tol: f64,
    out: &mut Vec<Change>,
    close: &mut bool,
) {
    let mut keys: Vec<&String> = golden.keys().chain(now.keys().filter(|k| !golden.contains_key(*k))).collect();
    keys.sort();
    let absent = Value::String("(absent)".into());
    for key in keys {
        let child = if path.is_empty() { key.to_string() } else { format!("{path}.{key}") };
        compare_values(
            &child,
            golden.get(key).unwrap_or(&absent),
            now.get(key).unwrap_or(&absent),
            rel_tol,
            out,
            close,
        );
    }
}

/// Compares final positions: bit for bit, or each within `rel_tol` times
/// the golden cloth's extent (its bounding box's diagonal). Returns whether
/// they differ within the tolerance.
fn compare_positions(golden: &[Vec3], now: &[Vec3], rel_tol: f64, out: &mut Vec<Change>) -> bool {
    if golden.len() != now.len() {
        out.push(Change {
            field: "final positions".into(),
            golden: format!("{} particles", golden.len()),
            now: format!("{} particles", now.len()),
        });
        return false;
    }
    let bits = |p: &Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let moved = golden.iter().zip(now).filter(|(a, b)| bits(a) != bits(b)).count();
    if moved == 0 {
        return false;
    }
    let (worst, distance) = golden
        .iter()
        .zip(now)
        .map(|(a, b)| (a - b).norm())
        .enumerate()
        .fold((0, 0.0f64), |best, (i, d)| if d > best.1 || d.is_nan() { (i, d) } else { best });
    let (lo, hi) = golden
        .iter()
        .fold((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    if distance <= rel_tol * (hi - lo).norm() {
        return true;
    }
    out.push(Change {
        field: "final positions".into(),
        golden: format!("particle {worst} at {:?}", golden[worst].as_slice()),
        now: format!("{moved} of {} particles moved, most {distance:.3e} m (particle {worst})", golden.len()),
    });
    false
}

fn print_row(c: &Checked, update: bool) {
    let opt = |v: Option<String>| v.unwrap_or_else(|| "-".into());
    let ms = c.step_ms.map(|(g, n)| match g {
        Some(g) => format!("{g:.2} -> {n:.2}"),
        None => format!("- -> {n:.2}"),
    });
    println!(
        "| {} | {} | {} | {} | {} |",
        c.name,
        opt(c.particles.map(|p| p.to_string())),
        opt(c.steps.map(|s| s.to_string())),
        opt(ms),
        c.outcome.label(update)
    );
}

/// Every changed field, golden -> now, per case.
fn print_changes(checked: &[Checked]) {
    let mut text = String::new();
    for c in checked.iter().filter(|c| !c.changes.is_empty()) {
        let _ = writeln!(text, "\n{}:", c.name);
        for ch in c.changes.iter().take(LISTED_CHANGES) {
            let _ = match ch.golden.as_str() {
                "" => writeln!(text, "  {}: {}", ch.field, ch.now),
                golden => writeln!(text, "  {}: {golden} -> {}", ch.field, ch.now),
            };
        }
        if c.changes.len() > LISTED_CHANGES {
            let _ = writeln!(text, "  and {} more", c.changes.len() - LISTED_CHANGES);
        }
    }
    print!("{text}");
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn changes(golden: Value, now: Value, rel_tol: f64) -> (Vec<Change>, bool) {
        let (mut out, mut close) = (Vec::new(), false);
        compare_values("", &golden, &now, rel_tol, &mut out, &mut close);
        (out, close)
    }

    #[test]
    fn one_bit_of_a_float_is_a_change_unless_a_tolerance_allows_it() {
        let a = 1.125f64;
        let b = f64::from_bits(a.to_bits() + 1);
        let (out, close) = changes(json!({"s": {"x": a}}), json!({"s": {"x": b}}), 0.0);
        assert_eq!(out, vec![Change { field: "s.x".into(), golden: a.to_string(), now: b.to_string() }]);
        assert!(!close);
        let (out, close) = changes(json!({"s": {"x": a}}), json!({"s": {"x": b}}), 1e-12);
        assert!(out.is_empty() && close);
    }

    #[test]
    fn counts_and_absent_fields_are_compared_exactly() {
        let (out, _) = changes(json!({"n": 3, "e": null, "v": [1, 2]}), json!({"n": 4, "v": [1, 2], "w": true}), 1.0);
        let fields: Vec<&str> = out.iter().map(|c| c.field.as_str()).collect();
        assert_eq!(fields, ["e", "n", "w"]);
        assert_eq!(out[0].now, "\"(absent)\"");
    }

    #[test]
    fn goldens_without_a_case_are_stale() {
        let dir = std::env::temp_dir().join(format!("cloth-regress-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for file in ["hang.json", "hang.final.obj", "gone.json", "gone.final.obj", "notes.txt"] {
            std::fs::write(dir.join(file), "").unwrap();
        }
        let hang = Case { name: "hang".into(), scene: "scenes/hang.toml".into(), overrides: vec![], max_steps: 60 };
        assert_eq!(stale_goldens(&dir, &[hang]), ["gone"]);
        assert!(stale_goldens(&dir.join("absent"), &[]).is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn positions_report_how_many_moved_and_the_farthest() {
        let golden = vec![Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let mut now = golden.clone();
        assert!(!compare_positions(&golden, &now, 0.0, &mut vec![]));
        now[2].z = 1e-6;
        now[1].x = f64::from_bits(1f64.to_bits() + 1);
        let mut out = vec![];
        assert!(!compare_positions(&golden, &now, 0.0, &mut out));
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].now, "2 of 3 particles moved, most 1.000e-6 m (particle 2)");
        // Within 1e-6 of the 1.41 m extent.
        assert!(compare_positions(&golden, &now, 1e-6, &mut vec![]));
    }
}
