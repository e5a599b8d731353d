//! The `cloth` binary end to end.

use std::path::PathBuf;
use std::process::Command;

fn cloth() -> Command {
    Command::new(env!("CARGO_BIN_EXE_cloth"))
}

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes").join(name)
}

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cloth-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Runs `cloth study <name> --quick` from the workspace root; returns its
/// output directory.
fn quick_study(name: &str) -> PathBuf {
    let out = out_dir(&format!("study-{name}"));
    let status = cloth()
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(["study", name, "--quick", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success(), "study {name}");
    out
}

/// `cloth run` on an 11 x 11 hang for 0.1 s (9 steps), frames every 5th
/// step, into `out_dir(name)`, with `extra` arguments.
fn run_small_hang(name: &str, extra: &[&str]) -> PathBuf {
    let out = out_dir(name);
    let status = cloth()
        .args(["run", scene("hang.toml").to_str().unwrap(), "--quiet", "--frames", "5"])
        .args(["--set", "panels.0.particles=[11, 11]", "--set", "pins.0.nodes=[[0, 10], [10, 10]]"])
        .args(["--set", "simulation.duration_s=0.1"])
        .args(extra)
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    out
}

#[test]
fn run_writes_summary_and_frames() {
    let out = run_small_hang("run", &[]);
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let s: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(s["particles"], 121);
    assert_eq!(s["steps"], 9);
    assert_eq!(s["integrator"], "bdf2");
    assert_eq!(s["model"], "choi-ko");
    assert_eq!(s["effects"], serde_json::json!(["gravity", "damping", "bending"]));
    assert_eq!(s["finite"], true);
    for key in ["dt_s", "sim_time_s", "wall_s", "max_stretch_ratio", "min_z_m", "max_speed_m_s"] {
        assert!(s[key].as_f64().is_some_and(f64::is_finite), "{key}");
    }
    assert!(s["cg_iterations_total"].as_u64().unwrap() >= s["cg_iterations_max"].as_u64().unwrap());
    assert_eq!(s["force_evaluations_total"], 9);
    assert_eq!(s["substeps_total"], 9);
    assert_eq!(s["rejected_steps_total"], 0);
    for stage in ["forces", "assembly", "solve", "update"] {
        assert!(s["stage_wall_s"][stage].as_f64().unwrap() >= 0.0, "{stage}");
    }
    // Frames 0 and 5 (steps 0..=9 every 5th), each a valid OBJ of 121
    // vertices, solids.json (no solids here, two frames of poses) and
    // steps.csv (a row a step, the last one the summary's stretch).
    let mut files: Vec<String> =
        std::fs::read_dir(out.join("frames")).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    files.sort();
    assert_eq!(files, ["frame_00000.obj", "frame_00005.obj", "solids.json", "steps.csv"]);
    let steps = std::fs::read_to_string(out.join("frames/steps.csv")).unwrap();
    let rows: Vec<&str> = steps.lines().collect();
    assert_eq!(rows.len(), 10, "{steps}");
    let last: Vec<&str> = rows[9].split(',').collect();
    assert_eq!((last[0], last[5].parse::<f64>().unwrap()), ("9", s["max_stretch_ratio"].as_f64().unwrap()));
    let solids: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("frames/solids.json")).unwrap()).unwrap();
    assert_eq!(solids["solids"].as_array().map(Vec::len), Some(0));
    assert_eq!(solids["frames"].as_array().map(Vec::len), Some(2));
    let obj = std::fs::read_to_string(out.join("frames/frame_00005.obj")).unwrap();
    assert_eq!(obj.lines().filter(|l| l.starts_with("v ")).count(), 121);
    assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), 200);
}

