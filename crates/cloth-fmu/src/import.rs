//! An FMI 3.0 co-simulation FMU as a [`Unit`] of `cloth-cosim`'s master,
//! so an FMU and native units can be co-simulated together.
//!
//! The archive is unpacked into a temporary directory, its binary loaded
//! (`binaries/x86_64-linux/<modelIdentifier>.so`), instantiated with its
//! resources and taken to step mode. Variables are the `Float64` ones of
//! `modelDescription.xml` (not `time`). States are kept as the FMU's
//! serialised bytes (`Send`, independent of the instance). Archives are
//! read by this crate's ZIP reader, so FMUs this crate wrote (stored
//! entries) load; others may not.

use crate::api::{LogMessage, Status, ValueReference};
use crate::description::known_unit;
use crate::package::{FmuError, read_fmu};
use cloth_cosim::unit::settable;
use cloth_cosim::{Causality, StepOutcome, Unit, UnitError, UnitState, ValueRef, Variable};
use std::ffi::{CStr, CString, c_char, c_void};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

type Instantiate = unsafe extern "C" fn(
    *const c_char,
    *const c_char,
    *const c_char,
    bool,
    bool,
    bool,
    bool,
    *const ValueReference,
    usize,
    *mut c_void,
    Option<LogMessage>,
    *const c_void,
) -> *mut c_void;
type EnterInit = unsafe extern "C" fn(*mut c_void, bool, f64, f64, bool, f64) -> Status;
type Simple = unsafe extern "C" fn(*mut c_void) -> Status;
type GetF64 = unsafe extern "C" fn(*mut c_void, *const ValueReference, usize, *mut f64, usize) -> Status;
type SetF64 = unsafe extern "C" fn(*mut c_void, *const ValueReference, usize, *const f64, usize) -> Status;
type DoStep = unsafe extern "C" fn(*mut c_void, f64, f64, bool, *mut bool, *mut bool, *mut bool, *mut f64) -> Status;
type StateOut = unsafe extern "C" fn(*mut c_void, *mut *mut c_void) -> Status;
type StateIn = unsafe extern "C" fn(*mut c_void, *mut c_void) -> Status;
type StateSize = unsafe extern "C" fn(*mut c_void, *mut c_void, *mut usize) -> Status;
type Serialize = unsafe extern "C" fn(*mut c_void, *mut c_void, *mut u8, usize) -> Status;
type Deserialize = unsafe extern "C" fn(*mut c_void, *const u8, usize, *mut *mut c_void) -> Status;
type Free = unsafe extern "C" fn(*mut c_void);

/// The FMI functions the unit calls, resolved once.
struct Functions {
    instantiate: Instantiate,
    enter_initialization: EnterInit,
    exit_initialization: Simple,
    terminate: Simple,
    free_instance: Free,
    get_float64: GetF64,
    set_float64: SetF64,
    do_step: DoStep,
    get_state: StateOut,
    set_state: StateIn,
    free_state: StateOut,
    state_size: StateSize,
    serialize: Serialize,
    deserialize: Deserialize,
}

/// Messages the FMU logged, newest last.
type Log = Mutex<Vec<String>>;

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

/// The serialised state of an [`FmuUnit`].
struct FmuBytes(Vec<u8>);

/// An FMU as a co-simulation unit.
pub struct FmuUnit {
    name: String,
    vars: Vec<Variable>,
    vrs: Vec<ValueReference>,
    f: Functions,
    instance: *mut c_void,
    log: Box<Log>,
    dir: PathBuf,
    // Dropped last: the functions above point into it.
    _library: libloading::Library,
}

// SAFETY: the instance is used only through `&mut self` (or `&self` for
// reads the FMU does not mutate), never from two threads at once; the
// library and the log are `Send`.
unsafe impl Send for FmuUnit {}

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

/// What the importer reads of a `modelDescription.xml`.
#[derive(Debug, Default)]
struct Description {
    token: Option<String>,
    identifier: Option<String>,
    /// `Float64` inputs, outputs and parameters, with their value
    /// references and the value reference their `derivative` names.
    variables: Vec<(Variable, ValueReference, Option<ValueReference>)>,
    /// `<Output>` value references and their `dependencies`, if given.
    outputs: Vec<(ValueReference, Option<Vec<ValueReference>>)>,
}

