//! The FMI 3.0 C API called as a host calls it: the cloth it steps is the
//! cloth unit's, bit for bit; states round-trip; calls out of sequence
//! and bad arguments get `fmi3Error` and a logged message.
#![allow(unsafe_code)]

use cloth_cosim::{ClothUnit, Unit};
use cloth_fmu::api::*;
use cloth_fmu::{OVERRIDES_FILE, SCENE_FILE, instantiation_token};
use std::ffi::{CStr, CString, c_char, c_void};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The hang fixture, small, its pins driven from outside.
const OVERRIDES: [&str; 4] = [
    "panels.0.particles=[11, 11]",
    "pins.0.nodes=[[0, 10], [10, 10]]",
    "pins.0.motion={ kind = \"external\" }",
    "solver.rel_tol=1e-10",
];

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/hang.toml")
}

/// A resources directory as an FMU carries it.
fn resources(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cloth-fmu-api-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(fixture(), dir.join(SCENE_FILE)).unwrap();
    std::fs::write(dir.join(OVERRIDES_FILE), OVERRIDES.join("\n")).unwrap();
    dir
}

fn overrides() -> Vec<String> {
    OVERRIDES.iter().map(|s| s.to_string()).collect()
}

/// Messages the FMU logged, per test (the environment pointer says which).
static LOGS: Mutex<Vec<(usize, Status, String)>> = Mutex::new(Vec::new());

unsafe extern "C" fn logger(env: *mut c_void, status: Status, _category: *const c_char, message: *const c_char) {
    let text = unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned();
    LOGS.lock().unwrap().push((env as usize, status, text));
}

fn logged(env: usize) -> Vec<String> {
    LOGS.lock().unwrap().iter().filter(|(e, _, _)| *e == env).map(|(_, _, m)| m.clone()).collect()
}

fn instantiate(dir: &Path, token: &str, env: usize) -> *mut c_void {
    let name = CString::new("cloth").unwrap();
    let token = CString::new(token).unwrap();
    let path = CString::new(format!("{}/", dir.display())).unwrap();
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
            env as *mut c_void,
            Some(logger),
            std::ptr::null(),
        )
    }
}

fn token() -> String {
    instantiation_token(&std::fs::read_to_string(fixture()).unwrap(), &overrides())
}

/// An instance in step mode.
fn stepping(name: &str, env: usize) -> *mut c_void {
    let fmu = instantiate(&resources(name), &token(), env);
    assert!(!fmu.is_null(), "{:?}", logged(env));
    unsafe {
        assert_eq!(fmi3EnterInitializationMode(fmu, false, 0.0, 0.0, false, 0.0), Status::Ok);
        assert_eq!(fmi3ExitInitializationMode(fmu), Status::Ok);
    }
    fmu
}

fn get(fmu: *mut c_void, vrs: &[u32]) -> Vec<f64> {
    let mut out = vec![f64::NAN; vrs.len()];
    assert_eq!(unsafe { fmi3GetFloat64(fmu, vrs.as_ptr(), vrs.len(), out.as_mut_ptr(), out.len()) }, Status::Ok);
    out
}

fn step(fmu: *mut c_void, t: f64, h: f64) -> Status {
    let mut last = f64::NAN;
    let (mut event, mut terminate, mut early) = (true, true, true);
    let status = unsafe { fmi3DoStep(fmu, t, h, false, &mut event, &mut terminate, &mut early, &mut last) };
    if status == Status::Ok {
        assert!(!event && !terminate && !early);
        assert_eq!(last, t + h);
    }
    status
}

/// The cloth unit of the same scene, stepped directly.
fn reference() -> ClothUnit {
    cloth_fmu::package::unit_from_scene(&fixture(), &overrides(), "cloth").unwrap()
}

