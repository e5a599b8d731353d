//! FMI 2.0 co-simulation calls on a loaded FMU binary.

use super::{Api, Binary, ERROR, Log, Opened, StateCalls, status};
use cloth_cosim::VarType;
use libloading::Library;
use std::ffi::{CStr, CString, c_char, c_void};

/// FMI 2.0's logger is variadic (printf arguments after the message);
/// stable Rust cannot define one, so it is taken with its five fixed
/// arguments, which the x86-64 System V convention passes alike either
/// way. The message is kept as the FMU formatted it, without its
/// arguments.
type Logger = unsafe extern "C" fn(*mut c_void, *const c_char, i32, *const c_char, *const c_char);

/// `fmi2CallbackFunctions`.
#[repr(C)]
struct Callbacks {
    logger: Option<Logger>,
    allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    step_finished: Option<unsafe extern "C" fn(*mut c_void, i32)>,
    component_environment: *mut c_void,
}

unsafe extern "C" {
    fn calloc(count: usize, size: usize) -> *mut c_void;
    fn free(pointer: *mut c_void);
}

unsafe extern "C" fn collect(
    env: *mut c_void,
    _name: *const c_char,
    _status: i32,
    _category: *const c_char,
    message: *const c_char,
) {
    // SAFETY: as FMI 3.0's logger: `env` is the unit's log, `message` a string.
    unsafe { super::collect(env, crate::api::Status::Ok, std::ptr::null(), message) }
}

type Instantiate =
    unsafe extern "C" fn(*const c_char, i32, *const c_char, *const c_char, *const Callbacks, i32, i32) -> *mut c_void;
type Setup = unsafe extern "C" fn(*mut c_void, i32, f64, f64, i32, f64) -> i32;
type Simple = unsafe extern "C" fn(*mut c_void) -> i32;
type Free = unsafe extern "C" fn(*mut c_void);
type Get<T> = unsafe extern "C" fn(*mut c_void, *const u32, usize, *mut T) -> i32;
type Set<T> = unsafe extern "C" fn(*mut c_void, *const u32, usize, *const T) -> i32;
type Derivatives = unsafe extern "C" fn(*mut c_void, *const u32, usize, *const i32, *const f64) -> i32;
type DoStep = unsafe extern "C" fn(*mut c_void, f64, f64, i32) -> i32;
type RealStatus = unsafe extern "C" fn(*mut c_void, i32, *mut f64) -> i32;

/// `fmi2CoSimulation`.
const CO_SIMULATION: i32 = 1;
/// `fmi2LastSuccessfulTime`.
const LAST_SUCCESSFUL_TIME: i32 = 2;

/// A live FMI 2.0 instance, its callbacks (which it may keep pointing to)
/// and the library it came from.
/// FMI 2.0's state functions.
const STATES: StateCalls = StateCalls {
    get: b"fmi2GetFMUstate\0",
    set: b"fmi2SetFMUstate\0",
    free: b"fmi2FreeFMUstate\0",
    size: b"fmi2SerializedFMUstateSize\0",
    serialize: b"fmi2SerializeFMUstate\0",
    deserialize: b"fmi2DeSerializeFMUstate\0",
};

pub(super) struct Fmi2 {
    b: Binary,
    _callbacks: Box<Callbacks>,
}

impl Fmi2 {
    /// Instantiates the co-simulation FMU in `library` as `name`, its
    /// messages going to `log`.
    pub(super) fn instantiate(library: Library, o: &Opened, log: &Log) -> Result<Self, String> {
        let c = |s: &str| CString::new(s).map_err(|_| format!("{s:?} holds a NUL"));
        let (name, guid) = (c(&o.name)?, c(&o.token)?);
        // FMI 2.0 takes the resources as a URI.
        let uri = c(&format!("file://{}/", o.resources.display()))?;
        let callbacks = Box::new(Callbacks {
            logger: Some(collect),
            allocate_memory: Some(calloc),
            free_memory: Some(free),
            step_finished: None,
            component_environment: log as *const Log as *mut c_void,
        });
        // SAFETY: the symbol has fmi2Instantiate's type; valid strings; the
        // callbacks and `log` outlive the instance (freed first).
        let instance = unsafe {
            let f: libloading::Symbol<Instantiate> =
                library.get(b"fmi2Instantiate\0").map_err(|e| format!("fmi2Instantiate: {e}"))?;
            f(name.as_ptr(), CO_SIMULATION, guid.as_ptr(), uri.as_ptr(), &*callbacks, 0, 0)
        };
        if instance.is_null() {
            return Err("fmi2Instantiate returned no instance".into());
        }
        Ok(Self { b: Binary { instance, library }, _callbacks: callbacks })
    }

