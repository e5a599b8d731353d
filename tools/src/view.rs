//! `cloth view OUT_DIR`: a page on localhost that plays a run's frames.
//!
//! A small HTTP/1.1 server (one request per connection, on 127.0.0.1
//! only): `/` the viewer page (WebGL, written here: `viewer.html`),
//! `/run.json` the run's frames and step, `/frames/<file>` the OBJ frames
//! and `solids.json` that `cloth run --frames N` writes.

use crate::run::SOLIDS_FILE;
use anyhow::{Context, Result, bail};
use cloth_tools::frames::{FRAMES_FILE, Frames};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The viewer page (also `cloth live`'s).
pub(crate) const PAGE: &str = include_str!("viewer.html");

/// Longest request head read, bytes.
const MAX_HEAD: usize = 16 * 1024;

/// What `cloth run --frames N` left in its output directory.
pub(crate) struct Recorded {
    /// The summary's scene path.
    pub scene: serde_json::Value,
    /// The run's step, s.
    pub dt_s: f64,
    /// The frames in order: step and file name under `frames/` (all
    /// `frames.bin` when the run wrote one).
    pub frames: Vec<(u64, String)>,
    /// `frames/`.
    pub dir: PathBuf,
    /// The frames are one `frames.bin` ([`cloth_tools::frames`]).
    pub binary: bool,
}

impl Recorded {
    /// Reads `out/summary.json` and lists the frames: those of
    /// `out/frames/frames.bin`, else `out/frames/frame_NNNNN.obj`.
    pub(crate) fn read(out: &Path) -> Result<Self> {
        let summary_path = out.join("summary.json");
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(&summary_path).with_context(|| format!("reading {}", summary_path.display()))?,
        )
        .with_context(|| format!("{} is not a summary", summary_path.display()))?;
        let dt_s = summary["dt_s"].as_f64().context("summary.json: no dt_s")?;
        let dir = out.join("frames");
        let bin = dir.join(FRAMES_FILE);
        if bin.is_file() {
            let frames: Vec<(u64, String)> =
                Frames::steps(&bin)?.into_iter().map(|step| (step, FRAMES_FILE.to_string())).collect();
            if frames.is_empty() {
                bail!("no frames in {}", bin.display());
            }
            return Ok(Self { scene: summary["scene"].clone(), dt_s, frames, dir, binary: true });
        }
        let mut frames: Vec<(u64, String)> = std::fs::read_dir(&dir)
            .with_context(|| format!("reading {} (run with --frames N)", dir.display()))?
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter_map(|name| {
                let step = name.strip_prefix("frame_")?.strip_suffix(".obj")?.parse().ok()?;
                Some((step, name))
            })
            .collect();
        frames.sort();
        if frames.is_empty() {
            bail!("no frames in {} (run with --frames N)", dir.display());
        }
        Ok(Self { scene: summary["scene"].clone(), dt_s, frames, dir, binary: false })
    }

    /// The solids file, when the run wrote one.
    pub(crate) fn solids_file(&self) -> Option<PathBuf> {
        Some(self.dir.join(SOLIDS_FILE)).filter(|p| p.is_file())
    }
}

/// What `/run.json` says: the frames in order and the run's step.
fn run_json(out: &Path) -> Result<String> {
    let run = Recorded::read(out)?;
    let frames: Vec<serde_json::Value> = run
        .frames
        .iter()
        .map(|(step, name)| serde_json::json!({ "file": name, "step": step, "time_s": *step as f64 * run.dt_s }))
        .collect();
    Ok(serde_json::to_string(&serde_json::json!({
        "scene": run.scene,
        "dt_s": run.dt_s,
        "frames": frames,
        "solids": run.solids_file().is_some(),
        "format": if run.binary { "bin" } else { "obj" },
        "steps": run.dir.join(crate::run::STEPS_FILE).is_file(),
    }))?)
}

