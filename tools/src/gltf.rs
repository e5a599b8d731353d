//! A recorded run as one binary glTF 2.0 file (`.glb`), which Blender
//! (File > Import > glTF 2.0, built in), three.js and most viewers open in
//! one step.
//!
//! Why glTF beside the OBJ sequence: an OBJ sequence is one file per frame
//! and no timing, which Blender imports only frame by frame or through an
//! add-on; point caches (MDD, PC2) carry timing but need the base mesh
//! imported first and a modifier added by hand. A `.glb` carries the mesh,
//! the motion, the frame times and the solids in one file:
//! - the cloth is one mesh whose first frame is its positions and every
//!   later frame a morph target (displacements from the first, f32); the
//!   animation sets the weights one-hot at each frame's time, linearly in
//!   between (Blender: shape keys and their keyed values);
//! - each solid is a mesh in its own frame under a node whose translation
//!   and rotation are keyed at every frame (LINEAR: slerp for rotations);
//! - everything hangs under one root node turned -90 degrees about x:
//!   the simulation's z-up world in glTF's y-up convention.
//!
//! Cost: 12 bytes per particle per frame (a 3,456-particle skirt at 30
//! frames per second: 1.2 MB per second of motion), and the weights, one
//! float per frame squared (4 kB for 30 frames, 1.4 MB for 600).

use anyhow::{Result, bail};
use serde_json::{Value, json};

/// One solid: its surface in its own frame and its pose at every frame.
pub struct SolidTrack {
    /// Vertices in the solid's frame, m.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles (vertex indices, counter-clockwise seen from outside).
    pub triangles: Vec<[u32; 3]>,
    /// Pose at each frame: `[x, y, z, qw, qx, qy, qz]` (m).
    pub poses: Vec<[f64; 7]>,
}

/// What a `.glb` holds.
pub struct Recording<'a> {
    /// Frame times, s, strictly increasing.
    pub times: &'a [f64],
    /// The cloth's triangles.
    pub triangles: &'a [[u32; 3]],
    /// The cloth's positions at each frame, m.
    pub frames: &'a [Vec<[f64; 3]>],
    /// The solids.
    pub solids: &'a [SolidTrack],
}

/// The root's rotation, `[x, y, z, w]`: -90 degrees about x takes the
/// simulation's z-up to glTF's y-up.
const Z_UP_TO_Y_UP: [f64; 4] = [-std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2];

/// Half of f32's largest value: coordinates within it, and the
/// differences of two of them, are finite in f32.
const F32_HALF_MAX: f64 = f32::MAX as f64 / 2.0;

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

/// The binary chunk and the JSON arrays that describe it.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Appends `bytes` as a buffer view (4-byte aligned); returns its index.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut view = json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() });
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.views.push(view);
        self.views.len() - 1
    }

    /// A float accessor of `width` components per element (with the
    /// component-wise min and max glTF asks of positions and times).
    fn floats(&mut self, values: &[f32], width: usize, target: Option<u32>) -> usize {
        let kind = ["SCALAR", "VEC2", "VEC3", "VEC4"][width - 1];
        let mut lo = vec![f32::INFINITY; width];
        let mut hi = vec![f32::NEG_INFINITY; width];
        for element in values.chunks_exact(width) {
            for (k, v) in element.iter().enumerate() {
                (lo[k], hi[k]) = (lo[k].min(*v), hi[k].max(*v));
            }
        }
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, target);
        self.accessors.push(json!({
            "bufferView": view, "componentType": FLOAT, "count": values.len() / width, "type": kind,
            "min": lo, "max": hi,
        }));
        self.accessors.len() - 1
    }

    /// An accessor of triangle indices.
    fn indices(&mut self, triangles: &[[u32; 3]]) -> usize {
        let bytes: Vec<u8> = triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        let count = triangles.len() * 3;
        self.accessors
            .push(json!({ "bufferView": view, "componentType": UNSIGNED_INT, "count": count, "type": "SCALAR" }));
        self.accessors.len() - 1
    }
}

fn flat(points: &[[f64; 3]]) -> Vec<f32> {
    points.iter().flatten().map(|c| *c as f32).collect()
}

