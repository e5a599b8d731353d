//! The FMI 3.0 C API (co-simulation), as `fmi3Functions.h` declares it.
//!
//! Every function checks its instance and pointers, runs inside
//! `catch_unwind` (a panic becomes `fmi3Error` with a logged message,
//! never an abort of the host), and checks that the call is allowed where
//! the instance is in FMI's state machine. What this FMU does not support
//! (model exchange, scheduled execution, event mode, clocks, derivatives,
//! non-`Float64` variables) returns `fmi3Error` with the reason logged.

use crate::instance::{Instance, Phase, log_to};
pub use crate::instance::{LogMessage, Status};
use cloth_cosim::{StepOutcome, Unit};
use std::ffi::{CStr, c_char, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;

/// `fmi3ValueReference`
pub type ValueReference = u32;

const VERSION: &CStr = c"3.0";

/// Every phase: where logging, reset, unsupported calls and FMU states are
/// allowed.
const ANY: [Phase; 4] = [Phase::Instantiated, Phase::Initialization, Phase::Step, Phase::Terminated];

/// Runs `body` on the instance behind `instance` when `phase` allows
/// `function` there; logs and returns `fmi3Error` otherwise, on an error
/// and on a panic.
fn call(
    instance: *mut c_void,
    function: &str,
    allowed: &[Phase],
    body: impl FnOnce(&mut Instance) -> Result<Status, String>,
) -> Status {
    if instance.is_null() {
        // No instance, no logger to say it with.
        return Status::Error;
    }
    let Some(inst) = crate::handles::lookup(instance, function) else { return Status::Error };
    // SAFETY: a live handle's instance, made by `Box::into_raw` and not
    // freed (`handles::release` takes it out of the registry first); FMI
    // makes no two calls on one instance at once.
    let inst = unsafe { &mut *inst };
    if !allowed.contains(&inst.phase) {
        let message = format!("{function} is not allowed in {:?} mode (allowed in {allowed:?})", inst.phase);
        inst.log(Status::Error, "logStatusError", &message);
        return Status::Error;
    }
    match catch_unwind(AssertUnwindSafe(|| body(inst))) {
        Ok(Ok(status)) => status,
        Ok(Err(message)) => {
            inst.log(Status::Error, "logStatusError", &format!("{function}: {message}"));
            Status::Error
        }
        Err(panic) => {
            let what =
                panic.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| panic.downcast_ref::<String>().cloned());
            let message = format!("{function}: internal error: {}", what.unwrap_or_else(|| "panic".into()));
            inst.log(Status::Error, "logStatusError", &message);
            Status::Error
        }
    }
}

/// Logs that `function` is not supported by this FMU.
fn unsupported(instance: *mut c_void, function: &str, why: &str) -> Status {
    call(instance, function, &ANY, |_| Err(format!("not supported: {why}")))
}

/// A slice from a host array, checked: null is allowed only when empty.
///
/// # Safety
/// `ptr` must point to `len` valid `T`s when not null.
unsafe fn slice<'a, T>(ptr: *const T, len: usize, what: &str) -> Result<&'a [T], String> {
    match (ptr.is_null(), len) {
        (_, 0) => Ok(&[]),
        (true, _) => Err(format!("{what} is null with {len} entries")),
        // SAFETY: the caller's contract.
        (false, _) => Ok(unsafe { std::slice::from_raw_parts(ptr, len) }),
    }
}

/// A mutable slice from a host array, checked as [`slice`].
///
/// # Safety
/// `ptr` must point to `len` writable `T`s when not null.
unsafe fn slice_mut<'a, T>(ptr: *mut T, len: usize, what: &str) -> Result<&'a mut [T], String> {
    match (ptr.is_null(), len) {
        (_, 0) => Ok(&mut []),
        (true, _) => Err(format!("{what} is null with {len} entries")),
        // SAFETY: the caller's contract.
        (false, _) => Ok(unsafe { std::slice::from_raw_parts_mut(ptr, len) }),
    }
}

/// A host string, or `None` when null or not UTF-8.
///
/// # Safety
/// `s` must be null or a NUL-terminated string.
unsafe fn string(s: *const c_char) -> Option<String> {
    // SAFETY: the caller's contract.
    (!s.is_null()).then(|| unsafe { CStr::from_ptr(s) }.to_str().ok().map(str::to_string)).flatten()
}

