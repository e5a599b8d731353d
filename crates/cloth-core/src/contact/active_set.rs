//! The active set of solid contacts in the filtered solve (Baraff & Witkin
//! 1998; Choi & Ko 2002 §5): constraining contacts in the filter, adding
//! particles that ended inside, releasing contacts that pull, and deciding
//! stick or slide from the constraint force.

use super::contacts::*;
use crate::{ClothModel, Vec3};
use cloth_linalg::{BlockSparseMatrix, Constraint, ConstraintFilter};
use rayon::prelude::*;

/// The rows of a solved system, `(A x)_i`, as the constraint forces are
/// read from them.
pub(crate) trait SystemRows: Sync {
    /// Row `i` of `A x`.
    fn row_times(&self, i: usize, x: &[Vec3]) -> Vec3;
}

impl SystemRows for BlockSparseMatrix {
    fn row_times(&self, i: usize, x: &[Vec3]) -> Vec3 {
        BlockSparseMatrix::row_times(self, i, x)
    }
}

/// A matrix with couplings outside its pattern ([`cloth_linalg::Couplings`]):
/// their product `E x` with the solution the rows are read at, taken
/// once after the solve.
pub(crate) struct CoupledRows<'a> {
    pub(crate) matrix: &'a BlockSparseMatrix,
    pub(crate) coupled: &'a [Vec3],
}

impl SystemRows for CoupledRows<'_> {
    fn row_times(&self, i: usize, x: &[Vec3]) -> Vec3 {
        self.matrix.row_times(i, x) + self.coupled[i]
    }
}