/// Parses a model description with an XML parser: the instantiation
/// token, the co-simulation model identifier, the `Float64` variables of
/// causality input, output or parameter (the default causality is local,
/// so a variable without one is passed over, as are other types) and the
/// outputs' dependencies. Errors name what is missing or malformed.
fn parse_description(xml: &str) -> Result<Description, String> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(xml);
    let mut d = Description::default();
    let mut root = false;
    loop {
        let event = reader.read_event().map_err(|e| format!("XML at byte {}: {e}", reader.buffer_position()))?;
        let element = match &event {
            Event::Start(e) | Event::Empty(e) => e,
            Event::Eof => break,
            _ => continue,
        };
        let mut attributes = std::collections::BTreeMap::new();
        for a in element.attributes() {
            let a = a.map_err(|e| format!("XML attribute: {e}"))?;
            let value = a.unescape_value().map_err(|e| format!("XML attribute value: {e}"))?;
            attributes.insert(String::from_utf8_lossy(a.key.as_ref()).into_owned(), value.into_owned());
        }
        let get = |k: &str| attributes.get(k).cloned();
        match element.name().as_ref() {
            b"fmiModelDescription" => {
                root = true;
                d.token = get("instantiationToken");
            }
            b"CoSimulation" => d.identifier = get("modelIdentifier"),
            b"Float64" => {
                let causality = match get("causality").as_deref().unwrap_or("local") {
                    "input" => Causality::Input,
                    "output" => Causality::Output,
                    "parameter" => Causality::Parameter,
                    _ => continue, // independent (time), local, calculated parameters
                };
                let name = get("name").ok_or("a Float64 variable without a name")?;
                let vr = get("valueReference")
                    .and_then(|v| v.parse().ok())
                    .ok_or_else(|| format!("{name}: no valueReference, or not a number"))?;
                let start = match get("start") {
                    Some(s) => s.parse().map_err(|_| format!("{name}: start {s:?} is not a number"))?,
                    None => 0.0,
                };
                // Variables carry `'static` unit names: this crate's own units.
                let unit = get("unit").and_then(|u| known_unit(&u)).map_or("", |(name, _)| name);
                let description = get("description").unwrap_or_default();
                let derivative = get("derivative").and_then(|v| v.parse().ok());
                d.variables.push((Variable::new(name, causality, unit, description).with_start(start), vr, derivative));
            }
            b"Output" => {
                let Some(vr) = get("valueReference").and_then(|v| v.parse().ok()) else { continue };
                let dependencies =
                    get("dependencies").map(|l| l.split_whitespace().filter_map(|v| v.parse().ok()).collect());
                d.outputs.push((vr, dependencies));
            }
            _ => {}
        }
    }
    if !root {
        return Err("not an FMI model description (no <fmiModelDescription>)".into());
    }
    Ok(d)
}