/// `--frame-format bin`: the frames in one `frames.bin` of the size its
/// format says, each position the OBJ frame's rounded to f32, the steps
/// the same; `cloth export` takes it; without `--frames` it is refused.
#[test]
fn binary_frames_hold_the_obj_frames_in_f32() {
    let (obj, bin) = (run_small_hang("frames-obj", &[]), run_small_hang("frames-bin", &["--frame-format", "bin"]));
    let read = cloth_tools::frames::Frames::read(&bin.join("frames/frames.bin")).unwrap();
    let bytes = std::fs::metadata(bin.join("frames/frames.bin")).unwrap().len();
    assert_eq!(bytes, 16 + 12 * 200 + 2 * (8 + 12 * 121));
    assert_eq!(read.frames.iter().map(|f| f.0).collect::<Vec<_>>(), [0, 5]);
    let text = std::fs::read_to_string(obj.join("frames/frame_00005.obj")).unwrap();
    let obj_x: Vec<[f32; 3]> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l.split_whitespace().map(|v| v.parse().unwrap()).collect();
            [c[0] as f32, c[1] as f32, c[2] as f32]
        })
        .collect();
    assert_eq!(read.frames[1].1, obj_x);
    let faces = text.lines().filter(|l| l.starts_with("f ")).count();
    assert_eq!(read.triangles.len(), faces);
    let export = cloth().arg("export").arg(&bin).output().unwrap();
    assert!(export.status.success() && bin.join("run.glb").is_file(), "{}", String::from_utf8_lossy(&export.stderr));
    let lone = cloth()
        .args(["run", scene("hang.toml").to_str().unwrap(), "--quiet", "--frame-format", "bin", "--out"])
        .arg(out_dir("frames-lone"))
        .output()
        .unwrap();
    assert!(!lone.status.success());
    assert!(String::from_utf8_lossy(&lone.stderr).contains("--frame-format bin needs --frames N"));
}

