//! A co-simulation FMU, FMI 3.0 or 2.0, from this crate or another tool,
//! as a [`Unit`] of `cloth-cosim`'s masters, so FMUs and native units are
//! co-simulated together.
//!
//! The archive (stored or deflated, read with the `zip` crate) is
//! unpacked into a temporary directory, its binary loaded
//! (`binaries/x86_64-linux/<modelIdentifier>.so` for 3.0,
//! `binaries/linux64/` for 2.0), instantiated with its resources, given its
//! start values and taken to step mode. The unit's variables are the
//! FMU's scalar inputs, outputs and parameters of every numeric type and
//! boolean ([`VarType`]; values travel as `f64`, exact for these); string
//! variables are set and read by name ([`FmuUnit::string`]). Arrays,
//! binaries and clocks are passed over and listed
//! ([`FmuUnit::passed_over`]). States are the FMU's serialised bytes
//! (`Send`, independent of the instance), when it can save them.

mod fmi2;
mod fmi3;
mod model;

use crate::api::Status;
use crate::package::{FmuError, read_fmu};
use cloth_cosim::unit::settable;
use cloth_cosim::{Causality, StepOutcome, Unit, UnitError, UnitState, ValueRef, VarType, Variable};
pub(crate) use model::{Declared, Kind, Version, parse_description};
use std::ffi::{CStr, CString, c_char, c_void};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Messages the FMU logged, newest last.
type Log = Mutex<Vec<String>>;

/// FMI 3.0's logger: keeps the message in the unit's [`Log`].
unsafe extern "C" fn collect(env: *mut c_void, _status: Status, _category: *const c_char, message: *const c_char) {
    if env.is_null() || message.is_null() {
        return;
    }
    // SAFETY: `env` is the `Log` this unit owns (boxed, alive while the
    // instance is); `message` a NUL-terminated string from the FMU.
    let (log, text) = unsafe { (&*(env as *const Log), CStr::from_ptr(message).to_string_lossy().into_owned()) };
    if let Ok(mut log) = log.lock() {
        log.push(text);
    }
}

/// An FMI status code as a result: OK and Warning succeed.
fn status(code: i32) -> Result<(), i32> {
    if code == 0 || code == 1 { Ok(()) } else { Err(code) }
}

type StateOut = unsafe extern "C" fn(*mut c_void, *mut *mut c_void) -> i32;
type StateIn = unsafe extern "C" fn(*mut c_void, *mut c_void) -> i32;
type StateSize = unsafe extern "C" fn(*mut c_void, *mut c_void, *mut usize) -> i32;
type Serialize = unsafe extern "C" fn(*mut c_void, *mut c_void, *mut u8, usize) -> i32;
type Deserialize = unsafe extern "C" fn(*mut c_void, *const u8, usize, *mut *mut c_void) -> i32;

/// The six state functions of one FMI version, by symbol (NUL-terminated):
/// FMI 3.0 and 2.0 give them the same types.
struct StateCalls {
    get: &'static [u8],
    set: &'static [u8],
    free: &'static [u8],
    size: &'static [u8],
    serialize: &'static [u8],
    deserialize: &'static [u8],
}

/// A live instance and the library it came from: FMI functions called by
/// symbol name.
struct Binary {
    instance: *mut c_void,
    library: libloading::Library,
}

/// `fmi3Error` / `fmi2Error`, for a function the binary does not export.
const ERROR: i32 = 3;

impl Binary {
    /// Calls the `T`-typed function `symbol` (NUL-terminated) through
    /// `with`; an error status when the binary lacks it.
    fn call<T: Copy>(&self, symbol: &[u8], with: impl FnOnce(T) -> i32) -> i32 {
        // SAFETY: the FMI standard gives each symbol named in this module
        // the type `T` its caller asks for.
        match unsafe { self.library.get::<T>(symbol) } {
            Ok(f) => with(*f),
            Err(_) => ERROR,
        }
    }

