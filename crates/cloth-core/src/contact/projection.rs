//! The safety net after a solve and the path without a matrix: moving
//! particles left inside a solid back to its surface, and the diagnostic
//! deepest penetration.

use super::contacts::*;
use crate::control::Control;
use crate::{ClothModel, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// The safety net after the active set: particles that still end closer
/// than half the thickness to a solid at `t_next` are moved back to the
/// thickness along the normal of the side they came from, and lose their
/// velocity into the solid (relative to it). Only particles released this
/// step are checked, or every particle when `all` (the active set ran out
/// of passes with contacts still being added: large steps). Positions move
/// without a matching velocity, so this is a projection, not a force; in
/// ordinary steps it finds nothing. Returns the number of particles moved.
pub(crate) fn project_out(
    model: &ClothModel,
    x: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut Contacts,
    all: bool,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) -> usize {
    let thickness = model.contact_thickness();
    let solids_next = bufs.next.at(model, &bufs.external, t + h);
    // One particle's projection: reads and moves only that particle.
    let fix = |i: usize, xi: &mut Vec3, vi: &mut Vec3| {
        let mut changed = false;
        for (c, next) in model.colliders().iter().zip(solids_next) {
            let Some((_, surface)) = reach_surface(c, (next, h), x[i], *xi, (0.5 * thickness, false), &mut 0).within()
            else {
                continue;
            };
            let n = surface.normal;
            let gap = n.dot(&(*xi - surface.point));
            if gap < thickness {
                *xi += n * (thickness - gap);
                let inward = n.dot(&(*vi - next.velocity_at(surface.point)));
                if inward < 0.0 {
                    *vi -= n * inward;
                }
                changed = true;
            }
        }
        usize::from(changed)
    };
    if all {
        // Particles are independent and the count is a sum of integers:
        // the same in any order, so in parallel. In the finish the memo of
        // the last projection skips a particle it left as it was and that
        // has not moved since.
        let (held, memo) = (&bufs.held, &mut bufs.projection_memo);
        let n = new_x.len();
        memo.at.resize(n, Vec3::zeros());
        memo.pushed.resize(n, false);
        let valid = memo.active && memo.valid;
        let moved = new_x
            .par_iter_mut()
            .zip(new_v.par_iter_mut())
            .zip(memo.at.par_iter_mut().zip(memo.pushed.par_iter_mut()))
            .enumerate()
            .with_min_len(ROW_CHUNK)
            .filter(|(i, _)| !prescribed(model, held, *i))
            .map(|(i, ((xi, vi), (at, pushed)))| {
                let same = valid && !*pushed && xi.iter().zip(at.iter()).all(|(a, b)| a.to_bits() == b.to_bits());
                if same {
                    return 0;
                }
                let m = fix(i, xi, vi);
                (*at, *pushed) = (*xi, m > 0);
                m
            })
            .sum();
        memo.valid = memo.active;
        moved
    } else {
        let mut moved = 0;
        for c in bufs.solid.iter().filter(|c| !c.active) {
            let i = c.particle as usize;
            moved += fix(i, &mut new_x[i], &mut new_v[i]);
        }
        moved
    }
}

/// Collision response for integrators without an assembled matrix (the
/// explicit ones and the fixed-iteration matrix-free backward Euler), after
/// the step, as in Provot (1995) and Bridson et al. (2002): a particle
/// ending closer than the thickness to a solid (at `t_next`) is moved back
/// to it along the normal of the side it came from, its velocity into the
/// solid is removed (an inelastic impulse `dv_n`), and its tangential
/// velocity relative to the solid loses at most `mu dv_n`, all of it when
/// that suffices (static friction: under gravity `dv_n = h g cos(theta)`
/// per step, so this is Coulomb's `mu m g cos(theta)`); the position moves
/// back by `h` times the tangential velocity removed. `x` are the
/// positions at the start of the step, at time `t`; the step is `h`. The
/// reported penetration is that of the start positions, as for the
/// implicit integrators.
pub(crate) fn collide_after_step(
    model: &ClothModel,
    x: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut Contacts,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) -> ContactStats {
    let thickness = model.contact_thickness();
    let t_next = t + h;
    bufs.candidate.resize(x.len(), [None; 2]);
    let (solids_now, solids_next) =
        (bufs.now.at(model, &bufs.external, t), bufs.next.at(model, &bufs.external, t_next));
    let (masses, held) = (model.masses(), &bufs.held);
    // Particles are independent; the counters add and the depth is a
    // maximum, so the parallel reduction is exact in any order.
    let stats = new_x
        .par_iter_mut()
        .zip(new_v.par_iter_mut())
        .zip(bufs.candidate.par_iter_mut())
        .enumerate()
        .with_min_len(ROW_CHUNK)
        .map(|(i, ((xi, vi), cand))| {
            let mut stats = ContactStats::default();
            *cand = [None; 2];
            if prescribed(model, held, i) {
                return stats;
            }
            let mut slot = 0;
            for (k, (c, (now, next))) in model.colliders().iter().zip(solids_now.iter().zip(solids_next)).enumerate() {
                let Some((_, surface)) =
                    reach_surface(c, (next, h), x[i], *xi, (thickness, false), &mut stats.narrow_phase_queries)
                        .within()
                else {
                    continue;
                };
                let before = c.shape.closest(now.pose(), x[i]);
                stats.max_penetration_m = stats.max_penetration_m.max(-before.distance_m);
                stats.narrow_phase_queries += 1;
                let n = surface.normal;
                let gap = n.dot(&(*xi - surface.point));
                if gap < thickness {
                    *xi += n * (thickness - gap);
                }
                let solid_v = next.velocity_at(surface.point);
                let rel = *vi - solid_v;
                let inward = n.dot(&rel);
                let v_before = *vi;
                if inward < 0.0 {
                    let tangential = rel - n * inward;
                    let speed = tangential.norm();
                    let budget = c.friction * -inward;
                    let slip = if speed <= budget { Vec3::zeros() } else { tangential * (1.0 - budget / speed) };
                    stats.sticking += usize::from(speed <= budget && c.friction > 0.0);
                    *vi = solid_v + slip;
                    // The step moved the particle with the velocity before
                    // friction: take back that part of the slide (x' = x + h v').
                    *xi += (slip - tangential) * h;
                }
                if slot < 2 {
                    let mut contact = contact(i, k, c, &surface, gap, 0.0, next);
                    contact.impulse_n_s = (*vi - v_before) * masses[i];
                    contact.normal_force_n = n.dot(&contact.impulse_n_s) / h;
                    cand[slot] = Some(contact);
                    slot += 1;
                }
                stats.contacts = 1;
            }
            stats
        })
        .reduce(ContactStats::default, |mut a, b| {
            a += b;
            a
        });
    bufs.solid.clear();
    bufs.solid.extend(bufs.candidate.iter().flatten().flatten());
    stats
}

/// A particle inside a solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inside {
    /// The particle.
    pub particle: usize,
    /// The solid it is deepest in (index among the model's colliders).
    pub solid: usize,
    /// How deep, m (> 0).
    pub depth_m: f64,
}

