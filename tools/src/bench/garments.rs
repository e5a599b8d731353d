//! `cloth bench garments`: whether each Table-1 garment holds when made
//! finer, on the primitives mannequin and on its triangle-mesh twin.
//!
//! A garment at scale `s` has about `s` times its Table-1 particles: a
//! pattern's pieces are meshed at `1/sqrt(s)` of their edge lengths; a grid
//! panel's intervals are multiplied by `f`, `sqrt(s)` rounded to a half
//! (seams are fractions of an edge and land on nodes when every panel's
//! intervals scale alike: 1, 2.25 and 4 times the particles for 1, 2, 4);
//! an OBJ garment is read from the finer file written beside it.
//!
//! It holds when its peak stretch stays under [`PEAK_STRETCH_LIMIT`], no
//! particle ends a step deeper inside a solid than the contact thickness,
//! no crossing of the cloth through itself lasts ([`cloth_core::LASTING_STEPS`]
//! steps), and every seam is closed at the end, no stitch wider than
//! [`SEAM_GAP_LIMIT_M`].

use super::{FRAME_RATE_HZ, GARMENTS, Garment};
use crate::output::Summary;
use crate::run::{SimulateOptions, simulate};
use anyhow::{Result, bail};
use cloth_rapier::CoupledScene;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Largest link stretch a garment that holds reaches at any step.
pub const PEAK_STRETCH_LIMIT: f64 = 1.15;

/// Widest stitch gap at the end of a garment whose seams are closed, m
/// (the default contact thickness: a wider gap shows).
pub const SEAM_GAP_LIMIT_M: f64 = 0.005;

/// The mannequin a garment walks on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Mannequin {
    /// `fixtures/rigs/mannequin.urdf`: capsules, spheres and boxes.
    Primitives,
    /// `fixtures/rigs/mannequin-mesh.urdf`: the same, 14,460 triangles.
    Mesh,
}

impl Mannequin {
    /// Its name on the command line and in the table.
    fn name(self) -> &'static str {
        match self {
            Mannequin::Primitives => "primitives",
            Mannequin::Mesh => "mesh",
        }
    }

    /// The override that puts a garment's scene on this mannequin.
    fn overrides(self) -> Vec<String> {
        match self {
            Mannequin::Primitives => vec![],
            Mannequin::Mesh => vec!["rig.urdf=\"../rigs/mannequin-mesh.urdf\"".into()],
        }
    }
}

/// Options of `cloth bench garments`.
pub struct GarmentsArgs {
    /// Where NAME.md and NAME.json go.
    pub out: PathBuf,
    /// Worker threads.
    pub threads: usize,
    /// Particle counts as multiples of Table 1's.
    pub scales: Vec<f64>,
    /// The mannequins.
    pub mannequins: Vec<Mannequin>,
    /// Only these garments (all when empty).
    pub garments: Vec<String>,
    /// Simulated time per run, s (the scene's own when absent).
    pub duration_s: Option<f64>,
    /// Overrides of every run, after the garment's own.
    pub overrides: Vec<String>,
    /// Stem of the written files.
    pub name: String,
    /// Wall time after which a run stops, its row saying how far it got, s.
    pub max_wall_s: Option<f64>,
}

impl GarmentsArgs {
    /// The command line that reproduces this run.
    fn command(&self) -> String {
        let list = |v: Vec<String>| v.join(",");
        let mut c = format!(
            "cargo run --release -p cloth-tools -- bench garments --scale {} --mannequin {}",
            list(self.scales.iter().map(|s| s.to_string()).collect()),
            list(self.mannequins.iter().map(|m| m.name().to_string()).collect()),
        );
        if !self.garments.is_empty() {
            c += &format!(" --garment {}", self.garments.join(","));
        }
        if self.name != "garments" {
            c += &format!(" --name {}", self.name);
        }
        if let Some(d) = self.duration_s {
            c += &format!(" --duration {d}");
        }
        if let Some(w) = self.max_wall_s {
            c += &format!(" --max-wall {w}");
        }
        for o in &self.overrides {
            c += &format!(" --set '{o}'");
        }
        c
    }
}

