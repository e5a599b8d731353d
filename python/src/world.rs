//! `cloth.World`: a scene with rapier bodies and a URDF rig, stepped as
//! `cloth run` steps it (the scene's coupling), with inputs to its bodies
//! and joints, readings of their poses and of what the cloth does to them,
//! and grasps by a point or a body.

use crate::grasp::{Grasps, Gripper};
use crate::{ControlError, control_error, grasp_error, override_args, rows, scene_error, triangles, vectors};
use cloth_core::{BodyPose, Vec3};
use cloth_rapier::convert::{pose_from_rapier, vec_from_rapier};
use cloth_rapier::rapier3d_f64::prelude::RigidBodyHandle;
use cloth_rapier::rig::JointValue;
use cloth_rapier::{CoupledRun, CoupledScene};
use nalgebra::UnitQuaternion;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// A cloth in a rapier world: its `[[bodies]]` and `[rig]`, stepped
/// together with the scene's `[coupling]`.
#[pyclass(module = "cloth")]
pub(crate) struct World {
    /// Which world this is, so that a snapshot goes back to its own.
    id: u64,
    run: CoupledRun,
    grasps: Grasps,
    pool: std::sync::Arc<rayon::ThreadPool>,
    /// The cloth's report of the last step (`None` before the first).
    last: Option<cloth_core::StepReport>,
}

