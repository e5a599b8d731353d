//! FMI 3.0 co-simulation calls on a loaded FMU binary.

use super::{Api, Binary, ERROR, Log, Opened, StateCalls, collect, status};
use crate::api::LogMessage;
use cloth_cosim::VarType;
use libloading::Library;
use std::ffi::{CStr, CString, c_char, c_void};

type Instantiate = unsafe extern "C" fn(
    *const c_char,
    *const c_char,
    *const c_char,
    bool,
    bool,
    bool,
    bool,
    *const u32,
    usize,
    *mut c_void,
    Option<LogMessage>,
    *const c_void,
) -> *mut c_void;
type EnterInit = unsafe extern "C" fn(*mut c_void, bool, f64, f64, bool, f64) -> i32;
type Simple = unsafe extern "C" fn(*mut c_void) -> i32;
type Free = unsafe extern "C" fn(*mut c_void);
type Get<T> = unsafe extern "C" fn(*mut c_void, *const u32, usize, *mut T, usize) -> i32;
type Set<T> = unsafe extern "C" fn(*mut c_void, *const u32, usize, *const T, usize) -> i32;
type DoStep = unsafe extern "C" fn(*mut c_void, f64, f64, bool, *mut bool, *mut bool, *mut bool, *mut f64) -> i32;

/// A live FMI 3.0 instance and the library it came from.
/// FMI 3.0's state functions.
const STATES: StateCalls = StateCalls {
    get: b"fmi3GetFMUState\0",
    set: b"fmi3SetFMUState\0",
    free: b"fmi3FreeFMUState\0",
    size: b"fmi3SerializedFMUStateSize\0",
    serialize: b"fmi3SerializeFMUState\0",
    deserialize: b"fmi3DeserializeFMUState\0",
};

pub(super) struct Fmi3 {
    b: Binary,
}

impl Fmi3 {
    /// Instantiates the co-simulation FMU in `library` as `name`, its
    /// messages going to `log`.
    pub(super) fn instantiate(library: Library, o: &Opened, log: &Log) -> Result<Self, String> {
        let c = |s: &str| CString::new(s).map_err(|_| format!("{s:?} holds a NUL"));
        let (name, token, resources) = (c(&o.name)?, c(&o.token)?, c(&format!("{}/", o.resources.display()))?);
        // SAFETY: the symbol has fmi3InstantiateCoSimulation's type; valid
        // strings; `log` outlives the instance (its owner frees it first).
        let instance = unsafe {
            let f: libloading::Symbol<Instantiate> = library
                .get(b"fmi3InstantiateCoSimulation\0")
                .map_err(|e| format!("fmi3InstantiateCoSimulation: {e}"))?;
            f(
                name.as_ptr(),
                token.as_ptr(),
                resources.as_ptr(),
                false,
                false,
                false,
                false,
                std::ptr::null(),
                0,
                log as *const Log as *mut c_void,
                Some(collect),
                std::ptr::null(),
            )
        };
        if instance.is_null() {
            return Err("fmi3InstantiateCoSimulation returned no instance".into());
        }
        Ok(Self { b: Binary { instance, library } })
    }

    fn get_one<T: Copy + Default>(&self, symbol: &[u8], vr: u32) -> Result<T, i32> {
        let mut value = T::default();
        // SAFETY: a live instance, one value reference and one value.
        let code = self.b.call(symbol, |f: Get<T>| unsafe { f(self.b.instance, &vr, 1, &mut value, 1) });
        if code <= 1 { Ok(value) } else { Err(code) }
    }

    fn set_one<T: Copy>(&mut self, symbol: &[u8], vr: u32, value: T) -> i32 {
        // SAFETY: a live instance, one value reference and one value.
        self.b.call(symbol, |f: Set<T>| unsafe { f(self.b.instance, &vr, 1, &value, 1) })
    }
}

impl Api for Fmi3 {
    fn initialize(&mut self) -> i32 {
        // SAFETY: a live instance.
        let entered = self.b.call(b"fmi3EnterInitializationMode\0", |f: EnterInit| unsafe {
            f(self.b.instance, false, 0.0, 0.0, false, 0.0)
        });
        if status(entered).is_err() {
            return entered;
        }
        // SAFETY: a live instance.
        self.b.call(b"fmi3ExitInitializationMode\0", |f: Simple| unsafe { f(self.b.instance) })
    }

