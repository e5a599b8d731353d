//! `cloth study vbd`: what the minimisers' accuracy costs (the vertex
//! solver's sweeps, the quasi-Newton step's iterations), on four scenes
//! and a garment on the walking mannequin,
//! against a converged BDF2/Newton reference, beside BDF2; and where the
//! sweeps leave stiff stretch unconverged, so that a cloth looks softer
//! than its material.

use super::{StudyArgs, grid, header, monitored_run, setup, write_outputs};
use crate::svg::{Axes, Series, line_plot};
use anyhow::Result;
use cloth_core::{ClothModel, Vec3};
use cloth_tools::table::CsvTable;
use std::fmt::Write as _;

/// One scene of the study: its file and overrides (1 s of simulation; the
/// garment 1.5 s).
struct Case {
    name: &'static str,
    scene: &'static str,
    overrides: Vec<String>,
}

fn cases(quick: bool) -> Vec<Case> {
    let n = if quick { 11 } else { 21 };
    let mut hang = grid(n, "corners");
    hang.push("simulation.duration_s=1.0".into());
    let mut drape = grid(n, "none");
    drape.push("simulation.duration_s=1.0".into());
    let mut all = vec![
        Case { name: "hanging cloth", scene: "fixtures/scenes/hang.toml", overrides: hang },
        Case { name: "drape on a sphere", scene: "fixtures/scenes/drape-sphere.toml", overrides: drape },
        Case {
            name: "Peirce's cantilever",
            scene: "fixtures/scenes/cantilever.toml",
            overrides: vec!["simulation.duration_s=1.0".into()],
        },
        Case {
            name: "catenary",
            scene: "fixtures/scenes/catenary.toml",
            overrides: vec!["simulation.duration_s=1.0".into()],
        },
        // A garment: the mannequin stands 0.5 s, then the walk blends in.
        Case {
            name: "skirt on the walking mannequin",
            scene: "fixtures/scenes/skirt-walk.toml",
            overrides: vec!["simulation.duration_s=1.5".into()],
        },
    ];
    if quick {
        all.truncate(1);
    }
    all
}

/// The reference: BDF2 with Newton iterations to 1e-9 m at h = 1/960 s.
fn reference_overrides() -> Vec<String> {
    [
        "simulation.integrator=bdf2",
        "simulation.dt_s=0.0010416666666666667",
        "solver.rel_tol=1e-10",
        "solver.max_iter=10000",
        "solver.newton.iterations=20",
        "solver.newton.tolerance_m=1e-9",
    ]
    .map(String::from)
    .to_vec()
}

/// Mean tensile strain of the surface triangles' edges, `max(0, |e| /
/// |e_0| - 1)`, over every edge of every triangle (a measure of stretch
/// every model shares; edges in compression count as 0).
fn mean_strain(model: &ClothModel, x: &[Vec3]) -> f64 {
    let rest = model.rest_positions();
    let mut sum = 0.0;
    let mut count = 0usize;
    for tri in model.triangles() {
        for k in 0..3 {
            let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
            sum += ((x[a] - x[b]).norm() / (rest[a] - rest[b]).norm() - 1.0).max(0.0);
            count += 1;
        }
    }
    sum / count as f64
}

fn rms(a: &[Vec3], b: &[Vec3]) -> f64 {
    (a.iter().zip(b).map(|(p, q)| (p - q).norm_squared()).sum::<f64>() / a.len() as f64).sqrt()
}

/// What one run gives the tables: RMS error (m, NaN when it blew up),
/// CPU s, and its mean strain over the reference's.
struct Outcome {
    error: f64,
    cpu_s: f64,
    strain_ratio: f64,
    stable: bool,
}

impl Outcome {
    /// The run's row of the study's CSV.
    fn csv_row(&self, scene: String, method: String, h: f64) -> [String; 7] {
        [
            scene,
            method,
            h.to_string(),
            format!("{:.6e}", self.error),
            format!("{:.2}", self.cpu_s),
            format!("{:.4}", self.strain_ratio),
            self.stable.to_string(),
        ]
    }
}

