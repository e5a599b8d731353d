//! `cloth regress`: the committed goldens hold, and a change is caught.

mod common;

use common::cloth;
use std::path::{Path, PathBuf};
use std::process::Output;

fn workspace() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// `cloth regress ARGS` from the workspace root.
fn regress(args: &[&str]) -> Output {
    cloth().current_dir(workspace()).arg("regress").args(args).output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// CI's fixture regression run: every fixture scene and the Table-1
/// garments, shortened, bit for bit against `fixtures/goldens`. After a
/// deliberate change to the physics: `cargo run --release -p cloth-tools
/// -- regress --update`, and commit the goldens with the change.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn every_fixture_matches_its_golden() {
    let o = regress(&[]);
    print!("{}", stdout(&o));
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = stdout(&o).lines().filter(|l| l.ends_with("| same |")).count();
    let scenes = std::fs::read_dir(workspace().join("fixtures/scenes")).unwrap().count();
    let garments = stdout(&o).lines().filter(|l| l.starts_with("| table1-")).count();
    assert_eq!(garments, 8, "the Table-1 garments: one-piece, top, skirt, the pattern garments, the OBJ skirt");
    assert_eq!(rows, scenes + garments, "every fixture and the Table-1 garments, bit for bit");
}

fn goldens_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cloth-regress-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Replaces the first `from` in `path` by `to`.
fn edit(path: &Path, from: &str, to: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.contains(from), "{} has no {from:?}", path.display());
    std::fs::write(path, text.replacen(from, to, 1)).unwrap();
}

#[test]
fn a_change_is_caught_named_and_taken_back_by_update() {
    let dir = goldens_dir("change");
    let g = dir.to_str().unwrap();
    let only = ["--only", "freefall", "--only", "incline", "--goldens", g];
    let o = regress(&[&only[..], &["--update"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).matches("new: golden written").count(), 2, "{}", stdout(&o));
    let o = regress(&only);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert_eq!(stdout(&o).matches("| same |").count(), 2);

    // A count in a summary, and one particle 1 mm off in a final frame.
    let json = dir.join("freefall.json");
    let golden: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let steps = golden["summary"]["force_evaluations_total"].as_u64().unwrap();
    edit(
        &json,
        &format!("\"force_evaluations_total\": {steps}"),
        &format!("\"force_evaluations_total\": {}", steps + 1),
    );
    let obj = dir.join("incline.final.obj");
    let text = std::fs::read_to_string(&obj).unwrap();
    let last = text.lines().last().unwrap().to_string();
    let x: f64 = last.split_whitespace().nth(1).unwrap().parse().unwrap();
    edit(&obj, &last, &last.replacen(&x.to_string(), &(x + 1e-3).to_string(), 1));
    let particles = text.lines().filter(|l| l.starts_with("v ")).count();

    let o = regress(&only);
    let out = stdout(&o);
    assert!(!o.status.success(), "{out}");
    assert!(out.contains("| freefall |") && out.contains("CHANGED"), "{out}");
    assert!(out.contains(&format!("force_evaluations_total: {} -> {steps}", steps + 1)), "{out}");
    let moved = format!("1 of {particles} particles moved, most 1.000e-3 m (particle {})", particles - 1);
    assert!(out.contains(&moved), "{out}");
    assert!(stderr(&o).contains("2 of 2 cases differ"), "{}", stderr(&o));

    // A tolerance does not excuse a changed count; the 1 mm is within
    // 1e-2 of the incline cloth's extent.
    let o = regress(&[&only[..], &["--rel-tol", "1e-2"]].concat());
    assert!(stdout(&o).contains("| incline |") && stdout(&o).contains("within tolerance"), "{}", stdout(&o));
    assert!(stderr(&o).contains("1 of 2 cases differ"), "{}", stderr(&o));

    let o = regress(&[&only[..], &["--update"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).matches("changed: golden rewritten").count(), 2, "{}", stdout(&o));
    let o = regress(&only);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
}

#[test]
fn a_changed_case_and_an_unknown_name_are_refused() {
    let dir = goldens_dir("case");
    let g = dir.to_str().unwrap();
    let only = ["--only", "freefall", "--goldens", g];
    assert!(regress(&[&only[..], &["--update"]].concat()).status.success());
    edit(&dir.join("freefall.json"), "\"max_steps\": 60", "\"max_steps\": 30");
    let o = regress(&only);
    assert!(!o.status.success());
    assert!(stdout(&o).contains("case: {\"name\":\"freefall\""), "{}", stdout(&o));

    let o = regress(&["--only", "no-such-scene", "--goldens", g]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("--only no-such-scene: no such case") && err.contains("table1-skirt"), "{err}");
    let o = regress(&["--only", "freefall", "--goldens", g, "--rel-tol=-1"]);
    assert!(stderr(&o).contains("--rel-tol must be finite and >= 0"), "{}", stderr(&o));
}

/// A case without a golden is new, and a scene that does not load fails,
/// naming the file and the field; both fail the run (the Table-1 cases
/// fail too: this fixtures directory has no garments).
#[test]
fn a_new_case_and_a_broken_scene_fail_the_run() {
    let dir = goldens_dir("fixtures");
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    let freefall = std::fs::read_to_string(workspace().join("fixtures/scenes/freefall.toml")).unwrap();
    std::fs::write(dir.join("scenes/tiny.toml"), &freefall).unwrap();
    let broken = freefall.replace("dt_s = 0.01", "dt_s = 0.01\nstep_count = 3");
    std::fs::write(dir.join("scenes/broken.toml"), broken).unwrap();
    let o = regress(&["--fixtures", dir.to_str().unwrap()]);
    let (out, err) = (stdout(&o), stderr(&o));
    assert!(!o.status.success());
    assert!(out.contains("| tiny | 441 | 50 |") && out.contains("NEW (no golden)"), "{out}");
    assert!(out.contains("| broken | - | - | - | FAILED |"), "{out}");
    assert!(out.contains("broken.toml") && out.contains("step_count"), "the error names the file and the field: {out}");
    assert!(out.contains("| table1-skirt | - | - | - | FAILED |"), "{out}");
    assert!(err.contains("9 of 10 cases did not run"), "{err}");
}

/// Outside the checkout (an installed `cloth`), the default fixtures are
/// the checkout's the binary was built from.
#[test]
fn regress_finds_the_fixtures_from_anywhere() {
    let elsewhere = std::env::temp_dir();
    let o = cloth().current_dir(&elsewhere).args(["regress", "--only", "freefall"]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("| freefall |") && stdout(&o).contains("| same |"), "{}", stdout(&o));
}