/// After a solve: a particle whose new position `new_x` ends closer than
/// half the thickness to a solid at `t_next` becomes a contact if it was
/// free (not pinned, not released this step), or gains a second contact
/// direction if it touched one other solid with a different normal. The
/// new constraints go into `filter` with `value(target, i)`. Returns how
/// many contacts were added (the system must then be solved again).
///
/// A contact released this step from a solid that `movable` picks (a
/// body in the solve) is taken up again when its particle ends within
/// that solid: a body moves with the solve, so a particle that pulled on
/// it may meet it again (a ball of 1e-3 the cloth's mass that all four
/// particles under it let go fell into the cloth, and the particles,
/// projected out after the step, gained 5.6 mJ with no body to take their
/// impulse). Not a prescribed solid's: a released particle moves away
/// from it, and taking it up again could cycle.
#[allow(clippy::too_many_arguments)]
pub(crate) fn add_penetrating(
    model: &ClothModel,
    x: &[Vec3],
    new_x: &[Vec3],
    (t, h): (f64, f64),
    bufs: &mut Contacts,
    filter: &mut ConstraintFilter,
    (value, movable): (impl Fn(Vec3, usize) -> Vec3, impl Fn(&SolidContact) -> bool + Sync),
) -> usize {
    let thickness = model.contact_thickness();
    let colliders = model.colliders();
    bufs.first_entry.clear();
    bufs.first_entry.resize(x.len(), u32::MAX);
    for range in groups(&bufs.solid) {
        bufs.first_entry[bufs.solid[range.start].particle as usize] = range.start as u32;
    }
    let solids_next = bufs.next.at(model, &bufs.external, t + h);
    bufs.clearance.resize(x.len(), Clearance::UNKNOWN);
    let (solid, first_entry, held) = (&bufs.solid, &bufs.first_entry, &bufs.held);
    let limit = 0.5 * thickness;
    let all_lipschitz = colliders.iter().all(|c| c.shape.distance_is_lipschitz());
    // Clearing and scanning every particle's candidate each pass was most
    // of a pass: see `has_candidate`.
    bufs.has_candidate.resize(x.len(), false);
    let candidates =
        bufs.candidate.par_iter_mut().zip(bufs.clearance.par_iter_mut()).zip(bufs.has_candidate.par_iter_mut());
    candidates.enumerate().for_each(|(i, ((cand, clearance), has))| {
        *has = false;
        if prescribed(model, held, i) {
            return;
        }
        // The one solid this particle already touches, if exactly one, or
        // the body it let go of.
        let (existing, revived) = match first_entry[i] {
            u32::MAX => (None, None),
            e => {
                let mine = solid[e as usize..].iter().take_while(|c| c.particle as usize == i);
                let (count, all_active) = mine.fold((0, true), |(n, a), c| (n + 1, a && c.active));
                let entry = solid[e as usize];
                match (count, all_active) {
                    (1, true) => (Some(entry), None),
                    (1, false) if movable(&entry) => (None, Some(entry.collider as usize)),
                    _ => return,
                }
            }
        };
        // Clear of every solid with a Lipschitz distance since the last
        // pass: those queries would all answer "beyond".
        let clear = clearance.clears(&new_x[i], limit);
        if clear && all_lipschitz {
            return;
        }
        let mut beyond = f64::INFINITY;
        // Made at the first solid within reach (most particles meet none:
        // four empty candidates a particle a pass were most of the pass).
        let mut nearest: Option<Nearest> = None;
        for (k, (c, next)) in colliders.iter().zip(solids_next).enumerate() {
            let lipschitz = c.shape.distance_is_lipschitz();
            if (clear && lipschitz) || revived.is_some_and(|r| r != k) {
                continue;
            }
            let reach = reach_surface(c, (next, h), x[i], new_x[i], (limit, true), &mut 0);
            if lipschitz {
                beyond = beyond.min(reach.distance_at_least());
            }
            let Some((s, surface)) = reach.within() else { continue };
            let distinct = existing.is_none_or(|e| {
                e.collider as usize != k && (-OPPOSED_COS..=PARALLEL_COS).contains(&e.normal.dot(&surface.normal))
            });
            if distinct {
                let travel = normal_travel(surface.normal.dot(&(x[i] - surface.point)), thickness, thickness);
                let found = contact(i, k, c, &surface, s.distance_m, travel, next);
                nearest.get_or_insert_with(Nearest::new).offer(s.distance_m, found);
            }
        }
        if let Some(found) = nearest.and_then(|nearest| nearest.pick(|_| false)[0]) {
            (cand[0], *has) = (Some(found), true);
        }
        if !clear {
            *clearance = Clearance { from: new_x[i], distance_m: beyond };
        }
    });
    let before = bufs.solid.len();
    let found = bufs.has_candidate.iter().zip(&bufs.candidate).filter(|(has, _)| **has);
    let mut revived = 0;
    for c in found.filter_map(|(_, c)| c[0].as_ref()) {
        // A released entry of the same solid is taken up in place.
        match bufs.first_entry[c.particle as usize] {
            u32::MAX => bufs.solid.push(*c),
            e => {
                let entry = &mut bufs.solid[e as usize];
                if entry.collider == c.collider && !entry.active {
                    // Held along its normal only: stuck again, it would
                    // pull again (the body joins the particles it holds).
                    let revivals = entry.revivals + 1;
                    *entry = SolidContact { friction_mode: FrictionMode::Slide, revivals, ..*c };
                    revived += 1;
                } else {
                    bufs.solid.push(*c);
                }
            }
        }
    }
    let added = bufs.solid.len() - before + revived;
    if added > 0 {
        bufs.solid.sort_unstable_by_key(|c| (c.particle, c.collider));
        for range in groups(&bufs.solid) {
            if bufs.has_candidate[bufs.solid[range.start].particle as usize] {
                constrain_particle(&bufs.solid[range], x, filter, &value);
            }
        }
    }
    added
}

/// The normal displacement over the step of a contact particle now at
/// distance `d` (m) from the solid's surface at `t + h`: particles closer
/// than the thickness go to it, particles arriving from beyond `reach`
/// land on it, and particles already within `(thickness, reach]` keep
/// their distance. Pulling those down to the thickness would take an
/// attractive force, so they would be released and re-solved every step;
/// holding them lets the cloth hover by at most the margin (0.25 mm for
/// a 5 mm thickness).
pub(crate) fn normal_travel(d: f64, thickness: f64, reach: f64) -> f64 {
    let target = if d > reach { thickness } else { d.max(thickness) };
    target - d
}