/// Checks that `n` values go with `n` value references (all variables are scalars).
/// What a value reference of the FMU reads: time, a unit variable, or a
/// row of an array output.
enum Reference {
    Time,
    Variable(usize),
    Array(crate::ArrayOutput, usize),
}

/// Resolves `vr` against `inst`'s unit and array outputs.
fn reference(inst: &Instance, vr: ValueReference) -> Result<Reference, String> {
    let m = inst.unit.variables().len();
    let arrays = crate::array_outputs(inst.unit.simulation().model().particle_count());
    match vr as usize {
        0 => Ok(Reference::Time),
        k if k <= m => Ok(Reference::Variable(k - 1)),
        k => arrays
            .get(k - m - 1)
            .map(|a| Reference::Array(*a, k - m - 1))
            .ok_or_else(|| format!("no variable with value reference {vr} (the last is {})", m + arrays.len())),
    }
}

/// How many values `refs` hold (an array output its every element), and
/// that the host gave that many.
fn values_for(inst: &Instance, refs: &[ValueReference], n_values: usize) -> Result<(), String> {
    let mut count = 0;
    for &vr in refs {
        count += match reference(inst, vr)? {
            Reference::Array(a, _) => a.len(),
            _ => 1,
        };
    }
    if count == n_values { Ok(()) } else { Err(format!("{n_values} values for value references that hold {count}")) }
}

/// `fmi3GetVersion`: "3.0".
#[unsafe(no_mangle)]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    VERSION.as_ptr()
}

/// `fmi3SetDebugLogging`: debug messages (events) on or off; errors are
/// always logged.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: *mut c_void,
    logging_on: bool,
    _n_categories: usize,
    _categories: *const *const c_char,
) -> Status {
    call(instance, "fmi3SetDebugLogging", &ANY, |inst| {
        inst.logging_on = logging_on;
        Ok(Status::Ok)
    })
}

/// `fmi3InstantiateModelExchange`: not supported (null, with the reason logged).
///
/// # Safety
/// Pointers as FMI 3.0 defines them.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    _instance_name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    environment: *mut c_void,
    log: Option<LogMessage>,
) -> *mut c_void {
    let message = "fmi3InstantiateModelExchange: not supported: this FMU is co-simulation only";
    log_to(log, environment, Status::Error, "logStatusError", message);
    std::ptr::null_mut()
}

/// `fmi3InstantiateScheduledExecution`: not supported (null, with the reason logged).
///
/// # Safety
/// Pointers as FMI 3.0 defines them.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    _instance_name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    environment: *mut c_void,
    log: Option<LogMessage>,
    _clock_update: *const c_void,
    _lock_preemption: *const c_void,
    _unlock_preemption: *const c_void,
) -> *mut c_void {
    let message = "fmi3InstantiateScheduledExecution: not supported: this FMU is co-simulation only";
    log_to(log, environment, Status::Error, "logStatusError", message);
    std::ptr::null_mut()
}

/// `fmi3InstantiateCoSimulation`: builds the cloth from the scene under
/// `resource_path` (checked against `token`). Null, with the reason
/// logged, when it cannot, or when the host asks for event mode.
///
/// # Safety
/// Strings are null or NUL-terminated; `log` is null or a valid callback.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instance_name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    _visible: bool,
    logging_on: bool,
    event_mode_used: bool,
    _early_return_allowed: bool,
    _required_intermediate_variables: *const ValueReference,
    _n_required_intermediate_variables: usize,
    environment: *mut c_void,
    log: Option<LogMessage>,
    _intermediate_update: *const c_void,
) -> *mut c_void {
    let fail = |message: &str| {
        log_to(log, environment, Status::Error, "logStatusError", &format!("fmi3InstantiateCoSimulation: {message}"));
        std::ptr::null_mut()
    };
    // SAFETY: the host passes NUL-terminated strings or null.
    let (name, token, resources) = unsafe { (string(instance_name), string(token), string(resource_path)) };
    let Some(name) = name else { return fail("instanceName is null or not UTF-8") };
    let Some(token) = token else { return fail("instantiationToken is null or not UTF-8") };
    let Some(resources) = resources else { return fail("resourcePath is null or not UTF-8 (the scene is there)") };
    if event_mode_used {
        return fail("eventModeUsed: this FMU has no event mode (hasEventMode=\"false\")");
    }
    // FMI 3.0 passes a path; accept a file URI too, as FMI 2.0 hosts gave.
    let resources = PathBuf::from(resources.strip_prefix("file://").unwrap_or(&resources));
    let built =
        catch_unwind(AssertUnwindSafe(|| Instance::new(name, &token, &resources, environment, log, logging_on)));
    match built {
        Ok(Ok(inst)) => {
            inst.log(Status::Ok, "logEvents", &format!("instantiated from {}", resources.display()));
            crate::handles::register(inst)
        }
        Ok(Err((log, environment, message))) => {
            log_to(
                log,
                environment,
                Status::Error,
                "logStatusError",
                &format!("fmi3InstantiateCoSimulation: {message}"),
            );
            std::ptr::null_mut()
        }
        Err(_) => fail("internal error while building the cloth"),
    }
}

