//! `cloth bench table1`: Choi & Ko's (2002) Table 1 on this machine.
//!
//! The paper's table: garments on walking characters at `h = 1/90 s`,
//! three steps per frame of 30 Hz animation, the CPU seconds each frame
//! took on a Pentium III 550 MHz (collision detection under 20% of it).
//! Each garment of ours runs its scene at the paper's particle count on
//! the walking mannequin and is printed beside the paper's row.

pub mod garments;

use crate::output::{StageWall, Summary};
use crate::run::{SimulateOptions, simulate};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One row of Choi & Ko's Table 1.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PaperRow {
    /// The paper's name of the animation.
    pub animation: &'static str,
    /// Cloth particles.
    pub particles: usize,
    /// Triangles of the solids (the character).
    pub solid_triangles: usize,
    /// CPU seconds per frame of 30 Hz animation (three steps).
    pub cpu_s_per_frame: f64,
}

/// Choi & Ko 2002, Table 1 ("Performance Summary"; Pentium III 550 MHz).
const PAPER: [PaperRow; 5] = [
    PaperRow { animation: "1(a)", particles: 5608, solid_triangles: 13802, cpu_s_per_frame: 6.13 },
    PaperRow { animation: "1(b)", particles: 5579, solid_triangles: 13802, cpu_s_per_frame: 5.86 },
    PaperRow { animation: "2", particles: 5579, solid_triangles: 15308, cpu_s_per_frame: 5.68 },
    PaperRow { animation: "top", particles: 3396, solid_triangles: 15308, cpu_s_per_frame: 2.98 },
    PaperRow { animation: "skirt", particles: 3456, solid_triangles: 15308, cpu_s_per_frame: 3.01 },
];

/// A garment of the table: the scene that runs it (a fixture and the
/// overrides that bring it to the paper's particle count) and the paper's
/// rows it compares with.
pub(crate) struct Garment {
    pub name: &'static str,
    pub scene: &'static str,
    /// The garment's own overrides of its scene (counts, meshes).
    own: &'static [&'static str],
    /// Whether Table 1 adds [`DEFORMATION_CONSTRAINTS`] the scene leaves out.
    constrained: bool,
    paper: &'static [usize],
    /// A garment read from an OBJ file: the same garment written finer,
    /// as `(file, as the scene names it; the vertices of its held top
    /// ring, 0..n)`, for `cloth bench garments`.
    pub finer_objs: &'static [(&'static str, usize)],
}