/// [`normal_travel`] for a solid that gives way to the cloth (a body that
/// moves with the solve), whose surface comes `approach` (m) closer to
/// the particle over the step on the guess's motion (negative when it
/// draws away). A contact in the margin does work `f (d_end - d_start)`
/// on the pair: holding the particle still while the body draws away
/// pushes the body on (a box resting on a trampoline bobbed at 3 mm/s
/// with the energy that put in). Drawing away, the particle keeps the
/// distance it had at the start of the step, `d + approach`, and follows
/// the surface; coming closer, it keeps its place, which does no work on
/// it and takes work from the body (Moreau's inelastic contact at rest).
pub(crate) fn yielding_normal_travel(d: f64, approach: f64, thickness: f64, reach: f64) -> f64 {
    if approach >= 0.0 {
        return normal_travel(d, thickness, reach);
    }
    normal_travel(d + approach, thickness, reach) + approach
}

/// Solves `[1 c; c 1] (a, b) = (p, q)` with `c = n . m`: the coefficients
/// of the vector in span{n, m} whose components along unit `n` and `m`
/// are `p` and `q`.
pub(crate) fn two_direction_coefficients(n: &Vec3, m: &Vec3, p: f64, q: f64) -> (f64, f64) {
    let c = n.dot(m);
    let det = 1.0 - c * c;
    ((p - c * q) / det, (q - c * p) / det)
}

/// Constrains one particle from its contact entries: one active entry
/// prescribes the normal component, two prescribe both (motion stays free
/// along the crease), none frees the particle.
pub(crate) fn constrain_particle(
    group: &[SolidContact],
    x: &[Vec3],
    filter: &mut ConstraintFilter,
    value: &impl Fn(Vec3, usize) -> Vec3,
) {
    let i = group[0].particle as usize;
    let mut active = group.iter().filter(|c| c.active && !c.pressed);
    // A non-finite value is caught as a non-finite state after the step.
    let _ = match (active.next(), active.next()) {
        (None, _) => filter.set(i, Constraint::Free, Vec3::zeros()),
        (Some(c), None) if c.friction_mode == FrictionMode::Stick => {
            let z = value(x[i] + c.normal * c.normal_travel_m + c.tangent_travel_m, i);
            filter.set(i, Constraint::Fixed, z)
        }
        (Some(c), None) => {
            let z = value(x[i] + c.normal * c.normal_travel_m, i);
            filter.set(i, Constraint::OneDirection { normal: c.normal }, z)
        }
        (Some(a), Some(b)) => {
            let (p, q) = two_direction_coefficients(&a.normal, &b.normal, a.normal_travel_m, b.normal_travel_m);
            let z = value(x[i] + a.normal * p + b.normal * q, i);
            filter.set(i, Constraint::TwoDirections { n: a.normal, m: b.normal }, z)
        }
    };
}

/// Adds the contacts of `contacts` (sorted by particle) to `filter`: the
/// normal components of particle `i`'s unknown become those of
/// `value(target, i)`, where `target` is the position that ends the step
/// on the offset surface(s). Released contacts are skipped.
pub(crate) fn constrain_contacts(
    contacts: &[SolidContact],
    x: &[Vec3],
    filter: &mut ConstraintFilter,
    value: impl Fn(Vec3, usize) -> Vec3,
) {
    for range in groups(contacts) {
        if contacts[range.clone()].iter().any(|c| c.active) {
            constrain_particle(&contacts[range], x, filter, &value);
        }
    }
}