/// Checks what glTF cannot hold: no frames, no particles or triangles,
/// frames of different sizes, values beyond f32,
/// times that are not strictly increasing as f32, indices out of range.
fn check(rec: &Recording<'_>) -> Result<()> {
    let Some(first) = rec.frames.first() else { bail!("no frames to export") };
    if rec.times.len() != rec.frames.len() {
        bail!("{} frame times for {} frames", rec.times.len(), rec.frames.len());
    }
    if let Some(k) = rec.frames.iter().position(|f| f.len() != first.len()) {
        bail!("frame {k} has {} particles, the first {}", rec.frames[k].len(), first.len());
    }
    if let Some(k) = rec.times.windows(2).position(|t| (t[1] as f32) <= (t[0] as f32)) {
        bail!(
            "frames {k} and {} are at {} s and {} s: not distinct as glTF's f32 times",
            k + 1,
            rec.times[k],
            rec.times[k + 1]
        );
    }
    // glTF's accessors and buffer views hold at least one element.
    if first.is_empty() || rec.triangles.is_empty() {
        bail!("the cloth has {} particles and {} triangles: glTF needs one of each", first.len(), rec.triangles.len());
    }
    if rec.triangles.iter().flatten().any(|&i| i as usize >= first.len()) {
        bail!("a cloth triangle names a particle beyond the {} of the frames", first.len());
    }
    for (s, solid) in rec.solids.iter().enumerate() {
        if solid.poses.len() != rec.frames.len() {
            bail!("solid {s}: {} poses for {} frames", solid.poses.len(), rec.frames.len());
        }
        if solid.triangles.iter().flatten().any(|&i| i as usize >= solid.vertices.len()) {
            bail!("solid {s}: a triangle names a vertex beyond its {}", solid.vertices.len());
        }
    }
    // glTF stores f32: positions, the morph targets' displacements between
    // them, times and poses must all be finite there.
    let fits = |c: &f64| c.abs() <= F32_HALF_MAX;
    if let Some(k) = rec.frames.iter().position(|f| !f.iter().flatten().all(fits)) {
        bail!("frame {k}: a position is not finite or beyond {F32_HALF_MAX:e} m (glTF stores f32)");
    }
    if let Some(s) = rec.solids.iter().position(|s| !s.vertices.iter().flatten().all(fits)) {
        bail!("solid {s}: a vertex is not finite or beyond {F32_HALF_MAX:e} m (glTF stores f32)");
    }
    if let Some(s) = rec.solids.iter().position(|s| !s.poses.iter().flatten().all(fits)) {
        bail!("solid {s}: a pose is not finite or beyond {F32_HALF_MAX:e} (glTF stores f32)");
    }
    if let Some(k) = rec.times.iter().position(|t| !fits(t)) {
        bail!("frame {k}: time {} s is not finite or beyond {F32_HALF_MAX:e} s (glTF stores f32)", rec.times[k]);
    }
    Ok(())
}

