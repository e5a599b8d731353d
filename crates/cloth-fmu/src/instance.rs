//! One FMU instance: the cloth unit, where the host is in FMI's state
//! machine, and the host's logger.

use crate::package::{instantiation_token, read_resources, unit_from_scene};
use cloth_cosim::{ClothUnit, Unit, UnitState};
use std::ffi::{CString, c_char, c_void};
use std::path::Path;

/// FMI 3.0 status codes (`fmi3Status`).
#[repr(i32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// `fmi3OK`
    Ok = 0,
    /// `fmi3Warning`
    Warning = 1,
    /// `fmi3Discard`: the step could not be taken; the FMU is where it was.
    Discard = 2,
    /// `fmi3Error`: the call failed; the instance is still usable.
    Error = 3,
    /// `fmi3Fatal`
    Fatal = 4,
}

/// The host's `fmi3LogMessageCallback`.
pub type LogMessage = unsafe extern "C" fn(*mut c_void, Status, *const c_char, *const c_char);

/// Where the instance is in FMI 3.0's co-simulation state machine
/// (without event mode, which this FMU does not have).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// After instantiation or reset: inputs may be set.
    Instantiated,
    /// Between `fmi3EnterInitializationMode` and `fmi3ExitInitializationMode`.
    Initialization,
    /// Stepping.
    Step,
    /// After `fmi3Terminate`: outputs may still be read.
    Terminated,
}

/// An FMU instance.
pub struct Instance {
    environment: *mut c_void,
    log: Option<LogMessage>,
    /// Debug logging (events); errors are logged whatever it says.
    pub(crate) logging_on: bool,
    pub(crate) phase: Phase,
    pub(crate) unit: ClothUnit,
    /// The unit as instantiated, for `fmi3Reset`.
    initial: UnitState,
    /// The host's time at the cloth's time 0, s (`startTime`).
    pub(crate) start_time_s: f64,
}

impl Instance {
    /// Builds the cloth unit from the scene under `resources` and checks
    /// that it is the one `token` was made for.
    pub(crate) fn new(
        name: String,
        token: &str,
        resources: &Path,
        environment: *mut c_void,
        log: Option<LogMessage>,
        logging_on: bool,
    ) -> Result<Self, (Option<LogMessage>, *mut c_void, String)> {
        let fail = |message: String| (log, environment, message);
        let (scene, overrides) = read_resources(resources).map_err(|e| fail(e.to_string()))?;
        let expected = instantiation_token(&scene, &overrides);
        if token != expected {
            return Err(fail(format!(
                "instantiationToken {token:?} is not this FMU's {expected:?} (a modelDescription.xml from another build?)"
            )));
        }
        let unit =
            unit_from_scene(&resources.join(crate::SCENE_FILE), &overrides, &name).map_err(|e| fail(e.to_string()))?;
        let initial = unit.get_state();
        Ok(Self { environment, log, logging_on, phase: Phase::Instantiated, unit, initial, start_time_s: 0.0 })
    }

    /// Back to the state after instantiation (`fmi3Reset`).
    pub(crate) fn reset(&mut self) -> Result<(), String> {
        self.unit.set_state(&self.initial).map_err(|e| e.to_string())?;
        self.phase = Phase::Instantiated;
        self.start_time_s = 0.0;
        Ok(())
    }

    /// The host's logger and its environment.
    pub(crate) fn logger(&self) -> (Option<LogMessage>, *mut c_void) {
        (self.log, self.environment)
    }

    /// Logs `message` through the host's callback: always for errors and
    /// discards, for the rest only with debug logging on.
    pub(crate) fn log(&self, status: Status, category: &str, message: &str) {
        if status == Status::Ok && !self.logging_on {
            return;
        }
        log_to(self.log, self.environment, status, category, message);
    }
}

/// Calls the host's logger `log`, if any, with `message` (interior NULs
/// replaced, so the text is never cut silently).
pub(crate) fn log_to(log: Option<LogMessage>, environment: *mut c_void, status: Status, category: &str, message: &str) {
    let Some(log) = log else { return };
    let category = CString::new(category.replace('\0', " ")).unwrap_or_default();
    let message = CString::new(message.replace('\0', " ")).unwrap_or_default();
    // SAFETY: the host gave this callback for this environment; both
    // strings live until it returns.
    unsafe { log(environment, status, category.as_ptr(), message.as_ptr()) }
}