/// The reference run of `case` ([`reference_overrides`]): its final
/// positions and its mean tensile strain over the steps.
fn reference(case: &Case, pool: &rayon::ThreadPool) -> Result<(Vec<Vec3>, f64)> {
    let all: Vec<String> = case.overrides.iter().cloned().chain(reference_overrides()).collect();
    let (_, runner, strain) = strained_run(&cloth_tools::in_checkout(case.scene), &all, pool)?;
    Ok((runner.sim().state().x.clone(), strain))
}

fn run(case: &Case, method: &[String], reference: &(Vec<Vec3>, f64), pool: &rayon::ThreadPool) -> Result<Outcome> {
    let overrides: Vec<String> = case.overrides.iter().cloned().chain(method.iter().cloned()).collect();
    let (r, runner, strain) = strained_run(&cloth_tools::in_checkout(case.scene), &overrides, pool)?;
    Ok(Outcome {
        error: if r.stable { rms(&runner.sim().state().x, &reference.0) } else { f64::NAN },
        cpu_s: r.cpu_s,
        strain_ratio: if r.stable { strain / reference.1 } else { f64::NAN },
        stable: r.stable,
    })
}

/// A monitored run that also averages [`mean_strain`] over its steps.
fn strained_run(
    scene: &std::path::Path,
    overrides: &[String],
    pool: &rayon::ThreadPool,
) -> Result<(super::RunStats, crate::run::Runner, f64)> {
    let (mut sum, mut steps) = (0.0, 0usize);
    let (r, runner) = monitored_run(scene, overrides, pool, |sim, _| {
        sum += mean_strain(sim.model(), &sim.state().x);
        steps += 1;
        false
    })?;
    Ok((r, runner, sum / steps.max(1) as f64))
}

/// Runs the study and writes `vbd-precision.{csv,md,svg}`.
pub fn vbd(args: &StudyArgs) -> Result<()> {
    let pool = setup(args)?;
    let sweeps: &[usize] = if args.quick { &[5, 20] } else { &[5, 10, 20, 50, 100] };
    let quasi_newton: &[usize] = if args.quick { &[10] } else { &[5, 20, 50, 200] };
    let steps: &[f64] = if args.quick { &[1.0 / 60.0] } else { &[1.0 / 30.0, 1.0 / 60.0, 1.0 / 120.0, 1.0 / 240.0] };
    let mut csv = CsvTable::new(&["scene", "method", "h_s", "error_rms_m", "cpu_s", "strain_over_reference", "stable"]);
    let mut md = header("The minimisers: what accuracy costs", "vbd", args);
    let _ = writeln!(
        md,
        "Each scene runs for 1 s (the skirt 1.5 s: the mannequin stands for 0.5 s, then the \
         walk blends in). Error: RMS distance of all particles at the end from BDF2 with \
         Newton iterations to 1e-9 m at h = 1/960 s (PCG to 1e-10). Strain: the mean tensile strain of the \
         triangles' edges, averaged over the steps, over the reference's (above 1: the cloth \
         stretched more than its material lets it, as if softer). CPU: process CPU seconds (user + system, both threads, \
         10 ms ticks). BDF2 and backward Euler (BE, the step VBD's sweeps converge to) solve to \
         rel_tol 1e-6; VBD with its defaults (line search on, no Chebyshev); QN (quasi-Newton, L-BFGS on \
         the same potential) with its defaults (history 5, at most the iterations shown, stopping at a \
         gradient of 1e-6 m).\n"
    );
    let mut plots = Vec::new();
    for case in cases(args.quick) {
        let reference = reference(&case, &pool)?;
        let _ = writeln!(
            md,
            "## {}\n\n`{} {}`; reference mean tensile strain {:.3e}.\n\n\
             | method | h (s) | RMS error (m) | CPU (s) | strain / reference |\n|---|---|---|---|---|",
            case.name,
            case.scene,
            case.overrides.iter().map(|o| format!("--set '{o}'")).collect::<Vec<_>>().join(" "),
            reference.1
        );
        // Backward Euler: the step the sweeps converge to, and its damping.
        let mut methods: Vec<(String, Vec<String>)> = vec![
            ("BDF2 PCG".into(), vec!["simulation.integrator=bdf2".into(), "solver.rel_tol=1e-6".into()]),
            ("BE PCG".into(), vec!["simulation.integrator=backward-euler".into(), "solver.rel_tol=1e-6".into()]),
        ];
        for &k in sweeps {
            methods.push((
                format!("VBD {k} sweeps"),
                vec!["simulation.integrator=vbd".into(), format!("solver.vbd.iterations={k}")],
            ));
        }
        for &k in quasi_newton {
            methods.push((
                format!("QN {k} iterations"),
                vec!["simulation.integrator=quasi-newton".into(), format!("solver.quasi_newton.iterations={k}")],
            ));
        }
        let mut series = Vec::new();
        for (label, overrides) in &methods {
            let mut points = Vec::new();
            for &h in steps {
                let mut o = overrides.clone();
                o.push(format!("simulation.dt_s={h}"));
                let out = run(&case, &o, &reference, &pool)?;
                csv.row(out.csv_row(case.name.to_string(), label.clone(), h))?;
                let shown = if out.stable { format!("{:.2e}", out.error) } else { "blew up".into() };
                let strain = if out.stable { format!("{:.3}", out.strain_ratio) } else { "-".into() };
                let _ = writeln!(md, "| {label} | 1/{:.0} | {shown} | {:.2} | {strain} |", 1.0 / h, out.cpu_s);
                if out.stable && out.error > 0.0 {
                    points.push((out.cpu_s.max(0.01), out.error.log10()));
                }
            }
            series.push(Series { name: label.clone(), points });
        }
        let file = format!("vbd-precision-{}.svg", case.name.split_whitespace().next().unwrap_or("case"));
        let title = format!("Work-precision, {}", case.name);
        let svg = line_plot(
            &Axes { title: &title, x_label: "CPU time (s)", y_label: "log10 RMS error (m)", log_x: true },
            &series,
        );
        let _ = writeln!(md, "\n![error vs CPU time]({file})\n");
        plots.push((file, svg));
    }
    stiffness_table(args, &pool, &mut csv, &mut md)?;
    write_outputs(&args.out, "vbd-precision", csv, &md, &plots)
}

