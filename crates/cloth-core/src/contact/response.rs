//! The response after the solve: friction of squeezed contacts, no
//! outward velocity off a holding solid, BDF2's history restarted at
//! contacts, and Coulomb friction on the end velocities.

use super::contacts::*;
use crate::{Mat3, Vec3};

/// Friction of squeezed particles that slide, inside the implicit solve:
/// [`sliding_friction`] linearised about the slip `w0 = P (v - v_s)` at
/// the start of the step, relative to the pressing solid (velocity `v_s`)
/// in the holding solid's tangent plane (`P = I - n n^T`), with `N` the
/// pressing force ([`squeeze_force`]): `f = f(w0) - C (w - w0)`, which is
/// `e - C v`; `C` is added to `damping` (N s/m) and `e` to `external`
/// (N). Only slips above [`SLIDE_SPEED`]. Why in the solve: a pressing
/// solid often rests on a few particles (a box on its leading edge), and
/// friction applied after the solve cannot exceed what stops that
/// particle alone (`m |w| / h`); in the solve its neighbours' links take
/// up the load and the full `mu N` reaches the cloth. A particle that
/// would stop within the step overshoots; `apply_friction` stops it. Returns whether any was added.
pub(crate) fn linearise_squeeze_friction(
    contacts: &mut [SolidContact],
    v: &[Vec3],
    damping: &mut [Mat3],
    external: &mut [Vec3],
) -> bool {
    let mut added = false;
    for group in contacts.chunk_by_mut(same_particle) {
        let Some(hold) = group.iter().find(|c| c.active && !c.pressed).map(|c| c.normal) else { continue };
        let tangent = Mat3::identity() - hold * hold.transpose();
        for c in group.iter_mut().filter(|c| c.pressed && c.friction > 0.0) {
            let i = c.particle as usize;
            let slip = tangent * (v[i] - c.solid_velocity);
            if slip.norm() <= SLIDE_SPEED {
                continue;
            }
            let limit = c.friction * c.normal_force_n;
            let damp = sliding_friction_damping(slip, limit, &tangent);
            // f(w0) - C (w - w0) with w = P (v - v_s), C P = C and C w0 = 0.
            let constant = sliding_friction(slip, limit) + damp * c.solid_velocity;
            damping[i] += damp;
            external[i] += constant;
            (c.solve_damping, c.solve_constant_n) = (damp, constant);
            added = true;
        }
    }
    added
}

/// The force each of `linearise_squeeze_friction`'s contacts exerted at
/// the solved velocities `v`, `e - C v`, N, into `solve_friction_n`.
pub(crate) fn squeeze_friction_forces(contacts: &mut [SolidContact], v: &[Vec3]) {
    for c in contacts.iter_mut() {
        c.solve_friction_n = c.solve_constant_n - c.solve_damping * v[c.particle as usize];
    }
}

/// The solids still holding each particle at the end of a step (active
/// constraint contacts, one or two; none for a squeezed particle, which
/// a penalty presses): `(first, second)` indices into `group`.
pub(crate) fn held_by(group: &[SolidContact]) -> Option<(usize, Option<usize>)> {
    if group.iter().any(|c| c.active && c.pressed) {
        return None;
    }
    let mut held = (0..group.len()).filter(|&k| group[k].active);
    held.next().map(|a| (a, held.next()))
}

/// The change `d` in span{`na`, `nb`} (`nb` only for a particle held by two
/// solids) with `na . d = p` and `nb . d = q`, as `(d_a, d_b)` along each.
pub(crate) fn along_normals(na: Vec3, nb: Option<Vec3>, p: f64, q: f64) -> (Vec3, Vec3) {
    match nb {
        None => (na * p, Vec3::zeros()),
        Some(nb) => {
            let (a, b) = two_direction_coefficients(&na, &nb, p, q);
            (na * a, nb * b)
        }
    }
}

/// No bounce off a holding solid: a particle that a solid still holds at
/// the end of a step (Choi & Ko 2002, §5: its displacement along the
/// normal prescribed) does not leave the step moving away from it; the
/// outward part of its normal velocity relative to the solid (to each
/// solid in a crease) is removed and the solid's impulse takes the change
/// of momentum `m dv` (N s). The constraint put the particle on the
/// surface, but the step's velocity differentiates across the impact:
/// BDF2's `(3 dx - delta) / (2h)` sent a particle pushed back 0.4 mm
/// after falling 0.4 mm the step before off at 70 mm/s (a restitution of
/// about a half), and it landed again two steps later: half the Table-1
/// one-piece's contacts and a quarter of the sphere drape's were made and
/// lost every other step, with friction every other step. An inward
/// velocity is left (the constraint holds the particle next step too):
/// stopped as well, a landing particle stopped dead while the cloth
/// behind it fell on, and the V-groove's landing stretched links to 1.28
/// (1.14 with the inward velocity left, 1.13 before).
/// See `restart_history_at_contacts`.
/// Particles held by one solid that `movable` picks (a body in the solve,
/// see `BodyBuffers::stop_separation`) are left out.
pub(crate) fn stop_separation(
    contacts: &mut [SolidContact],
    masses: &[f64],
    new_v: &mut [Vec3],
    movable: impl Fn(&SolidContact) -> bool,
) {
    for group in contacts.chunk_by_mut(same_particle) {
        let Some((a, b)) = held_by(group) else { continue };
        if b.is_none() && movable(&group[a]) {
            continue;
        }
        let i = group[a].particle as usize;
        let leaving = |c: &SolidContact| c.normal.dot(&(new_v[i] - c.solid_velocity)).max(0.0);
        let (p, q) = (leaving(&group[a]), b.map_or(0.0, |b| leaving(&group[b])));
        if p == 0.0 && q == 0.0 {
            continue;
        }
        let (dv_a, dv_b) = along_normals(group[a].normal, b.map(|b| group[b].normal), -p, -q);
        new_v[i] += dv_a + dv_b;
        group[a].impulse_n_s += dv_a * masses[i];
        if let Some(b) = b {
            group[b].impulse_n_s += dv_b * masses[i];
        }
    }
}

