//! What `cloth run --frames N` writes beside the frames: the per-step
//! series (`steps.csv`) and the solids with their poses at the frames
//! (`solids.json`).

use anyhow::{Context, Result};
use cloth_core::{ClothModel, Simulation, StepReport, TangleCounts};
use std::path::Path;

/// Beside the OBJ frames: the solids of the scene as triangle meshes in
/// their own frames, and where each was at every written frame (for
/// `cloth view`).
pub const SOLIDS_FILE: &str = "solids.json";

/// The per-step series `cloth run --frames N` writes beside the frames
/// (the viewer's time plot): one row a step.
pub const STEPS_FILE: &str = "steps.csv";

/// One step of the series: its energies (empty for steps the energy
/// monitor did not judge), largest stretch, CG iterations, contacts, the
/// cloth's crossings through itself and particles through a solid, and
/// the deformation constraints' link corrections.
#[derive(serde::Serialize)]
pub(super) struct StepRow {
    step: u64,
    time_s: f64,
    kinetic_j: Option<f64>,
    elastic_j: Option<f64>,
    gravitational_j: Option<f64>,
    max_stretch: f64,
    cg_iterations: usize,
    contacts: usize,
    self_crossings: usize,
    deep_in_solids: usize,
    strain_corrections: usize,
}

impl StepRow {
    pub(super) fn of(sim: &Simulation, r: &StepReport, max_stretch: f64, tangles: TangleCounts) -> Self {
        Self {
            step: sim.state().steps,
            time_s: sim.time(),
            kinetic_j: r.energy.map(|e| e.kinetic_j),
            elastic_j: r.energy.map(|e| e.elastic_j),
            gravitational_j: r.energy.map(|e| e.gravitational_j),
            max_stretch,
            cg_iterations: r.cg_iterations,
            contacts: r.contacts.contacts,
            self_crossings: tangles.self_crossings,
            deep_in_solids: tangles.deep_in_solids,
            strain_corrections: r.strain_corrections,
        }
    }
}

pub(super) fn write_steps(path: &Path, rows: &[StepRow]) -> Result<()> {
    let mut out = csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
    for row in rows {
        out.serialize(row).with_context(|| format!("writing {}", path.display()))?;
    }
    out.flush().with_context(|| format!("writing {}", path.display()))
}

/// Solid poses at the written frames.
#[derive(Default)]
pub(super) struct SolidPoses {
    frames: Vec<FrameSolids>,
}

/// A frame's step, each solid's position and orientation (`[x, y, z, qw,
/// qx, qy, qz]`, m) and each contact's `[particle, fx, fy, fz]` (N).
pub(super) type FrameSolids = (u64, Vec<[f64; 7]>, Vec<[f64; 4]>);

impl SolidPoses {
    /// The frame of `sim` after a step of `h` s: the poses, and each active
    /// contact's particle and the mean force the solid exerted on it over
    /// the step (its impulse over `h`, friction included), N.
    pub(super) fn add(&mut self, sim: &Simulation, h: f64) {
        let forces = sim
            .contacts()
            .solid()
            .iter()
            .filter(|c| c.active && sim.state().steps > 0)
            .map(|c| {
                let f = c.impulse_n_s / h;
                [c.particle as f64, f.x, f.y, f.z]
            })
            .collect();
        self.frames.push((sim.state().steps, solid_poses(sim), forces));
    }

    /// `{"solids": [{"name": "pelvis", "vertices": [x, y, z, ...], "triangles": [a, b, c, ...]}],
    /// "frames": [{"step": n, "poses": [[x, y, z, qw, qx, qy, qz], ...],
    /// "contacts": [[particle, fx, fy, fz], ...]}]}`; a solid's name is its
    /// body's, its rig link's, or `colliders[k]`.
    pub(super) fn to_json(&self, model: &ClothModel, names: &[String]) -> Result<String> {
        let mut solids = solid_meshes_json(model);
        if let serde_json::Value::Array(list) = &mut solids {
            for (solid, name) in list.iter_mut().zip(names) {
                solid["name"] = serde_json::Value::String(name.clone());
            }
        }
        let frames: Vec<serde_json::Value> = self
            .frames
            .iter()
            .map(|(step, poses, contacts)| serde_json::json!({ "step": step, "poses": poses, "contacts": contacts }))
            .collect();
        Ok(serde_json::to_string(&serde_json::json!({ "solids": solids, "frames": frames }))?)
    }
}

/// The model's solids as triangle meshes in their own frames:
/// `[{"vertices": [x, y, z, ...], "triangles": [a, b, c, ...]}, ...]`.
pub(crate) fn solid_meshes_json(model: &ClothModel) -> serde_json::Value {
    let identity =
        cloth_core::BodyPose { position: cloth_core::Vec3::zeros(), rotation: nalgebra::UnitQuaternion::identity() };
    model
        .colliders()
        .iter()
        .map(|c| {
            let (vertices, triangles) = c.shape.surface_mesh(&identity);
            serde_json::json!({
                "vertices": vertices.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
                "triangles": triangles.iter().flatten().collect::<Vec<_>>(),
            })
        })
        .collect()
}

/// Where each solid of `sim` is now: `[x, y, z, qw, qx, qy, qz]` (m).
pub(crate) fn solid_poses(sim: &Simulation) -> Vec<[f64; 7]> {
    (0..sim.model().colliders().len())
        .filter_map(|k| sim.solid_pose(k))
        .map(|p| {
            let q = p.rotation.quaternion();
            [p.position.x, p.position.y, p.position.z, q.w, q.i, q.j, q.k]
        })
        .collect()
}
