//! The `.fmu` archive: `modelDescription.xml`, the shared library under
//! `binaries/x86_64-linux/`, the scene, its overrides and the OBJ files of
//! its mesh solids under `resources/`.

use crate::description::{FmuInfo, model_description};
use crate::{MODEL_IDENTIFIER, OVERRIDES_FILE, SCENE_FILE};
use cloth_core::scene::{Scene, SceneError};
use cloth_cosim::{ClothUnit, Unit};
use std::path::{Path, PathBuf};

/// Why an FMU could not be built or instantiated.
#[derive(Debug, thiserror::Error)]
pub enum FmuError {
    /// The scene does not load or build (the message names file and field).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Reading or writing a file.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> FmuError + '_ {
    move |e| FmuError::Io { path: path.to_path_buf(), message: e.to_string() }
}

/// The `instantiationToken` of an FMU carrying `scene` (its text) with
/// `overrides`: a 128-bit FNV-1a digest written as a GUID, so that an
/// instance refuses a model description from another build.
pub fn instantiation_token(scene: &str, overrides: &[String]) -> String {
    let mut bytes = scene.as_bytes().to_vec();
    for o in overrides {
        bytes.push(b'\n');
        bytes.extend_from_slice(o.as_bytes());
    }
    let mut hash: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
    for b in bytes {
        hash ^= u128::from(b);
        hash = hash.wrapping_mul(0x0000_0000_0100_0000_0000_0000_0000_013B);
    }
    let h = format!("{hash:032x}");
    format!("{{{}-{}-{}-{}-{}}}", &h[0..8], &h[8..12], &h[12..16], &h[16..20], &h[20..32])
}

/// The scene text and the overrides an FMU carries under `resources`.
pub(crate) fn read_resources(resources: &Path) -> Result<(String, Vec<String>), FmuError> {
    let scene_path = resources.join(SCENE_FILE);
    let scene = std::fs::read_to_string(&scene_path).map_err(io(&scene_path))?;
    let overrides_path = resources.join(OVERRIDES_FILE);
    let overrides = std::fs::read_to_string(&overrides_path).map_err(io(&overrides_path))?;
    Ok((scene, overrides.lines().filter(|l| !l.trim().is_empty()).map(str::to_string).collect()))
}

/// The scene at `path` with `overrides` (rigid bodies and rigs are
/// `cloth-rapier`'s: the scene parser refuses their keys).
fn load_scene(path: &Path, overrides: &[String]) -> Result<Scene, FmuError> {
    Ok(Scene::parse_file(path, overrides)?)
}

/// An archive entry: its path in the archive and its bytes.
type Entry = (String, Vec<u8>);

/// The OBJ files of the scene's mesh solids, to carry under
/// `resources/meshes/`: `(entry name, bytes)`, and the overrides that
/// point the scene at them there.
fn meshes(scene_path: &Path, scene: &Scene) -> Result<(Vec<Entry>, Vec<String>), FmuError> {
    let (mut entries, mut overrides) = (Vec::new(), Vec::new());
    let base = scene_path.parent().unwrap_or(Path::new("."));
    for (k, c) in scene.colliders.iter().enumerate() {
        if let cloth_core::ShapeSpec::Mesh { obj, .. } = &c.shape {
            let source = base.join(obj);
            let stem: String = obj
                .file_name()
                .map(|n| {
                    n.to_string_lossy()
                        .chars()
                        .map(|c| if c.is_ascii_alphanumeric() || ".-_".contains(c) { c } else { '_' })
                        .collect()
                })
                .unwrap_or_default();
            let name = format!("meshes/{k}-{stem}");
            entries.push((format!("resources/{name}"), std::fs::read(&source).map_err(io(&source))?));
            overrides.push(format!("colliders.{k}.shape.obj=\"{name}\""));
        }
    }
    Ok((entries, overrides))
}

/// The cloth unit of the scene at `path` with `overrides`, named `name`,
/// as an FMU instance builds it: substeps of at most the scene's `dt_s`,
/// damping tunable.
pub fn unit_from_scene(path: &Path, overrides: &[String], name: &str) -> Result<ClothUnit, FmuError> {
    unit_of(&load_scene(path, overrides)?, path, name)
}

/// The cloth unit of `scene` (read from `path`), named `name`, taking a
/// communication step longer than the scene's `dt_s` as substeps of at
/// most `dt_s`, its damping tunable (the scene built again with it).
fn unit_of(scene: &Scene, path: &Path, name: &str) -> Result<ClothUnit, FmuError> {
    let (model, cfg) = scene.build().map_err(|kind| SceneError { file: path.to_path_buf(), kind })?;
    let (damping, base) = (scene.material.damping_n_s_m, scene.clone());
    let rebuild = move |d: f64| {
        let mut scene = base.clone();
        scene.material.damping_n_s_m = d;
        scene.build().map(|(model, _)| model).map_err(|e| e.to_string())
    };
    Ok(ClothUnit::new(name, cfg.simulation(model)).with_max_step(cfg.dt_s).with_tunable_damping(damping, rebuild))
}