/// One garment on one mannequin at one scale.
#[derive(Debug, Serialize)]
pub struct GarmentRow {
    /// Garment (a Table-1 name).
    pub garment: &'static str,
    /// Mannequin.
    pub mannequin: Mannequin,
    /// The scale asked for (particles over Table 1's).
    pub scale: f64,
    /// The scene and the overrides that ran.
    pub scene: String,
    /// Cloth particles (0: the scene did not build).
    pub particles: usize,
    /// Simulated time reached, s.
    pub sim_time_s: f64,
    /// Largest link stretch at any step.
    pub peak_stretch: f64,
    /// Deepest a particle was inside a solid after any step, m.
    pub deepest_in_solid_m: f64,
    /// Most particles deeper inside a solid than the contact thickness after a step.
    pub deep_in_solids_max: usize,
    /// Crossings of the cloth through itself after the last step.
    pub crossings_end: usize,
    /// Most crossings after any step.
    pub crossings_max: usize,
    /// The first crossing that lasted, in words, and when it began, s.
    pub lasting_crossing: Option<String>,
    /// When the first lasting crossing began, s.
    pub lasting_crossing_from_s: Option<f64>,
    /// Stitches closed at the end and in all (none: no seams).
    pub seams_closed: Option<[usize; 2]>,
    /// Widest stitch gap at the end, m.
    pub seam_gap_m: Option<f64>,
    /// Wall time per 30 Hz frame, ms.
    pub wall_ms_per_frame: f64,
    /// The error that stopped the run or kept it from starting.
    pub error: Option<String>,
    /// Which of the conditions failed (empty: it holds).
    pub fails: Vec<&'static str>,
}

/// Runs every garment at every scale on every mannequin; writes NAME.md
/// and NAME.json.
pub fn garments(args: &GarmentsArgs) -> Result<()> {
    if args.scales.is_empty() || args.scales.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        bail!("--scale takes positive multiples of the Table-1 particle counts, e.g. --scale 1,2,4");
    }
    if let Some(d) = args.duration_s
        && !(d.is_finite() && d > 0.0)
    {
        bail!("--duration must be finite and > 0 s, got {d}");
    }
    if let Some(w) = args.max_wall_s
        && !(w.is_finite() && w > 0.0)
    {
        bail!("--max-wall must be finite and > 0 s, got {w}");
    }
    let chosen: Vec<&Garment> =
        GARMENTS.iter().filter(|g| args.garments.is_empty() || args.garments.iter().any(|n| n == g.name)).collect();
    if let Some(unknown) = args.garments.iter().find(|n| !GARMENTS.iter().any(|g| g.name == n.as_str())) {
        let names: Vec<&str> = GARMENTS.iter().map(|g| g.name).collect();
        bail!("--garment {unknown}: no such garment (one of {})", names.join(", "));
    }
    let mut rows = Vec::new();
    for garment in chosen {
        for &mannequin in &args.mannequins {
            for &scale in &args.scales {
                let row = run_one(garment, mannequin, scale, args)?;
                eprintln!(
                    "{} on {} at {scale}x: {} particles, {}",
                    garment.name,
                    mannequin.name(),
                    row.particles,
                    if row.fails.is_empty() { "holds".to_string() } else { row.fails.join(", ") }
                );
                rows.push(row);
            }
        }
    }
    super::write_results(&markdown(&rows, args), &rows, &args.out, &args.name)
}

/// The overrides that make `garment` about `scale` times its Table-1
/// particle count, after its Table-1 overrides.
pub fn refined(garment: &Garment, scene: &Path, scale: f64) -> Result<Vec<String>> {
    let base = garment.overrides();
    if let Some(&(obj, ring)) = nearest_obj(garment, scale) {
        let ring: Vec<usize> = (0..ring).collect();
        return Ok(base
            .into_iter()
            .chain([format!("meshes.0.obj=\"{obj}\""), format!("pins.0.vertices={ring:?}")])
            .collect());
    }
    let loaded = CoupledScene::load(scene, &base).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut set = base;
    // Every panel's intervals times the same factor: a seam's ends, given
    // as fractions of edges, stay on nodes.
    let f = (2.0 * scale.sqrt()).round() / 2.0;
    for (k, p) in loaded.scene.panels.iter().enumerate() {
        let [nu, nv] = p.particles;
        let nu = if p.wrap_u { (nu as f64 * f).round() as usize } else { ((nu - 1) as f64 * f).round() as usize + 1 };
        let nv = ((nv - 1) as f64 * f).round() as usize + 1;
        set.push(format!("panels.{k}.particles=[{nu}, {nv}]"));
    }
    for (k, m) in loaded.scene.meshes.iter().enumerate() {
        if let Some(piece) = &m.pattern {
            set.push(format!("meshes.{k}.pattern.edge_length_m={}", piece.edge_length_m / scale.sqrt()));
        }
    }
    Ok(set)
}