/// Restarts BDF2's history along the normal(s) of each particle a solid
/// held over the step just committed (see `stop_separation`): its
/// previous position becomes `x - h v` and its previous velocity `v`
/// along them, as if it had moved at `v` all along. The two-step formula
/// otherwise carries the impact into the next step: the displacement
/// `delta` that pushed the particle out and the landing velocity in
/// `v_prev` make its free prediction `delta / 3 + h (8 v - 2 v_prev) / 9`
/// leave the surface again (a cloth dropped flat onto the floor, held
/// and stopped on landing, was off it entirely two steps later).
/// Tangential history is kept.
pub(crate) fn restart_history_at_contacts(
    contacts: &[SolidContact],
    h: f64,
    (x, v): (&[Vec3], &[Vec3]),
    (x_prev, v_prev): (&mut [Vec3], &mut [Vec3]),
) {
    for group in contacts.chunk_by(same_particle) {
        let Some((a, b)) = held_by(group) else { continue };
        let i = group[a].particle as usize;
        let (na, nb) = (group[a].normal, b.map(|b| group[b].normal));
        let along = |d: Vec3| {
            let (da, db) = along_normals(na, nb, na.dot(&d), nb.map_or(0.0, |nb| nb.dot(&d)));
            da + db
        };
        x_prev[i] += along(x[i] - v[i] * h - x_prev[i]);
        v_prev[i] += along(v[i] - v_prev[i]);
    }
}