/// `fmi3FreeInstance`. Freeing a handle twice, or one this FMU never
/// gave, is refused and logged.
///
/// # Safety
/// None beyond the C API's: the handle is looked up, never dereferenced
/// unchecked.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3FreeInstance(instance: *mut c_void) {
    if !instance.is_null()
        && let Some(inst) = crate::handles::release(instance, "fmi3FreeInstance")
    {
        let _ = catch_unwind(AssertUnwindSafe(move || drop(inst)));
    }
}

/// `fmi3EnterInitializationMode`: `start_time` is the host's time at the
/// cloth's start; tolerance and stop time are not used.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: *mut c_void,
    _tolerance_defined: bool,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: bool,
    _stop_time: f64,
) -> Status {
    call(instance, "fmi3EnterInitializationMode", &[Phase::Instantiated], |inst| {
        if !start_time.is_finite() {
            return Err(format!("startTime = {start_time} must be finite"));
        }
        inst.start_time_s = start_time;
        inst.phase = Phase::Initialization;
        Ok(Status::Ok)
    })
}

/// `fmi3ExitInitializationMode`: to step mode.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: *mut c_void) -> Status {
    call(instance, "fmi3ExitInitializationMode", &[Phase::Initialization], |inst| {
        inst.phase = Phase::Step;
        Ok(Status::Ok)
    })
}

/// `fmi3EnterEventMode`: not supported (no event mode).
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3EnterEventMode(instance: *mut c_void) -> Status {
    unsupported(instance, "fmi3EnterEventMode", "this FMU has no event mode")
}

/// `fmi3Terminate`: from step mode only, as FMI 3.0's co-simulation
/// state machine has it (not from initialization mode).
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3Terminate(instance: *mut c_void) -> Status {
    call(instance, "fmi3Terminate", &[Phase::Step], |inst| {
        inst.phase = Phase::Terminated;
        Ok(Status::Ok)
    })
}

/// `fmi3Reset`: back to the cloth as instantiated.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3Reset(instance: *mut c_void) -> Status {
    call(instance, "fmi3Reset", &ANY, |inst| inst.reset().map(|()| Status::Ok))
}

/// Phases in which variables may be read.
const READABLE: [Phase; 3] = [Phase::Initialization, Phase::Step, Phase::Terminated];
/// Phases in which inputs may be set.
const WRITABLE: [Phase; 3] = [Phase::Instantiated, Phase::Initialization, Phase::Step];

/// `fmi3GetFloat64`: `time` (value reference 0) and the unit's variables.
///
/// # Safety
/// The arrays hold the lengths given.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: *mut c_void,
    value_references: *const ValueReference,
    n_value_references: usize,
    values: *mut f64,
    n_values: usize,
) -> Status {
    call(instance, "fmi3GetFloat64", &READABLE, |inst| {
        // SAFETY: the host's arrays, of the lengths it gave.
        let refs = unsafe { slice(value_references, n_value_references, "valueReferences")? };
        values_for(inst, refs, n_values)?;
        let out = unsafe { slice_mut(values, n_values, "values")? };
        let mut at = 0;
        for &vr in refs {
            match reference(inst, vr)? {
                Reference::Time => out[at] = inst.start_time_s + inst.unit.simulation().time(),
                Reference::Variable(k) => out[at] = inst.unit.get(k).map_err(|e| e.to_string())?,
                Reference::Array(a, which) => {
                    let state = inst.unit.simulation().state();
                    let rows = if which == 0 { &state.x } else { &state.v };
                    for (slot, row) in out[at..at + a.len()].chunks_exact_mut(3).zip(rows) {
                        slot.copy_from_slice(&[row.x, row.y, row.z]);
                    }
                    at += a.len() - 1;
                }
            }
            at += 1;
        }
        Ok(Status::Ok)
    })
}

