//! Studies of this workspace's own solver and coupling: cost against size,
//! large steps, Peirce's cantilever, the co-simulation masters, and the
//! hard-case suite.

use super::{StudyArgs, grid, header, least_squares_slope, monitored_run, run_until, setup, write_outputs};
use crate::svg::{Axes, Series, line_plot};
use anyhow::{Context, Result};
use cloth_tools::table::CsvTable;
use std::fmt::Write as _;

/// Cost and CG iterations per step of the implicit step (BDF2, the
/// multigrid PCG) against the particle count, on the hanging cloth and the
/// drape on a sphere from `n = 33` to `513` (1,089 to 263,169 particles),
/// with the log-log slope of the cost.
pub fn scaling(args: &StudyArgs) -> Result<()> {
    let pool = setup(args)?;
    let sizes: &[usize] = if args.quick { &[11, 21] } else { &[33, 65, 129, 257, 513] };
    // The hang swings from the start; the drape lands on the sphere after
    // 0.14 s, so its run includes the steps with contacts.
    let scenes: [(&str, &str, f64); 2] = [("hang", "corners", 0.2), ("drape-sphere", "none", 0.5)];
    let mut csv =
        CsvTable::new(&["scene", "n", "particles", "steps", "cg_per_step", "ms_per_step", "us_per_particle_step"]);
    let mut md = header("Cost against size", "scaling", args);
    let _ = writeln!(
        md,
        "`hang.toml` (0.2 s) and `drape-sphere.toml` (0.5 s: it lands at 0.14 s) at n x n particles \
         over the same 1 m cloth, BDF2 at h = 1/90 s, PCG to `rel_tol = 1e-3` with the multigrid \
         preconditioner, the fixtures' material. Wall time per step (mean over the run, step \
         only). Slope: least squares of log(ms per step) against log(particles); 1 is linear.\n\n\
         | scene | n | particles | CG / step | ms / step | us / particle / step |\n|---|---|---|---|---|---|"
    );
    let (mut cost_series, mut cg_series, mut slopes) = (Vec::new(), Vec::new(), Vec::new());
    for (name, pins, duration) in scenes {
        let scene = cloth_tools::in_checkout(format!("fixtures/scenes/{name}.toml"));
        let (mut cost, mut cg, mut log_points) = (Vec::new(), Vec::new(), Vec::new());
        for &n in sizes {
            let mut o = grid(n, pins);
            o.push(format!("simulation.duration_s={duration}"));
            let (r, runner) = run_until(&scene, &o, &pool, f64::INFINITY, |_, _| false)?;
            let sim = runner.sim();
            if let Some(e) = r.error {
                anyhow::bail!("{name} at {n} x {n}: {e}");
            }
            let particles = sim.model().particle_count();
            let steps = r.steps.max(1) as f64;
            let (cg_per_step, ms) = (r.cg_iterations as f64 / steps, r.step_wall_s / steps * 1e3);
            let us = ms * 1e3 / particles as f64;
            eprintln!("scaling: {name} {n} x {n}: {cg_per_step:.1} CG, {ms:.1} ms a step");
            csv.row([
                name.to_string(),
                n.to_string(),
                particles.to_string(),
                r.steps.to_string(),
                format!("{cg_per_step:.2}"),
                format!("{ms:.3}"),
                format!("{us:.4}"),
            ])?;
            let _ = writeln!(md, "| {name} | {n} | {particles} | {cg_per_step:.1} | {ms:.1} | {us:.3} |");
            cost.push((particles as f64, us));
            cg.push((particles as f64, cg_per_step));
            log_points.push(((particles as f64).ln(), ms.ln()));
        }
        slopes.push((name, least_squares_slope(&log_points)));
        cost_series.push(Series { name: name.to_string(), points: cost });
        cg_series.push(Series { name: name.to_string(), points: cg });
    }
    let _ = writeln!(md);
    for (name, slope) in &slopes {
        let _ = writeln!(md, "- {name}: cost grows as particles^{slope:.2}");
    }
    let cost_svg = line_plot(
        &Axes {
            title: "Cost per particle per step",
            x_label: "particles",
            y_label: "us / particle / step",
            log_x: true,
        },
        &cost_series,
    );
    let cg_svg = line_plot(
        &Axes { title: "PCG iterations per step", x_label: "particles", y_label: "CG / step", log_x: true },
        &cg_series,
    );
    let _ = writeln!(md, "\n![cost per particle per step](scaling.svg)\n\n![CG per step](scaling_cg.svg)");
    write_outputs(
        &args.out,
        "scaling",
        csv,
        &md,
        &[("scaling.svg".into(), cost_svg), ("scaling_cg.svg".into(), cg_svg)],
    )
}