/// Coulomb friction on the new state, per particle in contact: each solid
/// `k` it touches drags it towards the solid's velocity `v_k` in the
/// particle's free directions (the tangent plane; the crease for two
/// solids at an angle; the plane for a particle squeezed between two
/// opposite solids) by at most `mu_k f_k tau / m`, `f_k` the normal force
/// of that contact and `mu_k` its coefficient. With one solid the
/// relative velocity stops when that is enough (static regime) and loses
/// exactly that much otherwise. With two, the new velocity `w` minimises
/// `m/(2 tau) |w - v|^2 + sum_k mu_k f_k |w - v_k|` over the free
/// directions (implicit Coulomb friction against both surfaces), found by
/// projected Gauss-Seidel on the two changes ([`FRICTION_SWEEPS`] sweeps).
/// Positions move by `tau` times the change. `tau` is the time over which
/// a force changes the new velocity in the integrator (`h` for backward
/// Euler, `2h/3` for BDF2), so each friction force is exactly `mu_k f_k`
/// while sliding. Friction already applied in the solve
/// (`solve_friction_n`, see `linearise_squeeze_friction`) stays; its
/// contact may only stop a particle it pushed past the solid's velocity
/// (an overshoot). Each contact's `impulse_n_s` becomes its normal
/// force plus its own friction force, times the step `h`. Returns how
/// many particles stick to a solid.
pub(crate) fn apply_friction(
    contacts: &mut [SolidContact],
    masses: &[f64],
    (tau, h): (f64, f64),
    solved: bool,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) -> usize {
    let mut sticking = 0;
    for group in contacts.chunk_by_mut(same_particle) {
        for c in group.iter_mut() {
            c.impulse_n_s = if c.active { c.normal * (c.normal_force_n * h) } else { Vec3::zeros() };
        }
        if let [c] = group
            && c.active
            && c.friction_mode != FrictionMode::AfterSolve
        {
            // Decided in the solve: the stuck contact's tangential
            // constraint force, or the sliding one's `mu N`.
            c.impulse_n_s += c.solve_constant_n * h;
            sticking += usize::from(c.friction_mode == FrictionMode::Stick);
            continue;
        }
        let mut active = group.iter().enumerate().filter(|(_, c)| c.active).map(|(k, _)| k);
        let Some(a) = active.next() else { continue };
        let b = active.next();
        let i = group[a].particle as usize;
        let squeezed = group[a].pressed || b.is_some_and(|b| group[b].pressed);
        let (na, nb) = (group[a].normal, b.map(|b| group[b].normal));
        let free = |u: Vec3| match nb {
            Some(nb) if !squeezed => {
                let crease = na.cross(&nb).normalize();
                crease * crease.dot(&u)
            }
            _ => u - na * na.dot(&u),
        };
        if squeezed {
            // The pressing force's part in the holding solid's tangent
            // plane moves the particle (its normal part the holding
            // solid carries, see `release_pulling`), as far as relieves
            // the overlap it was computed from and no further: as the
            // velocity change `f tau / m` of the particle alone, the
            // penalty's stiffness (`SQUEEZE m / h^2`) moved it 44 times
            // the overlap (a skirt particle of the Table-1 dress caught
            // where a thigh meets the pelvis: 10 cm in one step).
            for c in group.iter().filter(|c| c.active && c.pressed) {
                let push = free(c.normal);
                let overlap = squeeze_overlap(c.normal_force_n, masses[i], h);
                // Moving by `s push` changes the gap by `s |push|^2`.
                let relieving = overlap / push.norm_squared().max(f64::MIN_POSITIVE);
                let dx = push * (c.normal_force_n * tau * tau / masses[i]).min(relieving);
                new_v[i] += dx / tau;
                new_x[i] += dx;
            }
        }
        if group[a].friction <= 0.0 && b.is_none_or(|b| group[b].friction <= 0.0) {
            continue;
        }
        if solved && !squeezed {
            // Newton iterations solved this friction with the rest of the
            // cloth (the velocity change `f tau / m` would be that of the
            // particle alone: 100 m/s at h = 0.2 s). What remains is the
            // smoothing's creep below `FRICTION_SMOOTHING_M_S`: stopped.
            let slip = free(new_v[i] - group[a].solid_velocity);
            let stick = slip.norm() < FRICTION_SMOOTHING_M_S;
            let dv = if stick { -slip } else { Vec3::zeros() };
            new_v[i] += dv;
            new_x[i] += dv * tau;
            group[a].impulse_n_s += (group[a].solve_friction_n + dv * (masses[i] / tau)) * h;
            if let Some(b) = b {
                group[b].impulse_n_s += group[b].solve_friction_n * h;
            }
            sticking += usize::from(stick);
            continue;
        }
        // Each contact's bound on the change: `mu N tau / m`, or, for
        // friction the solve applied (`linearise_squeeze_friction`, kept
        // from the step's start when the particle is no longer squeezed),
        // only what stops an overshoot (the slip now runs along that
        // friction: the particle would have stopped within the step).
        // That friction is not taken out as the velocity change
        // `f tau / m` of the particle alone: the solve shared it with the
        // neighbours' links, and for a 26 mg particle of the Table-1 dress
        // `f tau / m` was 30 m/s (it jumped 22 cm in one step).
        let budget = |c: &SolidContact| {
            if c.solve_friction_n == Vec3::zeros() {
                return c.friction * c.normal_force_n.max(0.0) * tau / masses[i];
            }
            let slip = free(new_v[i] - c.solid_velocity);
            if slip.dot(&c.solve_friction_n) > 0.0 { slip.norm() } else { 0.0 }
        };
        // The change that would make the particle move with each solid.
        let to_a = free(group[a].solid_velocity - new_v[i]);
        let to_b = b.map(|b| free(group[b].solid_velocity - new_v[i]));
        let (budget_a, budget_b) = (budget(&group[a]), b.map_or(0.0, |b| budget(&group[b])));
        let clamp = |u: Vec3, limit: f64| if u.norm() <= limit { u } else { u * (limit / u.norm()) };
        let (mut dv_a, mut dv_b) = (clamp(to_a, budget_a), Vec3::zeros());
        if let Some(to_b) = to_b {
            for _ in 0..FRICTION_SWEEPS {
                dv_b = clamp(to_b - dv_a, budget_b);
                dv_a = clamp(to_a - dv_b, budget_a);
            }
        }
        let dv = dv_a + dv_b;
        new_v[i] += dv;
        new_x[i] += dv * tau;
        // A friction force is m dv / tau; over the step it gives h times that.
        let scale = masses[i] * h / tau;
        group[a].impulse_n_s += group[a].solve_friction_n * h + dv_a * scale;
        if let Some(b) = b {
            group[b].impulse_n_s += group[b].solve_friction_n * h + dv_b * scale;
        }
        let sticks = |dv: &Vec3, limit: f64| limit > 0.0 && dv.norm() < limit;
        sticking += usize::from(sticks(&dv_a, budget_a) || sticks(&dv_b, budget_b));
    }
    sticking
}

/// Sweeps of `apply_friction`'s projected Gauss-Seidel for a particle
/// against two solids: two suffice when both slide or one sticks; the rest
/// settle the case where the particle's velocity lies between the two
/// solids'. Fixed, so results do not depend on a tolerance.
pub(crate) const FRICTION_SWEEPS: usize = 16;