/// `fmi3SetFloat64`: inputs (and, before stepping, their start values).
///
/// # Safety
/// The arrays hold the lengths given.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: *mut c_void,
    value_references: *const ValueReference,
    n_value_references: usize,
    values: *const f64,
    n_values: usize,
) -> Status {
    call(instance, "fmi3SetFloat64", &WRITABLE, |inst| {
        // SAFETY: the host's arrays, of the lengths it gave.
        let refs = unsafe { slice(value_references, n_value_references, "valueReferences")? };
        values_for(inst, refs, n_values)?;
        let given = unsafe { slice(values, n_values, "values")? };
        for (vr, value) in refs.iter().zip(given) {
            match reference(inst, *vr)? {
                Reference::Time => {
                    return Err("time (value reference 0) is the independent variable: it cannot be set".into());
                }
                Reference::Variable(k) => inst.unit.set(k, *value).map_err(|e| e.to_string())?,
                Reference::Array(a, _) => return Err(format!("{} is an output: it cannot be set", a.name)),
            }
        }
        Ok(Status::Ok)
    })
}

/// Getters and setters of the types this FMU has no variables of: fine
/// for no value references, `fmi3Error` for any.
macro_rules! no_variables_of {
    ($get:ident, $set:ident, $t:ty, $type_name:literal) => {
        #[doc = concat!("`", stringify!($get), "`: this FMU has no ", $type_name, " variables.")]
        ///
        /// # Safety
        /// `instance` is null or from `fmi3InstantiateCoSimulation`.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $get(
            instance: *mut c_void,
            _value_references: *const ValueReference,
            n_value_references: usize,
            _values: *mut $t,
            _n_values: usize,
        ) -> Status {
            no_such(instance, stringify!($get), n_value_references, $type_name, &READABLE)
        }

        #[doc = concat!("`", stringify!($set), "`: this FMU has no ", $type_name, " variables.")]
        ///
        /// # Safety
        /// `instance` is null or from `fmi3InstantiateCoSimulation`.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $set(
            instance: *mut c_void,
            _value_references: *const ValueReference,
            n_value_references: usize,
            _values: *const $t,
            _n_values: usize,
        ) -> Status {
            no_such(instance, stringify!($set), n_value_references, $type_name, &WRITABLE)
        }
    };
}

fn no_such(instance: *mut c_void, function: &str, n: usize, type_name: &str, allowed: &[Phase]) -> Status {
    call(instance, function, allowed, |_| {
        if n == 0 {
            Ok(Status::Ok)
        } else {
            Err(format!("this FMU has no {type_name} variables ({n} value references given)"))
        }
    })
}

no_variables_of!(fmi3GetFloat32, fmi3SetFloat32, f32, "Float32");
no_variables_of!(fmi3GetInt8, fmi3SetInt8, i8, "Int8");
no_variables_of!(fmi3GetUInt8, fmi3SetUInt8, u8, "UInt8");
no_variables_of!(fmi3GetInt16, fmi3SetInt16, i16, "Int16");
no_variables_of!(fmi3GetUInt16, fmi3SetUInt16, u16, "UInt16");
no_variables_of!(fmi3GetInt32, fmi3SetInt32, i32, "Int32");
no_variables_of!(fmi3GetUInt32, fmi3SetUInt32, u32, "UInt32");
no_variables_of!(fmi3GetInt64, fmi3SetInt64, i64, "Int64");
no_variables_of!(fmi3GetUInt64, fmi3SetUInt64, u64, "UInt64");
no_variables_of!(fmi3GetBoolean, fmi3SetBoolean, bool, "Boolean");
no_variables_of!(fmi3GetString, fmi3SetString, *const c_char, "String");