/// The co-simulation masters on the two-mass oscillator benchmark: error
/// against the exact solution and energy drift over [0, 1] s per macro
/// step, and the measured order.
pub fn cosim(args: &StudyArgs) -> Result<()> {
    use cloth_cosim::oscillator::{benchmark, order};
    use cloth_cosim::{
        Extrapolation as E, GaussSeidelParams, InputOverStep, IteratedParams, JacobiParams, Master, Relaxation,
    };
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let steps: Vec<f64> = (0..if args.quick { 3 } else { 6 }).map(|k| 1.0 / (100.0 * 2f64.powi(k))).collect();
    let iterated = |inputs, relaxation| Master::Iterated(IteratedParams { inputs, relaxation, ..Default::default() });
    let masters: Vec<(&str, Master)> = vec![
        ("Jacobi, zero-order hold", Master::Jacobi(JacobiParams { extrapolation: E::ZeroOrderHold })),
        ("Jacobi, first-order hold", Master::Jacobi(JacobiParams { extrapolation: E::FirstOrderHold })),
        ("Gauss-Seidel A then B, zero-order hold", Master::GaussSeidel(GaussSeidelParams::default())),
        (
            "Gauss-Seidel B then A, first-order",
            Master::GaussSeidel(GaussSeidelParams { order: vec![1, 0], extrapolation: E::FirstOrderHold }),
        ),
        (
            "iterated, end value held, quasi-Newton",
            iterated(InputOverStep::EndValue, Relaxation::QuasiNewton { initial: 0.5 }),
        ),
        (
            "iterated, linear inputs, quasi-Newton",
            iterated(InputOverStep::Linear, Relaxation::QuasiNewton { initial: 0.5 }),
        ),
        ("iterated, linear inputs, fixed omega = 1", iterated(InputOverStep::Linear, Relaxation::Fixed(1.0))),
    ];
    let mut csv = CsvTable::new(&["master", "macro_step_s", "max_error_m", "energy_drift", "unit_steps"]);
    let mut md = header("Co-simulation masters on the two-mass oscillator", "cosim", args);
    let _ = writeln!(
        md,
        "m1 = m2 = 1 kg, k1 = k2 = 4 pi^2 N/m, k12 = 16 pi^2 N/m, x(0) = (1, 0) m, at rest; \
         split force-displacement (unit A takes the coupling force, unit B takes x1). Each unit \
         integrates with 20 RK4 substeps per macro step (its own error < 1e-9 m). Error: largest \
         |x_i - exact| at the communication points over [0, 1] s; drift: (E(1) - E(0)) / E(0); \
         unit steps: macro steps times iterations. Iterated tolerance: 1e-10 m + 1e-8 relative.\n"
    );
    let _ = write!(md, "| master |");
    for h in &steps {
        let _ = write!(md, " H = 1/{:.0} s |", 1.0 / h);
    }
    let _ = writeln!(md, " order | drift at the smallest H | unit steps per macro step |");
    let _ = writeln!(md, "|---|{}---|---|---|", "---|".repeat(steps.len()));
    let mut error_series = Vec::new();
    for (name, master) in &masters {
        let runs: Vec<_> = steps.iter().map(|&h| benchmark(master.clone(), h, 1.0, 20)).collect::<Result<_, _>>()?;
        let _ = write!(md, "| {name} |");
        for r in &runs {
            csv.row([
                name.to_string(),
                r.macro_step_s.to_string(),
                format!("{:.6e}", r.max_error_m),
                format!("{:.6e}", r.energy_drift),
                r.unit_steps.to_string(),
            ])?;
            let _ = write!(md, " {:.2e} |", r.max_error_m);
        }
        let last = runs.last().expect("at least one step size");
        let per_step = last.unit_steps as f64 * last.macro_step_s;
        let _ = writeln!(md, " {:.2} | {:+.1e} | {per_step:.1} |", order(&runs), last.energy_drift);
        let points = runs.iter().map(|r| (r.macro_step_s, r.max_error_m.log10())).collect();
        error_series.push(Series { name: name.to_string(), points });
    }
    let axes = Axes {
        title: "Two-mass oscillator: max error over [0, 1] s vs macro step",
        x_label: "macro step H (s)",
        y_label: "log10 max error (m)",
        log_x: true,
    };
    std::fs::write(args.out.join("cosim.svg"), line_plot(&axes, &error_series))?;
    let _ = writeln!(md, "\n![error vs macro step](cosim.svg)");
    std::fs::write(args.out.join("cosim.csv"), csv.into_string()?)?;
    std::fs::write(args.out.join("cosim.md"), md)?;
    println!("wrote {} (cosim.csv, cosim.md, cosim.svg)", args.out.display());
    Ok(())
}

