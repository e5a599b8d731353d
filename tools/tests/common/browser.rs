//! A page in headless Chromium driven as a user drives it: real mouse
//! events (press, move, release at page coordinates) sent through the
//! DevTools protocol (`Input.dispatchMouseEvent`), which reach the page as
//! the events a mouse makes. The page's state is read with
//! `Runtime.evaluate`; nothing here calls the page's own functions.

use serde_json::{Value, json};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

/// How long any wait here lasts before the test fails.
const PATIENCE: Duration = Duration::from_secs(60);

/// A Chromium showing one page; stopped when dropped.
pub struct Browser {
    child: Child,
    profile: PathBuf,
    socket: WebSocket<MaybeTlsStream<TcpStream>>,
    next_id: u64,
}

impl Browser {
    /// Opens `url` in `chromium` (an 800 x 600 window, software WebGL).
    pub fn open(chromium: &std::ffi::OsStr, url: &str) -> Self {
        let profile = std::env::temp_dir().join(format!("cloth-chromium-{}-{}", std::process::id(), unique()));
        std::fs::create_dir_all(&profile).unwrap();
        let child = Command::new(chromium)
            .args(["--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--window-size=800,600"])
            .arg("--remote-debugging-port=0")
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(url)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            // Its own process group: its GPU and renderer processes go
            // with it (killed alone, the browser leaves them running).
            .process_group(0)
            .spawn()
            .unwrap();
        // Chromium writes the port it took, then the browser's path.
        let started = Instant::now();
        let port = loop {
            let text = std::fs::read_to_string(profile.join("DevToolsActivePort")).unwrap_or_default();
            if let Some(port) = text.lines().next().and_then(|l| l.trim().parse::<u16>().ok()) {
                break port;
            }
            assert!(started.elapsed() < PATIENCE, "Chromium did not open its DevTools port");
            std::thread::sleep(Duration::from_millis(50));
        };
        let page = loop {
            let targets: Value = serde_json::from_str(&http_get(port, "/json/list")).unwrap_or(Value::Null);
            let page = targets.as_array().and_then(|t| t.iter().find(|t| t["type"] == "page").cloned());
            if let Some(url) = page.as_ref().and_then(|p| p["webSocketDebuggerUrl"].as_str()) {
                break url.to_string();
            }
            assert!(started.elapsed() < PATIENCE, "Chromium shows no page");
            std::thread::sleep(Duration::from_millis(50));
        };
        let (socket, _) = tungstenite::connect(page).unwrap();
        if let MaybeTlsStream::Plain(stream) = socket.get_ref() {
            stream.set_read_timeout(Some(PATIENCE)).unwrap();
        }
        Browser { child, profile, socket, next_id: 0 }
    }

    /// Sends one DevTools command and returns its result.
    fn call(&mut self, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        self.socket.send(Message::text(json!({ "id": id, "method": method, "params": params }).to_string())).unwrap();
        loop {
            let message = self.socket.read().unwrap();
            let Ok(text) = message.to_text() else { continue };
            let reply: Value = serde_json::from_str(text).unwrap();
            if reply["id"] == id {
                assert!(reply["error"].is_null(), "{method}: {}", reply["error"]);
                return reply["result"].clone();
            }
        }
    }

    /// The value of a JavaScript expression in the page (promises awaited).
    pub fn eval(&mut self, expression: &str) -> Value {
        let result = self
            .call("Runtime.evaluate", json!({ "expression": expression, "returnByValue": true, "awaitPromise": true }));
        assert!(result["exceptionDetails"].is_null(), "{expression}: {}", result["exceptionDetails"]);
        result["result"]["value"].clone()
    }

    /// Waits until `expression` is true in the page.
    pub fn wait_for(&mut self, expression: &str) {
        let started = Instant::now();
        while self.eval(expression) != Value::Bool(true) {
            assert!(started.elapsed() < PATIENCE, "the page never had {expression}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn mouse(&mut self, kind: &str, [x, y]: [f64; 2], buttons: u32) {
        self.call(
            "Input.dispatchMouseEvent",
            json!({ "type": kind, "x": x, "y": y, "button": "left", "buttons": buttons, "clickCount": 1 }),
        );
    }

    /// Presses the left button at page point `at` (CSS pixels).
    pub fn press(&mut self, at: [f64; 2]) {
        self.mouse("mousePressed", at, 1);
    }

    /// Moves the pressed mouse from `from` to `to` in `steps` equal moves.
    pub fn move_pressed(&mut self, from: [f64; 2], to: [f64; 2], steps: u32) {
        for k in 1..=steps {
            let s = f64::from(k) / f64::from(steps);
            self.mouse("mouseMoved", [from[0] + s * (to[0] - from[0]), from[1] + s * (to[1] - from[1])], 1);
        }
    }

    /// Releases the left button at `at`.
    pub fn release(&mut self, at: [f64; 2]) {
        self.mouse("mouseReleased", at, 0);
    }

    /// Press, move and release: a drag from `from` to `to`.
    pub fn drag(&mut self, from: [f64; 2], to: [f64; 2]) {
        self.press(from);
        self.move_pressed(from, to, 10);
        self.release(to);
    }

    /// The centre of the element `selector` matches and its size, CSS pixels.
    pub fn rect(&mut self, selector: &str) -> ([f64; 2], [f64; 2]) {
        let r = self.eval(&format!(
            "(() => {{ const r = document.querySelector({selector:?}).getBoundingClientRect(); \
             return [r.left + r.width / 2, r.top + r.height / 2, r.width, r.height]; }})()"
        ));
        let v: Vec<f64> = r.as_array().unwrap().iter().map(|c| c.as_f64().unwrap()).collect();
        ([v[0], v[1]], [v[2], v[3]])
    }

    /// Clicks the middle of the element `selector` matches.
    pub fn click(&mut self, selector: &str) {
        let (centre, _) = self.rect(selector);
        self.press(centre);
        self.release(centre);
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let group = format!("-{}", self.child.id());
        let _ = Command::new("kill").args(["-KILL", "--", &group]).status();
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

/// A number no other browser of this process has used.
fn unique() -> u64 {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

/// The body of `GET path` from the DevTools server on `port` ("" if it
/// does not answer yet). It keeps the connection open after its answer
/// (and does not answer HTTP/1.0): the body is read to its length.
fn http_get(port: u16, path: &str) -> String {
    let Ok(mut stream) = TcpStream::connect(("127.0.0.1", port)) else { return String::new() };
    let _ = stream.set_read_timeout(Some(Duration::from_secs(5)));
    let _ = write!(stream, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n");
    let mut response = Vec::new();
    let mut chunk = [0u8; 4096];
    loop {
        if let Some(end) = response.windows(4).position(|w| w == b"\r\n\r\n") {
            let head = String::from_utf8_lossy(&response[..end]).to_ascii_lowercase();
            let length = head
                .lines()
                .find_map(|l| l.strip_prefix("content-length:"))
                .and_then(|n| n.trim().parse::<usize>().ok())
                .unwrap_or(0);
            if response.len() >= end + 4 + length {
                return String::from_utf8_lossy(&response[end + 4..end + 4 + length]).to_string();
            }
        }
        match stream.read(&mut chunk) {
            Ok(n) if n > 0 => response.extend_from_slice(&chunk[..n]),
            _ => return String::new(),
        }
    }
}
