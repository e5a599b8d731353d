//! A [`Rig`] in a rapier world: one kinematic (position-based) body per
//! link carrying the link's collision shapes, moved by forward kinematics.
//!
//! Give the pose for the end of each step with [`RigBodies::drive`] before
//! stepping: rapier derives the bodies' velocities from it, and the cloth
//! sees each link move along the straight line (and the shortest turn)
//! between the two poses, as any kinematic body
//! ([`crate::world`]). Kinematic bodies do not collide with each other, so
//! overlapping links (a capsule arm through a box torso) cost nothing.

use crate::convert::pose_to_rapier;
use crate::rig::{Rig, RigError, RigGeometry, RigPose};
use cloth_collide::{BodyPose, SolidShape};
use nalgebra::Isometry3;
use rapier3d_f64::prelude::{ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle};
use std::path::Path;

/// The rapier bodies of a rig's links.
#[derive(Debug, Clone)]
pub struct RigBodies {
    /// One body per link, in [`Rig::links`] order.
    pub handles: Vec<RigidBodyHandle>,
    /// Scratch: the links' poses.
    poses: Vec<Isometry3<f64>>,
}

fn body_pose(p: &Isometry3<f64>) -> BodyPose {
    BodyPose { position: p.translation.vector, rotation: p.rotation }
}

impl RigBodies {
    /// Adds a kinematic body per link at `pose`, with the link's shapes as
    /// colliders of the given Coulomb `friction`. `file` names the rig in errors.
    pub fn insert(
        rig: &Rig,
        world: &mut PhysicsWorld,
        pose: &RigPose,
        friction: f64,
        file: &Path,
    ) -> Result<Self, RigError> {
        let mut poses = Vec::new();
        rig.link_poses(pose, &mut poses)?;
        let mut handles = Vec::with_capacity(rig.links.len());
        for (link, at) in rig.links.iter().zip(&poses) {
            let body = RigidBodyBuilder::kinematic_position_based().pose(pose_to_rapier(&body_pose(at))).build();
            let handle = world.bodies.insert(body);
            for (k, shape) in link.shapes.iter().enumerate() {
                let fail = |message: String| RigError::Invalid {
                    file: file.to_path_buf(),
                    element: "link",
                    name: link.name.clone(),
                    field: format!("collision[{k}].geometry"),
                    message,
                };
                let solid = match &shape.geometry {
                    RigGeometry::Solid(spec) => SolidShape::build(spec, Path::new("")),
                    RigGeometry::Mesh { path, scale } => SolidShape::obj_mesh(path, *scale),
                }
                .map_err(|e| fail(e.to_string()))?;
                let (parry_shape, local) = solid.parts();
                let origin = pose_to_rapier(&body_pose(&shape.origin)) * local;
                let collider = ColliderBuilder::new(parry_shape.clone()).position(origin).friction(friction).build();
                world.colliders.insert_with_parent(collider, handle, &mut world.bodies);
            }
            handles.push(handle);
        }
        Ok(Self { handles, poses })
    }

    /// Sends every link body to where `pose` puts it at the end of the next step.
    pub fn drive(&mut self, rig: &Rig, world: &mut PhysicsWorld, pose: &RigPose) -> Result<(), RigError> {
        rig.link_poses(pose, &mut self.poses)?;
        for (handle, at) in self.handles.iter().zip(&self.poses) {
            if let Some(body) = world.bodies.get_mut(*handle) {
                body.set_next_kinematic_position(pose_to_rapier(&body_pose(at)));
            }
        }
        Ok(())
    }
}