/// What [`build_fmu`] wrote.
#[derive(Debug, Clone)]
pub struct BuiltFmu {
    /// The archive.
    pub path: PathBuf,
    /// Its model description.
    pub model_description: String,
    /// Inputs and outputs, by name.
    pub inputs: Vec<String>,
    /// See `inputs`.
    pub outputs: Vec<String>,
}

/// Writes the FMU of the scene at `scene` with `overrides` to `out`, with
/// the shared library at `library` (this crate's `cdylib`) as its binary.
pub fn build_fmu(scene: &Path, overrides: &[String], library: &Path, out: &Path) -> Result<BuiltFmu, FmuError> {
    let text = std::fs::read_to_string(scene).map_err(io(scene))?;
    let parsed = load_scene(scene, overrides)?;
    let unit = unit_of(&parsed, scene, "cloth")?;
    let binary = std::fs::read(library).map_err(io(library))?;
    let (mesh_entries, mesh_overrides) = meshes(scene, &parsed)?;
    // The FMU's scene reads its meshes from resources/meshes/.
    let overrides: Vec<String> = overrides.iter().cloned().chain(mesh_overrides).collect();
    let token = instantiation_token(&text, &overrides);
    let model_name = scene.file_stem().map_or("cloth".into(), |s| s.to_string_lossy().into_owned());
    let info = FmuInfo {
        model_name: model_name.clone(),
        token,
        description: format!(
            "cloth scene {model_name} (Choi & Ko 2002 implicit cloth), co-simulation; internal steps of at most {} s, \
             a longer communication step taken as equal substeps",
            parsed.simulation.dt_s
        ),
        step_s: parsed.simulation.dt_s,
        stop_s: parsed.simulation.duration_s,
    };
    let variables = unit.variables();
    let arrays = crate::description::array_outputs(unit.simulation().model().particle_count());
    let xml = model_description(variables, &arrays, &info);
    let overrides_text: String = overrides.iter().map(|o| format!("{o}\n")).collect();
    let mut entries = vec![
        ("modelDescription.xml".to_string(), xml.clone().into_bytes()),
        (format!("binaries/x86_64-linux/{MODEL_IDENTIFIER}.so"), binary),
        (format!("resources/{SCENE_FILE}"), text.into_bytes()),
        (format!("resources/{OVERRIDES_FILE}"), overrides_text.into_bytes()),
    ];
    entries.extend(mesh_entries);
    std::fs::write(out, deflated(&entries).map_err(|e| FmuError::Io { path: out.to_path_buf(), message: e })?)
        .map_err(io(out))?;
    let names =
        |c: cloth_cosim::Causality| variables.iter().filter(|v| v.causality == c).map(|v| v.name.clone()).collect();
    Ok(BuiltFmu {
        path: out.to_path_buf(),
        model_description: xml,
        inputs: names(cloth_cosim::Causality::Input),
        outputs: names(cloth_cosim::Causality::Output),
    })
}

/// The archive of `entries` (path, contents), in order, deflated, with a
/// fixed time stamp (1980-01-01) so that the same FMU gives the same bytes.
fn deflated(entries: &[Entry]) -> Result<Vec<u8>, String> {
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .last_modified_time(zip::DateTime::default())
        .large_file(false);
    for (name, data) in entries {
        zip.start_file(name.as_str(), options).map_err(|e| format!("{name}: {e}"))?;
        std::io::Write::write_all(&mut zip, data).map_err(|e| format!("{name}: {e}"))?;
    }
    Ok(zip.finish().map_err(|e| e.to_string())?.into_inner())
}

/// The files of an FMU archive (name, bytes), stored or deflated as any
/// tool writes them; directory entries and the archive's comment are
/// passed over.
pub fn read_fmu(path: &Path) -> Result<Vec<Entry>, FmuError> {
    let bad = |message: String| FmuError::Io { path: path.to_path_buf(), message };
    let file = std::fs::File::open(path).map_err(io(path))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| bad(format!("not a ZIP archive: {e}")))?;
    let mut entries = Vec::new();
    for k in 0..archive.len() {
        let mut entry = archive.by_index(k).map_err(|e| bad(format!("entry {k}: {e}")))?;
        if entry.is_dir() {
            continue;
        }
        let name = entry.name().map_err(|e| bad(format!("entry {k}: its name: {e}")))?.to_string();
        let mut data = Vec::with_capacity(entry.size() as usize);
        std::io::Read::read_to_end(&mut entry, &mut data).map_err(|e| bad(format!("{name}: {e}")))?;
        entries.push((name, data));
    }
    Ok(entries)
}
