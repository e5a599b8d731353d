//! Fuzz targets: each reader of user input (scene TOML and `--set`
//! overrides, OBJ, glTF, URDF, BVH, a snapshot's bytes), the glTF
//! writer's input and call sequences on the FMU's C API, each a function
//! of arbitrary bytes.
//!
//! A target returns normally when the input was read or refused with a
//! typed error; a panic, an abort or a hang is the defect. The same
//! functions serve three drivers: libFuzzer through `cargo fuzz` (nightly,
//! coverage-guided, the `fuzz/` directory), the stable mutation runner
//! `cloth-fuzz`, and the tests that replay the committed corpus
//! (`fuzz/corpus/<target>/`).

pub mod driver;
mod fmi;
pub mod mutate;
mod readers;
mod writer;

use std::path::{Path, PathBuf};

/// A fuzz target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// A scene file's text, read with its rig and body extensions and built
    /// when small.
    SceneToml,
    /// Lines of `--set key=value` overrides on one of a few fixture scenes
    /// (the first byte picks it), built when small.
    Overrides,
    /// A Wavefront OBJ mesh.
    Obj,
    /// A binary or JSON glTF file.
    Gltf,
    /// A URDF rig, read in both up axes.
    Urdf,
    /// A BVH motion.
    Bvh,
    /// A recording for the glTF writer, decoded from the bytes; what the
    /// writer accepts must read back as valid glTF.
    GltfWriter,
    /// A sequence of FMI 3.0 calls on the FMU's C API, valid and invalid.
    FmiCalls,
    /// A cloth snapshot's bytes (`Snapshot::from_bytes`), restored into a
    /// small hanging cloth and stepped when they fit it.
    Snapshot,
}

impl Target {
    /// Every target.
    pub const ALL: [Target; 9] = [
        Target::SceneToml,
        Target::Overrides,
        Target::Obj,
        Target::Gltf,
        Target::Urdf,
        Target::Bvh,
        Target::GltfWriter,
        Target::FmiCalls,
        Target::Snapshot,
    ];

    /// The name, as the corpus directory and `cargo fuzz` spell it.
    pub fn name(self) -> &'static str {
        match self {
            Target::SceneToml => "scene_toml",
            Target::Overrides => "overrides",
            Target::Obj => "obj",
            Target::Gltf => "gltf",
            Target::Urdf => "urdf",
            Target::Bvh => "bvh",
            Target::GltfWriter => "gltf_writer",
            Target::FmiCalls => "fmi_calls",
            Target::Snapshot => "snapshot",
        }
    }

    /// The target of that name.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Whether the input is text: the mutator then also works on lines
    /// and numbers.
    pub fn is_text(self) -> bool {
        matches!(self, Target::SceneToml | Target::Overrides | Target::Obj | Target::Urdf | Target::Bvh)
    }

    /// Runs the target on one input. Returns a short label of the outcome
    /// ("ok" or the kind of refusal), which the stable runner uses to keep
    /// inputs that reach something new.
    pub fn run(self, data: &[u8]) -> String {
        match self {
            Target::SceneToml => readers::scene_toml(data),
            Target::Overrides => readers::overrides(data),
            Target::Obj => readers::obj(data),
            Target::Gltf => readers::gltf(data),
            Target::Urdf => readers::urdf(data),
            Target::Bvh => readers::bvh(data),
            Target::GltfWriter => writer::gltf_writer(data),
            Target::FmiCalls => fmi::calls(data),
            Target::Snapshot => readers::snapshot(data),
        }
    }

    /// The committed corpus's directory for this target.
    pub fn corpus_dir(self) -> PathBuf {
        repository().join("fuzz/corpus").join(self.name())
    }

    /// The corpus's inputs, sorted by file name: all of them, or
    /// (`Corpus::Kept`) only the seeds and the inputs that once crashed
    /// (`fixture-*`, `seed-*`, `found-*`); the fixtures of this target's
    /// kind when the directory holds none.
    pub fn corpus(self, which: Corpus) -> Vec<(PathBuf, Vec<u8>)> {
        let kept = |p: &PathBuf| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            which == Corpus::All || ["fixture-", "seed-", "found-"].iter().any(|k| name.starts_with(k))
        };
        let mut files: Vec<PathBuf> = std::fs::read_dir(self.corpus_dir())
            .map(|dir| dir.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file() && kept(p)).collect())
            .unwrap_or_default();
        if files.is_empty() {
            files = self.seed_files();
        }
        files.sort();
        files.into_iter().filter_map(|p| std::fs::read(&p).ok().map(|bytes| (p, bytes))).collect()
    }

    /// The fixtures a corpus starts from.
    pub fn seed_files(self) -> Vec<PathBuf> {
        let of = |dir: &str, ext: &str| -> Vec<PathBuf> {
            let dir = repository().join("fixtures").join(dir);
            let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
                .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
                .unwrap_or_default();
            files.retain(|p| p.extension().is_some_and(|e| e == ext));
            files.sort();
            files
        };
        match self {
            Target::SceneToml => of("scenes", "toml"),
            Target::Obj => [of("meshes", "obj"), of("meshes/mannequin", "obj")].concat(),
            Target::Gltf => of("meshes", "glb"),
            Target::Urdf => of("rigs", "urdf"),
            Target::Bvh => of("motions", "bvh"),
            Target::Overrides | Target::GltfWriter | Target::FmiCalls | Target::Snapshot => Vec::new(),
        }
    }
}

/// Which of a committed corpus to replay.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corpus {
    /// Every input (libFuzzer's merged corpus: thousands, tens of seconds).
    All,
    /// The seeds and every input that once crashed (the fast tier).
    Kept,
}

/// The repository's root (fixtures are read from there).
pub fn repository() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// Panics inside a target are printed as one line (the drivers catch or
/// report them); call once before running many inputs.
pub fn quiet_panics() {
    std::panic::set_hook(Box::new(|info| eprintln!("panic: {info}")));
}

/// Called first in every libFuzzer target: panics that the code under
/// test catches on purpose (the glTF and triangulator crates' own, turned
/// into errors) must unwind to their `catch_unwind`, not abort through
/// libFuzzer's hook. A panic that escapes a target still aborts: the
/// driver checks for it.
pub fn libfuzzer_once() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(quiet_panics);
}
