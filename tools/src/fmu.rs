//! `cloth fmu build`: a scene as an FMI 3.0 co-simulation FMU.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// The FMU's shared library: `library` when given, else the newer
/// `libcloth_fmu.so` beside this executable or in its `deps/`.
fn find_library(library: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = library {
        return Ok(path.to_path_buf());
    }
    let exe = std::env::current_exe().context("locating the cloth executable")?;
    let dir = exe.parent().context("the cloth executable has no directory")?;
    let name = format!("lib{}.so", cloth_fmu::MODEL_IDENTIFIER);
    // Building cloth-fmu on its own leaves one copy beside the executable,
    // building the tools another in deps/: take the newer.
    let modified = |p: &PathBuf| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let newest = [dir.join(&name), dir.join("deps").join(&name)]
        .into_iter()
        .filter_map(|p| modified(&p).map(|t| (t, p)))
        .max_by_key(|(t, _)| *t);
    if let Some((_, path)) = newest {
        return Ok(path);
    }
    bail!("no {name} beside {}: build it with `cargo build --release -p cloth-fmu`, or give --library", exe.display())
}

/// Writes the FMU of `scene` (with `overrides`) to `out`.
pub fn build(scene: &Path, overrides: &[String], library: Option<&Path>, out: &Path) -> Result<()> {
    if !cfg!(all(target_os = "linux", target_arch = "x86_64")) {
        bail!("FMUs are built for x86_64-linux only so far");
    }
    let library = find_library(library)?;
    let built = cloth_fmu::build_fmu(scene, overrides, &library, out)?;
    println!(
        "{}: {} inputs ({}), {} outputs; binary {}",
        built.path.display(),
        built.inputs.len(),
        built.inputs.join(", "),
        built.outputs.len(),
        library.display()
    );
    Ok(())
}
