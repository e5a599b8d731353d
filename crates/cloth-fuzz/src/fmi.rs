//! Call sequences on the FMU's C API as a target: each three bytes are one
//! call (which, a value reference or a pick, a value), in any mode and
//! order, with handles live, freed, unknown or null. The host's side of
//! the contract is kept (buffers as long as the counts say); everything
//! else is fair. A panic caught inside the FMU is logged as an "internal
//! error", which this target reports as the defect it is.
#![allow(unsafe_code)]

use cloth_fmu::api::*;
use cloth_fmu::{OVERRIDES_FILE, SCENE_FILE, instantiation_token};
use std::ffi::{CStr, CString, c_char, c_void};
use std::path::PathBuf;
use std::sync::{Mutex, OnceLock};

/// The hang fixture, 11 x 11, its pins driven from outside.
const OVERRIDES: [&str; 3] =
    ["panels.0.particles=[11, 11]", "pins.0.nodes=[[0, 10], [10, 10]]", "pins.0.motion={ kind = \"external\" }"];

/// Messages logged as internal errors (panics the FMU caught).
static INTERNAL: Mutex<Vec<String>> = Mutex::new(Vec::new());

unsafe extern "C" fn logger(_env: *mut c_void, _status: Status, _category: *const c_char, message: *const c_char) {
    // SAFETY: the FMU passes a NUL-terminated message.
    let text = unsafe { CStr::from_ptr(message) }.to_string_lossy();
    if text.contains("internal error") {
        INTERNAL.lock().unwrap_or_else(|e| e.into_inner()).push(text.into_owned());
    }
}

/// The resources directory (made once per process) and the token.
fn resources() -> &'static (PathBuf, CString, CString) {
    static DIR: OnceLock<(PathBuf, CString, CString)> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("cloth-fuzz-fmi-{}", std::process::id()));
        let scene = crate::repository().join("fixtures/scenes/hang.toml");
        let text = std::fs::read_to_string(&scene).expect("fixtures/scenes/hang.toml");
        std::fs::create_dir_all(&dir).expect("a temporary directory");
        std::fs::write(dir.join(SCENE_FILE), &text).expect("a temporary directory");
        std::fs::write(dir.join(OVERRIDES_FILE), OVERRIDES.join("\n")).expect("a temporary directory");
        let overrides: Vec<String> = OVERRIDES.iter().map(|s| s.to_string()).collect();
        let token = CString::new(instantiation_token(&text, &overrides)).expect("no NUL");
        let path = CString::new(format!("{}/", dir.display())).expect("no NUL");
        (dir, token, path)
    })
}

fn instantiate(wrong_token: bool) -> *mut c_void {
    let (_, token, path) = resources();
    let name = c"cloth";
    let token = if wrong_token { c"{00000000-0000-0000-0000-000000000000}" } else { token.as_c_str() };
    // SAFETY: every pointer is a NUL-terminated string or null, as FMI 3.0 asks.
    unsafe {
        fmi3InstantiateCoSimulation(
            name.as_ptr(),
            token.as_ptr(),
            path.as_ptr(),
            false,
            false,
            false,
            false,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            Some(logger),
            std::ptr::null(),
        )
    }
}

/// A value for a setter: ordinary, at the edges, or not finite.
fn value(b: u8) -> f64 {
    match b % 10 {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => 1e308,
        3 => -1e300,
        4 => 0.0,
        5 => 5e-324,
        _ => (b as f64 - 160.0) / 32.0,
    }
}

