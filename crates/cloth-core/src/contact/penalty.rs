//! Solid contacts inside Newton's minimisation: the penalty energy of
//! contacts and the lagged, smoothed Coulomb friction potential.

use super::contacts::*;
use crate::{ClothModel, Mat3, Vec3};
use rayon::prelude::*;

/// The contacts of a Newton iterate at positions `x_iter` (from `x` at the
/// start of the step) into `bufs.solid`, in particle order: each particle
/// (not pinned) closer than the thickness to a solid at `t_next` gets one
/// entry per such solid, on the solid's tangent plane at the closest point
/// of the iterate (of the start of the step, the side it came from, when
/// the iterate is inside), with `normal_force_n` its [`contact_penalty`]
/// force for the step `h`.
pub(crate) fn penalty_contacts(
    model: &ClothModel,
    x: &[Vec3],
    x_iter: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut Contacts,
) {
    let thickness = model.contact_thickness();
    let (colliders, masses) = (model.colliders(), model.masses());
    let solids_next = bufs.next.at(model, &bufs.external, t + h);
    bufs.candidate.resize(x.len(), [None; 2]);
    bufs.candidate.par_iter_mut().enumerate().for_each(|(i, cand)| {
        *cand = [None; 2];
        if model.is_pinned(i) {
            return;
        }
        let mut found = 0;
        for (k, (c, next)) in colliders.iter().zip(solids_next).enumerate() {
            // No sweep (`h = 0`): the penalty acts on each iterate, and
            // choosing the face a solid swept over the start position
            // stretched the ball-through-curtain's Newton steps to 1.153
            // (1.109 with the face nearest the iterate).
            let Some((at, side)) = reach_surface(c, (next, 0.0), x[i], x_iter[i], (thickness, false), &mut 0).within()
            else {
                continue;
            };
            let plane = if at.distance_m >= 0.0 { at } else { side };
            let gap = plane.normal.dot(&(x_iter[i] - plane.point));
            let (_, force) = contact_penalty(gap, thickness, contact_penalty_stiffness(masses[i], h));
            if force > 0.0 && found < 2 {
                let mut entry = contact(i, k, c, &plane, gap, 0.0, next);
                entry.normal_force_n = force;
                cand[found] = Some(entry);
                found += 1;
            }
        }
    });
    bufs.solid.clear();
    bufs.solid.extend(bufs.candidate.iter().flatten().flatten());
}

/// The solids a Newton correction `p` (unknown; positions move by `a p`)
/// would carry particles into, from the iterate `x_iter` whose contacts
/// `penalty_contacts` found: into `bufs.watch`, one entry per particle
/// whose full-step position `x_iter + a p` is closer than the thickness to
/// a solid it has no contact with, on the solid's tangent plane at the
/// point nearest the iterate (where the particle comes from, so its
/// penalty there is zero: the line's potential keeps the residual as its
/// slope). Without them the line search saw only the iterate's contacts:
/// an iterate just off a heavy ball moving into the cloth stepped its
/// particles deep into the ball (nothing to stop a full step), the next
/// pushed them out past the thickness, and Newton alternated between the
/// two for all 30 corrections, handing the coupling a 70 N penalty.
pub(crate) fn penalty_watch(model: &ClothModel, x_iter: &[Vec3], p: &[Vec3], a: f64, t_next: f64, bufs: &mut Contacts) {
    let thickness = model.contact_thickness();
    let colliders = model.colliders();
    let solids_next = bufs.next.at(model, &bufs.external, t_next);
    bufs.watch.clear();
    for i in 0..x_iter.len() {
        if model.is_pinned(i) || p[i] == Vec3::zeros() {
            continue;
        }
        let end = x_iter[i] + p[i] * a;
        for (k, (c, next)) in colliders.iter().zip(solids_next).enumerate() {
            let touching = bufs.candidate[i].iter().flatten().any(|e| e.collider as usize == k);
            if touching {
                continue;
            }
            let Some((_, side)) = reach_surface(c, (next, 0.0), x_iter[i], end, (thickness, false), &mut 0).within()
            else {
                continue;
            };
            let gap = side.normal.dot(&(x_iter[i] - side.point));
            bufs.watch.push(contact(i, k, c, &side, gap, 0.0, next));
        }
    }
}

/// The penalty energy of `contacts` (`penalty_contacts`) with particle
/// `i` at `x_i + beta p_i`, each on its frozen tangent plane, J.
pub(crate) fn contact_penalty_energy(
    contacts: &[SolidContact],
    model: &ClothModel,
    h: f64,
    x: &[Vec3],
    p: &[Vec3],
    beta: f64,
) -> f64 {
    let (thickness, masses) = (model.contact_thickness(), model.masses());
    contacts
        .iter()
        .map(|c| {
            let i = c.particle as usize;
            let gap = c.normal.dot(&(x[i] + p[i] * beta - c.point));
            contact_penalty(gap, thickness, contact_penalty_stiffness(masses[i], h)).0
        })
        .sum()
}

/// Whether a contact's friction is a Newton iterate's smoothed friction:
/// active, holding (a pressed contact's friction is
/// `linearise_squeeze_friction`'s), with a coefficient.
pub(crate) fn holds_with_friction(c: &SolidContact) -> bool {
    c.active && !c.pressed && c.friction > 0.0
}

/// The holding contacts' [`smoothed_friction`] linearised about the
/// velocities `v` of a Newton iterate, each with the normal force
/// `normal_force(contact)` (N; lagged, Li et al. 2020 §5.2):
/// `f(v) ~ f(v_k) - C (v - v_k)`, `C` added to `damping` (N s/m) and
/// `f(v_k) + C v_k` to `external` (N), and kept on the contact
/// (`solve_damping`, `solve_constant_n`, `solve_limit_n`) so
/// `contact_friction_potential` and `apply_friction` know what the
/// solve applied.
pub(crate) fn linearise_contact_friction(
    contacts: &mut [SolidContact],
    v: &[Vec3],
    normal_force: impl Fn(&SolidContact) -> f64,
    damping: &mut [Mat3],
    external: &mut [Vec3],
) {
    for c in contacts.iter_mut().filter(|c| holds_with_friction(c)) {
        let i = c.particle as usize;
        let tangent = Mat3::identity() - c.normal * c.normal.transpose();
        let slip = tangent * (v[i] - c.solid_velocity);
        let limit = c.friction * normal_force(c).max(0.0);
        let (force, damp) = smoothed_friction(slip, limit, FRICTION_SMOOTHING_M_S, &tangent);
        // f(w_k) - C (w - w_k) with w = P (v - v_s) and C P = C.
        let constant = force + damp * v[i];
        damping[i] += damp;
        external[i] += constant;
        (c.solve_damping, c.solve_constant_n, c.solve_limit_n) = (damp, constant, limit);
    }
}

/// The holding contacts' friction dissipation
/// `sum mu N F0(|P (v + beta p - v_s)|)`, W ([`smoothed_friction_potential`]),
/// with the bounds `mu N` of the last `linearise_contact_friction`.
pub(crate) fn contact_friction_potential(contacts: &[SolidContact], v: &[Vec3], p: &[Vec3], beta: f64) -> f64 {
    contacts
        .iter()
        .filter(|c| holds_with_friction(c))
        .map(|c| {
            let i = c.particle as usize;
            let w = v[i] + p[i] * beta - c.solid_velocity;
            let slip = w - c.normal * c.normal.dot(&w);
            smoothed_friction_potential(slip, c.solve_limit_n, FRICTION_SMOOTHING_M_S)
        })
        .sum()
}