/// The garments, each at twice its fixture's resolution (every panel's
/// spacing halved; the seams' fractions land on nodes at any multiple of
/// the fixtures' 48 nodes round). The skirt's 96 x 36 is the paper's 3456
/// particles (1.8 x 1.3 cm cells, in the paper's 1-2 cm); the top's tube
/// and straps (1.08 cm cells) make 2866 (the paper's top, 3396, had
/// sleeves), the one-piece's 5458 (the paper's, 5579-5608).
const TOP: [&str; 3] = ["panels.0.particles=[96, 23]", "panels.1.particles=[47, 7]", "panels.2.particles=[47, 7]"];
const ONE_PIECE: [&str; 4] = [
    "panels.0.particles=[96, 23]",
    "panels.1.particles=[47, 7]",
    "panels.2.particles=[47, 7]",
    "panels.3.particles=[96, 27]",
];
/// Provot's deformation constraints for the skirts and the one-piece, as
/// the T-shirt's, the dress's, the top's and the skirt's fixtures have
/// them (10%, 50 passes after 10 fast projections): without them the pattern skirt's layers lock where the legs
/// pinch its front (peak 1.58 on the primitives, 3.39 on the
/// triangle-mesh mannequin), the flared skirt at 2738 particles peaks at
/// 1.55 with a seam 5 mm open, and the shins striking the one-piece's hem
/// stretch it 1.47 times (3.1 at twice the count). Their fixtures leave
/// them out: at 3.5 cm the constraints, which follow the self-collision
/// response, bring the pattern skirt's layers to 2.9 mm of each other
/// (4.6 mm without); at the one-piece fixture's count the tube's lower
/// edge, which the skirt's seam draws down over the pelvis box (whose
/// outline is 23% longer than the edge), cannot stretch over it and a
/// seam stays 22 mm open. The OBJ skirt has them as `skirt-walk.toml`,
/// whose skirt it is, does: without them a shin striking its hem at four
/// times its Table-1 count stretched a link 1.49 times.
const DEFORMATION_CONSTRAINTS: [&str; 3] = [
    "simulation.effects=[\"gravity\", \"bending\", \"damping\", \"strain-limit\"]",
    "constraints.passes=50",
    "constraints.projections=10",
];
/// The pattern garments, meshed finer than their fixtures to the paper's
/// counts: the skirt's two pieces at 1.75 cm (3540 particles; the
/// fixture's 3.5 cm make 914), the dress's pieces at 0.6 of their edge
/// lengths (5510; the fixture's 2024).
const PATTERN_SKIRT: [&str; 2] = ["meshes.0.pattern.edge_length_m=0.0175", "meshes.1.pattern.edge_length_m=0.0175"];
const PATTERN_DRESS: [&str; 6] = [
    "meshes.0.pattern.edge_length_m=0.015",
    "meshes.1.pattern.edge_length_m=0.015",
    "meshes.2.pattern.edge_length_m=0.013",
    "meshes.3.pattern.edge_length_m=0.013",
    "meshes.4.pattern.edge_length_m=0.021",
    "meshes.5.pattern.edge_length_m=0.021",
];
/// The T-shirt and the flared skirt at the paper's counts or finer: the
/// T-shirt's pieces at 0.69 of their fixture's edge lengths (3411
/// particles; the paper's top had 3396), the flared skirt's gores at
/// 1.86 cm (3482; the paper's skirt had 3456).
const PATTERN_TSHIRT: [&str; 6] = [
    "meshes.0.pattern.edge_length_m=0.01725",
    "meshes.1.pattern.edge_length_m=0.01725",
    "meshes.2.pattern.edge_length_m=0.01518",
    "meshes.3.pattern.edge_length_m=0.01518",
    "meshes.4.pattern.edge_length_m=0.0138",
    "meshes.5.pattern.edge_length_m=0.0138",
];
const FLARED_SKIRT: [&str; 2] = ["meshes.0.pattern.edge_length_m=0.0186", "meshes.1.pattern.edge_length_m=0.0186"];
/// The OBJ skirt read from the same tube at the paper's count
/// (`fixtures/meshes/tube-skirt-3456.obj`, 96 x 36 vertices), its top
/// ring of 96 held by the pelvis.
const OBJ_SKIRT: [&str; 2] = [
    "meshes.0.obj=\"../meshes/tube-skirt-3456.obj\"",
    "pins.0.vertices=[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, \
     26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42, 43, 44, 45, 46, 47, 48, 49, 50, 51, 52, 53, \
     54, 55, 56, 57, 58, 59, 60, 61, 62, 63, 64, 65, 66, 67, 68, 69, 70, 71, 72, 73, 74, 75, 76, 77, 78, 79, 80, 81, \
     82, 83, 84, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95]",
];
pub(crate) const GARMENTS: [Garment; 8] = [
    Garment {
        name: "one-piece",
        scene: "fixtures/scenes/one-piece-walk.toml",
        own: &ONE_PIECE,
        constrained: true,
        paper: &[0, 1, 2],
        finer_objs: &[],
    },
    Garment {
        name: "top",
        scene: "fixtures/scenes/top-walk.toml",
        own: &TOP,
        constrained: false,
        paper: &[3],
        finer_objs: &[],
    },
    Garment {
        name: "skirt",
        scene: "fixtures/scenes/skirt-walk.toml",
        own: &["panels.0.particles=[96, 36]"],
        constrained: false,
        paper: &[4],
        finer_objs: &[],
    },
    Garment {
        name: "pattern-dress",
        scene: "fixtures/scenes/pattern-dress-walk.toml",
        own: &PATTERN_DRESS,
        constrained: false,
        paper: &[0, 1, 2],
        finer_objs: &[],
    },
    Garment {
        name: "pattern-skirt",
        scene: "fixtures/scenes/pattern-skirt-walk.toml",
        own: &PATTERN_SKIRT,
        constrained: true,
        paper: &[4],
        finer_objs: &[],
    },
    Garment {
        name: "pattern-tshirt",
        scene: "fixtures/scenes/pattern-tshirt-walk.toml",
        own: &PATTERN_TSHIRT,
        constrained: false,
        paper: &[3],
        finer_objs: &[],
    },
    Garment {
        name: "flared-skirt",
        scene: "fixtures/scenes/pattern-flared-skirt-walk.toml",
        own: &FLARED_SKIRT,
        constrained: true,
        paper: &[4],
        finer_objs: &[],
    },
    Garment {
        name: "obj-skirt",
        scene: "fixtures/scenes/obj-skirt-walk.toml",
        own: &OBJ_SKIRT,
        constrained: true,
        paper: &[4],
        // 144 x 54 and 192 x 71 vertices (`fixtures/meshes/make_tube_skirt.py`).
        finer_objs: &[("../meshes/tube-skirt-7776.obj", 144), ("../meshes/tube-skirt-13632.obj", 192)],
    },
];

