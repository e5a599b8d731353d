//! `cloth view`: the server answers what the page asks, refuses what it
//! should, and, in a real browser (headless Chromium, which `.ci/run`
//! installs and names in `CHROMIUM`), the page draws the cloth and the
//! solid.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

fn cloth() -> Command {
    Command::new(env!("CARGO_BIN_EXE_cloth"))
}

/// The sphere drape, small and short, with frames, in its own directory.
fn drape_run(name: &str) -> PathBuf {
    let out = std::env::temp_dir().join(format!("cloth-view-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/drape-sphere.toml");
    let status = cloth()
        .arg("run")
        .arg(scene)
        .args([
            "--quiet",
            "--frames",
            "9",
            "--set",
            "panels.0.particles=[21, 21]",
            "--set",
            "simulation.duration_s=0.6",
        ])
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    out
}

/// A running `cloth view` and its address; stopped when dropped.
struct Server {
    child: Child,
    address: String,
}

impl Server {
    /// `cloth view out`.
    fn start(out: &Path) -> Self {
        Self::spawn(cloth().arg("view").arg(out))
    }

    /// The server `command` starts on any free port, found in the line it
    /// prints first.
    fn spawn(command: &mut Command) -> Self {
        let mut child = command.args(["--port", "0", "--seconds", "120"]).stdout(Stdio::piped()).spawn().unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let address = line.trim().rsplit("http://").next().unwrap().trim_end_matches('/').to_string();
        Server { child, address }
    }

    /// The title of page `query` after headless Chromium loaded and ran it.
    fn title_in_chromium(&self, chromium: &std::ffi::OsStr, query: &str) -> String {
        let dom = Command::new(chromium)
            .args(["--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--window-size=800,600"])
            .args(["--virtual-time-budget=30000", "--dump-dom"])
            .arg(format!("http://{}/?{query}", self.address))
            .output()
            .unwrap();
        let dom = String::from_utf8_lossy(&dom.stdout);
        dom.split("<title>").nth(1).and_then(|t| t.split("</title>").next()).unwrap_or("").to_string()
    }

    /// Status code and body of `method path`.
    fn request(&self, method: &str, path: &str) -> (u16, Vec<u8>) {
        let mut stream = TcpStream::connect(&self.address).unwrap();
        write!(stream, "{method} {path} HTTP/1.1\r\nHost: {}\r\n\r\n", self.address).unwrap();
        let mut response = Vec::new();
        stream.read_to_end(&mut response).unwrap();
        let head_end = response.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
        let head = String::from_utf8_lossy(&response[..head_end]).to_string();
        let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
        (status, response[head_end + 4..].to_vec())
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn the_server_answers_the_page_and_refuses_the_rest() {
    let out = drape_run("server");
    let server = Server::start(&out);
    let (status, page) = server.request("GET", "/");
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&page).contains("<canvas id=\"view\">"));
    let (status, run) = server.request("GET", "/run.json");
    assert_eq!(status, 200);
    let run: serde_json::Value = serde_json::from_slice(&run).unwrap();
    // 0.6 s at 1/90 s: steps 0, 9, ..., 54.
    let frames = run["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 7);
    assert_eq!((frames[1]["step"].as_u64(), frames[1]["time_s"].as_f64()), (Some(9), Some(0.1)));
    assert_eq!(run["solids"], true);
    let (status, solids) = server.request("GET", "/frames/solids.json");
    assert_eq!(status, 200);
    let solids: serde_json::Value = serde_json::from_slice(&solids).unwrap();
    assert_eq!(solids["solids"].as_array().unwrap().len(), 1);
    assert_eq!(solids["frames"].as_array().unwrap().len(), 7);
    let (status, frame) = server.request("GET", "/frames/frame_00009.obj");
    assert_eq!(status, 200);
    assert_eq!(frame.iter().filter(|&&b| b == b'\n').count(), 21 * 21 + 2 * 20 * 20);
    for path in ["/frames/../summary.json", "/frames/%2e%2e/summary.json", "/summary.json", "/frames/", "/nothing"] {
        assert_eq!(server.request("GET", path).0, 404, "{path}");
    }
    assert_eq!(server.request("POST", "/run.json").0, 405);
}

#[test]
fn view_names_what_is_missing() {
    let empty = std::env::temp_dir().join(format!("cloth-view-empty-{}", std::process::id()));
    std::fs::create_dir_all(&empty).unwrap();
    let output = cloth().arg("view").arg(&empty).args(["--seconds", "1"]).output().unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("summary.json"));
}

/// The page in headless Chromium (software WebGL): in the first frame (the
/// flat cloth above the ball) and the last (draped on it) the cloth alone
/// and the ball alone each cover part of the middle of the canvas, and
/// together more; a page that failed says "error" in its title.
#[test]
fn chromium_draws_the_cloth_and_the_ball() {
    let Some(chromium) = common::outside_tool("CHROMIUM", "chromium-headless-shell") else { return };
    let out = drape_run("browser");
    let server = Server::start(&out);
    for frame in ["0", "last"] {
        let title = server.title_in_chromium(&chromium, &format!("check&frame={frame}"));
        // "drawn A of T; cloth B; solids C"
        let counts: Vec<f64> = title
            .split(|c: char| !c.is_ascii_digit())
            .filter(|n| !n.is_empty())
            .filter_map(|n| n.parse().ok())
            .collect();
        println!("frame {frame}: {title}");
        assert!(title.starts_with("drawn ") && counts.len() == 4, "frame {frame}: title {title:?}");
        let [all, total, cloth, ball] = [counts[0], counts[1], counts[2], counts[3]];
        assert!(all > 0.3 * total && cloth > 0.2 * total && ball > 0.1 * total, "frame {frame}: {title}");
    }
}

/// A running `cloth live`; stopped when dropped.
fn live(scene: &str, extra: &[&str]) -> Server {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes").join(scene);
    Server::spawn(cloth().arg("live").arg(scene).args(extra))
}

/// `/live.json` once the simulation has passed `t` seconds.
fn live_state_after(server: &Server, t: f64) -> serde_json::Value {
    let started = std::time::Instant::now();
    loop {
        let (status, body) = server.request("GET", "/live.json");
        assert_eq!(status, 200);
        let state: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert!(state["error"].is_null(), "{}", state["error"]);
        if state["time_s"].as_f64().unwrap() > t {
            return state;
        }
        assert!(started.elapsed().as_secs() < 60, "the simulation did not reach {t} s");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Mean y of the particles, m.
fn mean_y(state: &serde_json::Value) -> f64 {
    let p = state["positions"].as_array().unwrap();
    p.iter().skip(1).step_by(3).map(|y| y.as_f64().unwrap()).sum::<f64>() / (p.len() / 3) as f64
}

const FLAG_LIVE: [&str; 4] = ["--set", "wind.profile={ kind = \"external\" }", "--set", "panels.0.particles=[16, 11]"];

/// A wind set through the server reaches the running simulation: in still
/// air the flag hangs in its plane (mean y 0); blown along +y at 8 m/s
/// for 0.5 s it swings that way.
#[test]
fn a_wind_set_live_blows_the_flag() {
    let server = live("flag.toml", &FLAG_LIVE);
    let still = live_state_after(&server, 0.3);
    assert_eq!(still["wind_m_s"], serde_json::json!([0.0, 0.0, 0.0]));
    let (status, body) = server.request("GET", "/wind?x=0&y=8&z=0");
    assert_eq!((status, String::from_utf8_lossy(&body).trim()), (200, r#"{"wind_m_s":[0.0,8.0,0.0]}"#));
    let blown = live_state_after(&server, still["time_s"].as_f64().unwrap() + 0.5);
    assert_eq!(blown["wind_m_s"], serde_json::json!([0.0, 8.0, 0.0]));
    let (before, after) = (mean_y(&still), mean_y(&blown));
    println!("mean y {before:.4} m in still air, {after:.4} m after 0.5 s of 8 m/s along y");
    assert!(before.abs() < 1e-9 && after > 0.05, "{before} -> {after}");
    // Bad winds are refused and change nothing.
    for query in ["x=500", "x=nan", "w=1", "x"] {
        assert_eq!(server.request("GET", &format!("/wind?{query}")).0, 400, "{query}");
    }
    assert_eq!(live_state_after(&server, 0.0)["wind_m_s"], serde_json::json!([0.0, 8.0, 0.0]));
}

#[test]
fn live_refuses_what_it_cannot_drive() {
    // A scene whose wind is not external: no wind control.
    let server = live("drape-sphere.toml", &["--set", "panels.0.particles=[11, 11]"]);
    assert_eq!(server.request("GET", "/wind?x=1").0, 409);
    // Rigid bodies are cloth-rapier's: not live yet.
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/hammock.toml");
    let output = cloth().arg("live").arg(scene).args(["--seconds", "1"]).output().unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("cloth-only scenes"));
}

/// The live page in headless Chromium sets the wind from its own query
/// (as the pad does), waits for the cloth to feel it and draws it.
#[test]
fn chromium_sets_the_wind_live_and_draws_the_flag() {
    let Some(chromium) = common::outside_tool("CHROMIUM", "chromium-headless-shell") else { return };
    let server = live("flag.toml", &FLAG_LIVE);
    let title = server.title_in_chromium(&chromium, "check&wind=0,8,0");
    println!("{title}");
    assert!(title.contains("; wind 0,8,0;"), "{title}");
    let cloth: f64 =
        title.split("cloth ").nth(1).and_then(|t| t.split(';').next()).and_then(|n| n.parse().ok()).unwrap_or(0.0);
    assert!(cloth > 1000.0, "{title}");
    // The server agrees: the wind the page set is the one the steps use.
    assert_eq!(live_state_after(&server, 0.0)["wind_m_s"], serde_json::json!([0.0, 8.0, 0.0]));
}