    /// The instance's state, got, serialised and freed (`None` when any
    /// call fails).
    fn save(&self, names: &StateCalls) -> Option<Vec<u8>> {
        let mut state: *mut c_void = std::ptr::null_mut();
        let mut size = 0usize;
        // SAFETY: a live instance; the state is made, read and freed here.
        unsafe {
            let got = self.call(names.get, |f: StateOut| f(self.instance, &mut state)) <= 1;
            let sized = got && self.call(names.size, |f: StateSize| f(self.instance, state, &mut size)) <= 1;
            let mut bytes = vec![0u8; if sized { size } else { 0 }];
            let written = sized
                && self.call(names.serialize, |f: Serialize| f(self.instance, state, bytes.as_mut_ptr(), size)) <= 1;
            if got {
                self.call(names.free, |f: StateOut| f(self.instance, &mut state));
            }
            written.then_some(bytes)
        }
    }

    /// Sets the state serialised as `bytes`; the status of the first call
    /// that failed, or of the set.
    fn restore(&mut self, bytes: &[u8], names: &StateCalls) -> i32 {
        let mut state: *mut c_void = std::ptr::null_mut();
        // SAFETY: a live instance; the state is made, set and freed here.
        unsafe {
            let made = self
                .call(names.deserialize, |f: Deserialize| f(self.instance, bytes.as_ptr(), bytes.len(), &mut state));
            if status(made).is_err() {
                return made;
            }
            let set = self.call(names.set, |f: StateIn| f(self.instance, state));
            self.call(names.free, |f: StateOut| f(self.instance, &mut state));
            set
        }
    }
}

/// What instantiation needs, whatever the version.
struct Opened {
    name: String,
    token: String,
    resources: PathBuf,
}

/// One FMI version's calls on a live instance; status codes as the FMU
/// returned them. Dropping it terminates and frees the instance, then
/// unloads the library.
trait Api {
    /// Initialisation mode, entered and left (start time 0).
    fn initialize(&mut self) -> i32;
    fn get(&self, ty: VarType, vr: u32) -> Result<f64, i32>;
    fn set(&mut self, ty: VarType, vr: u32, value: f64) -> i32;
    fn get_string(&self, vr: u32) -> Result<String, i32>;
    fn set_string(&mut self, vr: u32, value: &CStr) -> i32;
    /// FMI 2.0's first-order input derivative (3.0 has none: an error).
    fn set_derivative(&mut self, vr: u32, du: f64) -> i32;
    /// The step's status and the last time reached.
    fn do_step(&mut self, t: f64, h: f64) -> (i32, f64);
    fn save(&self) -> Option<Vec<u8>>;
    fn restore(&mut self, bytes: &[u8]) -> i32;
}

/// An FMU's unpacked directory, removed when the load fails before the
/// unit that owns it exists.
struct Unpacked {
    dir: PathBuf,
    handed_on: bool,
}

