//! The instances and FMU states the host holds, by handle. A handle is an
//! opaque number, never reused, that every call looks up before it
//! touches an instance or a state: a handle already freed (a double free,
//! a call after free) or never given is refused and logged, never
//! dereferenced.

use crate::instance::{Instance, LogMessage, Status, log_to};
use cloth_cosim::UnitState;
use std::collections::BTreeMap;
use std::ffi::c_void;
use std::sync::Mutex;

/// The first handle given; handles step by 16 from there (they look like
/// aligned pointers to a host that prints them, and are never null).
const FIRST: usize = 0x00c1_0000;

struct Registry {
    next: usize,
    /// Live handles and their instances (`Box::into_raw`, as addresses).
    live: BTreeMap<usize, usize>,
    /// Freed handles and the logger each was made with (callback and
    /// environment), to say so through it.
    freed: BTreeMap<usize, (Option<LogMessage>, usize)>,
    /// Live FMU states (`Box::into_raw`, as addresses).
    states: BTreeMap<usize, usize>,
}

static REGISTRY: Mutex<Registry> =
    Mutex::new(Registry { next: FIRST, live: BTreeMap::new(), freed: BTreeMap::new(), states: BTreeMap::new() });

fn registry() -> std::sync::MutexGuard<'static, Registry> {
    // A panic elsewhere never leaves the maps half-written: keep going.
    REGISTRY.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Registry {
    /// A handle never given before.
    fn new_handle(&mut self) -> usize {
        let handle = self.next;
        self.next += 16;
        handle
    }
}

/// Takes `instance` into the registry; its handle for the host.
pub(crate) fn register(instance: Instance) -> *mut c_void {
    let address = Box::into_raw(Box::new(instance)) as usize;
    let mut r = registry();
    let handle = r.new_handle();
    r.live.insert(handle, address);
    handle as *mut c_void
}

/// The instance behind a live `handle`; `None` (and the refusal logged)
/// when it was freed or never given.
pub(crate) fn lookup(handle: *mut c_void, function: &str) -> Option<*mut Instance> {
    let r = registry();
    match r.live.get(&(handle as usize)) {
        Some(&address) => Some(address as *mut Instance),
        None => {
            refuse(&r, handle, function);
            None
        }
    }
}

/// Takes a live `handle`'s instance out of the registry, for freeing; the
/// handle is remembered as freed. `None` (and the refusal logged) as
/// [`lookup`].
pub(crate) fn release(handle: *mut c_void, function: &str) -> Option<Box<Instance>> {
    let mut r = registry();
    let Some(address) = r.live.remove(&(handle as usize)) else {
        refuse(&r, handle, function);
        return None;
    };
    // SAFETY: registered by `register` from `Box::into_raw`, and removed
    // from `live` just now, so never taken twice.
    let instance = unsafe { Box::from_raw(address as *mut Instance) };
    let (log, environment) = instance.logger();
    r.freed.insert(handle as usize, (log, environment as usize));
    Some(instance)
}

/// Says why `handle` is refused: through the logger it was made with if
/// it was freed, else on standard error (no logger is known for it).
fn refuse(r: &Registry, handle: *mut c_void, function: &str) {
    let h = handle as usize;
    match r.freed.get(&h) {
        Some(&(log, environment)) => {
            let message = format!("{function}: instance {h:#x} was freed already (fmi3FreeInstance); call refused");
            log_to(log, environment as *mut c_void, Status::Error, "logStatusError", &message);
        }
        None => eprintln!("cloth_fmu: {function}: {h:#x} is not an instance of this FMU; call refused"),
    }
}

/// Takes an FMU state into the registry; its handle for the host.
pub(crate) fn register_state(state: UnitState) -> *mut c_void {
    let address = Box::into_raw(Box::new(state)) as usize;
    let mut r = registry();
    let handle = r.new_handle();
    r.states.insert(handle, address);
    handle as *mut c_void
}

/// The FMU state behind a live state handle.
pub(crate) fn state(handle: *mut c_void) -> Result<*const UnitState, String> {
    let r = registry();
    r.states.get(&(handle as usize)).map(|&a| a as *const UnitState).ok_or_else(|| {
        format!("FMUState {:#x} is not a live state of this FMU (freed, or never given)", handle as usize)
    })
}

/// Takes a live state handle's state out of the registry, to free it.
pub(crate) fn release_state(handle: *mut c_void) -> Result<Box<UnitState>, String> {
    let mut r = registry();
    let address = r.states.remove(&(handle as usize)).ok_or_else(|| {
        format!("FMUState {:#x} is not a live state of this FMU (freed already, or never given)", handle as usize)
    })?;
    // SAFETY: registered by `register_state` from `Box::into_raw`, removed
    // just now, so taken once.
    Ok(unsafe { Box::from_raw(address as *mut UnitState) })
}
