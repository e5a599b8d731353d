//! `cloth live SCENE`: the simulation runs in the server, paced to real
//! time, and the viewer page shows it as it computes; the page sets the
//! wind (scenes whose wind is `profile = { kind = "external" }`) and holds
//! the cloth where the mouse drags it. Cloth-only scenes and scenes with
//! rapier bodies or a rig alike (the bodies are drawn where they are).
//!
//! Requests (127.0.0.1 only, one thread per connection): `/` the page,
//! `/run.json` the cloth's triangles and solids, `/live.json` the latest
//! state (positions, time, achieved rate, wind, solid poses),
//! `/wind?x=..&y=..&z=..` the air velocity from now on (m/s, finite,
//! at most 100 m/s), `/hold?particle=i&x=..&y=..&z=..` holds free
//! particle `i` at that point (m) until `/release?particle=i` (or
//! `/release`: every held particle) lets it go.

use crate::run::{CouplingTotals, Runner, solid_meshes_json, solid_poses};
use crate::view::{read_request, respond};
use anyhow::{Context, Result, bail};
use cloth_core::WindProfile;
use cloth_core::{ControlError, Simulation, Vec3};
use std::io::Write;
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Fastest wind the page may set, m/s.
const MAX_WIND_M_S: f64 = 100.0;

/// What the simulation thread publishes and the page reads.
struct Shared {
    /// Positions, m (x, y, z per particle).
    positions: Vec<f64>,
    time_s: f64,
    steps: u64,
    /// Simulated time over wall time since the start.
    rate: f64,
    /// The air velocity the last step used, m/s.
    wind_applied: [f64; 3],
    /// The air velocity the page asked for, m/s.
    wind_requested: [f64; 3],
    /// Solid poses `[x, y, z, qw, qx, qy, qz]`.
    poses: Vec<[f64; 7]>,
    /// The particles the page holds and where, m, sorted by particle.
    holds_requested: Vec<(usize, [f64; 3])>,
    /// The holds the last step used: particle, target (m) and the pull
    /// the cloth exerts on the hand (N).
    holds_applied: Vec<(usize, [f64; 3], [f64; 3])>,
    /// Why the simulation stopped, if it did.
    error: Option<String>,
    /// The page paused the run (it then steps only on `/step`).
    paused: bool,
    /// Steps the page asked for while paused, not yet taken.
    steps_requested: u64,
    /// The page asked to go back to the start.
    reset_requested: bool,
}

/// How `cloth live` runs.
#[derive(Clone, Copy, Debug)]
pub struct LiveArgs {
    /// Port on 127.0.0.1 (0: any free one).
    pub port: u16,
    /// Stop after this many wall-clock seconds (`None`: until stopped).
    pub seconds: Option<f64>,
    /// Worker threads of the simulation.
    pub threads: usize,
    /// Start paused at the scene's first state.
    pub paused: bool,
}

/// Runs `scene` live and serves it on 127.0.0.1:`args.port`.
pub fn live(scene: &Path, overrides: &[String], args: &LiveArgs) -> Result<()> {
    let LiveArgs { port, seconds, threads, paused } = *args;
    let (_, cfg, runner) = Runner::load(scene, overrides)?;
    let sim = runner.sim();
    let external_wind = sim.model().wind().is_some_and(|w| w.profile == WindProfile::External);
    let run_json = serde_json::to_string(&serde_json::json!({
        "live": true,
        "scene": scene.display().to_string(),
        "dt_s": cfg.dt_s,
        "wind_control": external_wind,
        "pinned": (0..sim.model().particle_count()).filter(|&i| sim.model().is_pinned(i)).collect::<Vec<_>>(),
        "triangles": sim.model().triangles().iter().flatten().collect::<Vec<_>>(),
        "solids": solid_meshes_json(sim.model()),
    }))?;
    let shared = Arc::new(Mutex::new(Shared {
        positions: flat(sim),
        time_s: 0.0,
        steps: 0,
        rate: 0.0,
        wind_applied: [0.0; 3],
        wind_requested: [0.0; 3],
        poses: solid_poses(sim),
        holds_requested: Vec::new(),
        holds_applied: Vec::new(),
        error: None,
        paused,
        steps_requested: 0,
        reset_requested: false,
    }));
    // Read by every connection's thread, never changed.
    let pinned: Arc<[bool]> = (0..sim.model().particle_count()).map(|i| sim.model().is_pinned(i)).collect();
    let run_json: Arc<str> = run_json.into();
    let listener = TcpListener::bind(("127.0.0.1", port)).with_context(|| format!("binding 127.0.0.1:{port}"))?;
    let address = listener.local_addr()?;
    println!("running {} live at http://{address}/", scene.display());
    std::io::stdout().flush()?;
    let deadline = seconds.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build()?;
    {
        let shared = Arc::clone(&shared);
        let h = cfg.dt_s;
        std::thread::spawn(move || pool.install(|| simulate(runner, h, external_wind, &shared)));
    }
    listener.set_nonblocking(true)?;
    loop {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            // A run that stopped on an error ends the command with it.
            return match shared.lock().ok().and_then(|s| s.error.clone()) {
                Some(error) => bail!("{}: the run stopped at {error}", scene.display()),
                None => Ok(()),
            };
        }
        match listener.accept() {
            Ok((stream, _)) => {
                let (shared, run_json, pinned) = (Arc::clone(&shared), Arc::clone(&run_json), Arc::clone(&pinned));
                std::thread::spawn(move || {
                    if let Err(e) = serve(stream, &shared, &run_json, external_wind, &pinned) {
                        eprintln!("request failed: {e}");
                    }
                });
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => std::thread::sleep(Duration::from_millis(5)),
            Err(e) => return Err(e.into()),
        }
    }
}