impl Drop for Unpacked {
    fn drop(&mut self) {
        if !self.handed_on {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// A start value given at load, before initialisation.
#[derive(Debug, Clone, PartialEq)]
pub enum StartValue {
    /// A number or boolean (0 or 1).
    Number(f64),
    /// A string.
    Text(String),
}

/// How to load an FMU beyond its path and name.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Values set by variable name after instantiation, before
    /// initialisation (where FMI allows fixed parameters to be set).
    pub start_values: Vec<(String, StartValue)>,
    /// Shared libraries loaded first with their symbols global, for FMUs
    /// whose binary resolves symbols from the host (pythonfmu's FMUs need
    /// `libpython3.x.so`: their `needsExecutionTool` is Python). They stay
    /// loaded for the process's life: an interpreter cannot be unloaded.
    pub preload: Vec<PathBuf>,
}

/// The serialised state of an [`FmuUnit`] (empty when the FMU cannot save one).
struct FmuBytes(Vec<u8>);

/// An FMU as a co-simulation unit.
pub struct FmuUnit {
    name: String,
    version: Version,
    vars: Vec<Variable>,
    vrs: Vec<u32>,
    strings: Vec<Declared>,
    passed_over: Vec<String>,
    can_save_state: bool,
    can_interpolate: bool,
    /// `None` only while dropping.
    api: Option<Box<dyn Api>>,
    log: Box<Log>,
    dir: PathBuf,
}

// SAFETY: the instance is used only through `&mut self` (or `&self` for
// reads the FMU does not mutate), never from two threads at once; the
// library and the log are `Send`.
unsafe impl Send for FmuUnit {}

/// A declared start value as a number: booleans as 0 or 1.
fn number(text: &str) -> Option<f64> {
    match text.trim() {
        "true" => Some(1.0),
        "false" => Some(0.0),
        t => t.parse().ok(),
    }
}

impl FmuUnit {
    /// Unpacks the FMU at `path`, loads and instantiates it as `name`, and
    /// takes it to step mode at time 0.
    pub fn load(path: &Path, name: &str) -> Result<Self, FmuError> {
        Self::load_with(path, name, &LoadOptions::default())
    }

    /// [`FmuUnit::load`] with start values and preloaded libraries.
    pub fn load_with(path: &Path, name: &str, options: &LoadOptions) -> Result<Self, FmuError> {
        let bad = |message: String| FmuError::Io { path: path.to_path_buf(), message };
        let entries = read_fmu(path)?;
        let xml = entries
            .iter()
            .find(|(n, _)| n == "modelDescription.xml")
            .and_then(|(_, d)| String::from_utf8(d.clone()).ok())
            .ok_or_else(|| bad("no modelDescription.xml".into()))?;
        let d = parse_description(&xml).map_err(|e| bad(format!("modelDescription.xml: {e}")))?;
        let (mut vars, mut vrs, mut strings) = (Vec::new(), Vec::new(), Vec::new());
        for v in &d.variables {
            let Kind::Number(ty) = v.kind else {
                strings.push(v.clone());
                continue;
            };
            let start = match v.start.as_deref() {
                Some(text) => number(text)
                    .ok_or_else(|| bad(format!("modelDescription.xml: {}: start {text:?} is not a number", v.name)))?,
                None => 0.0,
            };
            let var = Variable::new(v.name.clone(), v.causality, v.unit, v.description.clone());
            let var = var.with_type(ty).with_start(start);
            vars.push(if v.tunable { var.tunable() } else { var });
            vrs.push(v.vr);
        }
        let index = |vr: u32| vrs.iter().position(|&r| r == vr);
        // Derivatives of inputs, and outputs' direct dependencies on inputs
        // (absent: every input), as the unit's variable indices.
        for (k, v) in d.variables.iter().filter(|v| matches!(v.kind, Kind::Number(_))).enumerate() {
            if let Some(of) = v.derivative_of.and_then(index)
                && vars[k].causality == Causality::Input
                && vars[of].causality == Causality::Input
            {
                vars[k] = vars[k].clone().derivative_of(of);
            }
        }
        for (vr, dependencies) in &d.outputs {
            let (Some(k), Some(list)) = (index(*vr), dependencies) else { continue };
            let inputs =
                list.iter().filter_map(|&d| index(d)).filter(|&j| vars[j].causality == Causality::Input).collect();
            vars[k].dependencies = Some(inputs);
        }
        for library in &options.preload {
            // SAFETY: loading runs the library's initialisers; the caller
            // names a library the FMU needs. Kept loaded (see LoadOptions).
            let global = unsafe {
                libloading::os::unix::Library::open(
                    Some(library),
                    libloading::os::unix::RTLD_NOW | libloading::os::unix::RTLD_GLOBAL,
                )
            }
            .map_err(|e| bad(format!("preloading {}: {e}", library.display())))?;
            std::mem::forget(global);
        }
        // Unpack next to nothing else: a directory of its own.
        static COUNT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = COUNT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("cloth-fmu-unit-{}-{n}", std::process::id()));
        let mut unpacked = Unpacked { dir: dir.clone(), handed_on: false };
        for (entry, data) in &entries {
            let target = dir.join(entry);
            if entry.split('/').any(|part| part == "..") {
                return Err(bad(format!("entry {entry} leaves the archive")));
            }
            std::fs::create_dir_all(target.parent().unwrap_or(&dir)).map_err(|e| bad(e.to_string()))?;
            std::fs::write(&target, data).map_err(|e| bad(e.to_string()))?;
        }
        let platform = match d.version {
            Version::Fmi3 => "x86_64-linux",
            Version::Fmi2 => "linux64",
        };
        let binary = dir.join("binaries").join(platform).join(format!("{}.so", d.identifier));
        // SAFETY: loading runs the library's initialisers; this is an FMU's
        // binary, which FMI requires to be loadable this way.
        let library = unsafe { libloading::Library::new(&binary) }
            .map_err(|e| bad(format!("loading {}: {e}", binary.display())))?;
        let log: Box<Log> = Box::new(Mutex::new(Vec::new()));
        let opened = Opened { name: name.into(), token: d.token.clone(), resources: dir.join("resources") };
        let api: Result<Box<dyn Api>, String> = match d.version {
            Version::Fmi3 => fmi3::Fmi3::instantiate(library, &opened, &log).map(|a| Box::new(a) as Box<dyn Api>),
            Version::Fmi2 => fmi2::Fmi2::instantiate(library, &opened, &log).map(|a| Box::new(a) as Box<dyn Api>),
        };
        let last = |log: &Log| log.lock().ok().and_then(|l| l.last().cloned()).unwrap_or_default();
        let api = api.map_err(|e| bad(format!("instantiation failed: {e} {}", last(&log))))?;
        // From here the unit's drop removes the directory.
        unpacked.handed_on = true;
        let mut unit = Self {
            name: name.into(),
            version: d.version,
            vars,
            vrs,
            strings,
            passed_over: d.passed_over,
            can_save_state: d.can_save_state,
            can_interpolate: d.can_interpolate,
            api: Some(api),
            log,
            dir,
        };
        for (variable, value) in &options.start_values {
            let result = match value {
                StartValue::Number(v) => match unit.find(variable) {
                    Some(vr) => unit.set_any(vr, *v),
                    None => Err(unit.unknown(variable)),
                },
                StartValue::Text(text) => unit.set_string(variable, text),
            };
            result.map_err(|e| bad(format!("start value of {variable}: {e}")))?;
        }
        let code = unit.api_mut().initialize();
        if status(code).is_err() {
            return Err(bad(format!("initialisation failed: {}", unit.last_message())));
        }
        Ok(unit)
    }

    /// FMI 3.0 or 2.0.
    pub fn fmi_version(&self) -> &'static str {
        match self.version {
            Version::Fmi3 => "3.0",
            Version::Fmi2 => "2.0",
        }
    }

