//! The Python module `cloth`: scenes from TOML files, the model builder,
//! stepping with the GIL released, positions and velocities as NumPy
//! arrays, contacts and pin reactions, per-step control, grasps and
//! snapshots; coupled scenes (rapier bodies, URDF rigs) as `World`.
//! Errors are Python exceptions that name the file and field.

mod grasp;
mod threads;
mod world;

use cloth_core::scene::{Scene as SceneFile, SceneError as SceneFileError, SceneErrorKind};
use cloth_core::{
    BodyPose, ClothModel, Edge, GridPanel, IntegratorKind, Material, ModelBuilder, ModelKind,
    Simulation as CoreSimulation, SolidMotion, SolverParams, Vec3,
};
use grasp::Grasps;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;

create_exception!(cloth, SceneError, PyValueError, "A scene file or override is wrong: `.file`, `.field`, `.message`.");
create_exception!(cloth, ModelError, PyValueError, "A model cannot be built as described.");
create_exception!(cloth, ControlError, PyValueError, "A per-step input was refused.");
create_exception!(cloth, StepError, PyRuntimeError, "A step failed: `.time_s` is where the cloth stayed.");
create_exception!(
    cloth,
    SnapshotError,
    PyValueError,
    "A snapshot does not fit what it is restored into (another cloth, integrator or World); nothing was changed."
);

/// A `SceneError` exception carrying `file`, `field` (None when the
/// problem is not one field's) and `message`.
pub(crate) fn scene_error(py: Python<'_>, file: &std::path::Path, kind: &SceneErrorKind) -> PyErr {
    let field = match kind {
        SceneErrorKind::Invalid { field, .. } => Some(field.clone()),
        SceneErrorKind::Override { arg, .. } => arg.split('=').next().map(str::to_string),
        _ => None,
    };
    let message = SceneFileError { file: file.to_path_buf(), kind: kind.clone() }.to_string();
    let err = SceneError::new_err(message.clone());
    let value = err.value(py);
    // Attributes on a fresh exception object cannot fail but for memory.
    let _ = value.setattr("file", file.display().to_string());
    let _ = value.setattr("field", field);
    let _ = value.setattr("message", kind.to_string());
    err
}

/// One override as `--set` takes it: a string is TOML text (`"[21, 21]"`,
/// `'"bdf2"'`), a number, boolean or list of them is written as TOML.
fn toml_value(value: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(text) = value.extract::<String>() {
        return Ok(text);
    }
    if let Ok(b) = value.extract::<bool>() {
        return Ok(b.to_string());
    }
    if let Ok(i) = value.extract::<i64>() {
        return Ok(i.to_string());
    }
    if let Ok(x) = value.extract::<f64>() {
        return Ok(format!("{x:?}"));
    }
    if let Ok(list) = value.cast::<PyList>() {
        let items: PyResult<Vec<String>> = list.iter().map(|item| toml_value(&item)).collect();
        return Ok(format!("[{}]", items?.join(", ")));
    }
    Err(PyValueError::new_err(format!("override value {value}: a str (TOML text), number, bool or list of them")))
}

