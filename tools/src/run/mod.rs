//! `cloth run`, `cloth validate` and `cloth time`.

mod records;
mod totals;

pub(crate) use records::{SOLIDS_FILE, STEPS_FILE, solid_meshes_json, solid_poses};
use records::{SolidPoses, StepRow, write_steps};
use totals::{ContactTotals, EnergyTotals, NewtonTotals};

use crate::output::{
    BodySummary, CouplingSummary, CrossingSummary, GarmentHeights, SeamSummary, StageWall, StrainLimitSummary, Summary,
    TangleSummary, write_obj,
};
use anyhow::{Context, Result, bail};
use cloth_core::Effect;
use cloth_core::over_stretched;
use cloth_core::scene::{RunConfig, Scene, SceneError};
use cloth_core::{ClothModel, Inside, Simulation, StepReport, TangleEvent, TangleWatch, Vec3};
use cloth_rapier::scene::has_bodies;
use cloth_rapier::{CoupledRun, CoupledScene, CouplingReport, Master, Momentum};
use cloth_tools::frames::{FRAMES_FILE, FrameWriter};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct RunArgs {
    pub scene: PathBuf,
    pub out: PathBuf,
    pub overrides: Vec<String>,
    pub frames: Option<u64>,
    /// Frames as one `frames.bin` rather than OBJ files.
    pub binary_frames: bool,
    pub threads: usize,
    pub quiet: bool,
    /// A tangle (a lasting crossing, cloth through a solid) or a link left
    /// past the deformation constraints' limit stops the run with an error
    /// instead of a warning.
    pub strict: bool,
}

/// Reads, checks and builds a scene; errors name the file and the field.
fn load(path: &Path, overrides: &[String]) -> Result<(Scene, ClothModel, RunConfig)> {
    let scene = Scene::parse_file(path, overrides)?;
    let (model, cfg) = scene.build().map_err(|kind| SceneError { file: path.into(), kind })?;
    Ok((scene, model, cfg))
}

/// A cloth alone, or a cloth coupled with rapier bodies (a scene with
/// `[[bodies]]` or a `[rig]`).
pub(crate) enum Runner {
    /// A cloth alone, and what its scene allowed that looks wrong.
    Alone(Box<Simulation>, Option<String>),
    Coupled(Box<CoupledRun>),
}

/// A saved [`Runner`].
pub(crate) enum RunnerState {
    Alone(cloth_core::Snapshot),
    Coupled(Box<cloth_rapier::cloth_set::CoupledSnapshot>),
}