/// Puts the friction of every particle held by one solid alone (not
/// squeezed, not `prescribed` (pinned or held), with `mu > 0`, its
/// friction not yet in the solve) into the solve: a resting one starts
/// stuck ([`FrictionMode::Stick`]), moving with the surface over the step
/// `h` (s); a landing one (moving more than `LANDING_TRAVEL_M`, 1 mm, towards
/// the surface this step) starts sliding with no friction, which
/// `stick_or_slide` sets against its slip after the first solve (or
/// sticks it when it barely slips). Returns how many (constrain them
/// again, `constrain_contacts`).
/// Contacts found during the step's passes join too.
///
/// Solids whose motion from outside is a guess (`driven(collider)`:
/// [`crate::Control::set_solid_motion`], rapier's dynamic and fixed
/// bodies; not prescribed motions such as rig links, which are exact) keep
/// the friction after the solve. Their velocity over the step is the
/// co-simulation master's guess; a particle stuck to it hands the
/// body the whole cloth's tangential pull at once (up to `mu N`, with `N`
/// carrying the cloth's tension), and a body lighter than the cloth is
/// thrown by it between passes (`cloth study stability`, a ball of 1e-3
/// the cloth's mass: its energy rose 27% of the energy in play, 0 with the
/// friction after the solve).
pub(crate) fn stick_frictional_contacts(
    contacts: &mut [SolidContact],
    h: f64,
    prescribed: impl Fn(usize) -> bool,
    driven: impl Fn(usize) -> bool,
) -> usize {
    let mut stuck = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        let [c] = group else { continue };
        let eligible = c.active && !c.pressed && c.friction > 0.0 && c.friction_mode == FrictionMode::AfterSolve;
        if eligible && !driven(c.collider as usize) && !prescribed(c.particle as usize) {
            let n = c.normal;
            c.tangent_travel_m = (c.solid_velocity - n * n.dot(&c.solid_velocity)) * h;
            // A landing particle slides first (its friction set from its
            // slip after the first solve): stopped dead on landing it
            // would drag on its neighbours still in the air.
            let landing = c.normal_travel_m < -LANDING_TRAVEL_M;
            c.friction_mode = if landing { FrictionMode::Slide } else { FrictionMode::Stick };
            c.solve_constant_n = Vec3::zeros();
            stuck += 1;
        }
    }
    stuck
}

/// Travel towards a solid over a step beyond which a contact is landing,
/// not resting, m. A landing particle starts sliding: stuck at once it
/// stopped dead while its neighbours, not yet in contact, fell on (the
/// sphere drape's landing step stretched links to 1.46; sliding first,
/// 1.14, frictionless 1.13).
pub(crate) const LANDING_TRAVEL_M: f64 = 1e-3;

/// Slip along the friction over a step below which a sliding contact is
/// not taken as turned back (m): solver noise (the PCG's relative
/// tolerance of the step's motion), not motion.
pub(crate) const REVERSAL_SLIP_M: f64 = 1e-6;

