//! `cloth study`: reproduce and extend Volino & Magnenat-Thalmann's (2001)
//! comparison of integration methods. Each study writes CSV (every run),
//! Markdown (tables with the machine and the command) and SVG (plots).

use crate::svg::{Axes, Series, line_plot};
use anyhow::{Context, Result};
use cloth_core::scene::Scene;
use std::fmt::Write as _;
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

const METHODS: &[Method] = &[
    Method { label: "symplectic Euler", overrides: &["simulation.integrator=symplectic-euler"] },
    Method { label: "midpoint", overrides: &["simulation.integrator=midpoint"] },
    Method { label: "RK4", overrides: &["simulation.integrator=rk4"] },
    Method { label: "DOPRI5 tol 1e-4", overrides: &["simulation.integrator=dopri5", "solver.error_tolerance=1e-4"] },
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
];

/// What one free-fall run measured.
struct FallRun {
    stable: bool,
    /// Time at which the mean height has dropped 1 m, s (None: not reached).
    fall_time_s: Option<f64>,
    max_stretch: f64,
    force_evaluations: u64,
    cg_iterations: u64,
    wall_s: f64,
}

/// Exact time to fall 1 m at g = 10 m/s^2.
const EXACT_FALL_S: f64 = 0.447_213_595_499_958;
/// A fall time within this relative error counts as accurate.
const ACCURATE: f64 = 0.02;
/// A link stretched beyond this ratio means the run blew up.
const BLOWN_UP_STRETCH: f64 = 2.0;

fn free_fall(scene: &Path, overrides: &[String], pool: &rayon::ThreadPool) -> Result<FallRun> {
    let parsed = Scene::parse_file(scene, overrides)?;
    let (model, cfg) =
        parsed.build().map_err(|kind| cloth_core::scene::SceneError { file: scene.to_path_buf(), kind })?;
    let mut sim = cfg.simulation(model);
    let mean_z = |x: &[cloth_core::Vec3]| x.iter().map(|p| p.z).sum::<f64>() / x.len() as f64;
    let z0 = mean_z(&sim.state().x);
    let (mut run, mut z_prev) = (
        FallRun {
            stable: true,
            fall_time_s: None,
            max_stretch: 1.0,
            force_evaluations: 0,
            cg_iterations: 0,
            wall_s: 0.0,
        },
        z0,
    );
    let wall = Instant::now();
    for _ in 0..cfg.steps {
        let t_prev = sim.time();
        let report = match pool.install(|| sim.step(cfg.dt_s)) {
            Ok(r) => r,
            Err(_) => {
                run.stable = false;
                break;
            }
        };
        run.force_evaluations += report.force_evaluations as u64;
        run.cg_iterations += report.cg_iterations as u64;
        let x = &sim.state().x;
        let stretch = sim
            .model()
            .stretch_links()
            .iter()
            .map(|l| (x[l.j as usize] - x[l.i as usize]).norm() / l.rest)
            .fold(1.0, f64::max);
        run.max_stretch = run.max_stretch.max(stretch);
        if stretch.is_nan() || stretch >= BLOWN_UP_STRETCH {
            run.stable = false;
            break;
        }
        let z = mean_z(x);
        if run.fall_time_s.is_none() && z <= z0 - 1.0 {
            let frac = (z_prev - (z0 - 1.0)) / (z_prev - z);
            run.fall_time_s = Some(t_prev + frac * (sim.time() - t_prev));
        }
        z_prev = z;
    }
    run.wall_s = wall.elapsed().as_secs_f64();
    Ok(run)
}

