//! The cloth as an FMI 3.0 co-simulation FMU.
//!
//! - [`api`]: the FMI 3.0 C functions, exported by this crate's `cdylib`
//!   (`libcloth_fmu.so`, the FMU's binary). They wrap a
//!   [`cloth_cosim::ClothUnit`] built from the scene in the FMU's
//!   `resources/`; every function an importer may resolve is exported,
//!   what is not supported returns `fmi3Error` with a logged reason, and
//!   no panic crosses the C boundary.
//! - [`description`]: `modelDescription.xml` generated from the unit's
//!   variables.
//! - [`package`]: the `.fmu` archive (`cloth fmu build`).
//! - [`import`]: an FMI 3.0 or 2.0 FMU, this crate's or another tool's,
//!   loaded as a `cloth-cosim` unit ([`import::FmuUnit`]), so a master
//!   co-simulates FMUs and native units together.
//!
//! Value references: 0 is `time` (the independent variable); the unit's
//! variable `k` is `k + 1`.

// The C API takes raw pointers from the host: each is checked (null,
// lengths) in `api` before it is read or written, instance handles are
// looked up in `handles`, and nothing else here is unsafe.
#![allow(unsafe_code)]

pub mod api;
pub mod description;
mod handles;
pub mod import;
mod instance;
pub mod package;

pub use description::{ArrayOutput, FmuInfo, array_outputs, model_description};
pub use package::{FmuError, build_fmu, instantiation_token};

/// The FMU's model identifier: the name of its shared library
/// (`binaries/x86_64-linux/cloth_fmu.so`) and of `<CoSimulation modelIdentifier>`.
pub const MODEL_IDENTIFIER: &str = "cloth_fmu";

/// The scene inside the FMU, under `resources/`.
pub const SCENE_FILE: &str = "scene.toml";

/// The `--set` overrides applied to it, one per line, under `resources/`.
pub const OVERRIDES_FILE: &str = "overrides.txt";