impl Runner {
    /// Loads `path`: with `[[bodies]]` a coupled run, else a cloth alone.
    pub(crate) fn load(path: &Path, overrides: &[String]) -> Result<(Scene, RunConfig, Runner)> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        if !has_bodies(&text) {
            let (scene, model, cfg) = load(path, overrides)?;
            let sim = cfg.simulation(model);
            let name = |k: usize| format!("colliders[{k}]");
            let allowed = cloth_core::scene::check_start_outside(
                &sim.particles_inside(|_, _| false),
                scene.allows_start_inside(),
                name,
            )
            .map_err(|kind| SceneError { file: path.into(), kind })?;
            return Ok((scene, cfg, Runner::Alone(Box::new(sim), allowed)));
        }
        let coupled = CoupledScene::load(path, overrides)?;
        let run = coupled.build().map_err(|kind| SceneError { file: path.into(), kind })?;
        Ok((coupled.scene, run.config, Runner::Coupled(Box::new(run))))
    }

    /// What looks wrong before the first step (see [`CoupledRun::warnings`]).
    pub(crate) fn warnings(&self) -> Vec<String> {
        match self {
            Runner::Alone(_, allowed) => allowed.iter().cloned().collect(),
            Runner::Coupled(run) => run.warnings(),
        }
    }

    /// A name for each of the cloth's solids (see [`CoupledRun::solid_names`]).
    pub(crate) fn solid_names(&self) -> Vec<String> {
        match self {
            Runner::Alone(sim, _) => (0..sim.model().colliders().len()).map(|k| format!("colliders[{k}]")).collect(),
            Runner::Coupled(run) => run.solid_names(),
        }
    }

    /// The cloth's particles inside a solid now, but for pins inside the
    /// body that holds them (see [`CoupledRun::particles_inside`]).
    pub(crate) fn particles_inside(&self) -> Vec<Inside> {
        match self {
            Runner::Alone(sim, _) => sim.particles_inside(|_, _| false),
            Runner::Coupled(run) => run.particles_inside(),
        }
    }

    pub(crate) fn sim(&self) -> &Simulation {
        match self {
            Runner::Alone(sim, _) => sim,
            Runner::Coupled(run) => run.cloths[run.cloth].simulation(),
        }
    }

    /// Where the run is now, to come back to ([`Runner::restore`]).
    pub(crate) fn snapshot(&self) -> RunnerState {
        match self {
            Runner::Alone(sim, _) => RunnerState::Alone(sim.snapshot()),
            Runner::Coupled(run) => RunnerState::Coupled(Box::new(run.cloths.save(&run.world))),
        }
    }

    /// Puts the run back where [`Runner::snapshot`] took it.
    pub(crate) fn restore(&mut self, state: &RunnerState) -> std::result::Result<(), String> {
        match (self, state) {
            (Runner::Alone(sim, _), RunnerState::Alone(s)) => sim.restore(s).map_err(|e| e.to_string()),
            (Runner::Coupled(run), RunnerState::Coupled(s)) => {
                let run = &mut **run;
                run.cloths.restore(s, &mut run.world).map_err(|e| e.to_string())
            }
            _ => Err("a snapshot of another kind of run".into()),
        }
    }

    /// The cloth's simulation, to set its inputs (wind, held particles)
    /// between steps; stepped only through [`Runner::step`].
    pub(crate) fn sim_mut(&mut self) -> &mut Simulation {
        match self {
            Runner::Alone(sim, _) => sim,
            Runner::Coupled(run) => {
                run.cloths.get_mut(run.cloth).expect("the scene's own cloth handle").simulation_mut()
            }
        }
    }

    /// One step of `h` (a coupled run steps by its scene's step).
    pub(crate) fn step(&mut self, h: f64, totals: &mut CouplingTotals) -> Result<StepReport, String> {
        match self {
            Runner::Alone(sim, _) => sim.step(h).map_err(|e| e.to_string()),
            Runner::Coupled(run) => {
                let report = run.step().map_err(|e| e.to_string())?;
                totals.add(&report);
                Ok(report.cloths[0])
            }
        }
    }
}

/// The coupling master in words, with its settings.
fn describe_master(master: &Master) -> String {
    match master {
        Master::Staggered => "staggered (one pass a step)".into(),
        Master::Monolithic(p) => format!(
            "monolithic (bodies in the cloth's solve; at most {} solves a step, agreement {})",
            p.max_solves,
            p.tol_m.map_or("a fifth of the contact layer".into(), |t| format!("{t} m"))
        ),
        Master::Iterated(p) => format!(
            "iterated (at most {} passes, agreement {} m/s + {} relative)",
            p.max_iterations, p.abs_tol_m_s, p.rel_tol
        ),
    }
}

/// Coupling counters over a run.
#[derive(Default)]
pub(crate) struct CouplingTotals {
    passes: u64,
    passes_max: usize,
    unconverged: u64,
    residual_max: f64,
}

impl CouplingTotals {
    fn add(&mut self, r: &CouplingReport) {
        self.passes += r.iterations as u64;
        self.passes_max = self.passes_max.max(r.iterations);
        self.unconverged += u64::from(!r.converged);
        self.residual_max = self.residual_max.max(r.residual);
    }
}