/// Volino's free-fall test: fall time against the condition coefficient
/// `K = E d^-1 l^-2 h^2`, per method and model.
pub fn freefall(args: &StudyArgs) -> Result<()> {
    let scene = PathBuf::from("fixtures/scenes/freefall.toml");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(args.threads).build()?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let ks: Vec<f64> = if args.quick {
        vec![0.5, 64.0]
    } else {
        vec![0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0, 512.0, 1024.0]
    };
    let methods: Vec<&Method> =
        if args.quick { METHODS.iter().skip(1).step_by(4).collect() } else { METHODS.iter().collect() };
    let models: &[&str] = if args.quick { &["provot"] } else { &["provot", "choi-ko"] };
    // d = 0.1 kg/m^2, l = 0.05 m, h = 0.01 s (the fixture): E = K d l^2 / h^2.
    let (d, l, h) = (0.1, 0.05, 0.01);
    let mut csv = String::from(
        "model,method,K,E_n_m,stable,fall_time_s,fall_time_rel_error,max_stretch,force_evaluations,cg_iterations,wall_s\n",
    );
    let mut md = header("Free fall (Volino & Magnenat-Thalmann 2001)", "freefall", args);
    let _ = writeln!(
        md,
        "A 1 m square, l = 0.05 m (21 x 21 particles), h = 0.01 s, g = 10 m/s^2, gravity only (no \
         damping, no bending), each free particle jittered by up to 0.1 mm so that instabilities \
         have something to grow from. E = K d l^2 / h^2 with d = 0.1 kg/m^2. Cells: time (s) for \
         the mean height to drop 1 m (exact: 0.447 s); `x` = blew up (a link beyond {BLOWN_UP_STRETCH}x \
         its rest length, or a failed step); `-` = fell less than 1 m in 0.6 s. Accurate = within \
         {:.0}% of 0.447 s.\n",
        ACCURATE * 100.0
    );
    let mut svgs = Vec::new();
    for model in models {
        let _ = writeln!(md, "\n## Model `{model}`\n");
        let _ = write!(md, "| method |");
        for k in &ks {
            let _ = write!(md, " K={k} |");
        }
        let _ = writeln!(md, " largest stable K | largest accurate K | force evals at K=1 (to blow-up) |");
        let _ = writeln!(md, "|---|{}---|---|---|", "---|".repeat(ks.len()));
        let mut series = Vec::new();
        for method in &methods {
            let _ = write!(md, "| {} |", method.label);
            let (mut stable_k, mut accurate_k, mut evals_k1) = (None, None, None);
            let mut points = Vec::new();
            for &k in &ks {
                let e = k * d * l * l / (h * h);
                let mut o: Vec<String> = method.overrides.iter().map(|s| s.to_string()).collect();
                o.extend([
                    format!("simulation.model={model}"),
                    format!("material.tensile_stiffness_n_m={e}"),
                    format!("material.buckling_stiffness_n_m={e}"),
                    "simulation.effects=[\"gravity\"]".into(),
                    "simulation.initial_jitter_m=1e-4".into(),
                    "simulation.duration_s=0.6".into(),
                ]);
                let r = free_fall(&scene, &o, &pool)?;
                let rel = r.fall_time_s.map(|t| (t - EXACT_FALL_S) / EXACT_FALL_S);
                let _ = writeln!(
                    csv,
                    "{model},{},{k},{e},{},{},{},{},{},{},{:.4}",
                    method.label,
                    r.stable,
                    r.fall_time_s.map_or(String::new(), |t| format!("{t:.5}")),
                    rel.map_or(String::new(), |v| format!("{v:.5}")),
                    r.max_stretch,
                    r.force_evaluations,
                    r.cg_iterations,
                    r.wall_s
                );
                let cell = match (r.stable, r.fall_time_s) {
                    (false, _) => "x".to_string(),
                    (true, None) => "-".to_string(),
                    (true, Some(t)) => format!("{t:.3}"),
                };
                let _ = write!(md, " {cell} |");
                if r.stable && stable_k.is_none_or(|s: f64| s < k) {
                    stable_k = Some(k);
                }
                if r.stable && rel.is_some_and(|v| v.abs() <= ACCURATE) {
                    accurate_k = Some(k);
                }
                if k == 1.0 {
                    evals_k1 = Some(r.force_evaluations);
                }
                points.push((k, if r.stable { r.fall_time_s.unwrap_or(f64::NAN) } else { f64::NAN }));
            }
            let fmt_k = |v: Option<f64>| v.map_or("none".to_string(), |k| k.to_string());
            let _ = writeln!(
                md,
                " {} | {} | {} |",
                fmt_k(stable_k),
                fmt_k(accurate_k),
                evals_k1.map_or("-".into(), |v| v.to_string())
            );
            series.push(Series { name: method.label.to_string(), points });
        }
        let file = format!("freefall_{model}.svg");
        let title = format!("Free fall, {model}: time to fall 1 m (exact 0.447 s); gaps = unstable or short");
        let svg = line_plot(
            &Axes { title: &title, x_label: "condition coefficient K", y_label: "fall time (s)", log_x: true },
            &series,
        );
        std::fs::write(args.out.join(&file), svg)?;
        let _ = writeln!(md, "\n![fall time vs K, {model}]({file})");
        svgs.push(file);
    }
    std::fs::write(args.out.join("freefall.csv"), csv)?;
    std::fs::write(args.out.join("freefall.md"), md)?;
    println!("wrote {} (freefall.csv, freefall.md, {})", args.out.display(), svgs.join(", "));
    Ok(())
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