    /// Variables the unit does not carry (arrays, binaries, clocks), each
    /// with why.
    pub fn passed_over(&self) -> &[String] {
        &self.passed_over
    }

    /// The names of the FMU's string variables.
    pub fn string_names(&self) -> impl Iterator<Item = &str> {
        self.strings.iter().map(|s| s.name.as_str())
    }

    /// The string variable `name`'s value.
    pub fn string(&self, name: &str) -> Result<String, UnitError> {
        let v = self.strings.iter().find(|s| s.name == name).ok_or_else(|| self.unknown(name))?;
        self.api().get_string(v.vr).map_err(|_| self.failed(&format!("reading {name}")))
    }

    /// Sets the string input or parameter `name`.
    pub fn set_string(&mut self, name: &str, value: &str) -> Result<(), UnitError> {
        let v = self.strings.iter().find(|s| s.name == name).ok_or_else(|| self.unknown(name))?;
        if v.causality == Causality::Output {
            return Err(UnitError::Causality {
                unit: self.name.clone(),
                name: name.into(),
                causality: v.causality,
                message: "outputs cannot be set",
            });
        }
        let vr = v.vr;
        let text = CString::new(value).map_err(|_| UnitError::InvalidValue {
            unit: self.name.clone(),
            name: name.into(),
            value: f64::NAN,
            message: "holds a NUL".into(),
        })?;
        match status(self.api_mut().set_string(vr, &text)) {
            Ok(()) => Ok(()),
            Err(_) => Err(self.failed(&format!("setting {name}"))),
        }
    }

    fn api(&self) -> &dyn Api {
        self.api.as_deref().expect("the instance lives until drop")
    }

    fn api_mut(&mut self) -> &mut dyn Api {
        self.api.as_deref_mut().expect("the instance lives until drop")
    }

