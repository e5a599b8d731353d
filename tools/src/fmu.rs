//! `cloth fmu build`: a scene as an FMI 3.0 co-simulation FMU.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// The FMU's shared library: `library` when given, else
/// `CLOTH_FMU_LIBRARY`, else the newest `libcloth_fmu.so` beside this
/// executable, in its `deps/`, or in the release build of the checkout it
/// was built from (`cargo install --path tools` installs the executable
/// alone).
fn find_library(library: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = library {
        return Ok(path.to_path_buf());
    }
    if let Some(path) = std::env::var_os("CLOTH_FMU_LIBRARY") {
        return Ok(PathBuf::from(path));
    }
    let exe = std::env::current_exe().context("locating the cloth executable")?;
    let dir = exe.parent().context("the cloth executable has no directory")?;
    let name = format!("lib{}.so", cloth_fmu::MODEL_IDENTIFIER);
    let checkout = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/release");
    // Building cloth-fmu on its own leaves one copy beside the executable,
    // building the tools another in deps/: take the newest.
    let modified = |p: &PathBuf| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let newest = [dir.join(&name), dir.join("deps").join(&name), checkout.join(&name)]
        .into_iter()
        .filter_map(|p| modified(&p).map(|t| (t, p)))
        .max_by_key(|(t, _)| *t);
    if let Some((_, path)) = newest {
        return Ok(path);
    }
    bail!(
        "no {name} beside {} or in {}: build it with `cargo build --release -p cloth-fmu`, \
         or give --library (or CLOTH_FMU_LIBRARY)",
        exe.display(),
        checkout.display()
    )
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