impl Garment {
    /// The overrides that make the Table-1 variant of the scene: the
    /// garment's own, then the deformation constraints if it takes them.
    pub fn overrides(&self) -> Vec<String> {
        let constraints = if self.constrained { &DEFORMATION_CONSTRAINTS[..] } else { &[] };
        self.own.iter().chain(constraints).map(|o| o.to_string()).collect()
    }
}

/// Frames of 30 Hz animation per simulated second.
pub(crate) const FRAME_RATE_HZ: f64 = 30.0;

/// What one garment measured (the median run by wall time).
#[derive(Debug, Serialize)]
pub struct Measured {
    /// The scene file and the overrides that made the Table-1 variant.
    pub scene: String,
    /// Cloth particles.
    pub particles: usize,
    /// Solids the cloth meets (rig links and colliders).
    pub solids: usize,
    /// Triangles among them (0: the mannequin is capsules, spheres, boxes).
    pub solid_triangles: usize,
    /// Steps taken and the step, s.
    pub steps: u64,
    /// Time step, s.
    pub dt_s: f64,
    /// Frames of 30 Hz animation simulated.
    pub frames: f64,
    /// Wall time per frame, ms (threads as given).
    pub wall_ms_per_frame: f64,
    /// Processor time per frame, all threads, s (what the paper's "CPU
    /// sec/frame" measured on one processor); absent where unmeasured.
    pub cpu_s_per_frame: Option<f64>,
    /// Cloth-solid and self-collision time over the wall time.
    pub collision_share: f64,
    /// Where a frame's wall time goes, s: the cloth's stages ...
    pub stages_s_per_frame: StageWall,
    /// ... and the rest (driving the rig, rapier's step, the coupling).
    pub other_s_per_frame: f64,
    /// Mean CG iterations per step.
    pub cg_per_step: f64,
    /// Largest link stretch at any step.
    pub peak_stretch: f64,
    /// Deepest a particle was inside a solid, m.
    pub max_penetration_m: f64,
    /// The lowest particle's height at the end, m (a garment's hem).
    pub hem_z_m: f64,
}

/// A garment's row: measured, or why not, beside the paper's rows.
#[derive(Debug, Serialize)]
pub struct Table1Row {
    /// Garment.
    pub garment: &'static str,
    /// What ran.
    pub measured: Measured,
    /// The paper's rows for this garment.
    pub paper: Vec<PaperRow>,
    /// The paper's CPU s per frame over ours, per paper row.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub speedup: Vec<f64>,
}

/// Options of `cloth bench table1`.
pub struct BenchArgs {
    /// Where table1.md and table1.json go.
    pub out: PathBuf,
    /// Worker threads.
    pub threads: usize,
    /// Runs per garment; the median by wall time is reported.
    pub repeat: usize,
    /// Simulated time per run, s (the scene's own when absent).
    pub duration_s: Option<f64>,
    /// Overrides of every garment's scene, after the garment's own.
    pub overrides: Vec<String>,
    /// Stem of the written files.
    pub name: String,
}

impl BenchArgs {
    /// The command line that reproduces this run.
    fn command(&self) -> String {
        let mut c = String::from("cargo run --release -p cloth-tools -- bench table1");
        if self.threads != 2 {
            c += &format!(" --threads {}", self.threads);
        }
        if self.repeat != 3 {
            c += &format!(" --repeat {}", self.repeat);
        }
        if self.name != "table1" {
            c += &format!(" --name {}", self.name);
        }
        if let Some(d) = self.duration_s {
            c += &format!(" --duration {d}");
        }
        for o in &self.overrides {
            c += &format!(" --set '{o}'");
        }
        c
    }
}

/// Runs the Table-1 garments and writes table1.md and table1.json.
pub fn table1(args: &BenchArgs) -> Result<()> {
    if args.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    if let Some(d) = args.duration_s
        && !(d.is_finite() && d > 0.0)
    {
        bail!("--duration must be finite and > 0 s, got {d}");
    }
    let mut rows = Vec::new();
    for garment in &GARMENTS {
        let paper: Vec<PaperRow> = garment.paper.iter().map(|&k| PAPER[k]).collect();
        let measured = measure(&cloth_tools::in_checkout(garment.scene), &garment.overrides(), args)?;
        let speedup = match measured.cpu_s_per_frame {
            Some(ours) => paper.iter().map(|p| p.cpu_s_per_frame / ours).collect(),
            None => vec![],
        };
        rows.push(Table1Row { garment: garment.name, measured, paper, speedup });
    }
    write_results(&markdown(&rows, args), &rows, &args.out, &args.name)
}

/// Prints a benchmark's table and writes it as `NAME.md`, its rows as
/// `NAME.json`, in `out`.
pub(crate) fn write_results(md: &str, rows: &impl Serialize, out: &Path, name: &str) -> Result<()> {
    print!("{md}");
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    std::fs::write(out.join(format!("{name}.md")), md)?;
    std::fs::write(out.join(format!("{name}.json")), serde_json::to_string_pretty(rows)?)?;
    Ok(())
}