    fn get_one<T: Copy + Default>(&self, symbol: &[u8], vr: u32) -> Result<T, i32> {
        let mut value = T::default();
        // SAFETY: a live instance, one value reference and one value.
        status(self.b.call(symbol, |f: Get<T>| unsafe { f(self.b.instance, &vr, 1, &mut value) }))?;
        Ok(value)
    }

    fn set_one<T: Copy>(&mut self, symbol: &[u8], vr: u32, value: T) -> i32 {
        // SAFETY: a live instance, one value reference and one value.
        self.b.call(symbol, |f: Set<T>| unsafe { f(self.b.instance, &vr, 1, &value) })
    }
}

impl Api for Fmi2 {
    fn initialize(&mut self) -> i32 {
        // SAFETY: a live instance, in the order FMI 2.0 prescribes.
        let codes = [
            self.b.call(b"fmi2SetupExperiment\0", |f: Setup| unsafe { f(self.b.instance, 0, 0.0, 0.0, 0, 0.0) }),
            self.b.call(b"fmi2EnterInitializationMode\0", |f: Simple| unsafe { f(self.b.instance) }),
        ];
        if let Some(&failed) = codes.iter().find(|&&c| status(c).is_err()) {
            return failed;
        }
        // SAFETY: a live instance.
        self.b.call(b"fmi2ExitInitializationMode\0", |f: Simple| unsafe { f(self.b.instance) })
    }

    fn get(&self, ty: VarType, vr: u32) -> Result<f64, i32> {
        match ty {
            VarType::Float64 => self.get_one::<f64>(b"fmi2GetReal\0", vr),
            VarType::Boolean => Ok(f64::from(u8::from(self.get_one::<i32>(b"fmi2GetBoolean\0", vr)? != 0))),
            VarType::Integer { .. } => Ok(f64::from(self.get_one::<i32>(b"fmi2GetInteger\0", vr)?)),
            VarType::Float32 => Err(ERROR), // FMI 2.0 has no such type
        }
    }

    fn set(&mut self, ty: VarType, vr: u32, value: f64) -> i32 {
        match ty {
            VarType::Float64 => self.set_one(b"fmi2SetReal\0", vr, value),
            VarType::Boolean => self.set_one(b"fmi2SetBoolean\0", vr, i32::from(value != 0.0)),
            // Whole and within Int32 (`VarType::refuses`): exact.
            VarType::Integer { .. } => self.set_one(b"fmi2SetInteger\0", vr, value as i32),
            VarType::Float32 => ERROR,
        }
    }

    fn get_string(&self, vr: u32) -> Result<String, i32> {
        let mut text: *const c_char = std::ptr::null();
        // SAFETY: a live instance, one value reference and one value.
        status(
            self.b.call(b"fmi2GetString\0", |f: Get<*const c_char>| unsafe { f(self.b.instance, &vr, 1, &mut text) }),
        )?;
        // SAFETY: the FMU hands a NUL-terminated string valid until its next call.
        Ok(if text.is_null() { String::new() } else { unsafe { CStr::from_ptr(text) }.to_string_lossy().into_owned() })
    }

    fn set_string(&mut self, vr: u32, value: &CStr) -> i32 {
        self.set_one(b"fmi2SetString\0", vr, value.as_ptr())
    }

    fn set_derivative(&mut self, vr: u32, du: f64) -> i32 {
        // SAFETY: a live instance, one first-order derivative.
        self.b.call(b"fmi2SetRealInputDerivatives\0", |f: Derivatives| unsafe { f(self.b.instance, &vr, 1, &1, &du) })
    }

    fn do_step(&mut self, t: f64, h: f64) -> (i32, f64) {
        // SAFETY: a live instance.
        let code = self.b.call(b"fmi2DoStep\0", |f: DoStep| unsafe { f(self.b.instance, t, h, 0) });
        let mut last = t;
        if code == 2 {
            // SAFETY: a live instance, one value.
            self.b.call(b"fmi2GetRealStatus\0", |f: RealStatus| unsafe {
                f(self.b.instance, LAST_SUCCESSFUL_TIME, &mut last)
            });
        }
        (code, last)
    }

    fn save(&self) -> Option<Vec<u8>> {
        self.b.save(&STATES)
    }

    fn restore(&mut self, bytes: &[u8]) -> i32 {
        self.b.restore(bytes, &STATES)
    }
}

impl Drop for Fmi2 {
    fn drop(&mut self) {
        // SAFETY: a live instance, terminated and freed once.
        unsafe {
            self.b.call(b"fmi2Terminate\0", |f: Simple| f(self.b.instance));
            self.b.call(b"fmi2FreeInstance\0", |f: Free| {
                f(self.b.instance);
                0
            });
        }
    }
}