/// `fmi3GetBinary`: this FMU has no Binary variables.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetBinary(
    instance: *mut c_void,
    _value_references: *const ValueReference,
    n_value_references: usize,
    _value_sizes: *mut usize,
    _values: *mut *const u8,
    _n_values: usize,
) -> Status {
    no_such(instance, "fmi3GetBinary", n_value_references, "Binary", &READABLE)
}

/// `fmi3SetBinary`: this FMU has no Binary variables.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetBinary(
    instance: *mut c_void,
    _value_references: *const ValueReference,
    n_value_references: usize,
    _value_sizes: *const usize,
    _values: *const *const u8,
    _n_values: usize,
) -> Status {
    no_such(instance, "fmi3SetBinary", n_value_references, "Binary", &WRITABLE)
}

/// `fmi3GetClock`: this FMU has no clocks.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetClock(
    instance: *mut c_void,
    _value_references: *const ValueReference,
    n_value_references: usize,
    _values: *mut bool,
) -> Status {
    no_such(instance, "fmi3GetClock", n_value_references, "Clock", &READABLE)
}

/// `fmi3SetClock`: this FMU has no clocks.
///
/// # Safety
/// `instance` is null or from `fmi3InstantiateCoSimulation`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetClock(
    instance: *mut c_void,
    _value_references: *const ValueReference,
    n_value_references: usize,
    _values: *const bool,
) -> Status {
    no_such(instance, "fmi3SetClock", n_value_references, "Clock", &WRITABLE)
}

/// `fmi3GetFMUState`: a copy of the cloth's state (into `*state`, reusing
/// it when not null).
///
/// # Safety
/// `state` is a valid pointer to null or to a state handle (an unknown
/// or freed handle is refused).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3GetFMUState(instance: *mut c_void, state: *mut *mut c_void) -> Status {
    call(instance, "fmi3GetFMUState", &ANY, |inst| {
        if state.is_null() {
            return Err("FMUState is null".into());
        }
        // SAFETY: `state` is a valid pointer to the host's handle.
        unsafe { replace_state(state, inst.unit.get_state())? };
        Ok(Status::Ok)
    })
}

/// Puts `new` in the host's handle `*state`; a state already there is
/// overwritten (freed, the new one in its place), an unknown one refused.
///
/// # Safety
/// `state` is a valid, non-null pointer to the host's handle.
unsafe fn replace_state(state: *mut *mut c_void, new: cloth_cosim::UnitState) -> Result<(), String> {
    // SAFETY: the caller's contract.
    let previous = unsafe { *state };
    if !previous.is_null() {
        drop(crate::handles::release_state(previous)?);
    }
    // SAFETY: as above.
    unsafe { *state = crate::handles::register_state(new) };
    Ok(())
}

/// `fmi3SetFMUState`: the cloth back to a state got before.
///
/// # Safety
/// None beyond the C API's: state handles are looked up, an unknown or
/// freed one refused.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SetFMUState(instance: *mut c_void, state: *mut c_void) -> Status {
    call(instance, "fmi3SetFMUState", &ANY, |inst| {
        if state.is_null() {
            return Err("FMUState is null".into());
        }
        // SAFETY: a live state of the registry (freed only by `release_state`).
        let saved = unsafe { &*crate::handles::state(state)? };
        inst.unit.set_state(saved).map_err(|e| e.to_string())?;
        Ok(Status::Ok)
    })
}

/// `fmi3FreeFMUState`: frees `*state` and sets it to null.
///
/// # Safety
/// `state` is a valid pointer to null or to a state handle (an unknown
/// or freed handle is refused).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3FreeFMUState(instance: *mut c_void, state: *mut *mut c_void) -> Status {
    call(instance, "fmi3FreeFMUState", &ANY, |_| {
        if state.is_null() {
            return Err("FMUState is null".into());
        }
        // SAFETY: `state` is a valid pointer to the host's handle.
        let handle = unsafe { *state };
        if !handle.is_null() {
            drop(crate::handles::release_state(handle)?);
            // SAFETY: as above.
            unsafe { *state = std::ptr::null_mut() };
        }
        Ok(Status::Ok)
    })
}

