//! `cloth export OUT_DIR`: a recorded run (`cloth run --frames N`) as one
//! binary glTF file (see [`cloth_tools::gltf`] for what it holds and why).

use crate::view::Recorded;
use anyhow::{Context, Result, bail};
use cloth_tools::frames::{FRAMES_FILE, Frames};
use cloth_tools::gltf::{Recording, SolidTrack, glb};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// An OBJ frame: positions (m) and triangles (0-based).
type ObjFrame = (Vec<[f64; 3]>, Vec<[u32; 3]>);

/// The positions and triangles of an OBJ frame as `cloth run` writes it
/// (`v x y z` and `f a b c`, 1-based); errors name the file and line.
fn read_obj(path: &Path) -> Result<ObjFrame> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    for (n, line) in text.lines().enumerate() {
        let bad = || format!("{}:{}: expected 'v x y z' or 'f a b c', got {line:?}", path.display(), n + 1);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let v: Vec<f64> = words.map(str::parse).collect::<Result<_, _>>().with_context(bad)?;
                vertices.push(<[f64; 3]>::try_from(v).ok().with_context(bad)?);
            }
            Some("f") => {
                let f: Vec<u32> = words.map(str::parse).collect::<Result<_, _>>().with_context(bad)?;
                let f = <[u32; 3]>::try_from(f).ok().filter(|f| f.iter().all(|&i| i >= 1)).with_context(bad)?;
                triangles.push(f.map(|i| i - 1));
            }
            None => {}
            Some(_) => bail!(bad()),
        }
    }
    Ok((vertices, triangles))
}

/// The solids of `solids.json` with their pose at each of `steps`.
fn read_solids(path: &Path, steps: &[u64]) -> Result<Vec<SolidTrack>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let bad = |what: &str| format!("{}: {what}", path.display());
    let doc: serde_json::Value = serde_json::from_str(&text).with_context(|| bad("not JSON"))?;
    let by_step: HashMap<u64, &serde_json::Value> = doc["frames"]
        .as_array()
        .with_context(|| bad("no frames"))?
        .iter()
        .filter_map(|f| Some((f["step"].as_u64()?, &f["poses"])))
        .collect();
    let numbers = |v: &serde_json::Value, what: &str| -> Result<Vec<f64>> {
        v.as_array().and_then(|a| a.iter().map(serde_json::Value::as_f64).collect()).with_context(|| bad(what))
    };
    let solids = doc["solids"].as_array().with_context(|| bad("no solids"))?;
    solids
        .iter()
        .enumerate()
        .map(|(s, solid)| {
            let vertices =
                numbers(&solid["vertices"], "vertices")?.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            let corners = numbers(&solid["triangles"], "triangles")?;
            let triangles = corners.chunks_exact(3).map(|c| [c[0] as u32, c[1] as u32, c[2] as u32]).collect();
            let poses = steps
                .iter()
                .map(|step| {
                    let pose = by_step.get(step).with_context(|| bad(&format!("no poses at step {step}")))?;
                    let p = numbers(&pose[s], &format!("solid {s} at step {step}"))?;
                    <[f64; 7]>::try_from(p).ok().with_context(|| bad(&format!("solid {s} at step {step}: 7 numbers")))
                })
                .collect::<Result<_>>()?;
            Ok(SolidTrack { vertices, triangles, poses })
        })
        .collect()
}

/// Writes `out`'s recorded frames and solids as a `.glb` at `to` (default
/// `out/run.glb`); returns where.
pub fn export(out: &Path, to: Option<&Path>) -> Result<PathBuf> {
    let run = Recorded::read(out)?;
    let mut frames = Vec::with_capacity(run.frames.len());
    let mut triangles = Vec::new();
    if run.binary {
        let read = Frames::read(&run.dir.join(FRAMES_FILE))?;
        triangles = read.triangles;
        frames.extend(read.frames.into_iter().map(|(_, x)| x.iter().map(|p| p.map(f64::from)).collect()));
    } else {
        for (k, (_, name)) in run.frames.iter().enumerate() {
            let (vertices, faces) = read_obj(&run.dir.join(name))?;
            if k == 0 {
                triangles = faces;
            }
            frames.push(vertices);
        }
    }
    let steps: Vec<u64> = run.frames.iter().map(|(step, _)| *step).collect();
    let times: Vec<f64> = steps.iter().map(|&s| s as f64 * run.dt_s).collect();
    let solids = match run.solids_file() {
        Some(path) => read_solids(&path, &steps)?,
        None => Vec::new(),
    };
    let bytes = glb(&Recording { times: &times, triangles: &triangles, frames: &frames, solids: &solids })
        .with_context(|| format!("exporting {}", out.display()))?;
    let to = to.map_or_else(|| out.join("run.glb"), Path::to_path_buf);
    std::fs::write(&to, bytes).with_context(|| format!("writing {}", to.display()))?;
    Ok(to)
}