    fn get(&self, ty: VarType, vr: u32) -> Result<f64, i32> {
        Ok(match ty {
            VarType::Float64 => self.get_one::<f64>(b"fmi3GetFloat64\0", vr)?,
            VarType::Float32 => f64::from(self.get_one::<f32>(b"fmi3GetFloat32\0", vr)?),
            VarType::Boolean => f64::from(u8::from(self.get_one::<u8>(b"fmi3GetBoolean\0", vr)? != 0)),
            VarType::Integer { bits, signed } => match (bits, signed) {
                (8, true) => f64::from(self.get_one::<i8>(b"fmi3GetInt8\0", vr)?),
                (8, false) => f64::from(self.get_one::<u8>(b"fmi3GetUInt8\0", vr)?),
                (16, true) => f64::from(self.get_one::<i16>(b"fmi3GetInt16\0", vr)?),
                (16, false) => f64::from(self.get_one::<u16>(b"fmi3GetUInt16\0", vr)?),
                (32, true) => f64::from(self.get_one::<i32>(b"fmi3GetInt32\0", vr)?),
                (32, false) => f64::from(self.get_one::<u32>(b"fmi3GetUInt32\0", vr)?),
                (64, true) => self.get_one::<i64>(b"fmi3GetInt64\0", vr)? as f64,
                _ => self.get_one::<u64>(b"fmi3GetUInt64\0", vr)? as f64,
            },
        })
    }

    // The value passed `VarType::refuses`: whole and in range, so the casts are exact.
    fn set(&mut self, ty: VarType, vr: u32, value: f64) -> i32 {
        match ty {
            VarType::Float64 => self.set_one(b"fmi3SetFloat64\0", vr, value),
            VarType::Float32 => self.set_one(b"fmi3SetFloat32\0", vr, value as f32),
            VarType::Boolean => self.set_one(b"fmi3SetBoolean\0", vr, value != 0.0),
            VarType::Integer { bits, signed } => match (bits, signed) {
                (8, true) => self.set_one(b"fmi3SetInt8\0", vr, value as i8),
                (8, false) => self.set_one(b"fmi3SetUInt8\0", vr, value as u8),
                (16, true) => self.set_one(b"fmi3SetInt16\0", vr, value as i16),
                (16, false) => self.set_one(b"fmi3SetUInt16\0", vr, value as u16),
                (32, true) => self.set_one(b"fmi3SetInt32\0", vr, value as i32),
                (32, false) => self.set_one(b"fmi3SetUInt32\0", vr, value as u32),
                (64, true) => self.set_one(b"fmi3SetInt64\0", vr, value as i64),
                _ => self.set_one(b"fmi3SetUInt64\0", vr, value as u64),
            },
        }
    }

    fn get_string(&self, vr: u32) -> Result<String, i32> {
        let mut text: *const c_char = std::ptr::null();
        // SAFETY: a live instance, one value reference and one value.
        let code = self
            .b
            .call(b"fmi3GetString\0", |f: Get<*const c_char>| unsafe { f(self.b.instance, &vr, 1, &mut text, 1) });
        status(code)?;
        // SAFETY: the FMU hands a NUL-terminated string valid until its next call.
        Ok(if text.is_null() { String::new() } else { unsafe { CStr::from_ptr(text) }.to_string_lossy().into_owned() })
    }

    fn set_string(&mut self, vr: u32, value: &CStr) -> i32 {
        self.set_one(b"fmi3SetString\0", vr, value.as_ptr())
    }

    fn set_derivative(&mut self, _vr: u32, _du: f64) -> i32 {
        ERROR // FMI 3.0 co-simulation has no input derivatives.
    }

    fn do_step(&mut self, t: f64, h: f64) -> (i32, f64) {
        let (mut event, mut terminate, mut early, mut last) = (false, false, false, t);
        // SAFETY: a live instance, writable flags.
        let code = self.b.call(b"fmi3DoStep\0", |f: DoStep| unsafe {
            f(self.b.instance, t, h, false, &mut event, &mut terminate, &mut early, &mut last)
        });
        (code, last)
    }

    fn save(&self) -> Option<Vec<u8>> {
        self.b.save(&STATES)
    }

    fn restore(&mut self, bytes: &[u8]) -> i32 {
        self.b.restore(bytes, &STATES)
    }
}

impl Drop for Fmi3 {
    fn drop(&mut self) {
        // SAFETY: a live instance, terminated and freed once.
        unsafe {
            self.b.call(b"fmi3Terminate\0", |f: Simple| f(self.b.instance));
            self.b.call(b"fmi3FreeInstance\0", |f: Free| {
                f(self.b.instance);
                0
            });
        }
    }
}
