//! `cloth fmu build` and the FMU in an independent importer (FMPy).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn cloth() -> Command {
    Command::new(env!("CARGO_BIN_EXE_cloth"))
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn work_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cloth-fmu-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn fmu_build_packs_description_binary_and_scene() {
    let out = work_dir("build").join("hang.fmu");
    let status = cloth()
        .arg("fmu")
        .arg("build")
        .arg(root().join("fixtures/scenes/hang.toml"))
        .args(["--set", "pins.0.motion={ kind = \"external\" }", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let entries = cloth_fmu::package::read_fmu(&out).unwrap();
    let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "modelDescription.xml",
            "binaries/x86_64-linux/cloth_fmu.so",
            "resources/scene.toml",
            "resources/overrides.txt"
        ]
    );
    let xml = String::from_utf8(entries[0].1.clone()).unwrap();
    let scene = std::fs::read_to_string(root().join("fixtures/scenes/hang.toml")).unwrap();
    let overrides = vec!["pins.0.motion={ kind = \"external\" }".to_string()];
    assert!(xml.contains(&format!("instantiationToken=\"{}\"", cloth_fmu::instantiation_token(&scene, &overrides))));
    for name in ["pin0.target.x", "pin1.target.z", "pin0.reaction.x", "lowest_z", "max_stretch"] {
        assert!(xml.contains(&format!("name=\"{name}\"")), "{name}");
    }
    assert!(xml.contains(r#"canGetAndSetFMUState="true" canSerializeFMUState="true""#));
    // The binary is the shared library with the FMI 3.0 entry points.
    assert!(entries[1].1.starts_with(b"\x7fELF"));
    for symbol in ["fmi3InstantiateCoSimulation", "fmi3DoStep", "fmi3SerializeFMUState"] {
        assert!(entries[1].1.windows(symbol.len()).any(|w| w == symbol.as_bytes()), "{symbol}");
    }
    assert_eq!(entries[2].1, scene.as_bytes());
    // Deflated, the library stripped of debug info: what an engineer downloads.
    let size = std::fs::metadata(&out).unwrap().len();
    println!("hang.fmu: {size} bytes");
    assert!(size < 8_000_000, "{size} bytes");
}

#[test]
fn fmu_build_names_what_it_cannot_carry() {
    let dir = work_dir("refused");
    for (scene, expected) in [("hammock.toml", "hammock.toml"), ("no-such-scene.toml", "no-such-scene.toml")] {
        let output = cloth()
            .arg("fmu")
            .arg("build")
            .arg(root().join("fixtures/scenes").join(scene))
            .arg("--out")
            .arg(dir.join("x.fmu"))
            .output()
            .unwrap();
        assert!(!output.status.success(), "{scene}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains(expected), "{scene}: {stderr}");
    }
}

/// FMPy 0.3.32 validates, simulates and steps the FMUs (`fmpy_check.py`).
/// `.ci/run` installs it in a virtual environment and sets `FMPY_PYTHON`;
/// elsewhere the test says it did not run, and fails under CI without it.
#[test]
fn fmpy_validates_simulates_and_restores_the_fmus() {
    let Some(python) = common::outside_tool("FMPY_PYTHON", "FMPy 0.3.32") else { return };
    let output = Command::new(python)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fmpy_check.py"))
        .arg(env!("CARGO_BIN_EXE_cloth"))
        .arg(work_dir("fmpy"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    println!("{stdout}");
    assert!(output.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    assert!(stdout.contains("fmu: 19 passed, 0 failed"), "{stdout}");
}