/// Overrides as `--set` arguments: from a dict of dotted keys to values
/// or a list of `"key=value"` strings.
pub(crate) fn override_args(overrides: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<String>> {
    let mut sets = Vec::new();
    if let Some(o) = overrides {
        if let Ok(dict) = o.cast::<PyDict>() {
            for (key, value) in dict.iter() {
                sets.push(format!("{}={}", key.extract::<String>()?, toml_value(&value)?));
            }
        } else {
            sets = o.extract::<Vec<String>>()?;
        }
    }
    Ok(sets)
}

/// A scene file read with its overrides: what `cloth run` reads.
#[pyclass(module = "cloth", frozen)]
struct Scene {
    scene: SceneFile,
    file: PathBuf,
}

#[pymethods]
impl Scene {
    /// Reads the scene at `path` with `overrides`, a dict of dotted keys
    /// to values (`{"panels.0.particles": [21, 21]}`) or a list of
    /// `"key=value"` strings, as `cloth run --set` takes them.
    #[staticmethod]
    #[pyo3(signature = (path, overrides = None))]
    fn from_toml(py: Python<'_>, path: PathBuf, overrides: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let sets = override_args(overrides)?;
        let scene = SceneFile::parse_file(&path, &sets).map_err(|e| scene_error(py, &e.file, &e.kind))?;
        Ok(Self { scene, file: path })
    }

    /// Reads a scene from TOML `text` with `overrides` (as `from_toml`);
    /// relative paths in it resolve against `base_dir` (default: the
    /// current directory), and errors name `name`.
    #[staticmethod]
    #[pyo3(signature = (text, overrides = None, base_dir = None, name = "<text>"))]
    fn from_text(
        py: Python<'_>,
        text: &str,
        overrides: Option<&Bound<'_, PyAny>>,
        base_dir: Option<PathBuf>,
        name: &str,
    ) -> PyResult<Self> {
        let sets = override_args(overrides)?;
        let file = PathBuf::from(name);
        let mut scene = SceneFile::parse(text, &sets).map_err(|kind| scene_error(py, &file, &kind))?;
        scene.base_dir = base_dir.unwrap_or_default();
        Ok(Self { scene, file })
    }

    /// The scene's time step, s.
    #[getter]
    fn dt_s(&self) -> f64 {
        self.scene.simulation.dt_s
    }

    /// The scene's duration, s.
    #[getter]
    fn duration_s(&self) -> f64 {
        self.scene.simulation.duration_s
    }

    /// The simulation the scene describes, at t = 0, stepping on `threads`
    /// threads (default: rayon's, `RAYON_NUM_THREADS` or every core; the
    /// results are the same bits for any count).
    #[pyo3(signature = (threads = None))]
    fn simulation(&self, py: Python<'_>, threads: Option<usize>) -> PyResult<Simulation> {
        let (model, cfg) = self.scene.build().map_err(|e| scene_error(py, &self.file, &e))?;
        let pool = threads::pool(threads)?;
        Ok(Simulation { sim: cfg.simulation(model), dt_s: cfg.dt_s, grasps: Grasps::default(), pool, last: None })
    }
}

/// A grid-cloth model under construction (Rust's `ClothModel::builder`).
#[pyclass(module = "cloth")]
struct Builder {
    inner: ModelBuilder,
}

/// Parses a kebab-case name of a serde enum (`"choi-ko"`, `"j-max"`, `"bdf2"`).
fn named<T: serde::de::DeserializeOwned>(what: &str, name: &str) -> PyResult<T> {
    let de = serde::de::value::StrDeserializer::<serde::de::value::Error>::new(name);
    T::deserialize(de).map_err(|e| PyValueError::new_err(format!("{what} {name:?}: {e}")))
}

#[pymethods]
impl Builder {
    #[new]
    fn new() -> Self {
        Self { inner: ClothModel::builder() }
    }

    /// Adds a flat grid panel of `particles = (nx, ny)` spanning `size_m`
    /// (m) along +x and +y, particle (0, 0) at `origin_m`.
    #[pyo3(signature = (particles, size_m, origin_m = [0.0, 0.0, 0.0]))]
    fn panel(
        mut slf: PyRefMut<'_, Self>,
        particles: [usize; 2],
        size_m: [f64; 2],
        origin_m: [f64; 3],
    ) -> PyRefMut<'_, Self> {
        slf.inner = std::mem::take(&mut slf.inner).panel(GridPanel::flat(particles, size_m).origin(origin_m));
        slf
    }

    /// Sets the material from keyword arguments named as in a scene's
    /// `[material]` (`tensile_stiffness_n_m=500.0`, ...); the rest keep
    /// their defaults.
    #[pyo3(signature = (**constants))]
    fn material<'py>(
        mut slf: PyRefMut<'py, Self>,
        constants: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<PyRefMut<'py, Self>> {
        // The default material as TOML, the given constants over it.
        let mut table = toml::Table::try_from(Material::default()).map_err(|e| ModelError::new_err(e.to_string()))?;
        for (key, value) in constants.into_iter().flat_map(|d| d.iter()) {
            let key = key.extract::<String>()?;
            let text = format!("v = {}", toml_value(&value)?);
            let parsed: toml::Table =
                toml::from_str(&text).map_err(|e| ModelError::new_err(format!("material.{key}: {}", e.message())))?;
            table.insert(key, parsed["v"].clone());
        }
        let material: Material =
            table.try_into().map_err(|e: toml::de::Error| ModelError::new_err(format!("material: {}", e.message())))?;
        slf.inner = std::mem::take(&mut slf.inner).material(material);
        Ok(slf)
    }

    /// The model: `"choi-ko"` (default), `"provot"` or `"volino"`.
    fn kind(mut slf: PyRefMut<'_, Self>, kind: String) -> PyResult<PyRefMut<'_, Self>> {
        let kind: ModelKind = named("model kind", &kind)?;
        slf.inner = std::mem::take(&mut slf.inner).kind(kind);
        Ok(slf)
    }

    /// Gravity, m/s^2.
    fn gravity(mut slf: PyRefMut<'_, Self>, g_m_s2: [f64; 3]) -> PyRefMut<'_, Self> {
        slf.inner = std::mem::take(&mut slf.inner).gravity(g_m_s2);
        slf
    }

    /// Switches bending on.
    fn bending(mut slf: PyRefMut<'_, Self>) -> PyRefMut<'_, Self> {
        slf.inner = std::mem::take(&mut slf.inner).bending();
        slf
    }

    /// Switches damping on.
    fn damping(mut slf: PyRefMut<'_, Self>) -> PyRefMut<'_, Self> {
        slf.inner = std::mem::take(&mut slf.inner).damping();
        slf
    }

    /// Pins every node of panel `panel`'s `edge` (`"i-min"`, `"i-max"`,
    /// `"j-min"`, `"j-max"`).
    fn pin_edge(mut slf: PyRefMut<'_, Self>, panel: usize, edge: String) -> PyResult<PyRefMut<'_, Self>> {
        let edge: Edge = named("edge", &edge)?;
        slf.inner = std::mem::take(&mut slf.inner).pin_edge(panel, edge);
        Ok(slf)
    }

    /// Pins nodes `(i, j)` of panel `panel`.
    fn pin_nodes(mut slf: PyRefMut<'_, Self>, panel: usize, nodes: Vec<[usize; 2]>) -> PyRefMut<'_, Self> {
        slf.inner = std::mem::take(&mut slf.inner).pin_nodes(panel, nodes);
        slf
    }

    /// A simulation of the model built so far, stepping with `integrator`
    /// (`"bdf2"` by default, Choi & Ko's; `"backward-euler"`, `"vbd"`, `"quasi-newton"`, ...)
    /// at `dt_s` (s) by default, its linear solves to `rel_tol` (the
    /// solver's default when not given), on `threads` threads (default:
    /// rayon's).
    #[pyo3(signature = (dt_s = 1.0 / 90.0, integrator = "bdf2", rel_tol = None, threads = None))]
    fn simulation(
        &self,
        dt_s: f64,
        integrator: &str,
        rel_tol: Option<f64>,
        threads: Option<usize>,
    ) -> PyResult<Simulation> {
        let model = self.inner.build().map_err(|e| ModelError::new_err(e.to_string()))?;
        let kind: IntegratorKind = named("integrator", integrator)?;
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(PyValueError::new_err(format!("dt_s = {dt_s}: must be finite and > 0")));
        }
        let mut solver = SolverParams::default();
        if let Some(tol) = rel_tol {
            solver.rel_tol = tol;
        }
        solver.validate().map_err(|e| ModelError::new_err(e.within("solver").to_string()))?;
        let pool = threads::pool(threads)?;
        Ok(Simulation {
            sim: CoreSimulation::new(model, kind, solver),
            dt_s,
            grasps: Grasps::default(),
            pool,
            last: None,
        })
    }
}

/// A cloth state saved by [`Simulation::snapshot`]: positions,
/// velocities, the step before (BDF2's history), the stitches' states and
/// the integrator's memory. `Snapshot(data)` reads the bytes of
/// `to_bytes()` (a file, another process); snapshots pickle the same way.
#[pyclass(module = "cloth", frozen)]
struct Snapshot {
    state: cloth_core::Snapshot,
}

#[pymethods]
impl Snapshot {
    /// Reads bytes written by `to_bytes()`; `ValueError` when they are
    /// not a snapshot of this format (cut short, changed, another version).
    #[new]
    fn new(data: &[u8]) -> PyResult<Self> {
        cloth_core::Snapshot::from_bytes(data)
            .map(|state| Snapshot { state })
            .map_err(|e| PyValueError::new_err(format!("Snapshot({} bytes): {e}", data.len())))
    }

    /// The snapshot as bytes (a checksummed little-endian layout, about
    /// 96 bytes a particle), read back to the same bits by `Snapshot(data)`.
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, pyo3::types::PyBytes> {
        pyo3::types::PyBytes::new(py, &self.state.to_bytes())
    }

    /// Pickling: the class and the bytes.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> (Bound<'py, pyo3::types::PyType>, (Bound<'py, pyo3::types::PyBytes>,)) {
        (slf.get_type(), (slf.get().to_bytes(slf.py()),))
    }

    /// The time it was taken at, s.
    #[getter]
    fn time_s(&self) -> f64 {
        self.state.state.time_s
    }

    /// The steps taken when it was taken.
    #[getter]
    fn steps(&self) -> u64 {
        self.state.state.steps
    }

    /// The particles it holds.
    #[getter]
    fn particle_count(&self) -> usize {
        self.state.state.x.len()
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.state == other.state
    }
}

/// A running simulation.
#[pyclass(module = "cloth")]
struct Simulation {
    sim: CoreSimulation,
    dt_s: f64,
    grasps: Grasps,
    pool: std::sync::Arc<rayon::ThreadPool>,
    /// The last step's report (`None` before the first).
    last: Option<cloth_core::StepReport>,
}

/// `rows` 3-vectors as an `(n, 3)` NumPy array.
pub(crate) fn rows<'py>(py: Python<'py>, rows: impl ExactSizeIterator<Item = Vec3>) -> Bound<'py, PyArray2<f64>> {
    let n = rows.len();
    let flat: Vec<f64> = rows.flat_map(|p| [p.x, p.y, p.z]).collect();
    Array2::from_shape_vec((n, 3), flat).expect("3 values a row").into_pyarray(py)
}

/// The model's triangles as an `(m, 3)` array of particle indices.
pub(crate) fn triangles<'py>(py: Python<'py>, model: &ClothModel) -> Bound<'py, PyArray2<i64>> {
    let t = model.triangles();
    let flat: Vec<i64> = t.iter().flat_map(|t| t.map(i64::from)).collect();
    Array2::from_shape_vec((t.len(), 3), flat).expect("3 indices a row").into_pyarray(py)
}