/// Peirce's cantilever (ASTM D1388) against the heavy elastica: chord
/// angle and tip drop per model, grid spacing and overhang, with the cost.
/// The elastica is solved by shooting ([`cloth_core::testing::reference`]).
pub fn bending(args: &StudyArgs) -> Result<()> {
    use cloth_core::testing::reference::CantileverStrip;
    let pool = setup(args)?;
    let scene = cloth_tools::in_checkout("fixtures/scenes/cantilever.toml");
    // Model names as the table shows them, with the overrides that select them.
    let models: &[(&str, &[&str])] = if args.quick {
        &[("volino", &["simulation.model=\"volino\""])]
    } else {
        &[
            ("choi-ko arc-path", &["simulation.model=\"choi-ko\""]),
            ("choi-ko arc-chord", &["simulation.model=\"choi-ko\"", "simulation.bending_law=\"arc-chord\""]),
            ("volino", &["simulation.model=\"volino\""]),
            ("provot", &["simulation.model=\"provot\""]),
        ]
    };
    let spacings: &[f64] = if args.quick { &[0.01] } else { &[0.01, 0.005, 0.0025] };
    let overhangs: &[f64] = if args.quick { &[0.10] } else { &[0.05, 0.10, 0.15] };
    let mut csv = CsvTable::new(&[
        "model",
        "spacing_m",
        "overhang_m",
        "chord_deg",
        "exact_chord_deg",
        "drop_m",
        "exact_drop_m",
        "final_speed_m_s",
        "cg_per_step",
        "step_wall_s",
    ]);
    let mut table = String::from(
        "| model | spacing (cm) | overhang (cm) | chord (deg) | exact | drop (cm) | exact | error / overhang | CG per step |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    let mut bending_length = f64::NAN;
    for (model, selection) in models {
        for &spacing in spacings {
            for &overhang in overhangs {
                let strip = CantileverStrip { spacing, overhang, width: 0.02 };
                let mut overrides = strip.overrides();
                overrides.extend(selection.iter().map(|s| s.to_string()));
                let (run, runner) = monitored_run(&scene, &overrides, &pool, |_, _| false)?;
                let sim = runner.sim();
                let (exact, c) = strip.exact(sim.model());
                bending_length = c;
                let tip = strip.measure(&sim.state().x);
                let speed = sim.state().v.iter().map(|v| v.norm()).fold(0.0, f64::max);
                let cg = run.cg_iterations as f64 / run.steps.max(1) as f64;
                let (exact_chord, exact_drop) = (exact.chord_angle_deg(), exact.tip_drop * c);
                csv.row([
                    model.to_string(),
                    spacing.to_string(),
                    overhang.to_string(),
                    format!("{:.3}", tip.chord_angle_deg()),
                    format!("{exact_chord:.3}"),
                    format!("{:.5}", tip.tip_drop),
                    format!("{exact_drop:.5}"),
                    format!("{speed:.2e}"),
                    format!("{cg:.1}"),
                    format!("{:.3}", run.step_wall_s),
                ])?;
                let _ = writeln!(
                    table,
                    "| {model} | {} | {} | {:.2}{} | {exact_chord:.2} | {:.2} | {:.2} | {:+.1}% | {cg:.0} |",
                    spacing * 100.0,
                    overhang * 100.0,
                    tip.chord_angle_deg(),
                    if run.stable { "" } else { " (unstable)" },
                    tip.tip_drop * 100.0,
                    exact_drop * 100.0,
                    (tip.tip_drop - exact_drop) / overhang * 100.0
                );
            }
        }
    }
    let mut md = header("Peirce's cantilever against the heavy elastica", "bending", args);
    let _ = writeln!(
        md,
        "`fixtures/scenes/cantilever.toml`: a 2 cm strip, 0.1 kg/m^2, B = 1.226e-4 N m (bending length \
         c = {:.2} cm), E = 1e4 N/m, clamped by two pinned columns, BDF2 h = 5 ms for 3 s with link \
         damping and drag. Exact values: the heavy elastica by shooting. Target: chord \
         within 2 degrees, drop within 5% of the overhang.\n",
        bending_length * 100.0
    );
    md.push_str(&table);
    let _ = writeln!(
        md,
        "\n`arc-chord` is Choi & Ko's pair law (chord against the rest length, ramp of Eq. 11); \
         `arc-path` reads the chord against the path through the middle particle (material docs). \
         Provot's flexion springs have no term in B: their row shows what the compressive \
         stiffness alone gives."
    );
    write_outputs(&args.out, "bending", csv, &md, &[])
}

/// Large steps: the single linearised step against Newton with a line
/// search, on the hanging cloth (with drag, so that it comes to rest) and
/// the sphere drape: the largest stretch at any step, the rest shape
/// against the smallest step's, and the cost in Newton corrections, CG
/// iterations and time.
pub fn large_steps(args: &StudyArgs) -> Result<()> {
    let pool = setup(args)?;
    let hang_overrides: Vec<String> = if args.quick { grid(21, "corners") } else { vec![] }
        .into_iter()
        .chain([
            "simulation.effects=[\"gravity\", \"bending\", \"damping\", \"drag\"]".to_string(),
            "material.drag_n_s_m3=0.5".into(),
            format!("simulation.duration_s={}", if args.quick { 4 } else { 20 }),
        ])
        .collect();
    let scenes: Vec<(&str, Vec<String>)> = if args.quick {
        vec![("hang", hang_overrides)]
    } else {
        vec![("hang", hang_overrides), ("drape-sphere", vec![])]
    };
    let steps: &[f64] = if args.quick { &[0.2] } else { &[1.0 / 90.0, 0.05, 0.2] };
    let newtons: &[usize] = &[1, 10];
    let mut csv = CsvTable::new(&[
        "scene",
        "h_s",
        "newton_iterations",
        "peak_stretch",
        "final_stretch",
        "rest_gap_m",
        "steps",
        "corrections_per_step",
        "backtracks",
        "unconverged_steps",
        "cg_per_step",
        "step_wall_s",
        "error",
    ]);
    let mut table = String::from(
        "| scene | h (s) | solves per step (max) | peak stretch | final stretch | rest vs smallest h (cm) | \
         Newton corrections / step | CG / step | wall (s) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for (name, overrides) in &scenes {
        let scene = cloth_tools::in_checkout(format!("fixtures/scenes/{name}.toml"));
        let mut reference: Option<Vec<cloth_core::Vec3>> = None;
        for &h in steps {
            for &newton in newtons {
                let mut o = overrides.clone();
                o.extend([
                    format!("simulation.dt_s={h}"),
                    format!("solver.newton.iterations={newton}"),
                    "solver.newton.tolerance_m=1e-5".into(),
                    "solver.rel_tol=1e-6".into(),
                    // One solve is the single linearised step: not engaged on its own.
                    "solver.newton.auto_trigger=0".into(),
                ]);
                let (run, runner) = run_until(&scene, &o, &pool, f64::INFINITY, |_, _| false)?;
                let sim = runner.sim();
                let x = &sim.state().x;
                let final_stretch = sim.model().max_stretch_ratio(x);
                let reference = reference.get_or_insert_with(|| x.clone());
                let gap = reference.iter().zip(x).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
                let per_step = |n: u64| n as f64 / run.steps.max(1) as f64;
                csv.row([
                    name.to_string(),
                    h.to_string(),
                    newton.to_string(),
                    format!("{:.4}", run.max_stretch),
                    format!("{final_stretch:.4}"),
                    format!("{gap:.5}"),
                    run.steps.to_string(),
                    format!("{:.2}", per_step(run.newton_corrections)),
                    run.newton_backtracks.to_string(),
                    run.newton_unconverged.to_string(),
                    format!("{:.1}", per_step(run.cg_iterations)),
                    format!("{:.3}", run.step_wall_s),
                    run.error.as_deref().unwrap_or("").to_string(),
                ])?;
                let _ = writeln!(
                    table,
                    "| {name} | {h:.4} | {newton} | {:.3} | {:.3} | {:.2} | {:.1} | {:.0} | {:.2}{} |",
                    run.max_stretch,
                    final_stretch,
                    gap * 100.0,
                    per_step(run.newton_corrections),
                    per_step(run.cg_iterations),
                    run.step_wall_s,
                    run.error.map_or(String::new(), |e| format!(" ({e})"))
                );
            }
        }
    }
    let mut md = header("Large steps: one linearised solve against Newton with a line search", "large-steps", args);
    let _ = writeln!(
        md,
        "`hang.toml` with drag (0.5 N s/m^3) for {} s and `drape-sphere.toml` for 2 s, BDF2, PCG to 1e-6, \
         Newton tolerance 1e-5 m (residual as a distance). Peak stretch: the largest link length over \
         rest length at any step. Rest gap: the largest distance between final positions and those of \
         the first (smallest-step, single-solve) run.\n",
        if args.quick { 4 } else { 20 }
    );
    md.push_str(&table);
    write_outputs(&args.out, "large-steps", csv, &md, &[])
}

/// The hard-case suite ([`cloth_tools::stability`]): writes the table and
/// fails when a case's requirement does not hold.
pub fn stability(args: &StudyArgs) -> Result<()> {
    use cloth_tools::stability;
    let pool = setup(args)?;
    let rows = pool.install(|| stability::run_suite(args.quick));
    let mut md = header("The hard-case suite", "stability", args);
    let _ = writeln!(
        md,
        "Each case varies one thing of a 1 m square of cotton (21 x 21, 0.1 kg/m^2, E = 200 N/m, \
         B = 1e-5 N m) pinned at two corners, and states what must hold. Worst stretch: the largest \
         link length over rest length at any step.\n"
    );
    md.push_str(&stability::markdown(&rows));
    write_outputs(&args.out, "stability", stability::csv(&rows)?, &md, &[])?;
    let unexpected: Vec<String> = rows
        .iter()
        .filter(|r| !r.as_expected())
        .map(|r| format!("{} ({}, {}): {:?}", r.case, r.variant, r.integrator, r.verdict))
        .collect();
    anyhow::ensure!(
        unexpected.is_empty(),
        "{} of {} rows not as expected:\n{}",
        unexpected.len(),
        rows.len(),
        unexpected.join("\n")
    );
    Ok(())
}