/// The recording as a binary glTF 2.0 file.
pub fn glb(rec: &Recording<'_>) -> Result<Vec<u8>> {
    check(rec)?;
    let mut b = Builder::default();
    let base = &rec.frames[0];
    let position = b.floats(&flat(base), 3, Some(ARRAY_BUFFER));
    let indices = b.indices(rec.triangles);
    // Morph target k - 1 is frame k's displacement from the first frame.
    let targets: Vec<Value> = rec.frames[1..]
        .iter()
        .map(|frame| {
            let moved: Vec<[f64; 3]> =
                frame.iter().zip(base).map(|(p, q)| [p[0] - q[0], p[1] - q[1], p[2] - q[2]]).collect();
            json!({ "POSITION": b.floats(&flat(&moved), 3, Some(ARRAY_BUFFER)) })
        })
        .collect();
    let names: Vec<String> = (1..rec.frames.len()).map(|k| format!("frame {k}")).collect();
    let mut cloth_primitive = json!({ "attributes": { "POSITION": position }, "indices": indices, "material": 0 });
    let mut cloth_mesh = json!({ "name": "cloth", "primitives": [] });
    if !targets.is_empty() {
        cloth_primitive["targets"] = json!(targets);
        cloth_mesh["weights"] = json!(vec![0.0; targets.len()]);
        cloth_mesh["extras"] = json!({ "targetNames": names });
    }
    cloth_mesh["primitives"] = json!([cloth_primitive]);
    let mut meshes = vec![cloth_mesh];
    let mut nodes = vec![json!({ "name": "cloth", "mesh": 0 })];
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let animated = rec.frames.len() > 1;
    let times: Vec<f32> = rec.times.iter().map(|t| *t as f32).collect();
    let input = animated.then(|| b.floats(&times, 1, None));
    if let Some(input) = input {
        let count = targets.len();
        let mut weights = vec![0.0f32; rec.frames.len() * count];
        for k in 1..rec.frames.len() {
            weights[k * count + (k - 1)] = 1.0;
        }
        let output = b.floats(&weights, 1, None);
        samplers.push(json!({ "input": input, "output": output, "interpolation": "LINEAR" }));
        channels.push(json!({ "sampler": 0, "target": { "node": 0, "path": "weights" } }));
    }
    for (s, solid) in rec.solids.iter().enumerate().filter(|(_, s)| !s.triangles.is_empty()) {
        let position = b.floats(&flat(&solid.vertices), 3, Some(ARRAY_BUFFER));
        let indices = b.indices(&solid.triangles);
        meshes.push(json!({
            "name": format!("solid {s}"),
            "primitives": [{ "attributes": { "POSITION": position }, "indices": indices, "material": 1 }],
        }));
        let [x, y, z, qw, qx, qy, qz] = solid.poses[0];
        let node = nodes.len();
        nodes.push(json!({
            "name": format!("solid {s}"), "mesh": meshes.len() - 1,
            "translation": [x, y, z], "rotation": [qx, qy, qz, qw],
        }));
        if let Some(input) = input {
            let translations: Vec<f32> =
                solid.poses.iter().flat_map(|p| [p[0], p[1], p[2]]).map(|c| c as f32).collect();
            let rotations: Vec<f32> =
                solid.poses.iter().flat_map(|p| [p[4], p[5], p[6], p[3]]).map(|c| c as f32).collect();
            for (path, values, width) in [("translation", translations, 3), ("rotation", rotations, 4)] {
                let output = b.floats(&values, width, None);
                samplers.push(json!({ "input": input, "output": output, "interpolation": "LINEAR" }));
                channels.push(json!({ "sampler": samplers.len() - 1, "target": { "node": node, "path": path } }));
            }
        }
    }
    let children: Vec<usize> = (0..nodes.len()).collect();
    nodes.push(json!({ "name": "z-up world", "rotation": Z_UP_TO_Y_UP, "children": children }));
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": concat!("cloth-tools ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "nodes": [nodes.len() - 1] }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [
            { "name": "cloth", "doubleSided": true,
              "pbrMetallicRoughness": { "baseColorFactor": [0.93, 0.55, 0.25, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9 } },
            { "name": "solid",
              "pbrMetallicRoughness": { "baseColorFactor": [0.62, 0.64, 0.67, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.6 } },
        ],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{ "byteLength": b.bin.len() }],
    });
    if !channels.is_empty() {
        doc["animations"] = json!([{ "name": "run", "samplers": samplers, "channels": channels }]);
    }
    let mut text = serde_json::to_vec(&doc)?;
    text.resize(text.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + text.len() + 8 + b.bin.len();
    let Ok(total32) = u32::try_from(total) else { bail!("{total} bytes: beyond the 4 GiB a .glb can hold") };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    for (kind, chunk) in [(b"JSON", &text), (b"BIN\0", &b.bin)] {
        out.extend_from_slice(&(chunk.len() as u32).to_le_bytes());
        out.extend_from_slice(kind);
        out.extend_from_slice(chunk);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(frames: usize) -> (Vec<f64>, Vec<Vec<[f64; 3]>>) {
        let times = (0..frames).map(|k| k as f64 * 0.1).collect();
        let frames = (0..frames)
            .map(|k| vec![[0.0, 0.0, -(k as f64)], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
            .collect();
        (times, frames)
    }

    #[test]
    fn what_gltf_cannot_hold_is_refused_by_name() {
        let (mut times, frames) = square(3);
        let triangles = [[0, 1, 2], [1, 3, 2]];
        let rec = |times: &[f64], triangles: &[[u32; 3]]| {
            glb(&Recording { times, triangles, frames: &frames, solids: &[] }).map_err(|e| e.to_string())
        };
        assert!(rec(&times, &triangles).is_ok());
        assert!(rec(&times, &[[0, 1, 4]]).unwrap_err().contains("beyond the 4"));
        assert!(rec(&times, &[]).unwrap_err().contains("4 particles and 0 triangles"));
        times[2] = times[1] + 1e-12;
        assert!(rec(&times, &triangles).unwrap_err().contains("not distinct"));
        assert!(rec(&times[..2], &triangles).unwrap_err().contains("2 frame times for 3 frames"));
        times[2] = f64::NAN;
        assert!(rec(&times, &triangles).unwrap_err().contains("frame 2: time NaN s is not finite"));
        // Found by `cloth-fuzz`: finite in f64, infinite as glTF's f32 min/max.
        let (times, mut far) = square(2);
        far[1][3][0] = 1e300;
        let far = glb(&Recording { times: &times, triangles: &triangles, frames: &far, solids: &[] });
        assert!(far.unwrap_err().to_string().contains("frame 1: a position is not finite or beyond"));
        let solid =
            SolidTrack { vertices: vec![[0.0; 3]; 3], triangles: vec![[0, 1, 2]], poses: vec![[f64::NAN; 7]; 2] };
        let (times, frames) = square(2);
        let posed = glb(&Recording { times: &times, triangles: &triangles, frames: &frames, solids: &[solid] });
        assert!(posed.unwrap_err().to_string().contains("solid 0: a pose is not finite"));
    }

    #[test]
    fn chunks_are_aligned_and_sized() {
        let (times, frames) = square(4);
        let bytes = glb(&Recording { times: &times, triangles: &[[0, 1, 2]], frames: &frames, solids: &[] }).unwrap();
        let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        assert_eq!((&bytes[..4], word(4), word(8)), (&b"glTF"[..], 2, bytes.len()));
        let json_len = word(12);
        assert_eq!((json_len % 4, &bytes[16..20]), (0, &b"JSON"[..]));
        let bin_len = word(20 + json_len);
        assert_eq!(&bytes[24 + json_len..28 + json_len], b"BIN\0");
        assert_eq!(28 + json_len + bin_len, bytes.len());
    }
}
