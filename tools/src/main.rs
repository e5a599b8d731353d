//! `cloth`: run and validate cloth scenes.

mod bench;
mod export;
mod fmu;
mod live;
mod output;
mod regress;
mod run;
mod study;
mod svg;
mod view;

use bench::garments::Mannequin;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "cloth", version, about = "Run and validate cloth scenes (Choi & Ko 2002 implicit cloth)")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write DIR/summary.json (and frames with --frames).
    Run {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        // The help is an attribute: rustdoc would read "[75,75]" as a link.
        #[arg(
            long = "set",
            value_name = "KEY=VALUE",
            help = "Override a scene field, e.g. --set panels.0.particles=[75,75] (repeatable)"
        )]
        overrides: Vec<String>,
        /// Write every N-th state as DIR/frames/frame_NNNNN.obj.
        #[arg(long, value_name = "N")]
        frames: Option<u64>,
        /// How to write frames: `obj` (a file each, full precision) or `bin`
        /// (one DIR/frames/frames.bin, f32, about a fifth of the size).
        #[arg(long, value_name = "FORMAT", default_value = "obj", value_parser = ["obj", "bin"])]
        frame_format: String,
        /// Worker threads (default: the machine's cores; results are the
        /// same for any count).
        #[arg(long, default_value_t = cloth_tools::machine_threads())]
        threads: usize,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
        /// Stop with an error at the first tangle (a crossing of the cloth
        /// through itself that lasts, or cloth pushed through a solid), or
        /// at the first link the deformation constraints leave past their
        /// limit, instead of warning.
        #[arg(long)]
        strict: bool,
    },
    /// Run a scene several times and print a Markdown row of median timings
    /// (Choi & Ko Table-1 style: ms per step, CG iterations, stage split,
    /// and the run's tangle watch, which is outside the step). ms/step is
    /// the run's median step; each stage is its total over the run per
    /// step, the first step's set-up included, so on runs of a few steps
    /// a stage can exceed the median step.
    Time {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Overrides, as for `run`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        overrides: Vec<String>,
        /// Worker threads (default 2: timings are taken on the two cores
        /// of the target machine).
        #[arg(long, default_value_t = 2)]
        threads: usize,
        /// Runs to take the median over.
        #[arg(long, default_value_t = 5)]
        repeat: usize,
    },
    /// Reproduce Volino & Magnenat-Thalmann's (2001) comparison of integrators.
    Study {
        #[command(subcommand)]
        study: StudyKind,
        /// Output directory for CSV, Markdown and SVG.
        #[arg(long, global = true, default_value = "docs/results")]
        out: PathBuf,
        /// Worker threads (default: the machine's cores).
        #[arg(long, global = true, default_value_t = cloth_tools::machine_threads())]
        threads: usize,
        /// A small sweep (for tests and a quick look).
        #[arg(long, global = true)]
        quick: bool,
    },
    /// Benchmarks against the papers' own tables.
    Bench {
        #[command(subcommand)]
        bench: BenchKind,
        /// Output directory for Markdown and JSON.
        #[arg(long, global = true, default_value = "docs/results")]
        out: PathBuf,
        /// Worker threads (default 2: Table 1 is timed on the two cores
        /// of the target machine).
        #[arg(long, global = true, default_value_t = 2)]
        threads: usize,
        /// Runs per scene; the median by wall time is reported.
        #[arg(long, global = true, default_value_t = 3)]
        repeat: usize,
        /// Simulated time per run, s (default: each scene's own).
        #[arg(long, global = true, value_name = "S")]
        duration: Option<f64>,
        /// Override a key of every garment's scene (repeatable), e.g.
        /// `--set simulation.integrator=vbd`.
        #[arg(long = "set", global = true, value_name = "KEY=VALUE")]
        overrides: Vec<String>,
        /// Name of the written files, `NAME.md` and `NAME.json` (default:
        /// the benchmark's name).
        #[arg(long, global = true)]
        name: Option<String>,
    },
    /// The cloth as an FMI 3.0 co-simulation FMU.
    Fmu {
        #[command(subcommand)]
        fmu: FmuKind,
    },
    /// Serve a page on localhost that plays a run's frames (`cloth run
    /// --frames N`): the cloth with both faces lit, the scene's solids,
    /// orbit/zoom/pan, play/pause/scrub.
    View {
        /// The run's output directory.
        out: PathBuf,
        /// Port on 127.0.0.1 (0: any free one; the address is printed).
        #[arg(long, default_value_t = 8090)]
        port: u16,
        /// Stop after this many seconds (default: serve until stopped).
        #[arg(long, value_name = "S")]
        seconds: Option<f64>,
    },
    /// Write a recorded run (`cloth run --frames N`) as one binary glTF
    /// file: the cloth's motion as morph targets, the solids' as keyed
    /// poses, the frame times (Blender: File > Import > glTF 2.0).
    Export {
        /// The run's output directory.
        out: PathBuf,
        /// Where to write (default OUT/run.glb).
        #[arg(long, value_name = "FILE")]
        to: Option<PathBuf>,
    },
    /// Run a scene live: the simulation paced to real time in the server,
    /// the viewer page showing it as it computes and setting the wind
    /// (scenes whose wind is `profile = { kind = "external" }`).
    Live {
        /// Scene file (TOML), cloth only.
        scene: PathBuf,
        /// Overrides, as for `run`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        overrides: Vec<String>,
        /// Port on 127.0.0.1 (0: any free one; the address is printed).
        #[arg(long, default_value_t = 8091)]
        port: u16,
        /// Stop after this many seconds (default: run until stopped).
        #[arg(long, value_name = "S")]
        seconds: Option<f64>,
        /// Worker threads of the simulation (default: the machine's cores).
        #[arg(long, default_value_t = cloth_tools::machine_threads())]
        threads: usize,
        /// Start paused at the scene's first state (the page's play button
        /// or `/resume` starts it).
        #[arg(long)]
        paused: bool,
    },
    /// Run every fixture scene and the Table-1 garments, shortened, and
    /// compare each summary and final frame with its golden under
    /// fixtures/goldens: prints what changed, fails on any change.
    Regress {
        /// The fixtures directory (scenes/ and goldens/ in it; default
        /// `fixtures` here, else the checkout this binary was built from).
        #[arg(long, default_value = "fixtures")]
        fixtures: PathBuf,
        /// Where the goldens are (default FIXTURES/goldens).
        #[arg(long)]
        goldens: Option<PathBuf>,
        /// After a deliberate change: rewrite the goldens that changed,
        /// write the new ones, delete those no case has.
        #[arg(long)]
        update: bool,
        /// Only this case (repeatable), e.g. --only hang --only table1-skirt.
        #[arg(long, value_name = "CASE")]
        only: Vec<String>,
        /// Worker threads (default: the machine's cores; results are the
        /// same for any count).
        #[arg(long, default_value_t = cloth_tools::machine_threads())]
        threads: usize,
        /// Accept floats within this relative difference, and positions
        /// within it times the cloth's extent (default 0: bit for bit, as
        /// determinism promises on one platform; for another platform).
        #[arg(long, default_value_t = 0.0, value_name = "REL")]
        rel_tol: f64,
    },
    /// Check a scene without running it.
    Validate {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Overrides, as for `run`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        overrides: Vec<String>,
    },
}