#[test]
fn validate_accepts_fixtures_and_names_bad_fields() {
    let ok = cloth().args(["validate", scene("hang.toml").to_str().unwrap()]).output().unwrap();
    assert!(ok.status.success());
    let bad = cloth()
        .args(["validate", scene("hang.toml").to_str().unwrap(), "--set", "simulation.dt_s=nan"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("hang.toml") && err.contains("simulation.dt_s"), "{err}");
    let unknown = cloth()
        .args(["validate", scene("hang.toml").to_str().unwrap(), "--set", "material.colour=1"])
        .output()
        .unwrap();
    assert!(!unknown.status.success());
    let err = String::from_utf8_lossy(&unknown.stderr);
    assert!(err.contains("hang.toml") && err.contains("colour"), "{err}");
}

/// A pin dragged at an absurd speed blows the run up: it must stop with a
/// non-zero exit that says at which step and particle, and still write
/// summary.json with `finite: false`.
#[test]
fn a_run_that_goes_non_finite_says_where_and_when() {
    let out = out_dir("blowup");
    let output = cloth()
        .args(["run", scene("hang.toml").to_str().unwrap(), "--quiet"])
        .args(["--set", "panels.0.particles=[6, 6]", "--set", "pins.0.nodes=[[0, 5]]"])
        .args(["--set", "pins.0.motion={ kind = \"linear\", velocity_m_s = [1e307, 0.0, 0.0] }"])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(err.contains("step ") && err.contains("particle ") && err.contains("non-finite"), "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["finite"], false);
    assert!(s["error"].as_str().unwrap().contains("particle"));
}

/// An explicit run past its stability limit that ends while still finite
/// (the hanging cloth, 21 x 21, Provot's springs, symplectic Euler at 2 ms
/// for 0.1 s: stretch 1.7e44 in 50 steps) exits 0, as it did before, but
/// says that its energy windows gained energy, and `summary.json` counts
/// them; the same run at 0.2 ms says nothing.
#[test]
fn an_explicit_run_that_blows_up_without_overflowing_is_flagged() {
    let run = |name: &str, dt: &str| {
        let out = out_dir(name);
        let output = cloth()
            .args(["run", scene("hang.toml").to_str().unwrap(), "--quiet"])
            .args(["--set", "panels.0.particles=[21, 21]", "--set", "pins.0.nodes=[[0, 20], [20, 20]]"])
            .args(["--set", "simulation.model=\"provot\"", "--set", "simulation.integrator=\"symplectic-euler\""])
            .args(["--set", &format!("simulation.dt_s={dt}"), "--set", "simulation.duration_s=0.1"])
            // Let it blow up all the way, as the monitor is watched on.
            .args(["--set", "solver.blow_up_stretch=inf"])
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        (String::from_utf8_lossy(&output.stderr).into_owned(), s)
    };
    let (err, s) = run("explicit-unstable", "2e-3");
    assert_eq!(s["finite"], true);
    assert!(s["max_stretch_ratio"].as_f64().unwrap() > 100.0, "{s}");
    assert!(s["energy"]["flagged_steps"].as_u64().unwrap() > 0, "{s}");
    assert!(err.contains("warning") && err.contains("stability limit") && err.contains("dt_s"), "{err}");
    let (err, s) = run("explicit-stable", "2e-4");
    assert_eq!(s["energy"]["flagged_steps"], 0, "{s}");
    assert!(!err.contains("warning"), "{err}");
}

#[test]
fn time_prints_a_table_row_of_medians() {
    let out = cloth()
        .args(["time", scene("hang.toml").to_str().unwrap(), "--repeat", "1"])
        .args([
            "--set",
            "panels.0.particles=[7, 7]",
            "--set",
            "pins.0.nodes=[[0, 6]]",
            "--set",
            "simulation.duration_s=0.1",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    let row = text.lines().last().unwrap();
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    // | scene | particles | threads | steps | CG/step | ms/step | forces | assembly | solve | ...
    assert_eq!(cells[2], "49", "{row}");
    assert_eq!(cells[3], "2", "{row}");
    assert_eq!(cells[4], "9", "{row}");
    assert!(cells[6].parse::<f64>().unwrap() > 0.0, "{row}");
    // Eight stage columns after ms/step, the last two update and the
    // tangle watch, and the header names as many.
    let header = text.lines().find(|l| l.contains("tangle watch")).expect("a header");
    assert_eq!(header.split('|').count(), row.split('|').count(), "{header}\n{row}");
    assert_eq!(cells.len(), 15, "{row}");
    assert!(cells[12..14].iter().all(|c| c.parse::<f64>().is_ok_and(|t| t >= 0.0)), "{row}");
}

#[test]
fn study_freefall_writes_csv_markdown_and_svg() {
    let out = quick_study("freefall");
    let csv = std::fs::read_to_string(out.join("freefall.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert!(rows[0].starts_with("model,method,K,"));
    assert_eq!(rows.len(), 1 + 3 * 2, "3 methods x 2 K values");
    // BDF2 with a converged solve falls exactly like the analytic body at any K.
    for row in rows.iter().filter(|r| r.contains("BDF2")) {
        let fall: f64 = row.split(',').nth(5).unwrap().parse().unwrap();
        assert!((fall - 0.4472).abs() < 0.002, "{row}");
    }
    let md = std::fs::read_to_string(out.join("freefall.md")).unwrap();
    assert!(md.contains("Machine:") && md.contains("study freefall"));
    let svg = std::fs::read_to_string(out.join("freefall_provot.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("<path"));
}

#[test]
fn study_cost_reports_every_method_and_model() {
    let out = quick_study("cost");
    let csv = std::fs::read_to_string(out.join("cost.csv")).unwrap();
    // 3 models x 14 methods (13 + BE 0 CG) x 2 sizes.
    assert_eq!(csv.lines().count(), 1 + 3 * 14 * 2);
    for row in csv.lines().skip(1) {
        let us: f64 = row.split(',').nth(6).unwrap().parse().unwrap();
        assert!(us > 0.0 && us.is_finite(), "{row}");
    }
    let md = std::fs::read_to_string(out.join("cost.md")).unwrap();
    assert!(md.contains("BE per CG iteration"));
}

/// The quick bending study runs Volino's strip at 1 cm and compares it with
/// the elastica computed by shooting (41.49 degrees at 10 cm).
#[test]
fn study_bending_compares_the_cantilever_with_the_elastica() {
    let out = quick_study("bending");
    let csv = std::fs::read_to_string(out.join("bending.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 2, "{csv}");
    let cells: Vec<f64> = rows[1].split(',').skip(1).map(|c| c.parse().unwrap()).collect();
    assert!((cells[3] - 41.49).abs() < 0.01, "exact chord: {}", rows[1]);
    assert!((cells[2] - cells[3]).abs() < 2.0, "simulated chord: {}", rows[1]);
    let md = std::fs::read_to_string(out.join("bending.md")).unwrap();
    assert!(md.contains("| volino | 1 | 10 |"), "{md}");
}

/// The quick large-step study runs the 21 x 21 hanging cloth at h = 0.2 s
/// with one solve and with Newton: Newton's peak stretch is the cloth's
/// sag, the single solve's several times the rest length (3.9 measured).
#[test]
fn study_large_steps_compares_one_solve_with_newton() {
    let out = quick_study("large-steps");
    let csv = std::fs::read_to_string(out.join("large-steps.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 2, "{csv}");
    let peak = |row: &[&str]| row[3].parse::<f64>().unwrap();
    assert_eq!((rows[0][2], rows[1][2]), ("1", "10"), "{csv}");
    assert!(peak(&rows[0]) > 2.0 && peak(&rows[1]) < 1.1, "{csv}");
}

/// The co-simulation study's masters have commas in their names: its CSV
/// must still read back, through a CSV reader, with the header's columns.
#[test]
fn study_cosim_writes_csv_that_a_reader_parses() {
    let out = quick_study("cosim");
    let mut reader = csv::Reader::from_path(out.join("cosim.csv")).unwrap();
    let columns = reader.headers().unwrap().len();
    assert_eq!(columns, 5);
    let rows: Vec<csv::StringRecord> = reader.records().collect::<Result<_, _>>().unwrap();
    assert_eq!(rows.len(), 7 * 3, "seven masters at three macro steps");
    assert!(rows.iter().all(|r| r.len() == columns));
    assert_eq!(&rows[0][0], "Jacobi, zero-order hold");
    assert!(rows.iter().all(|r| r[2].parse::<f64>().is_ok_and(|e| e > 0.0)));
}

/// The quick scaling study runs the hang and the drape at 11 x 11 and
/// 21 x 21: every row has its particle count and a positive cost, and the
/// table states the slope of each scene and links both plots.
#[test]
fn study_scaling_reports_cost_and_iterations_against_size() {
    let out = quick_study("scaling");
    let csv = std::fs::read_to_string(out.join("scaling.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 4, "{csv}");
    for (row, (scene, particles)) in
        rows.iter().zip([("hang", "121"), ("hang", "441"), ("drape-sphere", "121"), ("drape-sphere", "441")])
    {
        assert_eq!((row[0], row[2]), (scene, particles), "{csv}");
        let (cg, ms): (f64, f64) = (row[4].parse().unwrap(), row[5].parse().unwrap());
        assert!(cg >= 1.0 && ms > 0.0, "{csv}");
    }
    let md = std::fs::read_to_string(out.join("scaling.md")).unwrap();
    assert!(md.contains("- hang: cost grows as particles^") && md.contains("- drape-sphere: cost grows"), "{md}");
    for svg in ["scaling.svg", "scaling_cg.svg"] {
        assert!(std::fs::read_to_string(out.join(svg)).unwrap().contains("<path"), "{svg}");
    }
}

/// Runs a fixture with overrides and returns its summary.
fn summary_of(name: &str, overrides: &[&str]) -> serde_json::Value {
    let out = out_dir(name);
    let mut cmd = cloth();
    cmd.args(["run", scene(name).to_str().unwrap(), "--quiet", "--out"]).arg(&out);
    for o in overrides {
        cmd.args(["--set", o]);
    }
    assert!(cmd.status().unwrap().success(), "{name}");
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    std::fs::remove_dir_all(&out).ok();
    serde_json::from_str(&text).unwrap()
}

/// Only what a scene declares is computed: without colliders no narrow-phase
/// query runs, without `[self_collision]` no spatial hash is built, and the
/// collision stages take no time; with them the counters and stages show
/// the work.
#[test]
fn collision_work_happens_only_when_the_scene_declares_it() {
    let plain = summary_of("hang.toml", &["simulation.duration_s=0.1"]);
    assert_eq!(plain["narrow_phase_queries_total"], 0);
    assert_eq!(plain["hash_builds_total"], 0);
    assert_eq!(plain["contacts_max"], 0);
    assert_eq!(plain["self_contacts_max"], 0);
    assert_eq!(plain["max_penetration_m"], 0.0);
    assert_eq!(plain["stage_wall_s"]["collision"], 0.0);
    assert_eq!(plain["stage_wall_s"]["self_collision"], 0.0);

    let solids = summary_of("drape-sphere.toml", &["simulation.duration_s=0.3"]);
    assert!(solids["narrow_phase_queries_total"].as_u64().unwrap() > 0);
    assert!(solids["contacts_max"].as_u64().unwrap() > 0);
    assert_eq!(solids["hash_builds_total"], 0, "no self-collision declared");
    assert!(solids["stage_wall_s"]["collision"].as_f64().unwrap() > 0.0);
    assert_eq!(solids["stage_wall_s"]["self_collision"], 0.0);

    let folding = summary_of("fold.toml", &["simulation.duration_s=0.05"]);
    assert_eq!(folding["hash_builds_total"], folding["steps"], "one hash build per step");
    assert!(folding["stage_wall_s"]["self_collision"].as_f64().unwrap() > 0.0);
}

/// A sewn garment's summary says how closed its seams are (the top's 16
/// stitches, closed within a millimetre once the mannequin has stood for
/// 0.6 s); a scene without seams has no such entry.
#[test]
fn summaries_report_the_seams() {
    let top = summary_of("top-walk.toml", &["simulation.duration_s=0.7"]);
    assert_eq!(top["seams"]["stitches"], 16);
    assert_eq!(top["seams"]["closed"], 16, "every stitch closed by 0.6 s");
    let gap = top["seams"]["max_gap_m"].as_f64().unwrap();
    assert!(gap < 1e-3, "seams open by {gap} m");
    assert!(summary_of("hang.toml", &["simulation.duration_s=0.02"]).get("seams").is_none());
}

#[test]
fn bench_table1_prints_the_garments_beside_the_paper() {
    let out = out_dir("table1");
    let status = cloth()
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(["bench", "table1", "--duration", "0.1", "--repeat", "1", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("table1.json")).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    let garments: Vec<&str> = rows.iter().map(|r| r["garment"].as_str().unwrap()).collect();
    assert_eq!(
        garments,
        ["one-piece", "top", "skirt", "pattern-dress", "pattern-skirt", "pattern-tshirt", "flared-skirt", "obj-skirt"]
    );
    // The sewn garments at twice their fixtures' resolution, and the pattern
    // garments meshed finer, beside the paper's rows.
    let finer = [&rows[0], &rows[1], &rows[3], &rows[4], &rows[5], &rows[6], &rows[7]];
    for (r, particles) in finer.into_iter().zip([5458, 2866, 5510, 3540, 3411, 3482, 3456]) {
        assert_eq!(r["measured"]["particles"], particles);
        assert_eq!(r["measured"]["steps"], 9);
        assert!(!r["paper"].as_array().unwrap().is_empty());
    }
    let skirt = &rows[2];
    let (m, paper) = (&skirt["measured"], &skirt["paper"][0]);
    // The paper's particle count, on the mannequin's 17 shapes (primitives, no triangles).
    assert_eq!(m["particles"], paper["particles"]);
    assert_eq!(paper["particles"], 3456);
    assert_eq!((m["solids"].as_u64(), m["solid_triangles"].as_u64()), (Some(17), Some(0)));
    // 0.1 s at 1/90 s: 9 steps, three per 30 Hz frame.
    assert_eq!(m["steps"], 9);
    let frames = m["frames"].as_f64().unwrap();
    assert!((frames - 3.0).abs() < 1e-9, "{frames}");
    // The stages add up to the frame's wall time; the ratio is the paper's
    // CPU time over ours.
    let wall = m["wall_ms_per_frame"].as_f64().unwrap();
    let stages: f64 = m["stages_s_per_frame"].as_object().unwrap().values().map(|v| v.as_f64().unwrap()).sum();
    let all = (stages + m["other_s_per_frame"].as_f64().unwrap()) * 1e3;
    assert!((all - wall).abs() < 1e-9 * wall, "{all} vs {wall}");
    if let Some(cpu) = m["cpu_s_per_frame"].as_f64() {
        let speedup = skirt["speedup"][0].as_f64().unwrap();
        assert!((speedup * cpu - 3.01).abs() < 1e-9, "{speedup} x {cpu}");
    }
    let md = std::fs::read_to_string(out.join("table1.md")).unwrap();
    assert!(md.contains("| skirt | 3456 | 17 (0) |"), "{md}");
}

/// `cloth bench garments` runs each chosen garment at each scale and
/// mannequin and says whether it holds: the top at 0.1 s is still being
/// sewn (its seams open), the skirt holds; refining keeps the seams sewn
/// node to node.
#[test]
fn bench_garments_says_which_garments_hold() {
    let out = out_dir("garments");
    let status = cloth()
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(["bench", "garments", "--garment", "top,skirt", "--scale", "1,2", "--mannequin", "primitives"])
        .args(["--duration", "0.1", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("garments.json")).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    let got: Vec<(&str, f64, u64)> = rows
        .iter()
        .map(|r| (r["garment"].as_str().unwrap(), r["scale"].as_f64().unwrap(), r["particles"].as_u64().unwrap()))
        .collect();
    // The top's intervals times 1.5 at 2x (2.2 times the particles).
    assert_eq!(got, [("top", 1.0, 2866), ("top", 2.0, 6296), ("skirt", 1.0, 3456), ("skirt", 2.0, 7776)]);
    for top in &rows[..2] {
        let [closed, all] = [0, 1].map(|k| top["seams_closed"][k].as_u64().unwrap());
        assert!(closed < all && all > 0, "{top}");
        assert!(top["fails"].as_array().unwrap().iter().any(|f| f == "seam open"), "{top}");
    }
    // Four seams of a strap's 7 nodes at 1x, of 10 at 2x: node to node.
    assert_eq!(rows[0]["seams_closed"][1], 28);
    assert_eq!(rows[1]["seams_closed"][1], 40);
    for skirt in &rows[2..] {
        assert_eq!(skirt["fails"].as_array().unwrap().len(), 0, "{skirt}");
        assert!(skirt["peak_stretch"].as_f64().unwrap() < 1.15);
    }
    let md = std::fs::read_to_string(out.join("garments.md")).unwrap();
    assert!(md.contains("| skirt | primitives | 2 | 7776 |"), "{md}");
    let bad = cloth()
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(["bench", "garments", "--garment", "cape", "--out"])
        .arg(out_dir("garments-bad"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--garment cape: no such garment"));
}

#[test]
fn bench_table1_refuses_bad_options() {
    let refusals = [
        ("--repeat", "0", "--repeat must be at least 1"),
        ("--duration", "0", "--duration must be finite and > 0 s, got 0"),
        ("--duration", "NaN", "--duration must be finite and > 0 s, got NaN"),
    ];
    for (flag, value, message) in refusals {
        let output = cloth()
            .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .args(["bench", "table1", flag, value, "--out"])
            .arg(out_dir("table1-bad"))
            .output()
            .unwrap();
        assert!(!output.status.success(), "{flag} {value}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains(message), "{flag} {value}: {stderr}");
    }
}

/// `cloth validate` prints the rig (links, height, up axis and scale, the
/// joints the motion drives) and warns about a character at the wrong
/// scale, naming the key; `cloth run` warns before its first step, keeps
/// the warning in summary.json, and names each solid in solids.json.
#[test]
fn rigs_are_described_warned_about_and_their_solids_named() {
    let walk = scene("skirt-walk.toml");
    let ok = cloth().args(["validate", walk.to_str().unwrap()]).output().unwrap();
    let text = String::from_utf8_lossy(&ok.stdout);
    assert!(ok.status.success());
    assert!(text.contains("rig's 15 links") && text.contains("1.760 m tall") && text.contains("up axis z"), "{text}");
    assert!(text.contains("the motion drives waist") && !text.contains("warning"), "{text}");
    // At 4 m per unit the character is 7 m tall and the skirt starts
    // inside its pelvis: an error naming the key, listing the particles.
    let tall = cloth().args(["validate", walk.to_str().unwrap(), "--set", "rig.scale=4.0"]).output().unwrap();
    let err = String::from_utf8_lossy(&tall.stderr);
    assert!(!tall.status.success() && err.contains("collision.allow_start_inside") && err.contains("\"pelvis\""));
    let allow = ["--set", "collision.allow_start_inside=true"];
    let tall =
        cloth().args(["validate", walk.to_str().unwrap(), "--set", "rig.scale=4.0"]).args(allow).output().unwrap();
    let text = String::from_utf8_lossy(&tall.stdout);
    assert!(text.contains("warning") && text.contains("7.04 m tall") && text.contains("set rig.scale"), "{text}");
    let out = out_dir("rig-warning");
    let run = cloth()
        .args(["run", walk.to_str().unwrap(), "--quiet", "--frames", "1"])
        .args(["--set", "rig.scale=4.0", "--set", "simulation.duration_s=0.02"])
        .args(allow)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("skirt-walk.toml: warning") && err.contains("rig.scale"), "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(s["warnings"][0].as_str().unwrap().contains("rig.scale"), "{s}");
    let solids: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("frames/solids.json")).unwrap()).unwrap();
    let names: Vec<&str> = solids["solids"].as_array().unwrap().iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"pelvis") && names.contains(&"foot_r"), "{names:?}");
    // The skirt's waist is pinned 8 cm above the hip joints and its 0.45 m
    // hang below: summary.json says where it is in the pelvis's frame.
    let out = out_dir("garment-heights");
    let skirt = scene("pattern-skirt-walk.toml");
    let run = cloth()
        .args(["run", skirt.to_str().unwrap(), "--quiet", "--set", "simulation.duration_s=0.3", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let g = &s["garment"];
    let (hem, top) = (g["hem_m"].as_f64().unwrap(), g["top_m"].as_f64().unwrap());
    assert!((top - 0.08).abs() < 1e-3 && (hem - (0.08 - 0.45)).abs() < 0.01, "{g}");
    assert!(g["hem_lowest_m"].as_f64().unwrap() <= hem && g["top_lowest_m"].as_f64().unwrap() <= top, "{g}");
}

/// Cloth that starts inside one of the scene's own solids stops `cloth
/// validate` with an error naming the file, the key, the particles and
/// the solid; allowed, it is a warning.
#[test]
fn cloth_starting_inside_a_collider_is_named() {
    let drape = scene("drape-sphere.toml");
    let through = ["--set", "colliders.0.position_m=[0.0, 0.0, 0.3]"];
    let bad = cloth().args(["validate", drape.to_str().unwrap()]).args(through).output().unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("drape-sphere.toml") && err.contains("collision.allow_start_inside"), "{err}");
    assert!(err.contains("particle 840 in \"colliders[0]\" by 200.0 mm") && err.contains("402 particles"), "{err}");
    let allowed = cloth()
        .args(["validate", drape.to_str().unwrap()])
        .args(through)
        .args(["--set", "collision.allow_start_inside=true"])
        .output()
        .unwrap();
    assert!(allowed.status.success());
    assert!(String::from_utf8_lossy(&allowed.stdout).contains("warning: the cloth starts inside solids"));
}

/// A scene built to tangle (`tangle-fold.toml`: the fold without
/// self-collision, its layers falling through each other) is flagged: a
/// warning naming the time and the particles, `summary.json`'s `tangle`
/// counts and words, `steps.csv`'s crossings a step. With `--strict` the
/// run stops there with a non-zero exit and the error in `summary.json`.
/// The same fold with self-collision does not tangle.
#[test]
fn a_tangling_scene_is_flagged_and_strict_mode_stops_it() {
    let out = out_dir("tangle");
    let run = cloth()
        .args(["run", scene("tangle-fold.toml").to_str().unwrap(), "--quiet", "--frames", "10", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains("warning: the cloth passes through itself from t = "), "{stderr}");
    assert!(stderr.contains("(step ") && stderr.contains("through triangle ("), "{stderr}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let tangle = &s["tangle"];
    assert!(tangle["self_crossings_max"].as_u64().unwrap() > 10, "{tangle}");
    assert!(tangle["self_crossing_steps"].as_u64().unwrap() >= cloth_core::LASTING_STEPS, "{tangle}");
    assert!(tangle["lasting_crossing"].as_str().is_some_and(|w| w.contains("no [self_collision]")), "{tangle}");
    assert_eq!(s["steps"], 200);
    let steps = std::fs::read_to_string(out.join("frames/steps.csv")).unwrap();
    let header: Vec<&str> = steps.lines().next().unwrap().split(',').collect();
    let column = header.iter().position(|h| *h == "self_crossings").expect("a crossings column");
    let most = steps.lines().skip(1).map(|l| l.split(',').nth(column).unwrap().parse::<u64>().unwrap()).max();
    assert_eq!(most, tangle["self_crossings_max"].as_u64());

    let strict = out_dir("tangle-strict");
    let run = cloth()
        .args(["run", scene("tangle-fold.toml").to_str().unwrap(), "--quiet", "--strict", "--out"])
        .arg(&strict)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "--strict must fail on a tangle: {stderr}");
    assert!(stderr.contains("tangled (--strict): the cloth passes through itself"), "{stderr}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(strict.join("summary.json")).unwrap()).unwrap();
    assert!(s["error"].as_str().is_some_and(|e| e.contains("--strict")), "{}", s["error"]);
    assert!(s["steps"].as_u64().unwrap() < 200, "stopped at the tangle");

    let held = summary_of("fold.toml", &["simulation.duration_s=1.0"]);
    assert_eq!(held["tangle"]["self_crossings_max"], 0, "{}", held["tangle"]);
    assert_eq!(held["tangle"]["deep_in_solids_max"], 0, "{}", held["tangle"]);
    for dir in [out, strict] {
        std::fs::remove_dir_all(dir).ok();
    }
}

/// A hanging sheet too soft for one pass of its deformation constraints
/// a step (20 N/m, 10% limit; measured: a link at 1.130 of its rest
/// length after step 11, 2.41 at worst) is reported: a warning naming the
/// time, the link and the passes, `summary.json`'s `strain_limit` counts
/// and words, `steps.csv`'s corrections a step. With `--strict` the run
/// stops there with a non-zero exit. The sheet at 200 N/m with 50 passes
/// stays within the limit (1.1015 at worst) and is not reported.
#[test]
fn a_link_left_past_the_strain_limit_is_reported_and_strict_mode_stops_it() {
    let hang = scene("hang.toml");
    let sheet = [
        "simulation.effects=[\"gravity\", \"bending\", \"damping\", \"strain-limit\"]",
        "constraints.max_strain=0.1",
        "panels.0.particles=[21, 21]",
        "pins.0.nodes=[[0, 20], [20, 20]]",
        "simulation.duration_s=1.0",
    ];
    let soft = ["constraints.passes=1", "material.tensile_stiffness_n_m=20"];
    let run = |name: &str, sets: &[&str], extra: &[&str]| {
        let out = out_dir(name);
        let mut cmd = cloth();
        cmd.args(["run", hang.to_str().unwrap(), "--quiet", "--frames", "10", "--out"]).arg(&out).args(extra);
        for s in sheet.iter().chain(sets) {
            cmd.args(["--set", s]);
        }
        let o = cmd.output().unwrap();
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        let steps = std::fs::read_to_string(out.join("frames/steps.csv")).ok();
        std::fs::remove_dir_all(&out).ok();
        (o.status.success(), String::from_utf8_lossy(&o.stderr).into_owned(), s, steps)
    };
    let (ok, err, s, steps) = run("over-stretched", &soft, &[]);
    assert!(ok, "{err}");
    assert!(
        err.contains("hang.toml: warning: the deformation constraints left a link past their limit at t = "),
        "{err}"
    );
    assert!(err.contains("(step ") && err.contains("the limit 1.100 (constraints.passes = 1)"), "{err}");
    let limit = &s["strain_limit"];
    assert_eq!(limit["limit_ratio"], 1.1, "{limit}");
    assert!(limit["steps_over"].as_u64().unwrap() > 10, "{limit}");
    assert_eq!(limit["worst_ratio"], s["peak_stretch_ratio"], "{limit}");
    assert!(limit["worst_ratio"].as_f64().unwrap() > 1.5, "{limit}");
    assert!(limit["first_over"].as_str().is_some_and(|w| w.contains("link ")), "{limit}");
    let steps = steps.expect("steps.csv");
    let header: Vec<&str> = steps.lines().next().unwrap().split(',').collect();
    let column = header.iter().position(|h| *h == "strain_corrections").expect("a corrections column");
    let corrections: u64 =
        steps.lines().skip(1).map(|l| l.split(',').nth(column).unwrap().parse::<u64>().unwrap()).sum();
    assert!(corrections > 0, "one pass a step corrects links");

    let (ok, err, s, _) = run("over-stretched-strict", &soft, &["--strict"]);
    assert!(!ok, "--strict must fail on a link past the limit: {err}");
    assert!(err.contains("over-stretched (--strict): the deformation constraints left a link"), "{err}");
    assert!(s["error"].as_str().is_some_and(|e| e.contains("--strict")), "{}", s["error"]);
    assert!(s["steps"].as_u64().unwrap() < 90, "stopped at the first link past the limit");

    let (ok, err, s, _) = run("within-limit", &[], &["--strict"]);
    assert!(ok && !err.contains("warning"), "{err}");
    assert_eq!(s["strain_limit"]["steps_over"], 0, "{}", s["strain_limit"]);
    assert!(s["strain_limit"].get("first_over").is_none(), "{}", s["strain_limit"]);
}