fn array3(py: Python<'_>, v: Vec3) -> Bound<'_, PyArray1<f64>> {
    vec![v.x, v.y, v.z].into_pyarray(py)
}

/// Two arrays: a position and a quaternion, or two velocities.
type ArrayPair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// A pose as its origin (m) and unit quaternion `[x, y, z, w]`.
fn pose_arrays(py: Python<'_>, pose: BodyPose) -> ArrayPair<'_> {
    let q = pose.rotation.coords;
    (array3(py, pose.position), vec![q.x, q.y, q.z, q.w].into_pyarray(py))
}

impl World {
    fn body_index(&self, name: &str) -> PyResult<usize> {
        self.run.bodies.iter().position(|b| b.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.run.bodies.iter().map(|b| b.name.as_str()).collect();
            ControlError::new_err(format!("no body named {name:?}; the scene's bodies: {names:?}"))
        })
    }

    fn sim(&self) -> &cloth_core::Simulation {
        self.run.cloths[self.run.cloth].simulation()
    }

    /// The rapier body a grasp can be on: `[[bodies]]` by name, then rig
    /// links by name.
    fn gripper_body(&self, name: &str) -> PyResult<RigidBodyHandle> {
        if let Some(b) = self.run.bodies.iter().find(|b| b.name == name) {
            return Ok(b.handle);
        }
        self.run.rig.as_ref().and_then(|r| r.body(name)).ok_or_else(|| {
            let mut names: Vec<String> = self.run.bodies.iter().map(|b| b.name.clone()).collect();
            names.extend(self.link_names());
            ControlError::new_err(format!("no body or rig link named {name:?}; the scene has {names:?}"))
        })
    }

    /// The gripper of a grasp at `point` (m), or on body `body` at its
    /// pose now.
    fn gripper(&self, point: Vec3, body: Option<&str>) -> PyResult<(Gripper, BodyPose)> {
        Ok(match body {
            None => (Gripper::Point, BodyPose { position: point, rotation: UnitQuaternion::identity() }),
            Some(name) => {
                let b = self.gripper_body(name)?;
                (Gripper::Body(b), pose_from_rapier(self.run.world.bodies[b].position()))
            }
        })
    }

    /// A body's pose at the end of the next step, as far as it is known
    /// before the step: a kinematic body's (and rig link's) next pose,
    /// which [`CoupledRun::pose_kinematics`] set; a dynamic one moved on
    /// over the step by its velocity and by gravity and the forces set for
    /// the step as rapier's substeps integrate them
    /// ([`cloth_rapier::gravity_share`]), without the step's contacts.
    fn predicted_pose(run: &CoupledRun, body: RigidBodyHandle) -> BodyPose {
        let rb = &run.world.bodies[body];
        if !rb.is_dynamic() {
            return pose_from_rapier(rb.next_position());
        }
        let h = run.config.dt_s;
        let pose = pose_from_rapier(rb.position());
        let (v, w) = (vec_from_rapier(rb.linvel()), vec_from_rapier(rb.angvel()));
        let com = vec_from_rapier(rb.center_of_mass());
        let gravity = vec_from_rapier(run.world.gravity) * rb.gravity_scale();
        let force = vec_from_rapier(rb.user_force());
        let pushed = if rb.mass() > 0.0 { gravity + force / rb.mass() } else { gravity };
        let v = v + pushed * (h * cloth_rapier::gravity_share(&run.world, rb));
        let turn = UnitQuaternion::from_scaled_axis(w * h);
        // The frame origin turns about the centre of mass as it moves.
        BodyPose { position: com + v * h + turn * (pose.position - com), rotation: turn * pose.rotation }
    }

    /// One step: kinematic poses set, body grasps placed where their
    /// bodies will be, the step, then each grasp's pull put on its body
    /// for the next step (if dynamic: kinematic and fixed bodies and rig
    /// links are not pushed).
    fn step_once(run: &mut CoupledRun, grasps: &Grasps) -> Result<Option<cloth_core::StepReport>, String> {
        run.pose_kinematics().map_err(|e| e.to_string())?;
        let handle = run.cloth;
        let targets: Vec<(RigidBodyHandle, BodyPose)> =
            grasps.on_bodies().map(|(b, _)| (b, Self::predicted_pose(run, b))).collect();
        if let Some(cloth) = run.cloths.get_mut(handle) {
            let pose_of = |b| targets.iter().find(|(h, _)| *h == b).map(|(_, p)| *p);
            grasps.follow_bodies(cloth.simulation_mut(), |b| pose_of(b).expect("every grasped body predicted"));
        }
        let report = run.step().map_err(|e| e.to_string())?.cloths.into_iter().next();
        let sim = run.cloths[handle].simulation();
        let mut pulls = Vec::new();
        for (b, grasp) in grasps.on_bodies() {
            let Some(k) = run.bodies.iter().position(|s| s.handle == b) else { continue };
            let (force, torque) = grasp.pull(sim, vec_from_rapier(run.world.bodies[b].center_of_mass()));
            pulls.push((k, force, torque));
        }
        for (k, force, torque) in pulls {
            // Refused for kinematic and fixed bodies: nothing there moves.
            let _ = run.apply_force(k, force, torque);
        }
        Ok(report)
    }
}

#[pymethods]
impl World {
    /// Reads and builds the scene at `path` with `overrides` (as
    /// `Scene.from_toml`): its cloth, `[[bodies]]`, `[[attachments]]`,
    /// `[rig]` and `[coupling]`. A scene without bodies is a world with
    /// none. It steps on `threads` threads (default: rayon's).
    #[staticmethod]
    #[pyo3(signature = (path, overrides = None, threads = None))]
    fn from_toml(
        py: Python<'_>,
        path: PathBuf,
        overrides: Option<&Bound<'_, PyAny>>,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        let sets = override_args(overrides)?;
        let scene = CoupledScene::load(&path, &sets).map_err(|e| scene_error(py, &e.file, &e.kind))?;
        let run = scene.build().map_err(|kind| scene_error(py, &path, &kind))?;
        static WORLDS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let id = WORLDS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(Self { id, run, grasps: Grasps::default(), pool: crate::threads::pool(threads)?, last: None })
    }

    /// Takes `n` steps of the scene's `dt_s`, with the GIL released. Body
    /// grasps follow their bodies, which feel the grasp's pull one step
    /// late. A step that fails raises `StepError` with `.time_s`.
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: usize) -> PyResult<()> {
        let (run, grasps, pool, last) = (&mut self.run, &self.grasps, &self.pool, &mut self.last);
        let failed = py.detach(|| {
            pool.install(|| {
                for k in 0..n {
                    match World::step_once(run, grasps) {
                        Ok(report) => *last = report,
                        Err(e) => return Some((k, run.cloths[run.cloth].simulation().time(), e)),
                    }
                }
                None
            })
        });
        crate::steps_taken(py, n, failed)
    }

    /// Simulated time, s.
    #[getter]
    fn time_s(&self) -> f64 {
        self.sim().time()
    }

    /// The step, s.
    #[getter]
    fn dt_s(&self) -> f64 {
        self.run.config.dt_s
    }

    /// Number of cloth particles.
    #[getter]
    fn particle_count(&self) -> usize {
        self.sim().model().particle_count()
    }

    /// Every particle's position, m, an `(n, 3)` array (a copy).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, self.sim().state().x.iter().copied())
    }

    /// Every particle's velocity, m/s, an `(n, 3)` array (a copy).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows(py, self.sim().state().v.iter().copied())
    }

    /// Every particle's mass, kg.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.sim().model().masses().to_vec().into_pyarray(py)
    }

    /// The cloth's triangles, an `(m, 3)` array of particle indices.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<i64>> {
        triangles(py, self.sim().model())
    }

    /// What the cloth's last step reported (as `Simulation.last_step`),
    /// or `None` before the first step.
    fn last_step<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.last.as_ref().map(|r| crate::report_dict(py, r)).transpose()
    }

    /// The longest link over its rest length.
    fn max_stretch(&self) -> f64 {
        self.sim().model().max_stretch_ratio(&self.sim().state().x)
    }

    /// The `[[bodies]]` names, in scene order.
    #[getter]
    fn body_names(&self) -> Vec<String> {
        self.run.bodies.iter().map(|b| b.name.clone()).collect()
    }

    /// The rig's link names, in the URDF's order (empty without a `[rig]`).
    #[getter]
    fn link_names(&self) -> Vec<String> {
        self.run.rig.as_ref().map(|r| r.rig.links.iter().map(|l| l.name.clone()).collect()).unwrap_or_default()
    }

    /// Rig link `name`'s pose: its frame origin (m) and orientation as a
    /// unit quaternion `[x, y, z, w]`.
    fn link_pose<'py>(&self, py: Python<'py>, name: &str) -> PyResult<ArrayPair<'py>> {
        let rig = self.run.rig.as_ref().ok_or_else(|| ControlError::new_err("the scene has no [rig]"))?;
        let handle = rig.body(name).ok_or_else(|| {
            ControlError::new_err(format!("the rig has no link {name:?}; its links: {:?}", self.link_names()))
        })?;
        Ok(pose_arrays(py, pose_from_rapier(self.run.world.bodies[handle].position())))
    }

    /// Body `name`'s mass, kg.
    fn body_mass(&self, name: &str) -> PyResult<f64> {
        let k = self.body_index(name)?;
        Ok(self.run.world.bodies[self.run.bodies[k].handle].mass())
    }

    /// Body `name`'s pose: its frame origin (m) and orientation as a unit
    /// quaternion `[x, y, z, w]`.
    fn body_pose<'py>(&self, py: Python<'py>, name: &str) -> PyResult<ArrayPair<'py>> {
        let (pose, _, _) = self.run.body_state(self.body_index(name)?).map_err(control_error)?;
        Ok(pose_arrays(py, pose))
    }

    /// Body `name`'s velocity: of its centre of mass (m/s) and angular (rad/s).
    fn body_velocity<'py>(&self, py: Python<'py>, name: &str) -> PyResult<ArrayPair<'py>> {
        let (_, v, w) = self.run.body_state(self.body_index(name)?).map_err(control_error)?;
        Ok((array3(py, v), array3(py, w)))
    }

    /// What the cloth did to body `name` over the last step, through its
    /// contacts and attached pins: a dict of `force` (N), `torque` (N m,
    /// about the centre of mass) and `contacts`.
    fn cloth_force<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let load = self.run.cloth_load(self.body_index(name)?).map_err(control_error)?;
        let out = PyDict::new(py);
        out.set_item("force", array3(py, load.force_n))?;
        out.set_item("torque", array3(py, load.torque_n_m))?;
        out.set_item("contacts", load.contacts)?;
        Ok(out)
    }

    /// Adds a force (N, through the centre of mass) and torque (N m) to
    /// dynamic body `name` for the next step.
    #[pyo3(signature = (name, force, torque = [0.0, 0.0, 0.0]))]
    fn apply_force(&mut self, name: &str, force: [f64; 3], torque: [f64; 3]) -> PyResult<()> {
        let k = self.body_index(name)?;
        self.run.apply_force(k, Vec3::from(force), Vec3::from(torque)).map_err(control_error)
    }

    /// Sends kinematic body `name`'s frame to `position` (m), turned by the
    /// rotation vector `rotation` (rad), by the end of the next step; it
    /// stays there (its scripted motion is replaced).
    #[pyo3(signature = (name, position, rotation = [0.0, 0.0, 0.0]))]
    fn set_kinematic_target(&mut self, name: &str, position: [f64; 3], rotation: [f64; 3]) -> PyResult<()> {
        let k = self.body_index(name)?;
        let pose = BodyPose {
            position: Vec3::from(position),
            rotation: UnitQuaternion::from_scaled_axis(Vec3::from(rotation)),
        };
        self.run.set_kinematic_target(k, pose).map_err(control_error)
    }

    /// The rig's joints and their values now: a float for revolute and
    /// continuous joints (rad) and prismatic ones (m), a rotation vector
    /// (rad) for spherical ones; fixed and floating joints are left out.
    fn joint_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for (name, value) in self.run.joint_positions().map_err(control_error)? {
            match value {
                JointValue::Angle(a) | JointValue::Offset(a) => out.set_item(name, a)?,
                JointValue::Rotation(q) => out.set_item(name, q.scaled_axis().as_slice().to_vec())?,
                JointValue::Motion(_) | JointValue::None => {}
            }
        }
        Ok(out)
    }

    /// Sets rig joints by name for the end of the next step and holds the
    /// pose from then on (the scene's motion no longer drives the rig):
    /// floats for revolute, continuous (rad) and prismatic (m) joints,
    /// rotation vectors (rad) for spherical ones.
    fn set_joint_positions(&mut self, values: &Bound<'_, PyDict>) -> PyResult<()> {
        let joints = self.run.joint_positions().map_err(control_error)?;
        let mut set = Vec::with_capacity(values.len());
        for (key, value) in values.iter() {
            let name = key.extract::<String>()?;
            let current = joints.iter().find(|(n, _)| *n == name).map(|(_, v)| v);
            let parsed = match current {
                Some(JointValue::Rotation(_)) => {
                    let r: [f64; 3] = value.extract().map_err(|_| {
                        ControlError::new_err(format!("joint {name:?} is spherical: a rotation vector [x, y, z], rad"))
                    })?;
                    JointValue::Rotation(UnitQuaternion::from_scaled_axis(Vec3::from(r)))
                }
                Some(JointValue::Offset(_)) => JointValue::Offset(
                    value
                        .extract()
                        .map_err(|_| ControlError::new_err(format!("joint {name:?} is prismatic: an offset, m")))?,
                ),
                // Revolute, continuous, or a name the rig refuses below.
                _ => JointValue::Angle(
                    value.extract().map_err(|_| ControlError::new_err(format!("joint {name:?}: an angle, rad")))?,
                ),
            };
            set.push((name, parsed));
        }
        self.run.set_joint_positions(&set).map_err(control_error)
    }

    /// Grasps the free particles within `radius_m` (m) of `point` (m): by a
    /// gripper at the point (moved with `move_grasp`), or by body `body`,
    /// which then carries them. Returns the grasp's id.
    #[pyo3(signature = (point, radius_m, body = None))]
    fn grasp(&mut self, point: [f64; 3], radius_m: f64, body: Option<&str>) -> PyResult<usize> {
        let p = Vec3::from(point);
        let gripper = self.gripper(p, body)?;
        let handle = self.run.cloth;
        let cloth = self.run.cloths.get_mut(handle).ok_or_else(|| ControlError::new_err("the scene has no cloth"))?;
        self.grasps.grasp(cloth.simulation_mut(), p, radius_m, gripper).map_err(grasp_error)
    }

    /// Grasps `particles` at `offsets` (m, an `(k, 3)` array; in the
    /// body's frame for a body) by a gripper at `point` (m) or by body
    /// `body` (one of the two), as `grasp_particles` and `grasp_offsets`
    /// gave them: a grasp taken again after `restore`. Returns the new
    /// grasp's id; `ControlError` for a particle that is not free or
    /// offsets that do not pair up, holding nothing then.
    #[pyo3(signature = (particles, offsets, point = None, body = None))]
    fn grasp_at_offsets(
        &mut self,
        particles: Vec<usize>,
        offsets: PyReadonlyArray2<'_, f64>,
        point: Option<[f64; 3]>,
        body: Option<&str>,
    ) -> PyResult<usize> {
        let offsets = vectors("offsets", offsets)?;
        let gripper = match (point, body) {
            (Some(p), None) => self.gripper(Vec3::from(p), None)?,
            (None, Some(name)) => self.gripper(Vec3::zeros(), Some(name))?,
            _ => return Err(ControlError::new_err("grasp_at_offsets: give a point or a body, one of the two")),
        };
        let handle = self.run.cloth;
        let cloth = self.run.cloths.get_mut(handle).ok_or_else(|| ControlError::new_err("the scene has no cloth"))?;
        self.grasps.grasp_at_offsets(cloth.simulation_mut(), particles, offsets, gripper).map_err(grasp_error)
    }

    /// Each of grasp `id`'s particles' offset from its gripper (world axes
    /// for a point, the body's frame for a body), m: an `(k, 3)` array in
    /// the order of `grasp_particles(id)`.
    fn grasp_offsets<'py>(&self, py: Python<'py>, id: usize) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(rows(py, self.grasps.get(id).map_err(grasp_error)?.offsets().iter().copied()))
    }

    /// Moves point grasp `id` to `point` (m) by the end of the next step.
    fn move_grasp(&mut self, id: usize, point: [f64; 3]) -> PyResult<()> {
        let handle = self.run.cloth;
        let cloth = self.run.cloths.get_mut(handle).ok_or_else(|| ControlError::new_err("the scene has no cloth"))?;
        self.grasps.move_to(cloth.simulation_mut(), id, Vec3::from(point)).map_err(grasp_error)
    }

    /// The mean force the cloth exerted on grasp `id` over the last step, N.
    fn grasp_force<'py>(&self, py: Python<'py>, id: usize) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(array3(py, self.grasps.force(self.sim(), id).map_err(grasp_error)?))
    }

    /// The particles grasp `id` holds.
    fn grasp_particles(&self, id: usize) -> PyResult<Vec<usize>> {
        Ok(self.grasps.get(id).map_err(grasp_error)?.particles.clone())
    }

    /// Lets grasp `id`'s particles go.
    fn release(&mut self, id: usize) -> PyResult<()> {
        let handle = self.run.cloth;
        let cloth = self.run.cloths.get_mut(handle).ok_or_else(|| ControlError::new_err("the scene has no cloth"))?;
        self.grasps.release(cloth.simulation_mut(), id).map_err(grasp_error)
    }

    /// The state of the cloth and of every rapier body, collider and joint
    /// (the rig's links included) now, to come back to with `restore`.
    fn snapshot(&self) -> WorldSnapshot {
        let saved = self.run.cloths.save(&self.run.world);
        WorldSnapshot { world: self.id, time_s: self.sim().time(), saved }
    }

    /// Goes back to a snapshot of this world: stepping on repeats the
    /// steps taken from it, to the bit. The inputs set since (forces,
    /// kinematic targets, joint positions, grasps) stay as they are.
    /// `SnapshotError` (a `ValueError`) for another world's snapshot,
    /// the world left as it was.
    fn restore(&mut self, snapshot: &WorldSnapshot) -> PyResult<()> {
        if snapshot.world != self.id {
            return Err(crate::SnapshotError::new_err(
                "a snapshot of another World: a World restores only its own (its rapier bodies are its own)",
            ));
        }
        self.run
            .cloths
            .restore(&snapshot.saved, &mut self.run.world)
            .map_err(|e| crate::SnapshotError::new_err(e.to_string()))
    }
}

/// A world's state saved by [`World::snapshot`] (held in memory, for the
/// world it came from).
#[pyclass(module = "cloth", frozen)]
pub(crate) struct WorldSnapshot {
    world: u64,
    time_s: f64,
    saved: cloth_rapier::CoupledSnapshot,
}

#[pymethods]
impl WorldSnapshot {
    /// The time it was taken at, s.
    #[getter]
    fn time_s(&self) -> f64 {
        self.time_s
    }
}