    /// Sets variable `vr` of any causality the FMU lets set now.
    fn set_any(&mut self, vr: ValueRef, value: f64) -> Result<(), UnitError> {
        let var = self.vars.get(vr).ok_or(UnitError::NoSuchVariable {
            unit: self.name.clone(),
            vr,
            count: self.vars.len(),
        })?;
        let (ty, name) = (var.ty, var.name.clone());
        if let Some(why) = ty.refuses(value) {
            return Err(UnitError::InvalidValue { unit: self.name.clone(), name, value, message: why });
        }
        let reference = self.vrs[vr];
        match status(self.api_mut().set(ty, reference, value)) {
            Ok(()) => Ok(()),
            Err(_) => {
                Err(UnitError::InvalidValue { unit: self.name.clone(), name, value, message: self.last_message() })
            }
        }
    }

    fn unknown(&self, name: &str) -> UnitError {
        let mut names: Vec<&str> = self.vars.iter().map(|v| v.name.as_str()).chain(self.string_names()).collect();
        names.sort_unstable();
        UnitError::InvalidValue {
            unit: self.name.clone(),
            name: name.into(),
            value: f64::NAN,
            message: format!("no such variable; it has {}", names.join(", ")),
        }
    }

    /// The FMU's last logged message ("" when none).
    fn last_message(&self) -> String {
        self.log.lock().ok().and_then(|l| l.last().cloned()).unwrap_or_default()
    }

    fn failed(&self, what: &str) -> UnitError {
        UnitError::StepFailed {
            unit: self.name.clone(),
            time_s: f64::NAN,
            message: format!("{what}: {}", self.last_message()),
        }
    }

    fn bad_state(&self, what: &str) -> UnitError {
        UnitError::BadState { unit: self.name.clone(), message: format!("{what}: {}", self.last_message()) }
    }
}

