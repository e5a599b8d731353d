//! `cloth study`: reproduce and extend Volino & Magnenat-Thalmann's (2001)
//! comparison of integration methods. Each study writes CSV (every run),
//! Markdown (tables with the machine and the command) and SVG (plots).
//!
//! One module a family: [`volino`] (the free fall, drape, cost and
//! work-precision comparisons of the paper), [`solver`] (cost against size,
//! large steps, bending, co-simulation and the hard-case suite). This file
//! holds what they share: the methods, a monitored run, the output files.

mod grid_stretch;
mod solver;
mod vbd;
mod volino;

pub use grid_stretch::grid_stretch;
pub use solver::{bending, cosim, large_steps, scaling, stability};
pub use vbd::vbd;
pub use volino::{cost, drape, freefall, precision};

use crate::run::{CouplingTotals, Runner};
use anyhow::{Context, Result};
use cloth_core::Simulation;
use cloth_tools::table::CsvTable;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options shared by the studies.
pub struct StudyArgs {
    pub out: PathBuf,
    pub threads: usize,
    /// A small sweep (for tests): two K values, three methods, one model.
    pub quick: bool,
}

/// One integration method as the studies run it.
struct Method {
    label: &'static str,
    overrides: &'static [&'static str],
}

/// Whether the method whose first override is `integrator` (`simulation.
/// integrator=...`) takes large steps (the implicit solvers and the vertex
/// solver) rather than the explicit ones' small stable steps.
fn takes_large_steps(integrator: &str) -> bool {
    ["backward", "bdf2", "vbd"].iter().any(|name| integrator.contains(name))
}

const METHODS: &[Method] = &[
    Method { label: "symplectic Euler", overrides: &["simulation.integrator=symplectic-euler"] },
    Method { label: "midpoint", overrides: &["simulation.integrator=midpoint"] },
    Method { label: "RK4", overrides: &["simulation.integrator=rk4"] },
    Method {
        label: "DOPRI5 tol 1e-4",
        overrides: &["simulation.integrator=dopri5", "solver.adaptive.error_tolerance=1e-4"],
    },
    Method {
        label: "BE 1 CG",
        overrides: &["simulation.integrator=backward-euler-fixed-cg", "solver.fixed_cg_iterations=1"],
    },
    Method {
        label: "BE 2 CG",
        overrides: &["simulation.integrator=backward-euler-fixed-cg", "solver.fixed_cg_iterations=2"],
    },
    Method {
        label: "BE 4 CG",
        overrides: &["simulation.integrator=backward-euler-fixed-cg", "solver.fixed_cg_iterations=4"],
    },
    Method {
        label: "BE 8 CG",
        overrides: &["simulation.integrator=backward-euler-fixed-cg", "solver.fixed_cg_iterations=8"],
    },
    Method { label: "BE PCG", overrides: &["simulation.integrator=backward-euler", "solver.rel_tol=1e-6"] },
    Method { label: "BDF2 PCG", overrides: &["simulation.integrator=bdf2", "solver.rel_tol=1e-6"] },
    Method { label: "VBD 5 sweeps", overrides: &["simulation.integrator=vbd", "solver.vbd.iterations=5"] },
    Method { label: "VBD 20 sweeps", overrides: &["simulation.integrator=vbd", "solver.vbd.iterations=20"] },
    Method { label: "VBD 100 sweeps", overrides: &["simulation.integrator=vbd", "solver.vbd.iterations=100"] },
];

/// What a monitored run measured.
pub(super) struct RunStats {
    /// False when a step failed or a link blew up.
    stable: bool,
    max_stretch: f64,
    steps: u64,
    force_evaluations: u64,
    cg_iterations: u64,
    /// Wall time inside `step` only (monitoring excluded), s.
    step_wall_s: f64,
    /// Process CPU time over the run (all threads, monitoring included;
    /// 10 ms ticks), s.
    cpu_s: f64,
    /// Newton corrections, line-search halvings and steps left above the
    /// Newton tolerance (`solver.newton.iterations > 1`).
    newton_corrections: u64,
    newton_backtracks: u64,
    newton_unconverged: u64,
    /// The error of a failed step.
    error: Option<String>,
}

/// A link stretched beyond this ratio means the run blew up.
const BLOWN_UP_STRETCH: f64 = 2.0;

/// Runs a scene step by step (a cloth alone, or coupled with its rapier
/// bodies or rig, as `cloth run` does); after each step `watch(sim,
/// t_before)` may stop the run by returning true. Stops as unstable when
/// a step fails or a link stretches beyond [`BLOWN_UP_STRETCH`].
fn monitored_run(
    scene: &Path,
    overrides: &[String],
    pool: &rayon::ThreadPool,
    watch: impl FnMut(&Simulation, f64) -> bool,
) -> Result<(RunStats, Runner)> {
    run_until(scene, overrides, pool, BLOWN_UP_STRETCH, watch)
}