/// The outcome of `n` steps: `failed` is the step that failed (counted
/// from 0), the time the cloth stayed at (s) and why, raised as
/// `StepError` with `.time_s`.
pub(crate) fn steps_taken(py: Python<'_>, n: usize, failed: Option<(usize, f64, String)>) -> PyResult<()> {
    let Some((k, time_s, message)) = failed else { return Ok(()) };
    let err = StepError::new_err(format!("step {} of {n} from t = {time_s} s: {message}", k + 1));
    let _ = err.value(py).setattr("time_s", time_s);
    Err(err)
}

/// What a step reported, as a dict: `cg_iterations`, `converged`,
/// `rel_residual`, `contacts` (cloth-solid, held this step),
/// `self_contacts`, `self_crossings` (crossings the continuous test
/// separated), `retaken` (the energy guard took it again) and `stages_s`
/// (wall time per stage, s).
pub(crate) fn report_dict<'py>(py: Python<'py>, r: &cloth_core::StepReport) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("cg_iterations", r.cg_iterations)?;
    out.set_item("converged", r.converged)?;
    out.set_item("rel_residual", r.rel_residual)?;
    out.set_item("contacts", r.contacts.contacts)?;
    out.set_item("self_contacts", r.contacts.self_contacts)?;
    out.set_item("self_crossings", r.contacts.self_crossings)?;
    out.set_item("retaken", r.retaken_as_backward_euler || r.retaken_with_newton)?;
    let stages = PyDict::new(py);
    let t = &r.stages;
    for (name, s) in [
        ("forces", t.forces_s),
        ("assembly", t.assembly_s),
        ("solve", t.solve_s),
        ("update", t.update_s),
        ("collision", t.collision_s),
        ("self_collision", t.self_collision_s),
    ] {
        stages.set_item(name, s)?;
    }
    out.set_item("stages_s", stages)?;
    Ok(out)
}

