//! The `cloth` tool's library part: the hard-case suite, shared by
//! `cloth study stability` and this crate's `stability` test, the
//! studies' CSV tables, the glTF writer (fuzzed by `cloth-fuzz`) and the
//! compact frame file.

pub mod frames;
pub mod gltf;
pub mod stability;
pub mod table;

/// A path of this repository (`fixtures/...`): as given when it exists
/// from the current directory (a run inside the checkout), else in the
/// checkout this binary was built from (an installed `cloth` run
/// elsewhere), else as given, for the command's error to name it.
pub fn in_checkout(rel: impl AsRef<std::path::Path>) -> std::path::PathBuf {
    let rel = rel.as_ref();
    if rel.is_absolute() || rel.exists() {
        return rel.to_path_buf();
    }
    let built_from = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel);
    if built_from.exists() { built_from } else { rel.to_path_buf() }
}

/// Worker threads when none are asked for: the machine's cores (results
/// are the same for any count).
pub fn machine_threads() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}