/// Every particle at positions `x` that is inside a solid at time `t`,
/// with the solid it is deepest in, in particle order (see
/// [`max_penetration`] for where the solids are); pairs `(particle,
/// solid)` that `held` says hold each other (a pin attached to that
/// solid's body) are left out.
pub(crate) fn particles_inside(
    model: &ClothModel,
    control: &Control,
    (x, t): (&[Vec3], f64),
    held: impl Fn(usize, usize) -> bool,
) -> Vec<Inside> {
    let mut deepest: Vec<Option<Inside>> = vec![None; x.len()];
    let mut frames = SolidFrames::default();
    for (solid, (c, s)) in model.colliders().iter().zip(frames.at(model, control.solid_motions(), t)).enumerate() {
        for (particle, p) in x.iter().enumerate().filter(|(i, p)| s.near(p, 0.0) && !held(*i, solid)) {
            let depth_m = -c.shape.closest(s.pose(), *p).distance_m;
            if depth_m > 0.0 && deepest[particle].is_none_or(|d| depth_m > d.depth_m) {
                deepest[particle] = Some(Inside { particle, solid, depth_m });
            }
        }
    }
    deepest.into_iter().flatten().collect()
}

/// Deepest any particle at positions `x` is inside a solid at time `t`, m
/// (0 when none is inside), with externally driven solids where `control`
/// puts them. A diagnostic: it queries every particle near every solid.
pub(crate) fn max_penetration(model: &ClothModel, control: &Control, x: &[Vec3], t: f64) -> f64 {
    let mut deepest: f64 = 0.0;
    let mut frames = SolidFrames::default();
    for (c, s) in model.colliders().iter().zip(frames.at(model, control.solid_motions(), t)) {
        for p in x.iter().filter(|p| s.near(p, 0.0)) {
            deepest = deepest.max(-c.shape.closest(s.pose(), *p).distance_m);
        }
    }
    deepest
}