fn flat(sim: &Simulation) -> Vec<f64> {
    sim.state().x.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

/// Steps `sim` by `h` for ever, never ahead of the wall clock, publishing
/// each state; paused, it steps only when the page asks, and a reset puts
/// it back at its start (the page's holds let go). Stops at the first step
/// error (published).
fn simulate(mut runner: Runner, h: f64, external_wind: bool, shared: &Mutex<Shared>) {
    let initial = runner.snapshot();
    // The wall-clock instant of simulated time 0, moved on by pauses.
    let mut start = Instant::now();
    let mut coupling = CouplingTotals::default();
    let mut was_paused = false;
    loop {
        let Ok(mut s) = shared.lock() else { return };
        if was_paused && !s.paused {
            // Resumed: real time goes on from where the run is.
            start = Instant::now() - Duration::from_secs_f64(runner.sim().time());
        }
        was_paused = s.paused;
        if std::mem::take(&mut s.reset_requested) {
            if let Err(e) = runner.restore(&initial) {
                return stop(&mut s, runner.sim().time(), format!("reset: {e}"));
            }
            s.holds_requested.clear();
            publish(&mut s, &runner, &[], 0.0);
            start = Instant::now();
            continue;
        }
        if s.paused {
            if s.steps_requested == 0 {
                drop(s);
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
            s.steps_requested -= 1;
        }
        let (paused, wind, holds) = (s.paused, s.wind_requested, s.holds_requested.clone());
        drop(s);
        if let Err(e) = apply_inputs(runner.sim_mut(), external_wind.then_some(wind), &holds) {
            if let Ok(mut s) = shared.lock() {
                stop(&mut s, runner.sim().time(), e);
            }
            return;
        }
        let result = runner.step(h, &mut coupling);
        let sim = runner.sim();
        let wall = start.elapsed().as_secs_f64();
        let Ok(mut s) = shared.lock() else { return };
        if let Err(e) = result {
            return stop(&mut s, sim.time(), e);
        }
        publish(&mut s, &runner, &holds, sim.time() / wall.max(1e-9));
        s.wind_applied = if external_wind { wind } else { [0.0; 3] };
        drop(s);
        // Real time at most: wait until the wall clock reaches the cloth.
        let ahead = sim.time() - start.elapsed().as_secs_f64();
        if ahead > 0.0 && !paused {
            std::thread::sleep(Duration::from_secs_f64(ahead));
        }
    }
}

/// Ends the run at simulated time `t_s` for `why`: said on stderr, and
/// published for the page (which shows its last state) and its inputs.
fn stop(s: &mut Shared, t_s: f64, why: impl std::fmt::Display) {
    let message = format!("t = {t_s:.4} s: {why}");
    eprintln!("the run stopped at {message}; the page shows its last state");
    s.error = Some(message);
}

/// Publishes the run's state (positions, time, solids, holds) for the page;
/// the wind it stepped with is the caller's to set.
fn publish(s: &mut Shared, runner: &Runner, holds: &[(usize, [f64; 3])], rate: f64) {
    let sim = runner.sim();
    s.positions = flat(sim);
    (s.time_s, s.steps, s.rate) = (sim.time(), sim.state().steps, rate);
    s.poses = solid_poses(sim);
    s.holds_applied =
        holds.iter().map(|&(i, target)| (i, target, sim.hold_reaction(i).unwrap_or_default().into())).collect();
}

/// Sets the page's wind (when the scene's is external) and makes the held
/// particles exactly `holds`.
fn apply_inputs(sim: &mut Simulation, wind: Option<[f64; 3]>, holds: &[(usize, [f64; 3])]) -> Result<(), ControlError> {
    if let Some(wind) = wind {
        sim.set_wind(Vec3::from(wind))?;
    }
    let gone: Vec<usize> =
        sim.control().holds().iter().map(|h| h.0).filter(|i| !holds.iter().any(|h| h.0 == *i)).collect();
    for i in gone {
        sim.let_go(i);
    }
    holds.iter().try_for_each(|&(i, target)| sim.hold(i, Vec3::from(target)))
}

/// The numbers of a query `key=value&...`, each key one of `keys` (at
/// most once; a missing one is 0), finite.
fn parse_numbers<const N: usize>(query: &str, keys: [&str; N]) -> Result<[f64; N], String> {
    let mut values = [0.0; N];
    let mut seen = [false; N];
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (key, value) = pair.split_once('=').ok_or_else(|| format!("{pair}: expected key=value"))?;
        let k = keys.iter().position(|a| *a == key).ok_or_else(|| format!("{key}: expected one of {keys:?}"))?;
        if std::mem::replace(&mut seen[k], true) {
            return Err(format!("{key}: given twice"));
        }
        let v: f64 = value.parse().map_err(|_| format!("{key} = {value}: not a number"))?;
        if !v.is_finite() {
            return Err(format!("{key} = {value}: must be finite"));
        }
        values[k] = v;
    }
    Ok(values)
}

/// The particle index of a query's `particle=i`, which must be a free
/// particle of the model (`pinned` per particle).
fn parse_particle(value: f64, pinned: &[bool]) -> Result<usize, (&'static str, String)> {
    let bad = "400 Bad Request";
    if value.fract() != 0.0 || value < 0.0 || value >= pinned.len() as f64 {
        return Err((bad, format!("particle = {value}: expected 0 to {}", pinned.len().saturating_sub(1))));
    }
    let i = value as usize;
    if pinned[i] {
        return Err(("409 Conflict", format!("particle {i} is pinned by the scene")));
    }
    Ok(i)
}

/// The wind a `/wind?x=..&y=..&z=..` query asks for.
fn parse_wind(query: &str) -> Result<[f64; 3], String> {
    let wind = parse_numbers(query, ["x", "y", "z"])?;
    let speed = Vec3::from(wind).norm();
    if speed > MAX_WIND_M_S {
        return Err(format!("{speed} m/s: at most {MAX_WIND_M_S} m/s"));
    }
    Ok(wind)
}

/// Farthest from the origin the page may hold a particle, m.
const MAX_HOLD_M: f64 = 1e3;

/// The hold a `/hold?particle=i&x=..&y=..&z=..` query asks for.
fn parse_hold(query: &str, pinned: &[bool]) -> Result<(usize, [f64; 3]), (&'static str, String)> {
    let bad = "400 Bad Request";
    if !query.split('&').any(|p| p.starts_with("particle=")) {
        return Err((bad, "particle: missing".into()));
    }
    let [particle, x, y, z] = parse_numbers(query, ["particle", "x", "y", "z"]).map_err(|e| (bad, e))?;
    if Vec3::new(x, y, z).norm() > MAX_HOLD_M {
        return Err((bad, format!("[{x}, {y}, {z}]: at most {MAX_HOLD_M} m from the origin")));
    }
    Ok((parse_particle(particle, pinned)?, [x, y, z]))
}

fn serve(
    mut stream: TcpStream,
    shared: &Mutex<Shared>,
    run_json: &str,
    external_wind: bool,
    pinned: &[bool],
) -> std::io::Result<()> {
    let lock = || shared.lock().map_err(|_| std::io::Error::other("simulation thread panicked"));
    let Some((method, target)) = read_request(&mut stream)? else {
        return respond(&mut stream, "400 Bad Request", "text/plain", b"bad request\n");
    };
    if method != "GET" {
        return respond(&mut stream, "405 Method Not Allowed", "text/plain", b"GET only\n");
    }
    let (path, query) = target.split_once('?').unwrap_or((&target, ""));
    match path {
        "/" | "/index.html" => respond(&mut stream, "200 OK", "text/html; charset=utf-8", crate::view::PAGE.as_bytes()),
        "/run.json" => respond(&mut stream, "200 OK", "application/json", run_json.as_bytes()),
        "/live.json" => {
            let body = {
                let s = lock()?;
                let holds: Vec<_> = s
                    .holds_applied
                    .iter()
                    .map(|(i, t, f)| serde_json::json!({ "particle": i, "target_m": t, "pull_n": f }))
                    .collect();
                serde_json::json!({
                    "time_s": s.time_s,
                    "steps": s.steps,
                    "rate": s.rate,
                    "wind_m_s": s.wind_applied,
                    "positions": s.positions,
                    "poses": s.poses,
                    "holds": holds,
                    "error": s.error,
                    "paused": s.paused,
                })
                .to_string()
            };
            respond(&mut stream, "200 OK", "application/json", body.as_bytes())
        }
        "/wind" | "/hold" | "/release" | "/pause" | "/resume" | "/step" | "/reset"
            if let Some(error) = lock()?.error.clone() =>
        {
            // Inputs to a run that has stopped change nothing: say so.
            let body = format!("the run stopped at {error}\n");
            respond(&mut stream, "409 Conflict", "text/plain", body.as_bytes())
        }
        "/wind" if !external_wind => respond(
            &mut stream,
            "409 Conflict",
            "text/plain",
            b"this scene's wind is not external: run with --set 'wind.profile={ kind = \"external\" }'\n",
        ),
        "/wind" => match parse_wind(query) {
            Ok(wind) => {
                if let Ok(mut s) = shared.lock() {
                    s.wind_requested = wind;
                }
                respond(
                    &mut stream,
                    "200 OK",
                    "application/json",
                    serde_json::json!({ "wind_m_s": wind }).to_string().as_bytes(),
                )
            }
            Err(e) => respond(&mut stream, "400 Bad Request", "text/plain", format!("{e}\n").as_bytes()),
        },
        "/hold" => match parse_hold(query, pinned) {
            Ok((i, target)) => {
                let mut s = lock()?;
                match s.holds_requested.binary_search_by_key(&i, |h| h.0) {
                    Ok(k) => s.holds_requested[k].1 = target,
                    Err(k) => s.holds_requested.insert(k, (i, target)),
                }
                drop(s);
                let body = serde_json::json!({ "particle": i, "target_m": target }).to_string();
                respond(&mut stream, "200 OK", "application/json", body.as_bytes())
            }
            Err((status, e)) => respond(&mut stream, status, "text/plain", format!("{e}\n").as_bytes()),
        },
        "/release" => {
            let which = match parse_numbers(query, ["particle"]) {
                Ok(_) if query.is_empty() => None,
                Ok([p]) => Some(p),
                Err(e) => return respond(&mut stream, "400 Bad Request", "text/plain", format!("{e}\n").as_bytes()),
            };
            let mut s = lock()?;
            let before = s.holds_requested.len();
            s.holds_requested.retain(|h| which.is_some_and(|p| h.0 as f64 != p));
            let released = before - s.holds_requested.len();
            drop(s);
            let body = serde_json::json!({ "released": released }).to_string();
            respond(&mut stream, "200 OK", "application/json", body.as_bytes())
        }
        "/pause" | "/resume" | "/step" | "/reset" => {
            let mut s = lock()?;
            match path {
                "/pause" => s.paused = true,
                "/resume" => (s.paused, s.steps_requested) = (false, 0),
                "/step" if !s.paused => {
                    drop(s);
                    return respond(&mut stream, "409 Conflict", "text/plain", b"running: pause first\n");
                }
                "/step" => s.steps_requested += 1,
                _ => s.reset_requested = true,
            }
            let body = serde_json::json!({ "paused": s.paused, "steps_requested": s.steps_requested }).to_string();
            drop(s);
            respond(&mut stream, "200 OK", "application/json", body.as_bytes())
        }
        _ => respond(&mut stream, "404 Not Found", "text/plain", b"not found\n"),
    }
}