#[test]
fn steps_are_the_cloth_units_bit_for_bit() {
    let fmu = stepping("bits", 1);
    let mut unit = reference();
    let h = 1.0 / 90.0;
    let all: Vec<u32> = (1..=unit.variables().len() as u32).collect();
    // Move the first pin 1 cm/step along x from outside.
    let pin_x = unit.find("pin0.target.x").unwrap();
    let start = unit.get(pin_x).unwrap();
    for n in 0..10 {
        let target = start + 0.01 * (n + 1) as f64;
        let vr = pin_x as u32 + 1;
        assert_eq!(unsafe { fmi3SetFloat64(fmu, &vr, 1, &target, 1) }, Status::Ok);
        unit.set(pin_x, target).unwrap();
        assert_eq!(step(fmu, n as f64 * h, h), Status::Ok);
        unit.do_step(n as f64 * h, h).unwrap();
        let expected: Vec<f64> = (0..all.len()).map(|k| unit.get(k).unwrap()).collect();
        assert_eq!(
            get(fmu, &all).iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            expected.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
    // time is value reference 0.
    assert!((get(fmu, &[0])[0] - 10.0 * h).abs() < 1e-12);
    // The array outputs after the variables: every particle's position and
    // velocity, a row each, in one call with a scalar.
    let (m, state) = (all.len() as u32, unit.simulation().state());
    let n = state.x.len();
    let refs = [m + 1, 0, m + 2];
    let mut values = vec![0.0; 6 * n + 1];
    assert_eq!(unsafe { fmi3GetFloat64(fmu, refs.as_ptr(), 3, values.as_mut_ptr(), values.len()) }, Status::Ok);
    let rows =
        |a: &[cloth_core::Vec3]| -> Vec<u64> { a.iter().flat_map(|p| [p.x, p.y, p.z]).map(f64::to_bits).collect() };
    assert_eq!(values[..3 * n].iter().map(|x| x.to_bits()).collect::<Vec<_>>(), rows(&state.x));
    assert_eq!(values[3 * n + 1..].iter().map(|x| x.to_bits()).collect::<Vec<_>>(), rows(&state.v));
    // Too few values for them, or setting one, is refused and said why.
    assert_eq!(unsafe { fmi3GetFloat64(fmu, refs.as_ptr(), 3, values.as_mut_ptr(), 3) }, Status::Error);
    assert!(
        logged(1).iter().any(|msg| msg.contains(&format!("3 values for value references that hold {}", 6 * n + 1)))
    );
    assert_eq!(unsafe { fmi3SetFloat64(fmu, &(m + 1), 1, values.as_ptr(), 3 * n) }, Status::Error);
    assert!(logged(1).iter().any(|msg| msg.contains("positions is an output")));
    unsafe { fmi3FreeInstance(fmu) };
}

#[test]
fn states_restore_and_serialise_exactly() {
    let fmu = stepping("states", 2);
    let h = 1.0 / 90.0;
    let all: Vec<u32> = (0..=reference().variables().len() as u32).collect();
    for n in 0..3 {
        assert_eq!(step(fmu, n as f64 * h, h), Status::Ok);
    }
    let mut state: *mut c_void = std::ptr::null_mut();
    unsafe { assert_eq!(fmi3GetFMUState(fmu, &mut state), Status::Ok) };
    let mut size = 0usize;
    unsafe { assert_eq!(fmi3SerializedFMUStateSize(fmu, state, &mut size), Status::Ok) };
    let mut bytes = vec![0u8; size];
    unsafe { assert_eq!(fmi3SerializeFMUState(fmu, state, bytes.as_mut_ptr(), size), Status::Ok) };
    for n in 3..6 {
        assert_eq!(step(fmu, n as f64 * h, h), Status::Ok);
    }
    let first = get(fmu, &all);
    // Back to the saved state and the same steps: the same outputs.
    unsafe { assert_eq!(fmi3SetFMUState(fmu, state), Status::Ok) };
    for n in 3..6 {
        assert_eq!(step(fmu, n as f64 * h, h), Status::Ok);
    }
    assert_eq!(get(fmu, &all), first);
    // Through the bytes: the same again.
    let mut restored: *mut c_void = std::ptr::null_mut();
    unsafe { assert_eq!(fmi3DeserializeFMUState(fmu, bytes.as_ptr(), size, &mut restored), Status::Ok) };
    unsafe { assert_eq!(fmi3SetFMUState(fmu, restored), Status::Ok) };
    for n in 3..6 {
        assert_eq!(step(fmu, n as f64 * h, h), Status::Ok);
    }
    assert_eq!(get(fmu, &all), first);
    // Truncated bytes are refused, and said why.
    let mut bad: *mut c_void = std::ptr::null_mut();
    unsafe { assert_eq!(fmi3DeserializeFMUState(fmu, bytes.as_ptr(), size - 8, &mut bad), Status::Error) };
    assert!(bad.is_null());
    assert!(logged(2).iter().any(|m| m.contains("fmi3DeserializeFMUState") && m.contains("not a serialised state")));
    unsafe {
        assert_eq!(fmi3FreeFMUState(fmu, &mut state), Status::Ok);
        assert_eq!(fmi3FreeFMUState(fmu, &mut restored), Status::Ok);
        assert!(state.is_null() && restored.is_null());
        // Reset: back to the start, stepping again from t = 0.
        assert_eq!(fmi3Reset(fmu), Status::Ok);
        assert_eq!(fmi3EnterInitializationMode(fmu, false, 0.0, 0.0, false, 0.0), Status::Ok);
        assert_eq!(fmi3ExitInitializationMode(fmu), Status::Ok);
    }
    for n in 0..6 {
        assert_eq!(step(fmu, n as f64 * h, h), Status::Ok);
    }
    assert_eq!(get(fmu, &all), first);
    unsafe { fmi3FreeInstance(fmu) };
}

#[test]
fn calls_out_of_sequence_and_bad_arguments_are_errors_that_say_why() {
    let env = 3;
    let dir = resources("sequence");
    // Another build's model description.
    assert!(instantiate(&dir, "{not-this-one}", env).is_null());
    assert!(logged(env).iter().any(|m| m.contains("instantiationToken")));
    let fmu = instantiate(&dir, &token(), env);
    assert!(!fmu.is_null());
    let vr = 1u32;
    let mut value = 0.0;
    unsafe {
        // A get before initialisation, a step before step mode.
        assert_eq!(fmi3GetFloat64(fmu, &vr, 1, &mut value, 1), Status::Error);
        assert_eq!(step(fmu, 0.0, 0.01), Status::Error);
        assert_eq!(fmi3EnterInitializationMode(fmu, false, 0.0, 0.0, false, 0.0), Status::Ok);
        assert_eq!(fmi3ExitInitializationMode(fmu), Status::Ok);
    }
    // A negative step, a step from the wrong time, setting an output, time, counts that disagree.
    assert_eq!(step(fmu, 0.0, -0.01), Status::Error);
    assert_eq!(step(fmu, 1.0, 0.01), Status::Error);
    // pin0.reaction.x: after the 12 pin inputs (a target and a rate per pin, value references 1-12)
    let output = 13u32;
    unsafe {
        assert_eq!(fmi3SetFloat64(fmu, &output, 1, &value, 1), Status::Error);
        assert_eq!(fmi3SetFloat64(fmu, &0, 1, &value, 1), Status::Error);
        assert_eq!(fmi3GetFloat64(fmu, &vr, 1, &mut value, 2), Status::Error);
        assert_eq!(fmi3GetFloat64(fmu, &999, 1, &mut value, 1), Status::Error);
        assert_eq!(fmi3GetFloat64(fmu, std::ptr::null(), 1, &mut value, 1), Status::Error);
        assert_eq!(fmi3GetInt32(fmu, &vr, 1, std::ptr::null_mut(), 1), Status::Error);
        assert_eq!(fmi3GetInt32(fmu, std::ptr::null(), 0, std::ptr::null_mut(), 0), Status::Ok);
        assert_eq!(fmi3EnterEventMode(fmu), Status::Error);
        assert_eq!(fmi3GetDirectionalDerivative(fmu, &vr, 1, &vr, 1, &value, 1, &mut value, 1), Status::Error);
    }
    let said = logged(env);
    for expected in [
        "fmi3GetFloat64 is not allowed in Instantiated mode",
        "fmi3DoStep is not allowed in Instantiated mode",
        "communicationStepSize = -0.01 s must be finite and > 0",
        "the cloth is at t = 0 s",
        "pin0.reaction.x",
        "time (value reference 0) is the independent variable",
        "2 values for value references that hold 1",
        "no variable with value reference 999",
        "valueReferences is null with 1 entries",
        "this FMU has no Int32 variables",
        "fmi3EnterEventMode: not supported",
        "fmi3GetDirectionalDerivative: not supported",
    ] {
        assert!(said.iter().any(|m| m.contains(expected)), "nothing logged with {expected:?}: {said:#?}");
    }
    // The instance still steps after all that.
    assert_eq!(step(fmu, 0.0, 0.01), Status::Ok);
    unsafe {
        assert_eq!(fmi3Terminate(fmu), Status::Ok);
        assert_eq!(fmi3GetFloat64(fmu, &vr, 1, &mut value, 1), Status::Ok);
        fmi3FreeInstance(fmu);
        // No instance at all.
        assert_eq!(fmi3GetFloat64(std::ptr::null_mut(), &vr, 1, &mut value, 1), Status::Error);
        assert_eq!(
            fmi3DoStep(
                std::ptr::null_mut(),
                0.0,
                0.01,
                false,
                std::ptr::null_mut(),
                std::ptr::null_mut(),
                std::ptr::null_mut(),
                std::ptr::null_mut()
            ),
            Status::Error
        );
    }
    assert_eq!(unsafe { CStr::from_ptr(fmi3GetVersion()) }.to_str(), Ok("3.0"));
}

/// What an independent FMI check found: a double free, a call after
/// free, a pin target of 1e308 (its square overflows), `fmi3Terminate` in
/// Initialization Mode and a serialised state with one byte changed. Each
/// is refused with `fmi3Error` and said why; none is undefined behaviour.
#[test]
fn unsafe_calls_and_inputs_are_refused_and_said_why() {
    let env = 5;
    let fmu = instantiate(&resources("safety"), &token(), env);
    assert!(!fmu.is_null());
    let pin_x = 1u32; // pin0.target.x
    unsafe {
        // Terminate is for step mode, not initialization mode.
        assert_eq!(fmi3EnterInitializationMode(fmu, false, 0.0, 0.0, false, 0.0), Status::Ok);
        assert_eq!(fmi3Terminate(fmu), Status::Error);
        for huge in [1e308, -1e300, f64::INFINITY] {
            assert_eq!(fmi3SetFloat64(fmu, &pin_x, 1, &huge, 1), Status::Error, "{huge}");
        }
        assert_eq!(fmi3SetFloat64(fmu, &pin_x, 1, &0.25, 1), Status::Ok);
        assert_eq!(fmi3ExitInitializationMode(fmu), Status::Ok);
    }
    assert_eq!(step(fmu, 0.0, 0.01), Status::Ok);
    // A serialised state with any one byte changed is refused.
    let mut state: *mut c_void = std::ptr::null_mut();
    let mut size = 0usize;
    unsafe {
        assert_eq!(fmi3GetFMUState(fmu, &mut state), Status::Ok);
        assert_eq!(fmi3SerializedFMUStateSize(fmu, state, &mut size), Status::Ok);
    }
    let mut bytes = vec![0u8; size];
    unsafe { assert_eq!(fmi3SerializeFMUState(fmu, state, bytes.as_mut_ptr(), size), Status::Ok) };
    for k in [0, 9, size / 2, size - 1] {
        let mut corrupted = bytes.clone();
        corrupted[k] ^= 0x10;
        let mut restored: *mut c_void = std::ptr::null_mut();
        let status = unsafe { fmi3DeserializeFMUState(fmu, corrupted.as_ptr(), size, &mut restored) };
        assert_eq!(status, Status::Error, "byte {k} changed");
        assert!(restored.is_null());
    }
    unsafe {
        assert_eq!(fmi3FreeFMUState(fmu, &mut state), Status::Ok);
        assert_eq!(fmi3Terminate(fmu), Status::Ok);
        fmi3FreeInstance(fmu);
        // Freed twice, then called: refused through the instance's logger.
        fmi3FreeInstance(fmu);
        let mut value = 0.0;
        assert_eq!(fmi3GetFloat64(fmu, &pin_x, 1, &mut value, 1), Status::Error);
        assert_eq!(step(fmu, 0.01, 0.01), Status::Error);
        // A handle this FMU never gave.
        assert_eq!(fmi3Reset(0xdead_bee0 as *mut c_void), Status::Error);
    }
    let said = logged(env);
    for expected in [
        "fmi3Terminate is not allowed in Initialization mode",
        "pin0.target.x",
        "within +-1e150",
        "checksum does not match",
        "fmi3FreeInstance: instance",
        "was freed already",
        "fmi3GetFloat64: instance",
        "fmi3DoStep: instance",
    ] {
        assert!(said.iter().any(|m| m.contains(expected)), "nothing logged with {expected:?}: {said:#?}");
    }
}

/// The FMU takes a communication step longer than its scene's 1/90 s as
/// substeps: stepped at 1/30 s and at 0.1 s, the cloth's lowest point and
/// largest stretch at t = 0.3 s are those of the 1/90 s run (the pins
/// held; measured equal to the bit; the reactions are means over each
/// step, so they differ by
/// step: `cloth-cosim`'s `substeps_make_the_motion_independent_of_the_macro_step`
/// checks their mean).
#[test]
fn any_macro_step_gives_the_same_cloth_at_common_times() {
    let unit = reference();
    let shape: Vec<u32> =
        ["lowest_z", "max_stretch"].iter().map(|n| unit.find(n).unwrap() as u32 + 1).chain([0]).collect();
    let outputs = |h: f64, env: usize| {
        let fmu = stepping(&format!("macro-{env}"), env);
        let steps = (0.3 / h).round() as usize;
        for n in 0..steps {
            assert_eq!(step(fmu, n as f64 * h, h), Status::Ok, "h = {h}");
        }
        let values = get(fmu, &shape);
        unsafe { fmi3FreeInstance(fmu) };
        values
    };
    let fine = outputs(1.0 / 90.0, 6);
    for (h, env) in [(1.0 / 30.0, 7), (0.1, 8)] {
        let coarse = outputs(h, env);
        let worst = fine.iter().zip(&coarse).map(|(a, b)| (a - b).abs() / a.abs().max(1e-3)).fold(0.0, f64::max);
        println!("h = {h}: lowest point, stretch and time within {worst:.1e} of the 1/90 s run at t = 0.3 s");
        assert!(worst < 1e-12, "h = {h}: {worst}");
    }
}