/// Settles the friction in the solve after a solve (and after
/// `release_pulling` read the normal forces), from the solved new
/// positions `new_x`: a stuck contact whose tangential constraint force
/// `f_t` (the unfiltered residual) exceeds `mu N` slides from now on,
/// with the friction `mu N f_t / |f_t|` added to `rhs` (times
/// `force_coefficient`) and only its normal constrained; a sliding one
/// whose slip over the step (relative to the surface) went along its
/// friction was turned back by it, so it sticks, once a step: turned back
/// and then over its bound again it is at the bound (`|f_t| = mu N` with
/// next to no slip, where sticking and sliding meet), and it slides on
/// from then (in the Table-1 garments contacts went stick, slide, stick,
/// slide, stick pass after pass; allowed to turn back every time, the
/// passes never settled). One sliding on keeps its
/// direction (that of the force that would have stuck it: implicit
/// Coulomb friction) at the new `mu N`; a landed one takes `mu N` against
/// its slip (or sticks if it barely slipped); a released one, or one whose
/// particle now touches a second solid, goes back to the friction after
/// the solve. Returns how many changed between sticking and sliding (a
/// re-solve is due; the caller caps the passes).
#[allow(clippy::too_many_arguments)]
pub(crate) fn stick_or_slide(
    contacts: &mut [SolidContact],
    matrix: &impl SystemRows,
    rhs: &mut [Vec3],
    (unknown, force_coefficient): (&[Vec3], f64),
    x: &[Vec3],
    new_x: &[Vec3],
    filter: &mut ConstraintFilter,
    value: impl Fn(Vec3, usize) -> Vec3,
) -> usize {
    let mut changed = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        let alone = group.len() == 1;
        for c in group.iter_mut().filter(|c| c.friction_mode != FrictionMode::AfterSolve) {
            let i = c.particle as usize;
            let (n, limit) = (c.normal, c.friction * c.normal_force_n.max(0.0));
            let before = c.friction_mode;
            let old = if c.friction_mode == FrictionMode::Slide { c.solve_constant_n } else { Vec3::zeros() };
            let friction = match c.friction_mode {
                // Released, or the particle now touches a second solid.
                _ if !c.active || !alone => {
                    rhs[i] -= old * force_coefficient;
                    (c.friction_mode, c.solve_constant_n) = (FrictionMode::AfterSolve, Vec3::zeros());
                    continue;
                }
                FrictionMode::Stick => {
                    let force = (matrix.row_times(i, unknown) - rhs[i]) / force_coefficient;
                    let tangential = force - n * n.dot(&force);
                    if tangential.norm() <= limit {
                        c.solve_constant_n = tangential;
                        continue;
                    }
                    c.friction_mode = FrictionMode::Slide;
                    tangential * (limit / tangential.norm())
                }
                FrictionMode::Slide => {
                    let moved = new_x[i] - x[i] - c.tangent_travel_m;
                    let slip = moved - n * n.dot(&moved);
                    match old.try_normalize(0.0) {
                        // Landed: against its slip, or stuck when it barely slips.
                        None if slip.norm() <= REVERSAL_SLIP_M => {
                            c.friction_mode = FrictionMode::Stick;
                            Vec3::zeros()
                        }
                        None => -slip.normalize() * limit,
                        Some(d) if slip.dot(&d) > REVERSAL_SLIP_M && !c.turned_back => {
                            (c.friction_mode, c.turned_back) = (FrictionMode::Stick, true);
                            Vec3::zeros()
                        }
                        Some(d) => d * limit,
                    }
                }
                FrictionMode::AfterSolve => unreachable!("filtered out"),
            };
            rhs[i] += (friction - old) * force_coefficient;
            c.solve_constant_n = friction;
            if before != c.friction_mode {
                constrain_particle(std::slice::from_ref(c), x, filter, &value);
            }
            if before != c.friction_mode || (old == Vec3::zeros() && friction != Vec3::zeros()) {
                changed += 1;
            }
        }
    }
    changed
}

/// Reads the normal forces of one particle's held (active, not pressed)
/// contacts from the unfiltered residual (see [`release_pulling`]);
/// returns the held entries and the constraint force, N (`None`: none held).
#[allow(clippy::type_complexity)]
fn read_normal_forces(
    group: &mut [SolidContact],
    matrix: &impl SystemRows,
    rhs: &[Vec3],
    unknown: &[Vec3],
    force_coefficient: f64,
) -> Option<((usize, Option<usize>), Vec3)> {
    let i = group[0].particle as usize;
    let mut active = (0..group.len()).filter(|&k| group[k].active && !group[k].pressed);
    let (a, second) = (active.next()?, active.next());
    // A squeezed particle's holding contact also carries the push of
    // the solid pressing from the other side (not part of the solve).
    let pressing: Vec3 = group.iter().filter(|c| c.active && c.pressed).map(|c| c.normal * c.normal_force_n).sum();
    let force = (matrix.row_times(i, unknown) - rhs[i]) / force_coefficient - pressing;
    match second {
        None => group[a].normal_force_n = group[a].normal.dot(&force),
        Some(b) => {
            let (na, nb) = (group[a].normal, group[b].normal);
            let (p, q) = two_direction_coefficients(&na, &nb, na.dot(&force), nb.dot(&force));
            (group[a].normal_force_n, group[b].normal_force_n) = (p, q);
        }
    }
    Some(((a, second), force))
}

