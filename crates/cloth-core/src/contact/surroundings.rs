//! The solids around each particle, for the integrators whose contacts are
//! energies ([`crate::ContactHandling::Penalties`]): up to two nearby
//! solid surfaces, each linearised as a plane, and a ball the particle may
//! move in without reaching any other solid. Conservative per-particle
//! bounds keep each local step from carrying a particle through a surface
//! (the idea of Offset Geometric Contact; Chen et al. 2025), with no
//! continuous collision detection and no active set.

use super::contacts::{Plane, SolidPose, Surroundings, contact_penalty, contact_penalty_stiffness, smoothed_friction};
use crate::{ClothModel, Mat3, Vec3};

impl Plane {
    /// The particle's gap at `x`, m (negative inside the solid).
    pub(crate) fn gap(&self, x: &Vec3) -> f64 {
        self.normal.dot(&(x - self.point))
    }
}

impl Surroundings {
    /// Nothing near.
    pub(crate) fn free(at: Vec3) -> Self {
        Self { planes: [None; 2], centre: at, radius_m: f64::INFINITY }
    }
}

/// The solids around a particle at `from` (m), found where each solid is
/// at the step's start (`start`: the side of the surface the particle is
/// on) and carried with it to the step's end (`end`): each solid whose
/// surface is closer than `reach` (m) at either instant becomes a plane,
/// the two nearest kept; every other solid bounds the ball the particle
/// may move in, its radius the solid's least distance at the two instants
/// less the contact `thickness` (m). A distance's magnitude bounds the
/// travel to the surface whatever its sign says, so meshes bound the ball
/// too. For a particle already at its end-of-step place, pass the end
/// poses as both.
///
/// Carrying the start's plane keeps a particle a solid sweeps towards on
/// the solid's near side: found against the end pose alone, a limb that
/// moved past most of its width in one step pushed the particles it
/// swept over out of its far side (the walking skirt at Table 1's
/// resolution reached a stretch of 27).
pub(crate) fn surroundings(
    model: &ClothModel,
    (start, end): (&[SolidPose], &[SolidPose]),
    from: Vec3,
    reach: f64,
    thickness: f64,
) -> (Surroundings, u32) {
    let mut kept: [(f64, Option<Plane>); 2] = [(f64::INFINITY, None); 2];
    let mut bound = f64::INFINITY;
    let mut queries = 0;
    for (k, ((c, before), after)) in model.colliders().iter().zip(start).zip(end).enumerate() {
        if !before.near(&from, reach) && !after.near(&from, reach) {
            bound = bound.min(before.box_distance(&from)).min(after.box_distance(&from));
            continue;
        }
        queries += 1;
        let s = c.shape.closest(before.pose(), from);
        let (point, normal) = carried(before.pose(), after.pose(), s.point, s.normal);
        let distance = s.distance_m.min(normal.dot(&(from - point)));
        if distance >= reach {
            bound = bound.min(distance.abs());
            continue;
        }
        let plane = Plane {
            collider: k as u32,
            point,
            normal,
            solid_velocity: after.velocity_at(point),
            friction: c.friction,
            lagged_normal_n: 0.0,
        };
        // Keep the two nearest; one pushed out bounds the ball instead.
        let mut offer = (distance, Some(plane));
        for slot in kept.iter_mut() {
            if offer.0 < slot.0 {
                std::mem::swap(slot, &mut offer);
            }
        }
        if offer.1.is_some() {
            bound = bound.min(offer.0.abs());
        }
    }
    let found = Surroundings { planes: [kept[0].1, kept[1].1], centre: from, radius_m: (bound - thickness).max(0.0) };
    (found, queries)
}

/// A point and normal of a solid at `before`, where the solid's motion
/// carries them at `after` (rigidly: the same place in the solid's frame).
fn carried(before: &crate::BodyPose, after: &crate::BodyPose, point: Vec3, normal: Vec3) -> (Vec3, Vec3) {
    let turn = after.rotation * before.rotation.inverse();
    (after.position + turn * (point - before.position), turn * normal)
}

/// A solid's penalty and lagged friction on a particle at `x` moving at
/// `v` (m/s): force (N) and `-df/dx` with friction's `-df/dv / h` folded
/// in (N/m) for a step of `h` s. Penalty [`contact_penalty`] of stiffness
/// `k` (N/m) below `thickness` (m); friction [`smoothed_friction`] with
/// the plane's lagged normal force, smoothed below `eps` (m/s).
pub(crate) fn plane_force(plane: &Plane, x: &Vec3, v: &Vec3, k: f64, thickness: f64, h: f64, eps: f64) -> (Vec3, Mat3) {
    let n = plane.normal;
    let (_, push) = contact_penalty(plane.gap(x), thickness, k);
    let mut force = n * push;
    let mut stiffness = if push > 0.0 { n * n.transpose() * k } else { Mat3::zeros() };
    let limit = plane.friction * plane.lagged_normal_n;
    if limit > 0.0 {
        let tangent = Mat3::identity() - n * n.transpose();
        let slip = tangent * (v - plane.solid_velocity);
        let (f, _) = smoothed_friction(slip, limit, eps, &tangent);
        force += f;
        stiffness += tangent * (friction_secant(slip.norm(), limit, eps) / h);
    }
    (force, stiffness)
}

