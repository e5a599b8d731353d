//! The readers of user files as targets.

use crate::repository;
use cloth_core::{PatternPiece, Snapshot};
use cloth_rapier::scene::CoupledScene;
use std::path::Path;

/// Fixture scenes the overrides target edits: a grid, contacts, rapier
/// bodies, a rigged garment, patterns, rings and wind.
const OVERRIDE_SCENES: [&str; 6] =
    ["hang.toml", "drape-sphere.toml", "hammock.toml", "skirt-walk.toml", "pattern-dress-walk.toml", "curtain.toml"];

/// Particles at most for a build (the readers are under test, not the
/// builder's speed: six pattern pieces near the bound of 4e6 triangles
/// took the machine's memory).
const BUILD_LIMIT: f64 = 20_000.0;

/// Particles at most for two steps after the build.
const STEP_LIMIT: f64 = 2_000.0;

/// An error's label: its text with numbers dropped, so that inputs
/// differing only in a value share one.
pub(crate) fn label(error: impl std::fmt::Display) -> String {
    let text = error.to_string();
    let kept: String = text.chars().filter(|c| !c.is_ascii_digit()).take(80).collect();
    format!("refused: {kept}")
}

/// About how many particles a pattern piece meshes into.
fn pattern_particles(piece: &PatternPiece) -> f64 {
    let (lo, hi) = piece.outline_m.iter().fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
    });
    (hi[0] - lo[0]) * (hi[1] - lo[1]) / (0.4 * piece.edge_length_m * piece.edge_length_m)
}

/// Reads, checks and (when small) builds and steps a scene.
fn scene(text: &str, overrides: &[String]) -> String {
    let mut scene = match CoupledScene::parse(text, overrides) {
        Ok(scene) => scene,
        Err(e) => return label(e),
    };
    scene.scene.base_dir = repository().join("fixtures/scenes");
    let grid: f64 = scene.scene.panels.iter().map(|p| p.particles[0] as f64 * p.particles[1] as f64).sum();
    let patterns: f64 = scene.scene.meshes.iter().filter_map(|m| m.pattern.as_ref()).map(pattern_particles).sum();
    let size = grid + patterns;
    if size.is_nan() || size > BUILD_LIMIT {
        return "parsed".into();
    }
    let mut run = match scene.build() {
        Ok(run) => run,
        Err(e) => return label(e),
    };
    let files = scene.scene.meshes.iter().any(|m| m.pattern.is_none());
    if size > STEP_LIMIT || files || scene.rig.is_some() {
        return "built".into();
    }
    for _ in 0..2 {
        if let Err(e) = run.step() {
            return label(e);
        }
    }
    "stepped".into()
}

pub(crate) fn scene_toml(data: &[u8]) -> String {
    scene(&String::from_utf8_lossy(data), &[])
}

pub(crate) fn overrides(data: &[u8]) -> String {
    let Some((&pick, rest)) = data.split_first() else { return "empty".into() };
    let file = OVERRIDE_SCENES[pick as usize % OVERRIDE_SCENES.len()];
    let Ok(text) = std::fs::read_to_string(repository().join("fixtures/scenes").join(file)) else {
        return "no fixture".into();
    };
    let sets: Vec<String> = String::from_utf8_lossy(rest).lines().map(str::to_string).collect();
    scene(&text, &sets)
}

pub(crate) fn obj(data: &[u8]) -> String {
    let text = String::from_utf8_lossy(data);
    let points = cloth_collide::parse_obj_points(&text).err().map(label);
    match cloth_collide::parse_obj(&text) {
        Ok(_) => "ok".into(),
        Err(e) => format!("{} {}", label(e), points.unwrap_or_default()),
    }
}

pub(crate) fn gltf(data: &[u8]) -> String {
    match cloth_collide::parse_gltf(data, Path::new("fuzz.glb"), None) {
        Ok(_) => "ok".into(),
        Err(e) => label(e),
    }
}

pub(crate) fn urdf(data: &[u8]) -> String {
    use cloth_rapier::rig::{Rig, RigOptions, UpAxis};
    let text = String::from_utf8_lossy(data);
    let file = repository().join("fixtures/rigs/fuzz.urdf");
    let mut labels = Vec::new();
    for (up_axis, scale) in [(UpAxis::Z, 1.0), (UpAxis::Y, 0.01)] {
        match Rig::parse(&text, &file, RigOptions { up_axis, scale }) {
            Ok(_) => labels.push("ok".to_string()),
            Err(e) => labels.push(label(e)),
        }
    }
    labels.join(" ")
}

pub(crate) fn bvh(data: &[u8]) -> String {
    match cloth_rapier::bvh::Bvh::parse(&String::from_utf8_lossy(data), Path::new("fuzz.bvh")) {
        Ok(_) => "ok".into(),
        Err(e) => label(e),
    }
}

/// The cloth a snapshot is restored into: `hang.toml` at 5 x 5 particles,
/// whose snapshots the corpus's seeds are.
const SNAPSHOT_SCENE: (&str, [&str; 2]) = ("hang.toml", ["panels.0.particles=[5, 5]", "pins.0.nodes=[[0, 4], [4, 4]]"]);

/// A snapshot read as it is, and again with its checksum made to match
/// (so that mutations reach the header and the values, not only the
/// checksum's refusal); what reads is restored into `SNAPSHOT_SCENE`'s
/// cloth and stepped twice.
pub(crate) fn snapshot(data: &[u8]) -> String {
    let as_is = restored_snapshot(data);
    let Some(body_len) = data.len().checked_sub(4) else { return as_is };
    let mut stamped = data[..body_len].to_vec();
    stamped.extend_from_slice(&crc32fast::hash(&stamped).to_le_bytes());
    format!("{as_is} / {}", restored_snapshot(&stamped))
}

fn restored_snapshot(data: &[u8]) -> String {
    let snapshot = match Snapshot::from_bytes(data) {
        Ok(snapshot) => snapshot,
        Err(e) => return label(e),
    };
    // Read and built once: the snapshot is under test, not the scene.
    static BUILT: std::sync::OnceLock<(cloth_core::ClothModel, cloth_core::scene::RunConfig)> =
        std::sync::OnceLock::new();
    let (model, cfg) = BUILT.get_or_init(|| {
        let (file, sets) = SNAPSHOT_SCENE;
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let text = std::fs::read_to_string(repository().join("fixtures/scenes").join(file)).expect("the fixture scene");
        let scene = cloth_core::scene::Scene::parse(&text, &sets).expect("the fixture scene parses");
        scene.build().expect("the fixture scene builds")
    });
    let mut sim = cfg.simulation(model.clone());
    if let Err(e) = sim.restore(&snapshot) {
        return label(e);
    }
    for _ in 0..2 {
        if let Err(e) = sim.step(cfg.dt_s) {
            return label(e);
        }
    }
    "stepped".into()
}
