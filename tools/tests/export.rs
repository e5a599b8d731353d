//! `cloth export`: a recorded run as a binary glTF file. The Khronos
//! glTF-Validator (from npm; `.ci/run` installs it and names its directory
//! in `GLTF_VALIDATOR`) finds nothing wrong with it, and what a viewer
//! shows at each key time is what `cloth run` wrote at that frame.

mod common;

use common::cloth;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The sweep (a ball on a path pushing into a hanging curtain), small and
/// short, with a frame every 9 steps, in its own directory.
fn sweep_run(name: &str) -> PathBuf {
    common::recorded_run("export", name, "sweep.toml", &["panels.0.particles=[16, 16]", "simulation.duration_s=1"])
}

#[test]
fn the_export_is_valid_gltf_and_shows_the_recorded_frames() {
    let out = sweep_run("valid");
    let output = cloth().arg("export").arg(&out).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let glb = out.join("run.glb");
    assert!(String::from_utf8_lossy(&output.stdout).contains("run.glb") && glb.is_file());
    let Some(validator) = common::outside_tool("GLTF_VALIDATOR", "the Khronos glTF-Validator") else { return };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf_check.mjs");
    let check = Command::new("node").arg(script).arg(validator).arg(&glb).arg(out.join("frames")).output().unwrap();
    assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stderr));
    let text = String::from_utf8_lossy(&check.stdout);
    println!("{text}");
    let report: serde_json::Value = serde_json::from_str(text.trim()).unwrap();
    assert_eq!((report["errors"].as_u64(), report["warnings"].as_u64()), (Some(0), Some(0)), "{report}");
    // 90 steps, a frame every 9: 11 frames, 10 morph targets, the ball.
    assert_eq!((report["frames"].as_u64(), report["objFrames"].as_u64()), (Some(11), Some(11)));
    assert_eq!((report["targets"].as_u64(), report["solidNodes"].as_u64()), (Some(10), Some(1)));
    assert!((report["lastTime"].as_f64().unwrap() - 1.0).abs() < 1e-6, "{report}");
    // Three f32 roundings (first frame, displacement, their sum) of
    // coordinates up to 1.2 m: at most 1.5 ulp, 1.8e-7 m (measured 1.15e-7).
    let (cloth_error, pose_error) = (report["clothError"].as_f64().unwrap(), report["poseError"].as_f64().unwrap());
    assert!(cloth_error < 1.8e-7 && pose_error < 6e-8, "{report}");
    assert_eq!(report["weightError"].as_f64(), Some(0.0));
}

#[test]
fn export_names_what_is_missing_or_malformed() {
    let empty = std::env::temp_dir().join(format!("cloth-export-{}-empty", std::process::id()));
    std::fs::create_dir_all(&empty).unwrap();
    let output = cloth().arg("export").arg(&empty).output().unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("summary.json"));
    let out = sweep_run("malformed");
    let frame = out.join("frames/frame_00009.obj");
    let text = std::fs::read_to_string(&frame).unwrap().replacen("v ", "v 1 nan-ish ", 1);
    std::fs::write(&frame, text).unwrap();
    let output = cloth().arg("export").arg(&out).output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && stderr.contains("frame_00009.obj:1:"), "{stderr}");
    assert!(!out.join("run.glb").exists());
}