pub fn validate(path: &Path, overrides: &[String]) -> Result<()> {
    let (_, cfg, runner) = Runner::load(path, overrides)?;
    let model = runner.sim().model();
    if let Runner::Coupled(run) = &runner {
        let links = run.rig.as_ref().map_or(String::new(), |r| format!(" and the rig's {} links", r.rig.links.len()));
        let master = describe_master(&run.master);
        println!("{}: {} rigid bodies{links}, coupled {master}", path.display(), run.bodies.len());
        if let Some(rig) = &run.rig {
            println!("{}: {}", path.display(), rig.summary(&run.world));
        }
    }
    for warning in runner.warnings() {
        println!("{}: warning: {warning}", path.display());
    }
    let el = model.elements();
    // Elements beside the links: membranes, bending triangles, type-2 triples and hinges.
    let elements: Vec<String> = [
        (el.membranes.len(), "membrane triangles"),
        (el.curvatures.len(), "bending triangles"),
        (el.triples.len(), "type-2 triples"),
        (el.hinges.len(), "type-2 hinges"),
    ]
    .iter()
    .filter(|(n, _)| *n > 0)
    .map(|(n, what)| format!(", {n} {what}"))
    .collect();
    println!(
        "{}: ok ({} particles, {} type-1 and {} type-2 links{}, {} pins, {} steps of {} s with {})",
        path.display(),
        model.particle_count(),
        model.stretch_links().len(),
        model.bend_links().len(),
        elements.concat(),
        model.pins().len(),
        cfg.steps,
        cfg.dt_s,
        cfg.integrator.name()
    );
    Ok(())
}

/// Where and how `cloth run --frames N` writes frames.
pub(crate) struct FrameOutput {
    /// Every this many steps.
    pub every: u64,
    /// `frames/`.
    pub dir: PathBuf,
    /// One binary `frames.bin` ([`cloth_tools::frames`]) instead of OBJ files.
    pub binary: bool,
}

/// How [`simulate`] runs a scene: threads, frames, a progress bar, and
/// where it stops early.
#[derive(Default)]
pub(crate) struct SimulateOptions {
    /// Worker threads (at least 1).
    pub threads: usize,
    /// Where and how frames are written (none: no frames).
    pub frames: Option<FrameOutput>,
    /// A progress bar on stderr.
    pub progress: bool,
    /// Stop after at most this many steps (the scene's own count otherwise).
    pub max_steps: Option<u64>,
    /// The first tangle, or the first link left past the deformation
    /// constraints' limit, is the error that ends the run, not a warning.
    pub strict: bool,
    /// Stop, as an error naming the time reached, once the run has taken
    /// this much wall time, s (a bench's bound on a run that bogs down).
    pub max_wall_s: Option<f64>,
}

impl SimulateOptions {
    /// `threads` workers and a progress bar; nothing else.
    pub(crate) fn with_progress(threads: usize) -> Self {
        Self { threads, progress: true, ..Self::default() }
    }
}

/// Runs a scene to its end (or its first error), writing frames as
/// `opts.frames` says; returns the summary (with `error` set when a step
/// failed).
pub(crate) fn simulate(scene_path: &Path, overrides: &[String], opts: SimulateOptions) -> Result<Summary> {
    simulate_steps(scene_path, overrides, opts).map(|run| run.summary)
}

/// What [`simulate_steps`] ran to.
pub(crate) struct Simulated {
    pub summary: Summary,
    /// The cloth's positions after the last step, m.
    pub final_x: Vec<Vec3>,
}