/// The finer OBJ closest in count to `scale` (none at 1x or for a garment
/// not read from a file).
fn nearest_obj(garment: &Garment, scale: f64) -> Option<&(&'static str, usize)> {
    if garment.finer_objs.is_empty() || scale < 1.5 {
        return None;
    }
    // The files' rings are 1.5 and 2 times the Table-1 mesh's 96 columns.
    garment.finer_objs.iter().min_by(|a, b| {
        let ratio = |ring: usize| (ring as f64 / 96.0).powi(2);
        (ratio(a.1) - scale).abs().total_cmp(&(ratio(b.1) - scale).abs())
    })
}

/// One run. A garment scene that does not load stops the bench; a run
/// that does not build or stops early is its row's.
fn run_one(garment: &Garment, mannequin: Mannequin, scale: f64, args: &GarmentsArgs) -> Result<GarmentRow> {
    let scene = cloth_tools::in_checkout(garment.scene);
    let mut set = refined(garment, &scene, scale)?;
    set.extend(mannequin.overrides());
    set.extend(args.overrides.iter().cloned());
    if let Some(d) = args.duration_s {
        set.push(format!("simulation.duration_s={d}"));
    }
    let command = std::iter::once(garment.scene.to_string())
        .chain(set.iter().map(|o| format!("--set '{o}'")))
        .collect::<Vec<_>>()
        .join(" ");
    let opts = SimulateOptions { max_wall_s: args.max_wall_s, ..SimulateOptions::with_progress(args.threads) };
    let summary = simulate(&scene, &set, opts);
    Ok(row(garment.name, mannequin, scale, command, summary))
}

/// A row from a run's summary, or from the error that kept it from starting.
fn row(garment: &'static str, mannequin: Mannequin, scale: f64, scene: String, run: Result<Summary>) -> GarmentRow {
    let mut r = GarmentRow {
        garment,
        mannequin,
        scale,
        scene,
        particles: 0,
        sim_time_s: 0.0,
        peak_stretch: f64::NAN,
        deepest_in_solid_m: f64::NAN,
        deep_in_solids_max: 0,
        crossings_end: 0,
        crossings_max: 0,
        lasting_crossing: None,
        lasting_crossing_from_s: None,
        seams_closed: None,
        seam_gap_m: None,
        wall_ms_per_frame: f64::NAN,
        error: None,
        fails: vec![],
    };
    let s = match run {
        Ok(s) => s,
        Err(e) => {
            r.error = Some(format!("{e:#}"));
            r.fails.push("did not start");
            return r;
        }
    };
    r.particles = s.particles;
    r.sim_time_s = s.sim_time_s;
    r.peak_stretch = s.peak_stretch_ratio;
    r.deepest_in_solid_m = s.tangle.deepest_in_solids_m;
    r.deep_in_solids_max = s.tangle.deep_in_solids_max;
    r.crossings_end = s.tangle.self_crossings_end;
    r.crossings_max = s.tangle.self_crossings_max;
    r.lasting_crossing = s.tangle.lasting_crossing.clone();
    r.lasting_crossing_from_s = s.tangle.lasting_crossing_from_s;
    r.seams_closed = s.seams.as_ref().map(|m| [m.closed, m.stitches]);
    r.seam_gap_m = s.seams.as_ref().map(|m| m.max_gap_m);
    r.wall_ms_per_frame = s.wall_s / (s.sim_time_s * FRAME_RATE_HZ) * 1e3;
    r.error = s.error.clone();
    r.fails = fails(&r);
    r
}

/// The conditions a run failed, in the table's words.
fn fails(r: &GarmentRow) -> Vec<&'static str> {
    let mut f = vec![];
    if r.error.is_some() {
        f.push("stopped");
    }
    if r.peak_stretch.is_nan() || r.peak_stretch >= PEAK_STRETCH_LIMIT {
        f.push("stretch");
    }
    if r.deep_in_solids_max > 0 {
        f.push("through a solid");
    }
    if r.lasting_crossing.is_some() {
        f.push("crossed itself");
    }
    let gap_open = r.seam_gap_m.is_some_and(|g| g.is_nan() || g >= SEAM_GAP_LIMIT_M);
    if r.seams_closed.is_some_and(|[closed, all]| closed < all) || gap_open {
        f.push("seam open");
    }
    f
}