/// Lags friction's normal forces (Li et al. 2020): each plane of
/// `around` takes the penalty's push (N) at its particle's position in `x`
/// (m), for a step of `h` s and the contact `thickness` (m), and holds it
/// until the next lag.
pub(crate) fn lag_normal_forces(model: &ClothModel, around: &mut [Surroundings], x: &[Vec3], h: f64, thickness: f64) {
    for (i, a) in around.iter_mut().enumerate() {
        let k = contact_penalty_stiffness(model.masses()[i], h);
        for p in a.planes.iter_mut().flatten() {
            p.lagged_normal_n = contact_penalty(p.gap(&x[i]), thickness, k).1;
        }
    }
}

/// The share of a move (in `[0, 1]`) that keeps a gap `gap` (m), which
/// the whole move changes by `change` (m), from going below `bound` (m):
/// 1 when the move stays above it. The minimisers' conservative bounds.
pub(crate) fn share_to_bound(gap: f64, change: f64, bound: f64) -> f64 {
    if change < 0.0 && gap + change < bound { ((bound - gap) / change).max(0.0) } else { 1.0 }
}

/// The friction's secant coefficient `mu N f1(s) / s` at slip speed `s`
/// (m/s) for `limit = mu N` (N), N s/m: the local step's friction
/// stiffness (over `h`), the same in every tangent direction. Not the
/// force's exact derivative, whose part along a sliding slip vanishes
/// (the force keeps its size): with it a local Newton step overshoots the
/// point of sticking and the particle rattles across it (measured 12 mm
/// of creep on the incline in 1 s where Coulomb holds it). The secant
/// never overshoots: each step solves for the slip with the coefficient
/// of the last, and the coefficient grows as the slip falls (a lagged,
/// reweighted fixed point of the same force law).
pub(crate) fn friction_secant(s: f64, limit: f64, eps: f64) -> f64 {
    let f1_over_s = if s >= eps { 1.0 / s } else { 2.0 / eps - s / (eps * eps) };
    limit * f1_over_s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::finite_differences::gradient;

    /// A plane's penalty force is minus its energy's gradient and its block
    /// the force's Jacobian; friction's force is the smoothed Coulomb law,
    /// and the secant coefficient times the slip is the force's size.
    #[test]
    fn plane_force_is_the_penalty_gradient_and_the_smoothed_coulomb_law() {
        let normal = Vec3::new(0.2, -0.3, 1.0).normalize();
        let plane = Plane {
            collider: 0,
            point: Vec3::new(0.1, 0.2, 0.3),
            normal,
            solid_velocity: Vec3::new(0.05, 0.0, 0.0),
            friction: 0.4,
            lagged_normal_n: 0.0,
        };
        let (k, e, h, eps) = (500.0, 0.005, 0.01, 1e-3);
        let x = plane.point + normal * 0.003 + Vec3::new(0.01, 0.02, 0.0);
        let energy = |p: Vec3| contact_penalty(plane.gap(&p), e, k).0;
        let (f, stiffness) = plane_force(&plane, &x, &Vec3::zeros(), k, e, h, eps);
        assert!((f + gradient(energy, x, 1e-7)).norm() < 1e-6 * f.norm(), "{f}");
        let fd = Mat3::from_fn(|r, c| {
            let d = Vec3::ith(c, 1e-7);
            let fp = plane_force(&plane, &(x + d), &Vec3::zeros(), k, e, h, eps).0;
            let fm = plane_force(&plane, &(x - d), &Vec3::zeros(), k, e, h, eps).0;
            -(fp - fm)[r] / 2e-7
        });
        assert!((stiffness - fd).norm() < 1e-6 * stiffness.norm());
        // Friction with a lagged normal force.
        let rubbing = Plane { lagged_normal_n: 2.0, ..plane };
        let tangent = Mat3::identity() - normal * normal.transpose();
        for speed in [2e-4, 5e-3, 0.3] {
            let v = plane.solid_velocity + (tangent * Vec3::new(1.0, 0.5, 0.0)).normalize() * speed;
            let (with, _) = plane_force(&rubbing, &x, &v, k, e, h, eps);
            let friction = with - f;
            let slip = tangent * (v - plane.solid_velocity);
            let (law, _) = smoothed_friction(slip, 0.8, eps, &tangent);
            assert!((friction - law).norm() < 1e-12, "{speed}: {friction} against {law}");
            assert!((friction_secant(speed, 0.8, eps) * speed - law.norm()).abs() < 1e-12);
        }
    }
}