/// Reads the constraint forces of the last solve into the contacts of the
/// particles `chosen` picks, without releasing any: the normal forces,
/// and a stuck contact's tangential force. A body in the solve took
/// exactly these forces, so its reported impulse must be them too, even
/// when the contact passes ended on a solve whose forces no pass read.
pub(crate) fn read_contact_forces(
    contacts: &mut [SolidContact],
    matrix: &impl SystemRows,
    rhs: &[Vec3],
    (unknown, force_coefficient): (&[Vec3], f64),
    chosen: impl Fn(&SolidContact) -> bool,
) {
    for group in contacts.chunk_by_mut(same_particle) {
        if !group.iter().any(&chosen) {
            continue;
        }
        let Some(((a, second), force)) = read_normal_forces(group, matrix, rhs, unknown, force_coefficient) else {
            continue;
        };
        let c = &mut group[a];
        if second.is_none() && c.friction_mode == FrictionMode::Stick {
            c.solve_constant_n = force - c.normal * c.normal.dot(&force);
        }
    }
}

/// How often a step's passes take a contact up again after a body let it
/// go ([`add_penetrating`]) before it is held for the rest of the step,
/// if the body is heavier than its particle (`release_pulling`'s `kept`).
/// Held, it pulled; released, its particle ended inside the body: the
/// consistent answer lies between, where it touches with no force, and
/// the passes alternated between the two until they ran out (`ten-balls`:
/// 12 of 90 steps at 30 passes, ending held). Twice: once let a hammock's
/// ball, resting in the cloth, move at 1.0 mm/s after 4 s instead of 0.61
/// (some contacts settle on the second take-up). A body lighter than the
/// particle (a 36 mg ball on a 36 g cloth) is not held so: the cloth,
/// joined to it for the rest of the step, threw it, and the energy in play
/// rose by 1.4e-3 to 2.1e-2 for a limit of 2 to 10.
pub(crate) const MAX_REVIVALS: u8 = 2;

/// Reads each contact's normal force from the unfiltered residual,
/// `f_c = (A u - b)_i / force_coefficient` (split along both normals for
/// a two-solid contact), and releases those that pull; the particle is
/// then re-constrained with what remains, through `value` as in
/// `constrain_contacts`. Returns how many were released.
///
/// A contact that `kept` picks stays (see [`MAX_REVIVALS`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn release_pulling(
    contacts: &mut [SolidContact],
    matrix: &impl SystemRows,
    rhs: &[Vec3],
    unknown: &[Vec3],
    force_coefficient: f64,
    x: &[Vec3],
    filter: &mut ConstraintFilter,
    (value, kept): (impl Fn(Vec3, usize) -> Vec3, impl Fn(&SolidContact) -> bool),
) -> usize {
    let mut released = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        let Some(((a, second), _)) = read_normal_forces(group, matrix, rhs, unknown, force_coefficient) else {
            continue;
        };
        let mut changed = false;
        for k in [Some(a), second].into_iter().flatten() {
            let c = &mut group[k];
            if c.normal_force_n < 0.0 && !kept(c) {
                (c.active, c.normal_force_n, changed) = (false, 0.0, true);
                released += 1;
            }
        }
        if changed && !group.iter().any(|c| c.active && !c.pressed) {
            // The holding solid let go: the pressing one holds instead.
            for c in group.iter_mut().filter(|c| c.active && c.pressed) {
                (c.pressed, c.normal_force_n) = (false, 0.0);
            }
        }
        if changed {
            constrain_particle(group, x, filter, &value);
        }
    }
    released
}