/// The table: one row per run.
fn markdown(rows: &[GarmentRow], args: &GarmentsArgs) -> String {
    let mut md = format!(
        "# Garments made finer\n\n\
         Each Table-1 garment at multiples of its Table-1 particle count (scale), walking on the \
         mannequin of its row (primitives: 17 capsules, spheres and boxes; mesh: the same as 14,460 \
         triangles), h = 1/90 s, {} threads, one run each. Holds: peak stretch under \
         {PEAK_STRETCH_LIMIT}, no particle deeper inside a solid than the contact thickness after any \
         step, no crossing of the cloth through itself lasting {} steps, every stitch closed and none \
         wider than {} mm at the end. \
         Produced by `{}`.\n\n\
         | garment | mannequin | scale | particles | peak stretch | deepest in a solid (mm) | particles past the thickness (max) | crossings end / max | first lasting crossing | seams closed, widest gap (mm) | ms/frame | holds |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
        args.threads,
        cloth_core::LASTING_STEPS,
        SEAM_GAP_LIMIT_M * 1e3,
        args.command()
    );
    for r in rows {
        let lasting = r.lasting_crossing_from_s.map_or("none".to_string(), |t| format!("from {t:.2} s"));
        let seams = match (r.seams_closed, r.seam_gap_m) {
            (Some([closed, all]), Some(gap)) => format!("{closed}/{all}, {:.1}", gap * 1e3),
            _ => "-".into(),
        };
        let holds = if r.fails.is_empty() { "yes".to_string() } else { format!("no: {}", r.fails.join(", ")) };
        md.push_str(&format!(
            "| {} | {} | {} | {} | {:.3} | {:.2} | {} | {} / {} | {} | {} | {:.0} | {} |\n",
            r.garment,
            r.mannequin.name(),
            r.scale,
            r.particles,
            r.peak_stretch,
            r.deepest_in_solid_m * 1e3,
            r.deep_in_solids_max,
            r.crossings_end,
            r.crossings_max,
            lasting,
            seams,
            r.wall_ms_per_frame,
            holds
        ));
    }
    let stopped: Vec<&GarmentRow> = rows.iter().filter(|r| r.error.is_some()).collect();
    if !stopped.is_empty() {
        md.push_str("\nStopped runs:\n\n");
        for r in stopped {
            md.push_str(&format!(
                "- {} on {} at {}x: {}\n",
                r.garment,
                r.mannequin.name(),
                r.scale,
                r.error.as_deref().unwrap_or("")
            ));
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn garment(name: &str) -> &'static Garment {
        GARMENTS.iter().find(|g| g.name == name).expect("a Table-1 garment")
    }

    fn particles(name: &str, scale: f64) -> usize {
        let g = garment(name);
        let scene = cloth_tools::in_checkout(g.scene);
        let set = refined(g, &scene, scale).expect("refined");
        let loaded = CoupledScene::load(&scene, &set).expect("loads");
        let run = loaded.build().expect("builds: seams on nodes");
        run.cloths.get(run.cloth).expect("the scene's cloth").simulation().model().particle_count()
    }

    /// The one-piece's panels share one spacing and their seams are
    /// fractions of the tube's edge: 1.5 times every interval keeps them
    /// on nodes (the build checks each seam's node counts).
    #[test]
    fn a_finer_grid_garment_keeps_its_seams() {
        let g = garment("one-piece");
        let set = refined(g, &cloth_tools::in_checkout(g.scene), 2.0).unwrap();
        let panels: Vec<&str> = set.iter().map(String::as_str).filter(|s| s.starts_with("panels.")).skip(4).collect();
        assert_eq!(
            panels,
            [
                "panels.0.particles=[144, 34]",
                "panels.1.particles=[70, 10]",
                "panels.2.particles=[70, 10]",
                "panels.3.particles=[144, 40]"
            ]
        );
        assert_eq!(particles("one-piece", 1.0), 5458);
        assert_eq!(particles("one-piece", 2.0), 12056);
    }

    /// Pattern pieces are meshed at 1/sqrt(s) of their edges, an OBJ
    /// garment read from its finer file.
    #[test]
    fn finer_pattern_and_obj_garments_have_about_the_asked_count() {
        assert_eq!(particles("pattern-tshirt", 1.0), 3411);
        let ratio = particles("pattern-tshirt", 4.0) as f64 / 3411.0;
        assert!((3.6..4.4).contains(&ratio), "{ratio}");
        assert_eq!(particles("obj-skirt", 2.0), 7776);
        assert_eq!(particles("obj-skirt", 4.0), 13632);
    }
}