/// The rows of an `(n, 3)` array as vectors; `ControlError` naming `what`
/// for another number of columns.
pub(crate) fn vectors(what: &str, array: PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Vec3>> {
    let a = array.as_array();
    if a.ncols() != 3 {
        return Err(ControlError::new_err(format!("{what}: {} columns, not 3 (x, y, z)", a.ncols())));
    }
    Ok(a.rows().into_iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect())
}

pub(crate) fn grasp_error(e: grasp::GraspError) -> PyErr {
    ControlError::new_err(e.to_string())
}

pub(crate) fn control_error(e: impl std::fmt::Display) -> PyErr {
    ControlError::new_err(e.to_string())
}

#[pymethods]
impl Simulation {
    /// Takes `n` steps of `dt_s` (s; the scene's by default), with the
    /// GIL released. A step that fails raises `StepError`; the cloth stays
    /// after the last step that succeeded.
    #[pyo3(signature = (n = 1, dt_s = None))]
    fn step(&mut self, py: Python<'_>, n: usize, dt_s: Option<f64>) -> PyResult<()> {
        let h = dt_s.unwrap_or(self.dt_s);
        if !(h.is_finite() && h > 0.0) {
            return Err(PyValueError::new_err(format!("dt_s = {h}: must be finite and > 0")));
        }
        let (sim, pool, last) = (&mut self.sim, &self.pool, &mut self.last);
        let failed = py.detach(|| {
            pool.install(|| {
                for k in 0..n {
                    match sim.step(h) {
                        Ok(report) => *last = Some(report),
                        Err(e) => return Some((k, sim.time(), e.to_string())),
                    }
                }
                None
            })
        });
        steps_taken(py, n, failed)
    }

    /// Simulated time, s.
    #[getter]
    fn time_s(&self) -> f64 {
        self.sim.time()
    }

    /// The default step, s.
    #[getter]
    fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Number of particles.
    #[getter]
    fn particle_count(&self) -> usize {
        self.sim.model().particle_count()
    }

    /// Every particle's position, m, as an `(n, 3)` array (a copy).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, self.sim.state().x.iter().copied())
    }

    /// Every particle's velocity, m/s, as an `(n, 3)` array (a copy).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, self.sim.state().v.iter().copied())
    }

    /// Every particle's mass, kg.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.sim.model().masses().to_vec().into_pyarray(py)
    }

    /// The longest link over its rest length.
    fn max_stretch(&self) -> f64 {
        self.sim.model().max_stretch_ratio(&self.sim.state().x)
    }

    /// The mean force the cloth exerted on each pin over the last step,
    /// N, as a `(pins, 3)` array.
    fn pin_reactions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let pins = self.sim.model().pins().len();
        rows(py, (0..pins).map(|k| self.sim.pin_reaction(k)))
    }

    /// The last step's cloth-solid contacts as a dict of arrays:
    /// `particle`, `solid` (indices), `point` and `normal` (`(m, 3)`, m and
    /// unit), `impulse` (`(m, 3)`, N s, on the cloth).
    fn contacts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.sim.contacts().solid();
        let out = PyDict::new(py);
        out.set_item("particle", c.iter().map(|c| c.particle as i64).collect::<Vec<_>>().into_pyarray(py))?;
        out.set_item("solid", c.iter().map(|c| c.collider as i64).collect::<Vec<_>>().into_pyarray(py))?;
        out.set_item("point", rows(py, c.iter().map(|c| c.point)))?;
        out.set_item("normal", rows(py, c.iter().map(|c| c.normal)))?;
        out.set_item("impulse", rows(py, c.iter().map(|c| c.impulse_n_s)))?;
        Ok(out)
    }

    /// Where external pin `index` is at the end of the next step, m.
    fn set_pin_target(&mut self, index: usize, target: [f64; 3]) -> PyResult<()> {
        self.sim.set_pin_target(index, Vec3::from(target)).map_err(control_error)
    }

    /// The air velocity of an external wind, m/s.
    fn set_wind(&mut self, velocity: [f64; 3]) -> PyResult<()> {
        self.sim.set_wind(Vec3::from(velocity)).map_err(control_error)
    }

    /// A factor on the wind's air velocity.
    fn set_wind_scale(&mut self, scale: f64) -> PyResult<()> {
        self.sim.set_wind_scale(scale).map_err(control_error)
    }

    /// Forces on every particle, N, an `(n, 3)` array, for the next steps.
    fn set_external_forces(&mut self, forces: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        let f = vectors("external forces", forces)?;
        self.sim.set_external_forces(&f).map_err(control_error)
    }

    /// No external forces from the next step on.
    fn clear_external_forces(&mut self) {
        self.sim.clear_external_forces();
    }

    /// External solid `index`'s motion over the next step: where its frame
    /// is at the end (m, rotation vector in rad) and its velocities (m/s,
    /// rad/s).
    #[pyo3(signature = (index, position, velocity, rotation = [0.0, 0.0, 0.0], angular_velocity = [0.0, 0.0, 0.0]))]
    fn set_solid_motion(
        &mut self,
        index: usize,
        position: [f64; 3],
        velocity: [f64; 3],
        rotation: [f64; 3],
        angular_velocity: [f64; 3],
    ) -> PyResult<()> {
        let pose = BodyPose {
            position: Vec3::from(position),
            rotation: nalgebra::UnitQuaternion::from_scaled_axis(Vec3::from(rotation)),
        };
        let motion = SolidMotion {
            time_s: self.sim.time() + self.dt_s,
            pose,
            linear_velocity: Vec3::from(velocity),
            angular_velocity: Vec3::from(angular_velocity),
        };
        self.sim.set_solid_motion(index, motion).map_err(control_error)
    }

    /// The cloth's triangles, an `(m, 3)` array of particle indices.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<i64>> {
        triangles(py, self.sim.model())
    }

    /// What the last step reported (CG iterations, contacts, stage wall
    /// times; see the guide), or `None` before the first step.
    fn last_step<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.last.as_ref().map(|r| report_dict(py, r)).transpose()
    }

    /// Grasps the free particles within `radius_m` (m) of `point` (m) with
    /// a gripper at `point`; returns the grasp's id. Each particle keeps
    /// its offset from the gripper. Raises `ControlError` when none is in
    /// reach.
    fn grasp(&mut self, point: [f64; 3], radius_m: f64) -> PyResult<usize> {
        let at = (
            grasp::Gripper::Point,
            BodyPose { position: Vec3::from(point), rotation: nalgebra::UnitQuaternion::identity() },
        );
        self.grasps.grasp(&mut self.sim, Vec3::from(point), radius_m, at).map_err(grasp_error)
    }

    /// Moves grasp `id`'s gripper to `point` (m) by the end of the next step.
    fn move_grasp(&mut self, id: usize, point: [f64; 3]) -> PyResult<()> {
        self.grasps.move_to(&mut self.sim, id, Vec3::from(point)).map_err(grasp_error)
    }

    /// The mean force the cloth exerted on grasp `id`'s gripper over the
    /// last step, N (a hanging cloth pulls it down).
    fn grasp_force<'py>(&self, py: Python<'py>, id: usize) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let f = self.grasps.force(&self.sim, id).map_err(grasp_error)?;
        Ok(vec![f.x, f.y, f.z].into_pyarray(py))
    }

    /// The particles grasp `id` holds.
    fn grasp_particles(&self, id: usize) -> PyResult<Vec<usize>> {
        Ok(self.grasps.get(id).map_err(grasp_error)?.particles.clone())
    }

    /// Each of grasp `id`'s particles' offset from its gripper, m: an
    /// `(k, 3)` array in the order of `grasp_particles(id)`.
    fn grasp_offsets<'py>(&self, py: Python<'py>, id: usize) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(rows(py, self.grasps.get(id).map_err(grasp_error)?.offsets().iter().copied()))
    }

    /// Grasps `particles` at `offsets` (m, an `(k, 3)` array) from a
    /// gripper at `point` (m), as `grasp_particles` and `grasp_offsets`
    /// gave them: a grasp taken again after `restore`, which holds the
    /// same particles to the bit. Returns the new grasp's id; raises
    /// `ControlError` for a particle that is not free (pinned, grasped,
    /// given twice) or offsets that do not pair up, holding nothing then.
    fn grasp_at_offsets(
        &mut self,
        particles: Vec<usize>,
        offsets: PyReadonlyArray2<'_, f64>,
        point: [f64; 3],
    ) -> PyResult<usize> {
        let offsets = vectors("offsets", offsets)?;
        let at = (
            grasp::Gripper::Point,
            BodyPose { position: Vec3::from(point), rotation: nalgebra::UnitQuaternion::identity() },
        );
        self.grasps.grasp_at_offsets(&mut self.sim, particles, offsets, at).map_err(grasp_error)
    }

    /// Lets grasp `id`'s particles go; they keep their velocities.
    fn release(&mut self, id: usize) -> PyResult<()> {
        self.grasps.release(&mut self.sim, id).map_err(grasp_error)
    }

    /// The cloth's state now, to come back to with [`Simulation::restore`].
    fn snapshot(&self) -> Snapshot {
        Snapshot { state: self.sim.snapshot() }
    }

    /// Goes back to a snapshot of this simulation, or of another one of
    /// the same scene and integrator; `SnapshotError` (a `ValueError`)
    /// when it does not fit (another particle or stitch count, another
    /// integrator's memory, a position or velocity that is not finite),
    /// the simulation left as it was.
    fn restore(&mut self, snapshot: &Snapshot) -> PyResult<()> {
        self.sim.restore(&snapshot.state).map_err(|e| SnapshotError::new_err(e.to_string()))
    }
}

/// The extension module, re-exported by the `cloth` package.
#[pymodule]
fn _cloth(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Scene>()?;
    m.add_class::<Builder>()?;
    m.add_class::<Simulation>()?;
    m.add_class::<Snapshot>()?;
    m.add_class::<world::World>()?;
    m.add_class::<world::WorldSnapshot>()?;
    let py = m.py();
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add("ControlError", py.get_type::<ControlError>())?;
    m.add("StepError", py.get_type::<StepError>())?;
    m.add("SnapshotError", py.get_type::<SnapshotError>())?;
    Ok(())
}