/// The serialised bytes of `state`.
///
/// # Safety
/// None beyond the C API's: state handles are looked up, an unknown or
/// freed one refused.
unsafe fn serialized(inst: &Instance, state: *mut c_void) -> Result<Vec<u8>, String> {
    if state.is_null() {
        return Err("FMUState is null".into());
    }
    // SAFETY: a live state of the registry.
    let saved = unsafe { &*crate::handles::state(state)? };
    inst.unit.serialize_state(saved).map_err(|e| e.to_string())
}

/// `fmi3SerializedFMUStateSize`.
///
/// # Safety
/// `size` is writable (state handles are looked up).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: *mut c_void,
    state: *mut c_void,
    size: *mut usize,
) -> Status {
    call(instance, "fmi3SerializedFMUStateSize", &ANY, |inst| {
        // SAFETY: the caller's contract.
        let bytes = unsafe { serialized(inst, state)? };
        let size = unsafe { size.as_mut() }.ok_or("size is null")?;
        *size = bytes.len();
        Ok(Status::Ok)
    })
}

/// `fmi3SerializeFMUState`: into `serialized_state` of exactly the size
/// `fmi3SerializedFMUStateSize` gave.
///
/// # Safety
/// `serialized_state` holds `size` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: *mut c_void,
    state: *mut c_void,
    serialized_state: *mut u8,
    size: usize,
) -> Status {
    call(instance, "fmi3SerializeFMUState", &ANY, |inst| {
        // SAFETY: the caller's contract.
        let bytes = unsafe { serialized(inst, state)? };
        if bytes.len() != size {
            return Err(format!("size {size}: the state takes {} bytes (fmi3SerializedFMUStateSize)", bytes.len()));
        }
        unsafe { slice_mut(serialized_state, size, "serializedState")? }.copy_from_slice(&bytes);
        Ok(Status::Ok)
    })
}

/// `fmi3DeserializeFMUState`: a new state (into `*state`) from bytes.
///
/// # Safety
/// `serialized_state` holds `size` bytes; `state` is writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: *mut c_void,
    serialized_state: *const u8,
    size: usize,
    state: *mut *mut c_void,
) -> Status {
    call(instance, "fmi3DeserializeFMUState", &ANY, |inst| {
        // SAFETY: the caller's contract.
        let bytes = unsafe { slice(serialized_state, size, "serializedState")? };
        let restored = inst.unit.deserialize_state(bytes).map_err(|e| e.to_string())?;
        if state.is_null() {
            return Err("FMUState is null".into());
        }
        // SAFETY: `state` is a valid pointer to the host's handle.
        unsafe { replace_state(state, restored)? };
        Ok(Status::Ok)
    })
}

/// `fmi3DoStep`: one cloth step from `current` (the host's time, which
/// must be where the cloth is) over `step`. `fmi3Discard` when the cloth
/// cannot take it (it stays at `current`), never an early return.
///
/// # Safety
/// The out-pointers are null or writable.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn fmi3DoStep(
    instance: *mut c_void,
    current: f64,
    step: f64,
    _no_set_fmu_state_prior: bool,
    event_handling_needed: *mut bool,
    terminate_simulation: *mut bool,
    early_return: *mut bool,
    last_successful_time: *mut f64,
) -> Status {
    call(instance, "fmi3DoStep", &[Phase::Step], |inst| {
        if !(step.is_finite() && step > 0.0) {
            return Err(format!("communicationStepSize = {step} s must be finite and > 0"));
        }
        if !current.is_finite() {
            return Err(format!("currentCommunicationPoint = {current} s must be finite"));
        }
        // SAFETY: null or writable, as FMI 3.0 defines them.
        unsafe {
            for flag in [event_handling_needed, terminate_simulation, early_return] {
                if let Some(flag) = flag.as_mut() {
                    *flag = false;
                }
            }
        }
        let outcome = inst.unit.do_step(current - inst.start_time_s, step).map_err(|e| e.to_string())?;
        let (status, reached) = match outcome {
            StepOutcome::Completed => (Status::Ok, current + step),
            StepOutcome::Discarded { reason, .. } => {
                inst.log(Status::Discard, "logStatusDiscard", &format!("fmi3DoStep at t = {current} s: {reason}"));
                (Status::Discard, current)
            }
        };
        // SAFETY: null or writable.
        if let Some(t) = unsafe { last_successful_time.as_mut() } {
            *t = reached;
        }
        Ok(status)
    })
}