/// The file under `frames/` a request names, if it is one (no path
/// separators, no parent directories).
fn frame_file(out: &Path, name: &str) -> Option<PathBuf> {
    let ok = !name.is_empty()
        && name.chars().all(|c| c.is_ascii_alphanumeric() || "._-".contains(c))
        && !name.starts_with('.');
    ok.then(|| out.join("frames").join(name)).filter(|p| p.is_file())
}

pub(crate) fn respond(stream: &mut TcpStream, status: &str, kind: &str, body: &[u8]) -> std::io::Result<()> {
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    stream.write_all(body)?;
    stream.flush()
}

/// The method and target of the request on `stream` (its head read to
/// the end, at most `MAX_HEAD` bytes), or `None` when there is none.
pub(crate) fn read_request(stream: &mut TcpStream) -> std::io::Result<Option<(String, String)>> {
    stream.set_read_timeout(Some(Duration::from_secs(5)))?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut request = String::new();
    reader.by_ref().take(MAX_HEAD as u64).read_line(&mut request)?;
    // The rest of the head is not needed; read it so the client sees a clean close.
    let mut line = String::new();
    let mut read = request.len();
    while read < MAX_HEAD && reader.read_line(&mut line)? > 2 {
        read += line.len();
        line.clear();
    }
    let mut parts = request.split_whitespace();
    Ok(match (parts.next(), parts.next()) {
        (Some(method), Some(target)) => Some((method.to_string(), target.to_string())),
        _ => None,
    })
}

/// Answers one request.
fn serve(stream: &mut TcpStream, out: &Path) -> std::io::Result<()> {
    let Some((method, target)) = read_request(stream)? else {
        return respond(stream, "400 Bad Request", "text/plain", b"bad request\n");
    };
    if method != "GET" {
        return respond(stream, "405 Method Not Allowed", "text/plain", b"GET only\n");
    }
    let path = target.split('?').next().unwrap_or("");
    match path {
        "/" | "/index.html" => respond(stream, "200 OK", "text/html; charset=utf-8", PAGE.as_bytes()),
        "/run.json" => match run_json(out) {
            Ok(json) => respond(stream, "200 OK", "application/json", json.as_bytes()),
            Err(e) => respond(stream, "500 Internal Server Error", "text/plain", format!("{e:#}\n").as_bytes()),
        },
        _ => match path.strip_prefix("/frames/").and_then(|name| frame_file(out, name)) {
            Some(file) => {
                let kind =
                    if file.extension().is_some_and(|e| e == "json") { "application/json" } else { "text/plain" };
                respond(stream, "200 OK", kind, &std::fs::read(file)?)
            }
            None => respond(stream, "404 Not Found", "text/plain", b"not found\n"),
        },
    }
}

/// Serves `out` (a `cloth run --frames N` output) on 127.0.0.1:`port` (0:
/// any free port) until stopped, or for `seconds` when given.
pub fn view(out: &Path, port: u16, seconds: Option<f64>) -> Result<()> {
    run_json(out)?; // fail now, naming the file, rather than in the page
    let listener = TcpListener::bind(("127.0.0.1", port)).with_context(|| format!("binding 127.0.0.1:{port}"))?;
    let address = listener.local_addr()?;
    println!("serving {} at http://{address}/", out.display());
    std::io::stdout().flush()?;
    let deadline = seconds.map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    listener.set_nonblocking(deadline.is_some())?;
    loop {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            return Ok(());
        }
        match listener.accept() {
            Ok((mut stream, _)) => {
                stream.set_nonblocking(false)?;
                // One thread a connection: a client holding an idle
                // connection open stalls only itself.
                let out = out.to_path_buf();
                std::thread::spawn(move || {
                    if let Err(e) = serve(&mut stream, &out) {
                        eprintln!("request failed: {e}");
                    }
                });
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => std::thread::sleep(Duration::from_millis(10)),
            Err(e) => return Err(e.into()),
        }
    }
}