/// [`simulate`], keeping the final positions. The first tangle of each
/// kind is a warning, or with `opts.strict` the error that ends the run.
pub(crate) fn simulate_steps(scene_path: &Path, overrides: &[String], opts: SimulateOptions) -> Result<Simulated> {
    let SimulateOptions { threads, frames, progress, max_steps, strict, max_wall_s } = opts;
    let started = Instant::now();
    if threads == 0 {
        bail!("--threads must be at least 1");
    }
    let (scene, mut cfg, mut runner) = Runner::load(scene_path, overrides)?;
    cfg.steps = max_steps.map_or(cfg.steps, |m| m.min(cfg.steps));
    let start_momentum = match &runner {
        Runner::Coupled(run) => Some(run.cloths.momentum(&run.world)),
        Runner::Alone(..) => None,
    };
    let mut coupling = CouplingTotals::default();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
    if let Some(f) = &frames {
        std::fs::create_dir_all(&f.dir).with_context(|| format!("creating {}", f.dir.display()))?;
    }
    let mut binary = match &frames {
        Some(f) if f.binary => {
            let model = runner.sim().model();
            Some(FrameWriter::create(&f.dir.join(FRAMES_FILE), model.particle_count(), model.triangles())?)
        }
        _ => None,
    };
    let bar = if progress { ProgressBar::new(cfg.steps) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} steps  {msg}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let mut stages = StageWall::default();
    let mut step_walls = Vec::with_capacity(cfg.steps as usize);
    let (mut cg_total, mut cg_max, mut unconverged) = (0u64, 0usize, 0u64);
    let (mut evaluations, mut substeps, mut rejected) = (0u64, 0u64, 0u64);
    let mut contacts = ContactTotals::default();
    let mut newton = NewtonTotals::default();
    let mut energy = EnergyTotals::default();
    let mut peak_stretch = runner.sim().model().max_stretch_ratio(&runner.sim().state().x);
    let mut series = frames.as_ref().map(|_| Vec::with_capacity(cfg.steps as usize));
    let mut garment: Option<GarmentHeights> = None;
    let mut watch = TangleWatch::new(runner.sim().model(), &runner.particles_inside());
    let mut tangle = TangleSummary::default();
    let limit = runner.sim().model().strain_limit();
    let mut strain = limit.as_ref().map(StrainLimitSummary::new);
    let solid_names = runner.solid_names();
    let mut error = None;
    let wall = Instant::now();
    let cpu_start = process_cpu_s();
    let mut solid_poses = SolidPoses::default();
    let pins = runner.sim().model().pins().len();
    let pin_window = ((0.5 / cfg.dt_s).ceil() as usize).max(1);
    let mut pin_loads = std::collections::VecDeque::with_capacity(pin_window + 1);
    let write_frame = |sim: &Simulation,
                       stages: &mut StageWall,
                       poses: &mut SolidPoses,
                       binary: &mut Option<FrameWriter>|
     -> Result<()> {
        if let Some(f) = &frames
            && sim.state().steps.is_multiple_of(f.every)
        {
            let t = Instant::now();
            if let Some(out) = binary {
                let path = f.dir.join(FRAMES_FILE);
                out.append(sim.state().steps, &sim.state().x).with_context(|| format!("writing {}", path.display()))?;
            } else {
                let path = f.dir.join(format!("frame_{:05}.obj", sim.state().steps));
                write_obj(&path, sim.model(), &sim.state().x).with_context(|| format!("writing {}", path.display()))?;
            }
            poses.add(sim, cfg.dt_s);
            stages.output += t.elapsed().as_secs_f64();
        }
        Ok(())
    };
    let warnings = runner.warnings();
    for w in &warnings {
        eprintln!("{}: warning: {w}", scene_path.display());
    }
    write_frame(runner.sim(), &mut stages, &mut solid_poses, &mut binary)?;
    for _ in 0..cfg.steps {
        let t = Instant::now();
        let result = pool.install(|| runner.step(cfg.dt_s, &mut coupling));
        step_walls.push(t.elapsed().as_secs_f64());
        match result {
            Ok(r) => {
                cg_total += r.cg_iterations as u64;
                cg_max = cg_max.max(r.cg_iterations);
                unconverged += u64::from(!r.converged);
                evaluations += r.force_evaluations as u64;
                substeps += r.substeps as u64;
                rejected += r.rejected_steps as u64;
                stages.forces += r.stages.forces_s;
                stages.assembly += r.stages.assembly_s;
                stages.solve += r.stages.solve_s;
                stages.update += r.stages.update_s;
                stages.collision += r.stages.collision_s;
                stages.self_collision += r.stages.self_collision_s;
                contacts.add(&r.contacts);
                newton.add(r.newton.as_ref(), runner.sim().time());
                energy.add(&r);
                let stretch = runner.sim().model().max_stretch_ratio(&runner.sim().state().x);
                peak_stretch = peak_stretch.max(stretch);
                let t = Instant::now();
                let inside = runner.particles_inside();
                let sim = runner.sim();
                let at = (sim.state().steps, sim.time());
                let (counts, events) = watch.after_step(sim.model(), &sim.state().x, &inside, at);
                stages.tangle += t.elapsed().as_secs_f64();
                tangle.add(counts);
                if let Some(series) = series.as_mut() {
                    series.push(StepRow::of(runner.sim(), &r, stretch, counts));
                }
                let mut stop = None;
                if let (Some(strain), Some(limit)) = (strain.as_mut(), limit) {
                    // The maximum is at hand: the link is looked for only past the limit.
                    let past = stretch > limit.reported_ratio();
                    let over = if past { over_stretched(sim.model(), &sim.state().x) } else { None };
                    if let Some(words) = strain.add(over, at, limit.passes) {
                        if strict {
                            stop.get_or_insert(format!("over-stretched (--strict): {words}"));
                        } else {
                            eprintln!("{}: warning: {words}", scene_path.display());
                        }
                    }
                }
                for event in events {
                    let mut words =
                        event.describe(|k| solid_names.get(k).cloned().unwrap_or_else(|| format!("solid {k}")));
                    if matches!(event, TangleEvent::LastingCrossing { .. }) && sim.model().self_collision().is_none() {
                        words += " (the scene has no [self_collision])";
                    }
                    tangle.record(&event, &words);
                    if strict {
                        stop.get_or_insert(format!("tangled (--strict): {words}"));
                    } else {
                        eprintln!("{}: warning: {words}", scene_path.display());
                    }
                }
                if let Some(limit) = max_wall_s.filter(|&l| started.elapsed().as_secs_f64() > l) {
                    stop.get_or_insert(format!(
                        "stopped at t = {:.4} s (step {}): the run took more than its {limit} s of wall time",
                        sim.time(),
                        sim.state().steps
                    ));
                }
                if stop.is_some() {
                    error = stop;
                    write_frame(runner.sim(), &mut stages, &mut solid_poses, &mut binary)?;
                    bar.inc(1);
                    break;
                }
                if let Runner::Coupled(run) = &runner
                    && let Some(heights) = garment_heights(run)
                {
                    garment = GarmentHeights::add(garment, heights);
                }
                if pins > 0 {
                    pin_loads.push_back((0..pins).map(|k| runner.sim().pin_reaction(k)).sum::<Vec3>());
                    if pin_loads.len() > pin_window {
                        pin_loads.pop_front();
                    }
                }
                bar.set_message(format!("t = {:.3} s, CG {}", runner.sim().time(), r.cg_iterations));
            }
            Err(e) => {
                error = Some(e);
                break;
            }
        }
        write_frame(runner.sim(), &mut stages, &mut solid_poses, &mut binary)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    if let Some(out) = binary {
        let path = frames.as_ref().map(|f| f.dir.join(FRAMES_FILE)).unwrap_or_default();
        out.finish().with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(FrameOutput { dir, .. }) = &frames {
        let path = dir.join(SOLIDS_FILE);
        std::fs::write(&path, solid_poses.to_json(runner.sim().model(), &runner.solid_names())?)
            .with_context(|| format!("writing {}", path.display()))?;
        write_steps(&dir.join(STEPS_FILE), series.as_deref().unwrap_or_default())?;
    }
    let wall_s = wall.elapsed().as_secs_f64();
    let cpu_s = cpu_start.zip(process_cpu_s()).map(|(start, end)| end - start);
    let sim = runner.sim();
    let state = sim.state();
    let model = sim.model();
    let steps = state.steps;
    step_walls.sort_by(f64::total_cmp);
    let summary = Summary {
        scene: scene_path.display().to_string(),
        particles: model.particle_count(),
        stretch_links: model.stretch_links().len(),
        bend_links: model.bend_links().len(),
        effects: Effect::ALL.iter().filter(|e| scene.has_effect(**e)).map(|e| e.name().to_string()).collect(),
        model: scene.simulation.model.name().to_string(),
        integrator: cfg.integrator.name().to_string(),
        threads,
        steps,
        dt_s: cfg.dt_s,
        sim_time_s: state.time_s,
        wall_s,
        cpu_s,
        step_wall_s_median: step_walls.get(step_walls.len() / 2).copied().unwrap_or(0.0),
        force_evaluations_total: evaluations,
        substeps_total: substeps,
        rejected_steps_total: rejected,
        cg_iterations_total: cg_total,
        cg_iterations_max: cg_max,
        cg_iterations_mean: if steps > 0 { cg_total as f64 / steps as f64 } else { 0.0 },
        unconverged_steps: unconverged,
        max_stretch_ratio: model.max_stretch_ratio(&state.x),
        peak_stretch_ratio: peak_stretch,
        seams: (!model.stitches().is_empty()).then(|| SeamSummary {
            stitches: model.stitches().len(),
            closed: state.stitches_closed.iter().filter(|&&c| c).count(),
            max_gap_m: model.max_seam_gap(&state.x),
        }),
        newton: newton.summary(),
        energy: energy.summary(),
        min_z_m: state.x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min),
        max_speed_m_s: state.v.iter().map(|v| v.norm()).fold(0.0, f64::max),
        finite: error.is_none() && state.first_non_finite().is_none(),
        solids: model.colliders().len(),
        solid_triangles: model.colliders().iter().map(|c| c.shape.triangle_count()).sum(),
        contacts_max: contacts.contacts_max,
        max_penetration_m: contacts.max_penetration_m.max(sim.max_penetration()),
        pin_load_n: (!pin_loads.is_empty()).then(|| (pin_loads.iter().sum::<Vec3>() / pin_loads.len() as f64).into()),
        self_contacts_max: contacts.self_contacts_max,
        released_contacts_total: contacts.released,
        narrow_phase_queries_total: contacts.queries,
        hash_builds_total: contacts.hash_builds,
        tangle,
        strain_limit: strain,
        crossings: (contacts.crossings > 0).then_some(CrossingSummary {
            steps: contacts.crossing_steps,
            meetings_total: contacts.crossings,
            left_total: contacts.crossings_left,
        }),
        error,
        warnings,
        stage_wall_s: stages,
        garment,
        bodies: None,
        coupling: None,
    };
    let final_x = state.x.clone();
    let summary = match (&runner, start_momentum) {
        (Runner::Coupled(run), Some(start)) => coupled_summary(summary, run, start, &coupling),
        _ => summary,
    };
    Ok(Simulated { summary, final_x })
}

/// The cloth's lowest and highest particle along the rig's up axis in its
/// root link's frame, m (`None` without a rig).
fn garment_heights(run: &CoupledRun) -> Option<(f64, f64)> {
    let rig = run.rig.as_ref()?;
    let root = &run.world.bodies[rig.bodies.handles[rig.rig.root]];
    let frame = cloth_rapier::convert::pose_from_rapier(root.position());
    let x = &run.cloths[run.cloth].simulation().state().x;
    let height = |p: &Vec3| (rig.rig.up * (frame.rotation.inverse() * (p - frame.position))).z;
    Some(x.iter().map(height).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), z| (lo.min(z), hi.max(z))))
}