/// Functions of FMI 3.0 this FMU does not support: each returns
/// `fmi3Error` and logs why.
macro_rules! not_supported {
    ($( $name:ident ( $($arg:ident : $t:ty),* ) => $why:literal; )*) => {
        $(
            #[doc = concat!("`", stringify!($name), "`: not supported (", $why, ").")]
            ///
            /// # Safety
            /// `instance` is null or from `fmi3InstantiateCoSimulation`.
            #[unsafe(no_mangle)]
            pub unsafe extern "C" fn $name(instance: *mut c_void, $(_: $t),*) -> Status {
                unsupported(instance, stringify!($name), $why)
            }
        )*
    };
}

not_supported! {
    fmi3GetNumberOfVariableDependencies(vr: ValueReference, n: *mut usize) => "no dependency information";
    fmi3GetVariableDependencies(dependent: ValueReference, a: *mut usize, b: *mut ValueReference, c: *mut usize, d: *mut i32, n: usize) => "no dependency information";
    fmi3GetDirectionalDerivative(u: *const ValueReference, nu: usize, k: *const ValueReference, nk: usize, seed: *const f64, ns: usize, s: *mut f64, nsens: usize) => "no derivatives";
    fmi3GetAdjointDerivative(u: *const ValueReference, nu: usize, k: *const ValueReference, nk: usize, seed: *const f64, ns: usize, s: *mut f64, nsens: usize) => "no derivatives";
    fmi3EnterConfigurationMode() => "no structural parameters";
    fmi3ExitConfigurationMode() => "no structural parameters";
    fmi3GetIntervalDecimal(v: *const ValueReference, n: usize, i: *mut f64, q: *mut i32) => "no clocks";
    fmi3GetIntervalFraction(v: *const ValueReference, n: usize, c: *mut u64, r: *mut u64, q: *mut i32) => "no clocks";
    fmi3GetShiftDecimal(v: *const ValueReference, n: usize, s: *mut f64) => "no clocks";
    fmi3GetShiftFraction(v: *const ValueReference, n: usize, c: *mut u64, r: *mut u64) => "no clocks";
    fmi3SetIntervalDecimal(v: *const ValueReference, n: usize, i: *const f64) => "no clocks";
    fmi3SetIntervalFraction(v: *const ValueReference, n: usize, c: *const u64, r: *const u64) => "no clocks";
    fmi3SetShiftDecimal(v: *const ValueReference, n: usize, s: *const f64) => "no clocks";
    fmi3SetShiftFraction(v: *const ValueReference, n: usize, c: *const u64, r: *const u64) => "no clocks";
    fmi3EvaluateDiscreteStates() => "no event mode";
    fmi3UpdateDiscreteStates(a: *mut bool, b: *mut bool, c: *mut bool, d: *mut bool, e: *mut bool, t: *mut f64) => "no event mode";
    fmi3EnterContinuousTimeMode() => "co-simulation only, no model exchange";
    fmi3CompletedIntegratorStep(no_set: bool, a: *mut bool, b: *mut bool) => "co-simulation only, no model exchange";
    fmi3SetTime(t: f64) => "co-simulation only, no model exchange";
    fmi3SetContinuousStates(x: *const f64, n: usize) => "co-simulation only, no model exchange";
    fmi3GetContinuousStateDerivatives(x: *mut f64, n: usize) => "co-simulation only, no model exchange";
    fmi3GetEventIndicators(x: *mut f64, n: usize) => "co-simulation only, no model exchange";
    fmi3GetContinuousStates(x: *mut f64, n: usize) => "co-simulation only, no model exchange";
    fmi3GetNominalsOfContinuousStates(x: *mut f64, n: usize) => "co-simulation only, no model exchange";
    fmi3GetNumberOfEventIndicators(n: *mut usize) => "co-simulation only, no model exchange";
    fmi3GetNumberOfContinuousStates(n: *mut usize) => "co-simulation only, no model exchange";
    fmi3EnterStepMode() => "no event mode (step mode follows initialisation)";
    fmi3GetOutputDerivatives(v: *const ValueReference, n: usize, o: *const i32, x: *mut f64, nx: usize) => "no output derivatives";
    fmi3ActivateModelPartition(clock: ValueReference, t: f64) => "no scheduled execution";
}