impl FmuUnit {
    /// Unpacks the FMU at `path`, loads and instantiates it as `name`, and
    /// takes it to step mode at time 0.
    pub fn load(path: &Path, name: &str) -> Result<Self, FmuError> {
        let bad = |message: String| FmuError::Io { path: path.to_path_buf(), message };
        let entries = read_fmu(path)?;
        let xml = entries
            .iter()
            .find(|(n, _)| n == "modelDescription.xml")
            .and_then(|(_, d)| String::from_utf8(d.clone()).ok())
            .ok_or_else(|| bad("no modelDescription.xml".into()))?;
        let d = parse_description(&xml).map_err(|e| bad(format!("modelDescription.xml: {e}")))?;
        let token = d.token.ok_or_else(|| bad("modelDescription.xml: no instantiationToken".into()))?;
        let identifier = d
            .identifier
            .ok_or_else(|| bad("modelDescription.xml: not a co-simulation FMU (no <CoSimulation>)".into()))?;
        let mut vars = Vec::new();
        let (mut vrs, mut derivatives) = (Vec::new(), Vec::new());
        for (var, vr, derivative) in d.variables {
            vars.push(var);
            vrs.push(vr);
            derivatives.push(derivative);
        }
        // An input that is another input's derivative takes its
        // `set_input_derivative` (FMI 3.0 co-simulation has no call for it).
        for (k, derivative) in derivatives.into_iter().enumerate() {
            let of = derivative.and_then(|d| vrs.iter().position(|&r| r == d));
            if let Some(of) =
                of.filter(|&of| vars[of].causality == Causality::Input && vars[k].causality == Causality::Input)
            {
                vars[k] = vars[k].clone().derivative_of(of);
            }
        }
        // Outputs' direct dependencies on inputs (absent: every input), as
        // the unit's variable indices.
        for (vr, dependencies) in d.outputs {
            let (Some(k), Some(list)) = (vrs.iter().position(|&r| r == vr), dependencies) else { continue };
            let inputs = list
                .into_iter()
                .filter_map(|d| vrs.iter().position(|&r| r == d))
                .filter(|&j| vars[j].causality == Causality::Input)
                .collect();
            vars[k].dependencies = Some(inputs);
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
        let binary = dir.join("binaries/x86_64-linux").join(format!("{identifier}.so"));
        // SAFETY: loading runs the library's initialisers; this is an FMU's
        // binary, which FMI requires to be loadable this way.
        let library = unsafe { libloading::Library::new(&binary) }
            .map_err(|e| bad(format!("loading {}: {e}", binary.display())))?;
        // SAFETY: the symbols have the types of fmi3FunctionTypes.h; the
        // pointers stay valid while `library` is loaded (it is dropped last).
        let f = unsafe {
            macro_rules! get {
                ($name:literal) => {
                    *library.get(concat!($name, "\0").as_bytes()).map_err(|e| bad(format!("{}: {e}", $name)))?
                };
            }
            Functions {
                instantiate: get!("fmi3InstantiateCoSimulation"),
                enter_initialization: get!("fmi3EnterInitializationMode"),
                exit_initialization: get!("fmi3ExitInitializationMode"),
                terminate: get!("fmi3Terminate"),
                free_instance: get!("fmi3FreeInstance"),
                get_float64: get!("fmi3GetFloat64"),
                set_float64: get!("fmi3SetFloat64"),
                do_step: get!("fmi3DoStep"),
                get_state: get!("fmi3GetFMUState"),
                set_state: get!("fmi3SetFMUState"),
                free_state: get!("fmi3FreeFMUState"),
                state_size: get!("fmi3SerializedFMUStateSize"),
                serialize: get!("fmi3SerializeFMUState"),
                deserialize: get!("fmi3DeserializeFMUState"),
            }
        };
        let log: Box<Log> = Box::new(Mutex::new(Vec::new()));
        let c = |s: &str| CString::new(s).map_err(|_| bad(format!("{s:?} holds a NUL")));
        let (c_name, c_token) = (c(name)?, c(&token)?);
        let c_resources = c(&format!("{}/", dir.join("resources").display()))?;
        let env = &*log as *const Log as *mut c_void;
        // SAFETY: valid strings and callback; `env` outlives the instance.
        let instance = unsafe {
            (f.instantiate)(
                c_name.as_ptr(),
                c_token.as_ptr(),
                c_resources.as_ptr(),
                false,
                false,
                false,
                false,
                std::ptr::null(),
                0,
                env,
                Some(collect),
                std::ptr::null(),
            )
        };
        // From here the unit's drop removes the directory.
        unpacked.handed_on = true;
        let mut unit = Self { name: name.into(), vars, vrs, f, instance, log, dir, _library: library };
        if instance.is_null() {
            return Err(bad(format!("instantiation failed: {}", unit.last_message())));
        }
        // SAFETY: a live instance.
        let entered = unsafe { (unit.f.enter_initialization)(instance, false, 0.0, 0.0, false, 0.0) };
        let exited = unsafe { (unit.f.exit_initialization)(instance) };
        if entered != Status::Ok || exited != Status::Ok {
            let message = unit.last_message();
            unit.vars.clear();
            return Err(bad(format!("initialisation failed: {message}")));
        }
        Ok(unit)
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
        if !self.instance.is_null() {
            // SAFETY: a live instance, freed once.
            unsafe {
                (self.f.terminate)(self.instance);
                (self.f.free_instance)(self.instance);
            }
            self.instance = std::ptr::null_mut();
        }
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
        let var = settable(&self.name, &self.vars, vr, value)?;
        // SAFETY: a live instance, one value.
        let status = unsafe { (self.f.set_float64)(self.instance, &self.vrs[vr], 1, &value, 1) };
        if status != Status::Ok {
            return Err(UnitError::InvalidValue {
                unit: self.name.clone(),
                name: var.name.clone(),
                value,
                message: self.last_message(),
            });
        }
        Ok(())
    }

    /// Sets the input the model description declares as `vr`'s derivative.
    fn set_input_derivative(&mut self, vr: ValueRef, du: f64) -> Result<(), UnitError> {
        match self.vars.iter().position(|v| v.derivative_of == Some(vr)) {
            Some(rate) => self.set(rate, du),
            None => Err(UnitError::Unsupported { unit: self.name.clone(), what: "input derivatives" }),
        }
    }

    fn get(&self, vr: ValueRef) -> Result<f64, UnitError> {
        let reference = *self.vrs.get(vr).ok_or(UnitError::NoSuchVariable {
            unit: self.name.clone(),
            vr,
            count: self.vars.len(),
        })?;
        let mut value = f64::NAN;
        // SAFETY: a live instance, one value.
        let status = unsafe { (self.f.get_float64)(self.instance, &reference, 1, &mut value, 1) };
        if status != Status::Ok {
            return Err(self.failed(&format!("reading {}", self.vars[vr].name)));
        }
        Ok(value)
    }

    fn do_step(&mut self, t: f64, h: f64) -> Result<StepOutcome, UnitError> {
        let (mut event, mut terminate, mut early, mut last) = (false, false, false, t);
        // SAFETY: a live instance, writable flags.
        let status =
            unsafe { (self.f.do_step)(self.instance, t, h, false, &mut event, &mut terminate, &mut early, &mut last) };
        match status {
            Status::Ok | Status::Warning => Ok(StepOutcome::Completed),
            Status::Discard => Ok(StepOutcome::Discarded { last_time_s: last, reason: self.last_message() }),
            _ => Err(UnitError::StepFailed { unit: self.name.clone(), time_s: t, message: self.last_message() }),
        }
    }

    fn get_state(&self) -> UnitState {
        let mut state: *mut c_void = std::ptr::null_mut();
        let mut size = 0usize;
        // SAFETY: a live instance; the state is made, read and freed here.
        let bytes = unsafe {
            let ok = (self.f.get_state)(self.instance, &mut state) == Status::Ok
                && (self.f.state_size)(self.instance, state, &mut size) == Status::Ok;
            let mut bytes = vec![0u8; if ok { size } else { 0 }];
            let ok = ok && (self.f.serialize)(self.instance, state, bytes.as_mut_ptr(), size) == Status::Ok;
            (self.f.free_state)(self.instance, &mut state);
            if ok { bytes } else { Vec::new() }
        };
        // An empty state (the FMU refused) is refused in turn by set_state.
        UnitState(Box::new(FmuBytes(bytes)))
    }

    fn set_state(&mut self, state: &UnitState) -> Result<(), UnitError> {
        let FmuBytes(bytes) = state.downcast::<FmuBytes>(&self.name, "FMU")?;
        let mut restored: *mut c_void = std::ptr::null_mut();
        // SAFETY: a live instance; the state is made, set and freed here.
        unsafe {
            if (self.f.deserialize)(self.instance, bytes.as_ptr(), bytes.len(), &mut restored) != Status::Ok {
                return Err(self.bad_state("deserialising"));
            }
            let status = (self.f.set_state)(self.instance, restored);
            (self.f.free_state)(self.instance, &mut restored);
            if status != Status::Ok {
                return Err(self.bad_state("setting the state"));
            }
        }
        Ok(())
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
    /// with no causality (local by default) and an `Int32`, both passed over.
    const OTHER_TOOL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- exported by some tool -->
<fmiModelDescription fmiVersion='3.0' modelName="m" instantiationToken="{1234}">
  <CoSimulation modelIdentifier='model_x' canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name='u' valueReference='7' causality='input' start='1.5' description="force &amp; &quot;torque&quot;"/>
    <Float64 name="y" valueReference="8" causality="output" unit="m"/>
    <Float64 name="z" valueReference="9" causality="output"/>
    <Float64 name="internal" valueReference="10"/>
    <Int32 name="count" valueReference="11" causality="output"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="8" dependencies="7"/>
    <Output valueReference="9" dependencies=""/>
  </ModelStructure>
</fmiModelDescription>"#;

    #[test]
    fn a_description_from_another_tool_is_read_with_its_defaults() {
        let d = parse_description(OTHER_TOOL).unwrap();
        assert_eq!(d.token.as_deref(), Some("{1234}"));
        assert_eq!(d.identifier.as_deref(), Some("model_x"));
        let names: Vec<(&str, ValueReference)> = d.variables.iter().map(|(v, r, _)| (v.name.as_str(), *r)).collect();
        assert_eq!(names, [("u", 7), ("y", 8), ("z", 9)]);
        let u = &d.variables[0].0;
        assert_eq!((u.causality, u.start, u.description.as_str()), (Causality::Input, 1.5, "force & \"torque\""));
        assert_eq!(d.variables[1].0.unit, "m");
        assert_eq!(d.outputs, [(8, Some(vec![7])), (9, Some(vec![]))]);
        for bad in ["<notFmi/>", "<fmiModelDescription><Float64 valueReference=\"1\" causality=\"input\"/>", "<a"] {
            assert!(parse_description(bad).is_err(), "{bad}");
        }
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