#[derive(Subcommand)]
enum FmuKind {
    /// Package SCENE as NAME.fmu: modelDescription.xml from the cloth
    /// unit's variables, the shared library, the scene under resources/.
    Build {
        /// Scene file (TOML).
        scene: PathBuf,
        /// The .fmu to write.
        #[arg(long)]
        out: PathBuf,
        /// Overrides, as for `run` (carried into the FMU).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        overrides: Vec<String>,
        /// The FMU's binary (default: libcloth_fmu.so beside this
        /// executable, from `cargo build --release -p cloth-fmu`).
        #[arg(long)]
        library: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum BenchKind {
    /// Choi & Ko's Table 1: garments on a walking character at the paper's
    /// particle counts, CPU s per 30 Hz frame beside the paper's.
    Table1,
    /// Each Table-1 garment made finer (particle counts as multiples of
    /// Table 1's) on both mannequins: peak stretch, depth inside a solid,
    /// self-crossings, seams, ms per frame, and whether it holds.
    Garments {
        /// Multiples of the Table-1 particle counts, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = [1.0, 2.0, 4.0])]
        scale: Vec<f64>,
        /// Mannequins, comma separated.
        #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Mannequin::Primitives, Mannequin::Mesh])]
        mannequin: Vec<Mannequin>,
        /// Only these garments, comma separated (Table 1's names).
        #[arg(long, value_delimiter = ',')]
        garment: Vec<String>,
        /// Stop a run after this much wall time, s; its row says the time
        /// it reached (a tangled garment can bog down).
        #[arg(long, value_name = "S")]
        max_wall: Option<f64>,
    },
}

#[derive(Subcommand)]
enum StudyKind {
    /// Fall time against the condition coefficient K, per method and model.
    Freefall,
    /// Steps, CG iterations and wall time to drape to the vertical, against h.
    Drape,
    /// Time per polygon per step, per method and model, across grid sizes.
    Cost,
    /// Error against a converged reference versus CPU time (work-precision).
    Precision,
    /// The minimisers' (vertex solver, quasi-Newton) work-precision on four
    /// scenes and a garment on the walking mannequin beside BDF2, and where
    /// the sweeps leave stiff stretch unconverged.
    Vbd,
    /// Co-simulation masters on the two-mass oscillator: order and energy drift.
    Cosim,
    /// Peirce's cantilever against the heavy elastica, per model and resolution.
    Bending,
    /// Large steps: the single linearised step against Newton with a line search.
    LargeSteps,
    /// The hard-case suite: what must hold in each case, and whether it does.
    Stability,
    /// Cost and CG iterations per step against particle count, 1k to 263k.
    Scaling,
    /// A strip under its own weight: sag per model against flexural rigidity and strain.
    GridStretch,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scene, out, overrides, frames, frame_format, threads, quiet, strict } => {
            let binary_frames = frame_format == "bin";
            run::run(&run::RunArgs { scene, out, overrides, frames, binary_frames, threads, quiet, strict })
        }
        Command::Bench { bench: BenchKind::Table1, out, threads, repeat, duration, overrides, name } => {
            let name = name.unwrap_or_else(|| "table1".into());
            bench::table1(&bench::BenchArgs { out, threads, repeat, duration_s: duration, overrides, name })
        }
        Command::Bench {
            bench: BenchKind::Garments { scale, mannequin, garment, max_wall },
            out,
            threads,
            duration,
            overrides,
            name,
            ..
        } => bench::garments::garments(&bench::garments::GarmentsArgs {
            out,
            threads,
            scales: scale,
            mannequins: mannequin,
            garments: garment,
            duration_s: duration,
            overrides,
            name: name.unwrap_or_else(|| "garments".into()),
            max_wall_s: max_wall,
        }),
        Command::Fmu { fmu: FmuKind::Build { scene, out, overrides, library } } => {
            fmu::build(&scene, &overrides, library.as_deref(), &out)
        }
        Command::View { out, port, seconds } => view::view(&out, port, seconds),
        Command::Export { out, to } => export::export(&out, to.as_deref()).map(|path| {
            println!("wrote {}", path.display());
        }),
        Command::Live { scene, overrides, port, seconds, threads, paused } => {
            live::live(&scene, &overrides, &live::LiveArgs { port, seconds, threads, paused })
        }
        Command::Regress { fixtures, goldens, update, only, threads, rel_tol } => {
            let fixtures = cloth_tools::in_checkout(fixtures);
            regress::regress(&regress::RegressArgs { fixtures, goldens, update, only, threads, rel_tol })
        }
        Command::Validate { scene, overrides } => run::validate(&scene, &overrides),
        Command::Time { scene, overrides, threads, repeat } => run::time(&scene, &overrides, threads, repeat),
        Command::Study { study, out, threads, quick } => {
            let args = study::StudyArgs { out, threads, quick };
            match study {
                StudyKind::Freefall => study::freefall(&args),
                StudyKind::Drape => study::drape(&args),
                StudyKind::Cost => study::cost(&args),
                StudyKind::Precision => study::precision(&args),
                StudyKind::Vbd => study::vbd(&args),
                StudyKind::Cosim => study::cosim(&args),
                StudyKind::Bending => study::bending(&args),
                StudyKind::LargeSteps => study::large_steps(&args),
                StudyKind::Stability => study::stability(&args),
                StudyKind::Scaling => study::scaling(&args),
                StudyKind::GridStretch => study::grid_stretch(&args),
            }
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