impl Drop for FmuUnit {
    fn drop(&mut self) {
        // The instance goes first (terminated, freed, its library unloaded),
        // while the log it writes to still exists; then its files.
        drop(self.api.take());
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

impl Unit for FmuUnit {
    fn name(&self) -> &str {
        &self.name
    }

    fn variables(&self) -> &[Variable] {
        &self.vars
    }

    fn set(&mut self, vr: ValueRef, value: f64) -> Result<(), UnitError> {
        settable(&self.name, &self.vars, vr, value)?;
        self.set_any(vr, value)
    }

    /// Sets the input the model description declares as `vr`'s
    /// derivative, or, in an FMI 2.0 FMU that can interpolate its inputs,
    /// calls `fmi2SetRealInputDerivatives`.
    fn set_input_derivative(&mut self, vr: ValueRef, du: f64) -> Result<(), UnitError> {
        if let Some(rate) = self.vars.iter().position(|v| v.derivative_of == Some(vr)) {
            return self.set(rate, du);
        }
        let var = settable(&self.name, &self.vars, vr, du)?;
        if !(self.can_interpolate && var.ty == VarType::Float64 && var.causality == Causality::Input) {
            return Err(UnitError::Unsupported { unit: self.name.clone(), what: "input derivatives" });
        }
        let reference = self.vrs[vr];
        match status(self.api_mut().set_derivative(reference, du)) {
            Ok(()) => Ok(()),
            Err(_) => Err(self.failed("fmi2SetRealInputDerivatives")),
        }
    }

    fn get(&self, vr: ValueRef) -> Result<f64, UnitError> {
        let var = self.vars.get(vr).ok_or(UnitError::NoSuchVariable {
            unit: self.name.clone(),
            vr,
            count: self.vars.len(),
        })?;
        self.api().get(var.ty, self.vrs[vr]).map_err(|_| self.failed(&format!("reading {}", var.name)))
    }

    fn do_step(&mut self, t: f64, h: f64) -> Result<StepOutcome, UnitError> {
        let (code, last) = self.api_mut().do_step(t, h);
        match code {
            0 | 1 => Ok(StepOutcome::Completed),
            2 => Ok(StepOutcome::Discarded { last_time_s: last, reason: self.last_message() }),
            _ => Err(UnitError::StepFailed { unit: self.name.clone(), time_s: t, message: self.last_message() }),
        }
    }

    /// Empty when the FMU declares it cannot get and serialise its state;
    /// [`Unit::set_state`] then refuses it and says so.
    fn get_state(&self) -> UnitState {
        let bytes = if self.can_save_state { self.api().save().unwrap_or_default() } else { Vec::new() };
        UnitState(Box::new(FmuBytes(bytes)))
    }

    fn set_state(&mut self, state: &UnitState) -> Result<(), UnitError> {
        let FmuBytes(bytes) = state.downcast::<FmuBytes>(&self.name, "FMU")?;
        if !self.can_save_state {
            return Err(UnitError::BadState {
                unit: self.name.clone(),
                message:
                    "the FMU cannot go back to a state (its model description says it cannot get and serialise one)"
                        .into(),
            });
        }
        match status(self.api_mut().restore(bytes)) {
            Ok(()) => Ok(()),
            Err(_) => Err(self.bad_state("restoring a state")),
        }
    }

    fn serialize_state(&self, state: &UnitState) -> Result<Vec<u8>, UnitError> {
        Ok(state.downcast::<FmuBytes>(&self.name, "FMU")?.0.clone())
    }

    fn deserialize_state(&self, bytes: &[u8]) -> Result<UnitState, UnitError> {
        Ok(UnitState(Box::new(FmuBytes(bytes.to_vec()))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model description as another tool might write it: a declaration
    /// and a comment, single-quoted attributes, escaped text, a `Float64`
    /// with no causality (local by default, passed over), an `Int32`, a
    /// `Boolean`, a `String` with its `<Start>`, a derivative, and an array
    /// and a `Binary`, passed over and listed.
    const OTHER_TOOL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- exported by some tool -->
<fmiModelDescription fmiVersion='3.0' modelName="m" instantiationToken="{1234}">
  <CoSimulation modelIdentifier='model_x' canHandleVariableCommunicationStepSize="true" canGetAndSetFMUState="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name='u' valueReference='7' causality='input' start='1.5' description="force &amp; &quot;torque&quot;"/>
    <Float64 name="y" valueReference="8" causality="output" unit="m"/>
    <Float64 name="z" valueReference="9" causality="output"/>
    <Float64 name="internal" valueReference="10"/>
    <Int32 name="count" valueReference="11" causality="output"/>
    <Boolean name="on" valueReference="12" causality="parameter" variability="fixed" start="true"/>
    <String name="label" valueReference="13" causality="parameter" variability="fixed"><Start value="a &amp; b"/></String>
    <Float64 name="du" valueReference="14" causality="input" derivative="7"/>
    <Float64 name="positions" valueReference="15" causality="output"><Dimension start="3"/></Float64>
    <Binary name="blob" valueReference="16" causality="output"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="8" dependencies="7"/>
    <Output valueReference="9" dependencies=""/>
  </ModelStructure>
</fmiModelDescription>"#;

    #[test]
    fn a_description_from_another_tool_is_read_with_its_defaults() {
        let d = parse_description(OTHER_TOOL).unwrap();
        assert_eq!((d.version, d.token.as_str(), d.identifier.as_str()), (Version::Fmi3, "{1234}", "model_x"));
        let names: Vec<(&str, u32)> = d.variables.iter().map(|v| (v.name.as_str(), v.vr)).collect();
        assert_eq!(names, [("u", 7), ("y", 8), ("z", 9), ("count", 11), ("on", 12), ("label", 13), ("du", 14)]);
        let u = &d.variables[0];
        assert_eq!(
            (u.causality, u.start.as_deref(), u.description.as_str()),
            (Causality::Input, Some("1.5"), "force & \"torque\"")
        );
        assert_eq!(d.variables[1].unit, "m");
        assert_eq!(d.variables[3].kind, Kind::Number(VarType::Integer { bits: 32, signed: true }));
        assert_eq!(
            (d.variables[4].kind, d.variables[4].start.as_deref()),
            (Kind::Number(VarType::Boolean), Some("true"))
        );
        assert_eq!((d.variables[5].kind, d.variables[5].start.as_deref()), (Kind::String, Some("a & b")));
        assert_eq!(d.variables[6].derivative_of, Some(7));
        assert_eq!(
            d.passed_over,
            ["positions: an array (<Dimension>)", "blob: a type this importer does not read (Binary, Clock)"]
        );
        assert_eq!(d.outputs, [(8, Some(vec![7])), (9, Some(vec![]))]);
        assert!(!d.can_save_state);
        for bad in ["<notFmi/>", "<fmiModelDescription><Float64 valueReference=\"1\" causality=\"input\"/>", "<a", FMI1]
        {
            assert!(parse_description(bad).is_err(), "{bad}");
        }
    }

    /// The same kinds of variable as FMI 2.0 writes them: ScalarVariables
    /// with a type element, derivatives and output dependencies by
    /// 1-based position.
    const FMI2: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{abcd}">
  <CoSimulation modelIdentifier="m2" canGetAndSetFMUstate="true" canSerializeFMUstate="true" canInterpolateInputs="true"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="3" causality="input"><Real start="2" unit="N"/></ScalarVariable>
    <ScalarVariable name="local" valueReference="4"><Real/></ScalarVariable>
    <ScalarVariable name="du" valueReference="5" causality="input"><Real derivative="1"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="6" causality="output"><Integer/></ScalarVariable>
    <ScalarVariable name="on" valueReference="7" causality="parameter" variability="fixed"><Boolean start="false"/></ScalarVariable>
    <ScalarVariable name="label" valueReference="8" causality="parameter" variability="fixed"><String start="x"></String></ScalarVariable>
    <ScalarVariable name="mode" valueReference="9" causality="output"><Enumeration declaredType="Mode"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="4" dependencies="1 2"/><Unknown index="7"/></Outputs>
    <InitialUnknowns><Unknown index="2"/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>"#;

    const FMI1: &str = r#"<fmiModelDescription fmiVersion="1.0" guid="x"><Implementation/></fmiModelDescription>"#;

    #[test]
    fn an_fmi2_description_is_read_by_position() {
        let d = parse_description(FMI2).unwrap();
        assert_eq!((d.version, d.token.as_str(), d.identifier.as_str()), (Version::Fmi2, "{abcd}", "m2"));
        assert!(d.can_save_state && d.can_interpolate);
        let names: Vec<(&str, u32, Kind)> = d.variables.iter().map(|v| (v.name.as_str(), v.vr, v.kind)).collect();
        let int32 = Kind::Number(VarType::Integer { bits: 32, signed: true });
        assert_eq!(
            names,
            [
                ("u", 3, Kind::Number(VarType::Float64)),
                ("du", 5, Kind::Number(VarType::Float64)),
                ("n", 6, int32),
                ("on", 7, Kind::Number(VarType::Boolean)),
                ("label", 8, Kind::String),
                ("mode", 9, int32),
            ]
        );
        assert_eq!((d.variables[0].start.as_deref(), d.variables[0].unit), (Some("2"), "N"));
        assert_eq!(d.variables[1].derivative_of, Some(3));
        assert_eq!(d.variables[4].start.as_deref(), Some("x"));
        assert_eq!(d.outputs, [(6, Some(vec![3, 4])), (9, None)]);
    }

    /// An FMU whose library is missing is refused, and leaves no unpacked
    /// directory behind.
    #[test]
    fn a_failed_load_leaves_no_directory_behind() {
        let path = std::env::temp_dir().join(format!("cloth-fmu-no-library-{}.fmu", std::process::id()));
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
        zip.start_file("modelDescription.xml", zip::write::SimpleFileOptions::default()).unwrap();
        std::io::Write::write_all(&mut zip, OTHER_TOOL.as_bytes()).unwrap();
        zip.finish().unwrap();
        let e = FmuUnit::load(&path, "x").err().expect("no library to load");
        assert!(e.to_string().contains("model_x.so"), "{e}");
        let prefix = format!("cloth-fmu-unit-{}-", std::process::id());
        let left: Vec<_> = std::fs::read_dir(std::env::temp_dir())
            .unwrap()
            .filter_map(|d| d.ok())
            .filter(|d| d.file_name().to_string_lossy().starts_with(&prefix))
            .collect();
        assert!(left.is_empty(), "left behind: {:?}", left.iter().map(|d| d.path()).collect::<Vec<_>>());
        let _ = std::fs::remove_file(&path);
    }
}
