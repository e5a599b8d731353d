//! The thread pools simulations step in.
//!
//! A step makes many short parallel calls (each CG iteration's products).
//! Made from Python's thread, each would hand its work to rayon's pool and
//! wait on a lock: on a 25 x 25 cloth the handoffs took ten times the
//! work. Stepping inside a pool (`ThreadPool::install`) keeps the calls on
//! its threads. Pools are shared by thread count within a process and made
//! anew in a forked child (the parent's threads are not in it).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::{ThreadPool, ThreadPoolBuilder};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

/// Pools by requested thread count (0: rayon's default, which reads
/// `RAYON_NUM_THREADS`), with the process they were made in.
static POOLS: OnceLock<Mutex<Pools>> = OnceLock::new();

/// The process id the pools were made in, and the pools by thread count.
type Pools = (u32, HashMap<usize, Arc<ThreadPool>>);

/// The pool of `threads` threads (`None`: rayon's default count).
pub(crate) fn pool(threads: Option<usize>) -> PyResult<Arc<ThreadPool>> {
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads = 0: give at least 1, or None for the default"));
    }
    let key = threads.unwrap_or(0);
    let pools = POOLS.get_or_init(|| Mutex::new((std::process::id(), HashMap::new())));
    // A poisoned lock only means a panic elsewhere while it was held; the map is still whole.
    let mut guard = pools.lock().unwrap_or_else(|e| e.into_inner());
    let (pid, map) = &mut *guard;
    if *pid != std::process::id() {
        // A forked child: the pools' threads stayed in the parent.
        map.drain().for_each(std::mem::forget);
        *pid = std::process::id();
    }
    if let Some(p) = map.get(&key) {
        return Ok(p.clone());
    }
    let mut builder = ThreadPoolBuilder::new().thread_name(|i| format!("cloth-{i}"));
    if let Some(n) = threads {
        builder = builder.num_threads(n);
    }
    let pool = Arc::new(builder.build().map_err(|e| PyValueError::new_err(format!("thread pool: {e}")))?);
    map.insert(key, pool.clone());
    Ok(pool)
}