/// [`monitored_run`] with the blow-up stretch given (`f64::INFINITY`: run
/// on however far links stretch).
fn run_until(
    scene: &Path,
    overrides: &[String],
    pool: &rayon::ThreadPool,
    blown_up_stretch: f64,
    mut watch: impl FnMut(&Simulation, f64) -> bool,
) -> Result<(RunStats, Runner)> {
    let (_, cfg, mut runner) = Runner::load(scene, overrides)?;
    let mut coupling = CouplingTotals::default();
    let mut run = RunStats {
        stable: true,
        max_stretch: 1.0,
        steps: 0,
        force_evaluations: 0,
        cg_iterations: 0,
        step_wall_s: 0.0,
        cpu_s: 0.0,
        newton_corrections: 0,
        newton_backtracks: 0,
        newton_unconverged: 0,
        error: None,
    };
    let bar = run_progress(scene, cfg.steps);
    let cpu_start = crate::run::process_cpu_s();
    for _ in 0..cfg.steps {
        bar.inc(1);
        let t_prev = runner.sim().time();
        let t = Instant::now();
        let result = pool.install(|| runner.step(cfg.dt_s, &mut coupling));
        run.step_wall_s += t.elapsed().as_secs_f64();
        let report = match result {
            Ok(r) => r,
            Err(e) => {
                (run.stable, run.error) = (false, Some(e));
                break;
            }
        };
        run.steps += 1;
        run.force_evaluations += report.force_evaluations as u64;
        run.cg_iterations += report.cg_iterations as u64;
        if let Some(n) = report.newton {
            run.newton_corrections += n.corrections as u64;
            run.newton_backtracks += n.backtracks as u64;
            run.newton_unconverged += u64::from(!n.converged);
        }
        let sim = runner.sim();
        let x = &sim.state().x;
        let stretch = sim.model().max_stretch_ratio(x);
        run.max_stretch = run.max_stretch.max(stretch);
        if stretch.is_nan() || stretch >= blown_up_stretch {
            run.stable = false;
            break;
        }
        if watch(sim, t_prev) {
            break;
        }
    }
    bar.finish_and_clear();
    run.cpu_s = cpu_start.zip(crate::run::process_cpu_s()).map_or(f64::NAN, |(a, b)| b - a);
    Ok((run, runner))
}

/// A progress bar over one run's steps, drawn on a terminal only (a study
/// runs the same scene dozens of times, some for minutes).
fn run_progress(scene: &Path, steps: u64) -> ProgressBar {
    let bar = ProgressBar::new(steps);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} steps  {msg}")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.set_message(scene.file_name().map_or(String::new(), |f| f.to_string_lossy().into_owned()));
    bar
}

/// The thread pool of a study, after creating its output directory.
fn setup(args: &StudyArgs) -> Result<rayon::ThreadPool> {
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    Ok(rayon::ThreadPoolBuilder::new().num_threads(args.threads).build()?)
}

/// Title, machine, threads and the command that produced a result file.
fn header(title: &str, study: &str, args: &StudyArgs) -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!(
        "# {title}\n\nMachine: {cpu}, {cores} cores; {} threads. Produced by \
         `cargo run --release -p cloth-tools -- study {study} --out {}{}`.\n\n",
        args.threads,
        args.out.display(),
        if args.quick { " --quick" } else { "" }
    )
}

/// Overrides for a square grid of `n x n` particles on the hanging-cloth or
/// draping fixtures (pins follow the grid size).
fn grid(n: usize, pins: &str) -> Vec<String> {
    let last = n - 1;
    let mut o = vec![format!("panels.0.particles=[{n}, {n}]")];
    if pins == "corners" {
        o.push(format!("pins.0.nodes=[[0, {last}], [{last}, {last}]]"));
    }
    o
}

fn with(method: &Method, extra: Vec<String>) -> Vec<String> {
    method.overrides.iter().map(|s| s.to_string()).chain(extra).collect()
}

fn write_outputs(out: &Path, name: &str, csv: CsvTable, md: &str, plots: &[(String, String)]) -> Result<()> {
    std::fs::write(out.join(format!("{name}.csv")), csv.into_string()?)?;
    std::fs::write(out.join(format!("{name}.md")), md)?;
    for (file, svg) in plots {
        std::fs::write(out.join(file), svg)?;
    }
    println!("wrote {}/{name}.csv, {name}.md and {} plot(s)", out.display(), plots.len());
    Ok(())
}

/// Slope of the least-squares line through `(x, y)` points (NaN for fewer than two).
fn least_squares_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = points.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_slope_of_a_line_and_of_noise_around_it() {
        let line: Vec<(f64, f64)> = (0..5).map(|k| (k as f64, 1.05 * k as f64 - 3.0)).collect();
        assert!((least_squares_slope(&line) - 1.05).abs() < 1e-14);
        // About y = x, by hand: sxy = 4.8, sxx = 5.
        let noisy: Vec<(f64, f64)> = [(0.0, 0.1), (1.0, 0.9), (2.0, 2.1), (3.0, 2.9)].to_vec();
        assert!((least_squares_slope(&noisy) - 0.96).abs() < 1e-12, "{}", least_squares_slope(&noisy));
        assert!(least_squares_slope(&[(1.0, 2.0)]).is_nan());
    }

    /// A study runs a scene with a rig as `cloth run` does: the skirt on
    /// the walking mannequin, walking from the first step, ends where
    /// `cloth run`'s steps leave it, to the bit, carried by the pelvis
    /// (run alone, without the rig, its waistband would stay still).
    #[test]
    fn a_study_runs_a_rigged_garment_as_cloth_run_does() {
        let scene = cloth_tools::in_checkout("fixtures/scenes/skirt-walk.toml");
        let overrides = ["simulation.duration_s=0.2", "rig.settle_s=0.0"].map(String::from);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let (stats, runner) = monitored_run(&scene, &overrides, &pool, |_, _| false).unwrap();
        assert!(stats.stable && stats.steps == 18, "{} steps, stable {}", stats.steps, stats.stable);
        assert!(matches!(runner, Runner::Coupled(_)));
        let run = crate::run::simulate_steps(
            &scene,
            &overrides,
            crate::run::SimulateOptions { threads: 2, ..Default::default() },
        )
        .unwrap();
        let x = &runner.sim().state().x;
        assert!(x == &run.final_x, "the study's skirt and cloth run's differ");
        let moved =
            x.iter().zip(runner.sim().model().rest_positions()).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        // 21 mm as the walk blends in from the first step; 0.8 mm standing.
        assert!(moved > 0.015, "the skirt moved at most {moved} m");
    }
}