/// Adds the bodies and the coupling counters to a coupled run's summary.
fn coupled_summary(mut summary: Summary, run: &CoupledRun, start: Momentum, totals: &CouplingTotals) -> Summary {
    let v3 = |v: cloth_rapier::rapier3d_f64::math::Vector| [v.x, v.y, v.z];
    summary.bodies = Some(
        run.bodies
            .iter()
            .map(|b| {
                let rb = &run.world.bodies[b.handle];
                let q = rb.rotation();
                BodySummary {
                    name: b.name.clone(),
                    position_m: v3(rb.translation()),
                    rotation_xyzw: [q.x, q.y, q.z, q.w],
                    velocity_m_s: v3(rb.linvel()),
                    angular_velocity_rad_s: v3(rb.angvel()),
                }
            })
            .collect(),
    );
    let end = run.cloths.momentum(&run.world);
    let steps = summary.steps.max(1);
    summary.coupling = Some(CouplingSummary {
        master: match run.master {
            Master::Staggered => "staggered",
            Master::Iterated(_) => "iterated",
            Master::Monolithic(_) => "monolithic",
        }
        .to_string(),
        passes_total: totals.passes,
        passes_max: totals.passes_max,
        passes_mean: totals.passes as f64 / steps as f64,
        unconverged_steps: totals.unconverged,
        residual_max: totals.residual_max,
        linear_momentum_change_n_s: (end.linear - start.linear).into(),
        angular_momentum_change_n_m_s: (end.angular - start.angular).into(),
    });
    summary
}