/// Runs one garment `repeat` times and keeps the median run by wall time.
fn measure(scene: &Path, overrides: &[String], args: &BenchArgs) -> Result<Measured> {
    let mut set: Vec<String> = overrides.iter().chain(&args.overrides).cloned().collect();
    if let Some(d) = args.duration_s {
        set.push(format!("simulation.duration_s={d}"));
    }
    let mut runs: Vec<Summary> = Vec::with_capacity(args.repeat);
    for _ in 0..args.repeat {
        let s = simulate(scene, &set, SimulateOptions::with_progress(args.threads))?;
        if let Some(e) = &s.error {
            bail!("{}: {e}", scene.display());
        }
        runs.push(s);
    }
    runs.sort_by(|a, b| a.wall_s.total_cmp(&b.wall_s));
    let s = &runs[runs.len() / 2];
    let frames = s.sim_time_s * FRAME_RATE_HZ;
    let stages = s.stage_wall_s.scaled(1.0 / frames);
    let collision = s.stage_wall_s.collision + s.stage_wall_s.self_collision;
    Ok(Measured {
        scene: std::iter::once(scene.display().to_string())
            .chain(set.iter().map(|o| format!("--set '{o}'")))
            .collect::<Vec<_>>()
            .join(" "),
        particles: s.particles,
        solids: s.solids,
        solid_triangles: s.solid_triangles,
        steps: s.steps,
        dt_s: s.dt_s,
        frames,
        wall_ms_per_frame: s.wall_s / frames * 1e3,
        cpu_s_per_frame: s.cpu_s.map(|c| c / frames),
        collision_share: collision / s.wall_s,
        other_s_per_frame: s.wall_s / frames - stages.total(),
        stages_s_per_frame: stages,
        cg_per_step: s.cg_iterations_mean,
        peak_stretch: s.peak_stretch_ratio,
        max_penetration_m: s.max_penetration_m,
        hem_z_m: s.min_z_m,
    })
}

/// The table as the paper prints it, ours beside the paper's rows.
fn markdown(rows: &[Table1Row], args: &BenchArgs) -> String {
    let threads = args.threads;
    let mut md = format!(
        "# Choi & Ko 2002, Table 1, on this machine\n\n\
         Garments on the walking mannequin, h = 1/90 s, three steps per frame of 30 Hz animation, \
         {threads} threads. CPU s/frame is processor time of all threads (the paper's: one Pentium III \
         550 MHz); real time is 33.3 ms of wall time per frame. Produced by \
         `{}`.\n\n\
         | garment | particles | solids (triangles) | wall ms/frame | CPU s/frame | collision share | CG/step | peak stretch | max penetration (mm) | hem z (m) | paper: animation, particles, solid triangles, CPU s/frame | paper / ours (CPU) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
        args.command()
    );
    for r in rows {
        let paper: Vec<String> = r
            .paper
            .iter()
            .map(|p| format!("{}: {}, {}, {:.2}", p.animation, p.particles, p.solid_triangles, p.cpu_s_per_frame))
            .collect();
        let speedup: Vec<String> = r.speedup.iter().map(|x| format!("{x:.0}x")).collect();
        let m = &r.measured;
        md.push_str(&format!(
            "| {} | {} | {} ({}) | {:.1} | {} | {:.0}% | {:.1} | {:.3} | {:.1} | {:.3} | {} | {} |\n",
            r.garment,
            m.particles,
            m.solids,
            m.solid_triangles,
            m.wall_ms_per_frame,
            m.cpu_s_per_frame.map_or("n/a".into(), |c| format!("{c:.4}")),
            m.collision_share * 100.0,
            m.cg_per_step,
            m.peak_stretch,
            m.max_penetration_m * 1e3,
            m.hem_z_m,
            paper.join("; "),
            if speedup.is_empty() { "n/a".into() } else { speedup.join(", ") },
        ));
    }
    for r in rows {
        let m = &r.measured;
        let t = m.stages_s_per_frame.scaled(1e3);
        md.push_str(&format!(
            "\n{}: `{}`, {} steps. A frame's wall time, ms: forces {:.1}, assembly {:.1}, solve {:.1}, \
             update {:.1}, collision {:.1}, self-collision {:.1}, tangle check {:.1}, other (rig, rapier, \
             coupling) {:.1}.\n",
            r.garment,
            m.scene,
            m.steps,
            t.forces,
            t.assembly,
            t.solve,
            t.update,
            t.collision,
            t.self_collision,
            t.tangle,
            m.other_s_per_frame * 1e3
        ));
    }
    md
}