/// The hanging cloth at h = 1/60 s with its tension stiffness raised:
/// the sweeps' strain over the reference's, per stiffness and sweep count.
fn stiffness_table(args: &StudyArgs, pool: &rayon::ThreadPool, csv: &mut CsvTable, md: &mut String) -> Result<()> {
    let n = if args.quick { 11 } else { 21 };
    let stiffnesses: &[f64] = if args.quick { &[200.0] } else { &[200.0, 2e3, 2e4] };
    let sweeps: &[usize] = if args.quick { &[5] } else { &[5, 10, 20, 50, 100] };
    let _ = writeln!(
        md,
        "## Where the sweeps leave stretch unconverged\n\nThe hanging cloth ({n} x {n}, 1 s) at \
         h = 1/60 s with its tension (and buckling) stiffness E raised; each cell the mean tensile \
         strain over the steps over the reference's (1: as stiff as the material; 2: stretched twice as far), \
         and the RMS error (m).\n"
    );
    let _ = write!(md, "| E (N/m) |");
    for k in sweeps {
        let _ = write!(md, " VBD {k} |");
    }
    let _ = writeln!(md, "\n|---|{}", "---|".repeat(sweeps.len()));
    for &e in stiffnesses {
        let mut overrides = grid(n, "corners");
        overrides.push("simulation.duration_s=1.0".into());
        overrides.push(format!("material.tensile_stiffness_n_m={e}"));
        overrides.push(format!("material.buckling_stiffness_n_m={e}"));
        let case = Case { name: "hanging cloth, stiffer", scene: "fixtures/scenes/hang.toml", overrides };
        let reference = reference(&case, pool)?;
        let _ = write!(md, "| {e:.0e} |");
        for &k in sweeps {
            let method = [
                "simulation.integrator=vbd".into(),
                format!("solver.vbd.iterations={k}"),
                "simulation.dt_s=0.016666666666666666".into(),
            ];
            let out = run(&case, &method, &reference, pool)?;
            csv.row(out.csv_row(format!("hanging cloth, E = {e} N/m"), format!("VBD {k} sweeps"), 1.0 / 60.0))?;
            if out.stable {
                let _ = write!(md, " {:.2} ({:.1e} m) |", out.strain_ratio, out.error);
            } else {
                let _ = write!(md, " blew up |");
            }
        }
        let _ = writeln!(md);
    }
    Ok(())
}
