//! What the `cloth` tool's tests share.

use std::ffi::OsString;

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