pub fn run(args: &RunArgs) -> Result<()> {
    if args.frames == Some(0) {
        bail!("--frames must be at least 1");
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    if args.binary_frames && args.frames.is_none() {
        bail!("--frame-format bin needs --frames N");
    }
    let frames =
        args.frames.map(|every| FrameOutput { every, dir: args.out.join("frames"), binary: args.binary_frames });
    let opts = SimulateOptions {
        threads: args.threads,
        frames,
        progress: !args.quiet,
        strict: args.strict,
        ..Default::default()
    };
    let summary = simulate(&args.scene, &args.overrides, opts)?;
    let path = args.out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    if let Some(e) = &summary.error {
        bail!("{}: {e}", args.scene.display());
    }
    if !args.quiet {
        println!(
            "{}: {} steps of {} s in {:.2} s wall ({:.2} ms/step median), CG {:.1}/step (max {}), max stretch {:.4}; wrote {}",
            args.scene.display(),
            summary.steps,
            summary.dt_s,
            summary.wall_s,
            summary.step_wall_s_median * 1e3,
            summary.cg_iterations_mean,
            summary.cg_iterations_max,
            summary.max_stretch_ratio,
            path.display()
        );
    }
    if !args.quiet && (summary.narrow_phase_queries_total > 0 || summary.hash_builds_total > 0) {
        println!(
            "  contacts up to {}, deepest inside a solid {:.2e} m, self contacts up to {}, collision {:.2} s, self-collision {:.2} s",
            summary.contacts_max,
            summary.max_penetration_m,
            summary.self_contacts_max,
            summary.stage_wall_s.collision,
            summary.stage_wall_s.self_collision
        );
    }
    if let Some(n) = summary.newton.as_ref().filter(|n| n.automatic_steps > 0) {
        eprintln!(
            "{}: steps large for the material from t = {:.4} s on: {} steps took Newton iterations \
             (solver.newton.auto_trigger; {} of them unconverged)",
            args.scene.display(),
            n.engaged_at_s.unwrap_or(0.0),
            n.automatic_steps,
            n.unconverged_steps
        );
    }
    if let Some(e) =
        summary.energy.as_ref().filter(|e| e.retaken_as_backward_euler_steps + e.retaken_with_newton_steps > 0)
    {
        eprintln!(
            "{}: steps that created energy were retaken (solver.energy_guard): {} as backward Euler, {} with \
             Newton iterations",
            args.scene.display(),
            e.retaken_as_backward_euler_steps,
            e.retaken_with_newton_steps
        );
    }
    if let Some(line) = summary.energy.as_ref().and_then(|e| energy_warning(&summary.integrator, e.flagged_steps)) {
        eprintln!("{}: {line}", args.scene.display());
    }
    Ok(())
}

/// What `cloth run` says when the energy monitor flagged windows of an
/// explicit integrator's steps (`None` for the implicit ones, whose
/// flagged steps BDF2 retakes and `summary.json` counts, and when none
/// was flagged): past its stability limit an explicit step multiplies the
/// energy every step, and the run may stay finite while it blows up.
fn energy_warning(integrator: &str, flagged: u64) -> Option<String> {
    let kind = cloth_core::IntegratorKind::ALL.into_iter().find(|k| k.name() == integrator);
    if flagged == 0 || kind.is_none_or(|k| k.is_implicit()) {
        return None;
    }
    let windows = if flagged == 1 { "window" } else { "windows" };
    Some(format!(
        "warning: {flagged} {windows} of {} steps gained more than {:.0}% of the energy in play beyond the work \
         done on the cloth: an explicit step beyond its stability limit does that; try a smaller \
         simulation.dt_s or an implicit integrator (summary.json: energy)",
        cloth_core::ENERGY_WINDOW,
        cloth_core::GAIN_TOLERANCE * 100.0
    ))
}

/// `cloth time`: runs a scene `repeat` times and prints one Markdown table
/// row of medians (the machine is noisy: quote medians, not single runs).
pub fn time(scene: &Path, overrides: &[String], threads: usize, repeat: usize) -> Result<()> {
    if repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let mut runs = Vec::with_capacity(repeat);
    for _ in 0..repeat {
        let s = simulate(scene, overrides, SimulateOptions::with_progress(threads))?;
        if let Some(e) = &s.error {
            bail!("{}: {e}", scene.display());
        }
        runs.push(s);
    }
    let median = |f: &dyn Fn(&Summary) -> f64| {
        let mut v: Vec<f64> = runs.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let s = &runs[0];
    let per_step = |stage: f64| stage / s.steps.max(1) as f64 * 1e3;
    println!(
        "| scene | particles | threads | steps | CG/step | ms/step (median of {repeat}) | forces | assembly | solve | collision | self-collision | update | tangle watch |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {} {} | {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
        scene.file_name().map_or_else(|| scene.display().to_string(), |n| n.to_string_lossy().into_owned()),
        overrides.join(" "),
        s.particles,
        threads,
        s.steps,
        s.cg_iterations_mean,
        median(&|r| r.step_wall_s_median) * 1e3,
        per_step(median(&|r| r.stage_wall_s.forces)),
        per_step(median(&|r| r.stage_wall_s.assembly)),
        per_step(median(&|r| r.stage_wall_s.solve)),
        per_step(median(&|r| r.stage_wall_s.collision)),
        per_step(median(&|r| r.stage_wall_s.self_collision)),
        per_step(median(&|r| r.stage_wall_s.update)),
        per_step(median(&|r| r.stage_wall_s.tangle)),
    );
    Ok(())
}

/// Processor time this process has used, all threads, s: user plus system
/// time from `/proc/self/stat` (fields 14 and 15, in Linux's fixed 100
/// ticks per second). `None` where that file is not there.
pub(crate) fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) is in parentheses and may hold spaces.
    let after_name = &stat[stat.rfind(')')? + 1..];
    let mut fields = after_name.split_whitespace().skip(11);
    let user: f64 = fields.next()?.parse().ok()?;
    let system: f64 = fields.next()?.parse().ok()?;
    Some((user + system) / 100.0)
}
