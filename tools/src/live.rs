//! `cloth live SCENE`: the simulation runs in the server, paced to real
//! time, and the viewer page shows it as it computes; the page sets the
//! wind (scenes whose wind is `profile = { kind = "external" }`).
//!
//! Requests (127.0.0.1 only, one thread per connection): `/` the page,
//! `/run.json` the cloth's triangles and solids, `/live.json` the latest
//! state (positions, time, achieved rate, wind, solid poses),
//! `/wind?x=..&y=..&z=..` the air velocity from now on (m/s, finite,
//! at most 100 m/s).

use crate::run::{solid_meshes_json, solid_poses};
use crate::view::{read_request, respond};
use anyhow::{Context, Result, bail};
use cloth_core::scene::{Scene, SceneError};
use cloth_core::wind::WindProfile;
use cloth_core::{Simulation, Vec3};
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
    /// Why the simulation stopped, if it did.
    error: Option<String>,
}

/// Runs `scene` live and serves it on 127.0.0.1:`port`.
pub fn live(scene: &Path, overrides: &[String], port: u16, seconds: Option<f64>, threads: usize) -> Result<()> {
    let text = std::fs::read_to_string(scene).with_context(|| format!("reading {}", scene.display()))?;
    if cloth_rapier::scene::has_bodies(&text) {
        bail!("{}: cloth live runs cloth-only scenes so far (no [[bodies]] or [rig])", scene.display());
    }
    let parsed = Scene::parse_file(scene, overrides)?;
    let (model, cfg) = parsed.build().map_err(|kind| SceneError { file: scene.into(), kind })?;
    let external_wind = model.wind().is_some_and(|w| w.profile == WindProfile::External);
    let sim = cfg.simulation(model);
    let run_json = serde_json::to_string(&serde_json::json!({
        "live": true,
        "scene": scene.display().to_string(),
        "dt_s": cfg.dt_s,
        "wind_control": external_wind,
        "triangles": sim.model().triangles().iter().flatten().collect::<Vec<_>>(),
        "solids": solid_meshes_json(sim.model()),
    }))?;
    let shared = Arc::new(Mutex::new(Shared {
        positions: flat(&sim),
        time_s: 0.0,
        steps: 0,
        rate: 0.0,
        wind_applied: [0.0; 3],
        wind_requested: [0.0; 3],
        poses: solid_poses(&sim),
        error: None,
    }));
    let listener = TcpListener::bind(("127.0.0.1", port)).with_context(|| format!("binding 127.0.0.1:{port}"))?;
    let address = listener.local_addr()?;
    println!("running {} live at http://{address}/", scene.display());
    std::io::stdout().flush()?;
    let deadline = seconds.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build()?;
    {
        let shared = Arc::clone(&shared);
        let h = cfg.dt_s;
        std::thread::spawn(move || pool.install(|| simulate(sim, h, external_wind, &shared)));
    }
    listener.set_nonblocking(true)?;
    loop {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            return Ok(());
        }
        match listener.accept() {
            Ok((stream, _)) => {
                let (shared, run_json) = (Arc::clone(&shared), run_json.clone());
                std::thread::spawn(move || {
                    if let Err(e) = serve(stream, &shared, &run_json, external_wind) {
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
/// each state; stops at the first step error (published).
fn simulate(mut sim: Simulation, h: f64, external_wind: bool, shared: &Mutex<Shared>) {
    let start = Instant::now();
    loop {
        let wind = shared.lock().map(|s| s.wind_requested).unwrap_or([0.0; 3]);
        if external_wind && let Err(e) = sim.set_wind(Vec3::from(wind)) {
            if let Ok(mut s) = shared.lock() {
                s.error = Some(e.to_string());
            }
            return;
        }
        let result = sim.step(h);
        let wall = start.elapsed().as_secs_f64();
        let Ok(mut s) = shared.lock() else { return };
        if let Err(e) = result {
            s.error = Some(format!("t = {:.4} s: {e}", sim.time()));
            return;
        }
        s.positions = flat(&sim);
        (s.time_s, s.steps, s.rate) = (sim.time(), sim.state().steps, sim.time() / wall.max(1e-9));
        s.wind_applied = if external_wind { wind } else { [0.0; 3] };
        s.poses = solid_poses(&sim);
        drop(s);
        // Real time at most: wait until the wall clock reaches the cloth.
        let ahead = sim.time() - start.elapsed().as_secs_f64();
        if ahead > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(ahead));
        }
    }
}

/// The wind a `/wind?x=..&y=..&z=..` query asks for.
fn parse_wind(query: &str) -> Result<[f64; 3], String> {
    let mut wind = [0.0; 3];
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (key, value) = pair.split_once('=').ok_or_else(|| format!("{pair}: expected key=value"))?;
        let axis =
            ["x", "y", "z"].iter().position(|a| *a == key).ok_or_else(|| format!("{key}: expected x, y or z"))?;
        let v: f64 = value.parse().map_err(|_| format!("{key} = {value}: not a number"))?;
        if !v.is_finite() {
            return Err(format!("{key} = {value}: must be finite"));
        }
        wind[axis] = v;
    }
    let speed = Vec3::from(wind).norm();
    if speed > MAX_WIND_M_S {
        return Err(format!("{speed} m/s: at most {MAX_WIND_M_S} m/s"));
    }
    Ok(wind)
}

fn serve(mut stream: TcpStream, shared: &Mutex<Shared>, run_json: &str, external_wind: bool) -> std::io::Result<()> {
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
                let s = shared.lock().map_err(|_| std::io::Error::other("simulation thread panicked"))?;
                serde_json::json!({
                    "time_s": s.time_s,
                    "steps": s.steps,
                    "rate": s.rate,
                    "wind_m_s": s.wind_applied,
                    "positions": s.positions,
                    "poses": s.poses,
                    "error": s.error,
                })
                .to_string()
            };
            respond(&mut stream, "200 OK", "application/json", body.as_bytes())
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
        _ => respond(&mut stream, "404 Not Found", "text/plain", b"not found\n"),
    }
}