pub(crate) fn calls(data: &[u8]) -> String {
    INTERNAL.lock().unwrap_or_else(|e| e.into_inner()).clear();
    let mut fmu = instantiate(false);
    let mut freed: Vec<*mut c_void> = Vec::new();
    let mut states: Vec<*mut c_void> = Vec::new();
    let mut t = 0.0;
    let mut statuses = [0usize; 5];
    let bad = 0xbad0 as *mut c_void;
    let pick = |k: u8, list: &[*mut c_void], other: *mut c_void| {
        list.get(k as usize % (list.len() + 1)).copied().unwrap_or(other)
    };
    for call in data.chunks(3) {
        let [op, a, v] = [call[0], *call.get(1).unwrap_or(&0), *call.get(2).unwrap_or(&0)];
        let vr = a as u32 % 80;
        let status = unsafe {
            match op % 18 {
                0 => {
                    let start = if a.is_multiple_of(5) { value(v) } else { 0.0 };
                    fmi3EnterInitializationMode(
                        fmu,
                        a.is_multiple_of(2),
                        value(v),
                        start,
                        a.is_multiple_of(3),
                        value(v),
                    )
                }
                1 => fmi3ExitInitializationMode(fmu),
                2 => fmi3SetFloat64(fmu, &vr, 1, &value(v), 1),
                3 => {
                    // Several references, the values' count right or not.
                    let refs: Vec<u32> = (0..1 + a % 4).map(|k| (vr + k as u32 * 7) % 80).collect();
                    let mut out = vec![0.0; refs.len() + (v % 3) as usize * 64];
                    fmi3GetFloat64(fmu, refs.as_ptr(), refs.len(), out.as_mut_ptr(), out.len())
                }
                4 | 5 => {
                    let h = [1.0 / 90.0, 0.05, -0.01, 0.0, 1e300, f64::NAN, 0.4][v as usize % 7];
                    let current = if a.is_multiple_of(5) { t + 1.0 } else { t };
                    let mut last = f64::NAN;
                    let (mut e, mut s, mut r) = (false, false, false);
                    let status = fmi3DoStep(fmu, current, h, false, &mut e, &mut s, &mut r, &mut last);
                    if status == Status::Ok || status == Status::Discard {
                        t = last;
                    }
                    status
                }
                6 => fmi3Terminate(fmu),
                7 => {
                    t = 0.0;
                    fmi3Reset(fmu)
                }
                8 => {
                    let mut s =
                        if a.is_multiple_of(4) { pick(v, &states, std::ptr::null_mut()) } else { std::ptr::null_mut() };
                    let status = fmi3GetFMUState(fmu, &mut s);
                    if !s.is_null() && !states.contains(&s) {
                        states.push(s);
                    }
                    status
                }
                9 => {
                    fmi3SetFMUState(fmu, pick(v, &states, if a.is_multiple_of(2) { bad } else { std::ptr::null_mut() }))
                }
                10 => {
                    // Freed states stay listed: later calls use them after free.
                    let mut s = pick(v, &states, bad);
                    fmi3FreeFMUState(fmu, &mut s)
                }
                11 => {
                    let s = pick(v, &states, bad);
                    let mut size = 0usize;
                    let status = fmi3SerializedFMUStateSize(fmu, s, &mut size);
                    if status != Status::Ok {
                        status
                    } else {
                        let mut bytes = vec![0u8; size];
                        let claimed = if a.is_multiple_of(6) { size.saturating_sub(1) } else { size };
                        fmi3SerializeFMUState(fmu, s, bytes.as_mut_ptr(), claimed);
                        if a.is_multiple_of(3) && size > 0 {
                            bytes[v as usize % size] ^= 1 << (a % 8);
                        }
                        let cut = if a.is_multiple_of(7) { size / 2 } else { size };
                        let mut back = std::ptr::null_mut();
                        let status = fmi3DeserializeFMUState(fmu, bytes.as_ptr(), cut, &mut back);
                        if !back.is_null() {
                            states.push(back);
                        }
                        status
                    }
                }
                12 => {
                    // Free the instance, or a freed or unknown one, and go on with a new one.
                    let victim = match a % 3 {
                        0 => pick(v, &freed, bad),
                        _ => fmu,
                    };
                    fmi3FreeInstance(victim);
                    if victim == fmu {
                        freed.push(fmu);
                        fmu = instantiate(v.is_multiple_of(9));
                        t = 0.0;
                    }
                    Status::Ok
                }
                13 => {
                    let mut out = 0.0;
                    fmi3GetFloat64(pick(v, &freed, bad), &vr, 1, &mut out, 1)
                }
                14 => {
                    let mut out = [0i32; 2];
                    let n = (v % 3) as usize;
                    fmi3GetInt32(fmu, [vr, vr + 1].as_ptr(), n, out.as_mut_ptr(), n)
                }
                15 => fmi3EnterEventMode(fmu),
                16 => {
                    let name = if a.is_multiple_of(2) { c"logStatusError" } else { c"nonsense" };
                    let categories = [name.as_ptr()];
                    fmi3SetDebugLogging(fmu, v.is_multiple_of(2), (a % 3) as usize % 2, categories.as_ptr())
                }
                _ => {
                    let mut sizes = [0usize; 1];
                    let mut values = [std::ptr::null::<u8>(); 1];
                    fmi3GetBinary(fmu, &vr, (v % 2) as usize, sizes.as_mut_ptr(), values.as_mut_ptr(), 1)
                }
            }
        };
        if let Some(count) = statuses.get_mut(status as usize) {
            *count += 1;
        }
    }
    unsafe {
        for s in &states {
            let mut s = *s;
            fmi3FreeFMUState(fmu, &mut s);
        }
        fmi3FreeInstance(fmu);
    }
    let internal = std::mem::take(&mut *INTERNAL.lock().unwrap_or_else(|e| e.into_inner()));
    if let Some(first) = internal.first() {
        panic!("the FMU caught a panic: {first}");
    }
    let seen: Vec<&str> = ["ok", "warning", "discard", "error", "fatal"]
        .iter()
        .zip(statuses)
        .filter(|(_, n)| *n > 0)
        .map(|(s, _)| *s)
        .collect();
    seen.join(" ")
}
