//! What the `cloth` tool's tests share.

// Each test file compiles this module on its own and uses part of it.
#![allow(dead_code)]

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The `cloth` binary under test.
pub fn cloth() -> Command {
    Command::new(env!("CARGO_BIN_EXE_cloth"))
}

/// `cloth run fixtures/scenes/SCENE --frames 9` with `overrides`, into a
/// directory of its own named after the test file and `name`.
pub fn recorded_run(test: &str, name: &str, scene: &str, overrides: &[&str]) -> PathBuf {
    recorded_run_as(test, name, scene, overrides, "obj")
}

/// [`recorded_run`] with its frames in `format` (`obj` or `bin`).
pub fn recorded_run_as(test: &str, name: &str, scene: &str, overrides: &[&str], format: &str) -> PathBuf {
    let out = std::env::temp_dir().join(format!("cloth-{test}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes").join(scene);
    let mut command = cloth();
    command.arg("run").arg(scene).args(["--quiet", "--frames", "9", "--frame-format", format]);
    for o in overrides {
        command.args(["--set", o]);
    }
    assert!(command.arg("--out").arg(&out).status().unwrap().success());
    out
}

/// An outside program a test needs, named by environment variable `var`
/// (`.ci/run` installs it and sets the variable). Without it the test says
/// it did not run, and fails under CI (`CI` set): a check CI skips silently
/// would pass whatever the code does.
pub fn outside_tool(var: &str, what: &str) -> Option<OsString> {
    let tool = std::env::var_os(var);
    if tool.is_none() {
        assert!(std::env::var_os("CI").is_none(), "CI must set {var} (.ci/run installs {what})");
        println!("{var} not set: the {what} check did not run (see .ci/run)");
    }
    tool
}
