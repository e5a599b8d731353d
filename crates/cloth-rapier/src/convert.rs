//! Conversions at the rapier boundary: rapier speaks glam (`DVec3`,
//! `DQuat`, `DPose3` through its `math` re-exports), the cloth nalgebra.
//! Component-wise, so no nalgebra version has to match rapier's.

use cloth_core::{BodyPose, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};
use rapier3d_f64::math::{Pose, Rotation, Vector};

/// A rapier vector as a cloth vector.
pub fn vec_from_rapier(v: Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// A cloth vector as a rapier vector.
pub fn vec_to_rapier(v: Vec3) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

/// A rapier rotation as a unit quaternion.
pub fn rotation_from_rapier(q: Rotation) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(Quaternion::new(q.w, q.x, q.y, q.z))
}

/// A unit quaternion as a rapier rotation.
pub fn rotation_to_rapier(q: UnitQuaternion<f64>) -> Rotation {
    Rotation::from_xyzw(q.i, q.j, q.k, q.w)
}

/// A rapier pose as a cloth solid pose.
pub fn pose_from_rapier(p: &Pose) -> BodyPose {
    BodyPose { position: vec_from_rapier(p.translation), rotation: rotation_from_rapier(p.rotation) }
}

/// A cloth solid pose as a rapier pose.
pub fn pose_to_rapier(p: &BodyPose) -> Pose {
    Pose::from_parts(vec_to_rapier(p.position), rotation_to_rapier(p.rotation))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_round_trip_and_transform_points_alike() {
        let pose = BodyPose {
            position: Vec3::new(0.3, -1.2, 2.5),
            rotation: UnitQuaternion::from_scaled_axis(Vec3::new(0.4, -0.9, 1.3)),
        };
        let back = pose_from_rapier(&pose_to_rapier(&pose));
        assert!((back.position - pose.position).norm() < 1e-15);
        assert!(back.rotation.angle_to(&pose.rotation) < 1e-12);
        let local = Vec3::new(0.1, 0.2, -0.7);
        let ours = pose.position + pose.rotation * local;
        let theirs = vec_from_rapier(pose_to_rapier(&pose).transform_point(vec_to_rapier(local)));
        assert!((ours - theirs).norm() < 1e-14, "{ours} vs {theirs}");
    }
}
