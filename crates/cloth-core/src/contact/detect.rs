//! Detection of cloth-solid contacts: which particles come within the
//! thickness of which solid over a step, and from which side.

use super::contacts::*;
use crate::control::SolidMotion;
use crate::{ClothModel, ClothState, Vec3};
use cloth_collide::{BodyPose, SurfacePoint};
use rayon::prelude::*;

/// A predicted position closer than `(1 + CONTACT_MARGIN)` times the
/// thickness makes a contact. A particle resting on the offset surface is
/// predicted exactly at the thickness: without a margin it would drop out
/// of contact (and out of static friction) every other step. A wider
/// margin costs more: contacts that would pull must be released, one more
/// solve each time (measured: 0.5 doubled the CG iterations of the drape).
pub(crate) const CONTACT_MARGIN: f64 = 0.05;

/// Two contact normals closer than this (cosine) constrain one direction.
pub(crate) const PARALLEL_COS: f64 = 0.98;

/// Two contact normals further apart than this (cosine below its
/// negative, more than 120 degrees) squeeze the particle between their
/// solids: one holds it, the other presses ([`squeeze_force`]). Holding
/// it with both would lock it in the plane of the two normals: a cloth
/// pulled under a resting box's edge (whose normal turns from the bottom
/// face's as the particle passes) would push the box instead of sliding.
/// Between the two bounds the normals make a crease, both hold.
pub(crate) const OPPOSED_COS: f64 = 0.5;

/// Keeps the deepest solid and the deepest other one whose normal is not
/// parallel to it, from up to four solids in reach.
pub(crate) struct Nearest {
    pub(crate) found: [(f64, Option<SolidContact>); 4],
}

impl Nearest {
    pub(crate) fn new() -> Self {
        Self { found: [(f64::INFINITY, None); 4] }
    }

    pub(crate) fn offer(&mut self, distance: f64, contact: SolidContact) {
        // Replace the shallowest kept candidate if this one is deeper.
        let (slot, worst) = self
            .found
            .iter()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |acc, (k, (d, _))| if *d > acc.1 { (k, *d) } else { acc });
        if distance < worst {
            self.found[slot] = (distance, Some(contact));
        }
    }

    /// The deepest contact and a second one: a crease, or a solid on the
    /// opposite side (`pressed`). `yielding` tells whether a contact's
    /// solid gives way ([`crate::Collider::yielding`]).
    pub(crate) fn pick(&self, yielding: impl Fn(&SolidContact) -> bool) -> [Option<SolidContact>; 2] {
        // By reference: a contact is a few hundred bytes, and copying
        // candidates through the fold was 7% of a garment's step.
        let deepest = |skip: &dyn Fn(&SolidContact) -> bool| {
            self.found
                .iter()
                .filter_map(|(d, c)| c.as_ref().filter(|c| !skip(c)).map(|c| (*d, c)))
                .fold(None, |best: Option<(f64, &SolidContact)>, (d, c)| match best {
                    Some((bd, bc)) if bd < d || (bd == d && bc.collider <= c.collider) => Some((bd, bc)),
                    _ => Some((d, c)),
                })
                .map(|(_, c)| *c)
        };
        let first = deepest(&|_| false);
        let crease = first.and_then(|f| {
            deepest(&|c| c.collider == f.collider || !(-OPPOSED_COS..=PARALLEL_COS).contains(&f.normal.dot(&c.normal)))
        });
        if crease.is_some() {
            return [first, crease];
        }
        let opposite =
            first.and_then(|f| deepest(&|c| c.collider == f.collider || f.normal.dot(&c.normal) >= -OPPOSED_COS));
        match (first, opposite) {
            // Squeezed: a solid that gives way presses, the other holds
            // (the deeper one when both or neither give way).
            (Some(f), Some(o)) => {
                let (hold, mut press) = if yielding(&f) && !yielding(&o) { (o, f) } else { (f, o) };
                press.pressed = true;
                [Some(hold), Some(press)]
            }
            _ => [first, None],
        }
    }
}

impl SolidPose {
    /// The solid frame's pose at this instant.
    pub(crate) fn pose(&self) -> &BodyPose {
        &self.motion.pose
    }

    /// Whether `p` is within `margin` of the bounding box.
    pub(crate) fn near(&self, p: &Vec3, margin: f64) -> bool {
        (0..3).all(|a| p[a] >= self.lo[a] - margin && p[a] <= self.hi[a] + margin)
    }

    /// Distance from `p` to the bounding box (0 inside it), m: a lower
    /// bound on `p`'s distance to the solid.
    pub(crate) fn box_distance(&self, p: &Vec3) -> f64 {
        Vec3::from_fn(|a, _| (self.lo[a] - p[a]).max(p[a] - self.hi[a]).max(0.0)).norm()
    }

    /// Velocity of the solid's material point at `point` (m), m/s.
    pub(crate) fn velocity_at(&self, point: Vec3) -> Vec3 {
        self.motion.velocity_at(self.motion.time_s, point)
    }
}

impl SolidFrames {
    /// The solids of `model` at `time` (s), recomputed only when the time
    /// changes: path-driven ones from their path, external ones from
    /// `external` (held at their anchor when not set).
    pub(crate) fn at(&mut self, model: &ClothModel, external: &[Option<SolidMotion>], time: f64) -> &[SolidPose] {
        if self.time != Some(time) || self.solids.len() != model.colliders().len() {
            self.solids.clear();
            self.solids.extend(model.colliders().iter().enumerate().map(|(k, c)| {
                let motion = match external.get(k).copied().flatten() {
                    Some(m) if c.is_external() => SolidMotion { time_s: time, pose: m.pose_at(time), ..m },
                    _ => SolidMotion {
                        time_s: time,
                        pose: c.pose(time),
                        linear_velocity: c.motion.velocity(time),
                        angular_velocity: c.spin_rad_s,
                    },
                };
                let (lo, hi) = c.shape.aabb(&motion.pose);
                SolidPose { motion, lo, hi }
            }));
            self.time = Some(time);
        }
        &self.solids
    }
}

/// Finds cloth-solid contacts for the step from `t` to `t + h` into
/// `bufs.solid`. The end of the step is predicted with the velocity
/// extrapolated from the last step, `x + h (2 v - v_prev)`, so
/// accelerating particles are caught before they pass the surface.
pub(crate) fn detect_solid_contacts(
    model: &ClothModel,
    state: &ClothState,
    h: f64,
    bufs: &mut Contacts,
) -> ContactStats {
    let (x, v, t) = (&state.x, &state.v, state.time_s);
    let v_prev = if state.has_history { &state.v_prev } else { &state.v };
    let n = x.len();
    bufs.candidate.resize(n, [None; 2]);
    bufs.probe.resize(n, (0.0, 0));
    // The solids are at a new time: what was learnt of them is void, and
    // the predictions below measure them anew.
    bufs.clearance.clear();
    bufs.clearance.resize(n, Clearance::UNKNOWN);
    bufs.has_candidate.resize(n, false);
    let thickness = model.contact_thickness();
    let reach = thickness * (1.0 + CONTACT_MARGIN);
    let (colliders, masses) = (model.colliders(), model.masses());
    let (solids_now, solids_next) = (bufs.now.at(model, &bufs.external, t), bufs.next.at(model, &bufs.external, t + h));
    let (held, body_mass) = (&bufs.held, &bufs.body_mass);
    let per_particle = bufs.candidate.par_iter_mut().zip(bufs.probe.par_iter_mut());
    let per_particle = per_particle.zip(bufs.clearance.par_iter_mut().zip(bufs.has_candidate.par_iter_mut()));
    per_particle.enumerate().for_each(|(i, ((cand, probe), (clearance, has)))| {
        *probe = (0.0, 0);
        *has = false;
        if prescribed(model, held, i) {
            return;
        }
        let predicted = x[i] + (v[i] * 2.0 - v_prev[i]) * h;
        let mut beyond = f64::INFINITY;
        let mut nearest: Option<Nearest> = None;
        for (k, (c, (now, next))) in colliders.iter().zip(solids_now.iter().zip(solids_next)).enumerate() {
            let mut here = None;
            if now.near(&x[i], reach) {
                let s = c.shape.closest(now.pose(), x[i]);
                probe.0 = probe.0.max(-s.distance_m);
                probe.1 += 1;
                here = Some(s);
            }
            let lipschitz = c.shape.distance_is_lipschitz();
            let mut queries = 0;
            let s = if next.near(&predicted, reach) {
                probe.1 += 1;
                c.shape.closest(next.pose(), predicted)
            } else {
                SurfacePoint { point: predicted, normal: Vec3::z(), distance_m: next.box_distance(&predicted) }
            };
            if lipschitz {
                beyond = beyond.min(s.distance_m);
            }
            if s.distance_m >= reach {
                // Ending clear of the solid, it may still pass through it.
                if let Some((past, entry)) = crossing(c, (next, h), x[i], predicted, reach, &mut queries) {
                    let travel = normal_travel(entry.normal.dot(&(x[i] - entry.point)), thickness, reach);
                    let found = contact(i, k, c, &entry, past.distance_m, travel, next);
                    nearest.get_or_insert_with(Nearest::new).offer(past.distance_m, found);
                }
                probe.1 += queries as u32;
                continue;
            }
            // The side the particle comes from: a prediction deep inside
            // a thin solid is closest to its far face.
            let surface = if c.is_moving() {
                let side = side_of(c, (next, h), x[i], s, &mut queries);
                probe.1 += queries as u32;
                side
            } else {
                here.filter(|f| f.distance_m > 0.0).unwrap_or(s)
            };
            let gap = surface.normal.dot(&(x[i] - surface.point));
            // A body that outweighs the particle is followed; the particle
            // carries a lighter one (a ball of 1e-3 the cloth's mass,
            // followed, was flung with 1.6e-2 of the energy in play). The
            // same rule as `BodyBuffers::outweighs`, whose bodies are not
            // yet prepared when contacts are detected.
            let followed = body_mass.get(k).is_some_and(|&m| m > masses[i]);
            let travel = if followed {
                let approach = h * next.velocity_at(surface.point).dot(&surface.normal);
                yielding_normal_travel(gap, approach, thickness, reach)
            } else {
                normal_travel(gap, thickness, reach)
            };
            let found = contact(i, k, c, &surface, s.distance_m, travel, next);
            nearest.get_or_insert_with(Nearest::new).offer(s.distance_m, found);
        }
        *clearance = Clearance { from: predicted, distance_m: beyond };
        let Some(nearest) = nearest else { return };
        (*cand, *has) = (nearest.pick(|c| colliders[c.collider as usize].yielding), true);
        if let [Some(held), Some(pressed)] = cand
            && pressed.pressed
        {
            // The particle ends the step where the holding solid puts it.
            let end = x[i] + held.normal * held.normal_travel_m;
            let gap = pressed.normal.dot(&(end - pressed.point));
            pressed.normal_force_n = squeeze_force(gap, thickness, masses[i], h);
        }
    });
    bufs.solid.clear();
    let mut stats = ContactStats::default();
    for ((cand, probe), has) in bufs.candidate.iter().zip(&bufs.probe).zip(&bufs.has_candidate) {
        stats.max_penetration_m = stats.max_penetration_m.max(probe.0);
        stats.narrow_phase_queries += probe.1 as usize;
        if *has {
            bufs.solid.extend(cand.iter().flatten());
        }
    }
    stats.contacts = bufs.solid.len();
    stats
}

pub(crate) fn contact(
    i: usize,
    k: usize,
    c: &crate::Collider,
    s: &SurfacePoint,
    distance: f64,
    travel: f64,
    next: &SolidPose,
) -> SolidContact {
    let held = SolidContact::new(i, k, s.point, s.normal, next.velocity_at(s.point), c.friction);
    SolidContact { distance_m: distance, normal_travel_m: travel, ..held }
}

/// What [`reach_surface`] found of solid `c` from a particle's new
/// position `to`.
pub(crate) enum Reach {
    /// Closer than the limit: the closest point to `to` and the surface
    /// point to push back to.
    Within(SurfacePoint, SurfacePoint),
    /// Not closer than the limit; `to`'s signed distance is at least
    /// `distance_m` (its bounding box's distance, or the query's).
    Beyond { distance_m: f64 },
}

impl Reach {
    /// A lower bound on `to`'s signed distance, m (within reach: the
    /// closest point's distance itself).
    pub(crate) fn distance_at_least(&self) -> f64 {
        match self {
            Reach::Within(at, _) => at.distance_m,
            Reach::Beyond { distance_m } => *distance_m,
        }
    }

    /// The two surface points when within reach.
    pub(crate) fn within(self) -> Option<(SurfacePoint, SurfacePoint)> {
        match self {
            Reach::Within(at, side) => Some((at, side)),
            Reach::Beyond { .. } => None,
        }
    }
}

/// Whether `to` (a particle's new position) is closer than `limit` to
/// solid `c` (posed as `next` at the end of a step of `h` s), or, with
/// `cast_path`, got there through it ([`crossing`]): if so the closest
/// point to `to` (the depth past the entry) and the surface point to push
/// back to ([`side_of`], with the closest point to `to` as the fallback;
/// the entry), else how far it is at least. Point queries made are added
/// to `queries`. The solves' results cast their paths (the active set);
/// the last projection and Newton's penalties do not: casting there let a
/// coupled ball 1000 times the cloth's mass gain 6-7% of the energy in
/// play under Newton (the hard-case suite), where it holds to 1e-4 without.
pub(crate) fn reach_surface(
    c: &crate::Collider,
    (next, h): (&SolidPose, f64),
    from: Vec3,
    to: Vec3,
    (limit, cast_path): (f64, bool),
    queries: &mut usize,
) -> Reach {
    let distance_m = if next.near(&to, limit) {
        let at = c.shape.closest(next.pose(), to);
        *queries += 1;
        if at.distance_m < limit {
            return Reach::Within(at, side_of(c, (next, h), from, at, queries));
        }
        at.distance_m
    } else {
        next.box_distance(&to)
    };
    let crossed = if cast_path { crossing(c, (next, h), from, to, limit, queries) } else { None };
    match crossed {
        Some((past, entry)) => Reach::Within(past, entry),
        None => Reach::Beyond { distance_m },
    }
}

/// Whether a particle going in a line from `from` (its place at the start
/// of the step) to `to` passes through solid `c` (posed `next` at the end
/// of a step of `h` s) although `to` is not within `limit` of it:
/// continuous collision detection, for a step longer than the solid is
/// thick, which the distance at `to` alone misses (tunnelling). The path
/// is taken relative to the solid: `from` where it sat in the new pose (as
/// [`side_of`] takes it). A path shorter than `limit` cannot cross
/// without ending within it, and is not cast. Returns `to`'s depth past
/// the entry face (a negative distance along the entry normal) and the
/// entry point, the surface to go back to.
///
/// Always inlined: it runs for every particle and solid and mostly
/// returns at once, and as a call it took a third more of the collision
/// stage (docs/results/stages.md).
#[inline(always)]
pub(crate) fn crossing(
    c: &crate::Collider,
    (next, h): (&SolidPose, f64),
    from: Vec3,
    to: Vec3,
    limit: f64,
    queries: &mut usize,
) -> Option<(SurfacePoint, SurfacePoint)> {
    let start = if c.is_moving() { from + next.velocity_at(from) * h } else { from };
    let half = (to - start) * 0.5;
    let length = 2.0 * half.norm();
    if length < limit || !next.near(&(start + half), limit + 0.5 * length) {
        return None;
    }
    *queries += 1;
    let (share, normal) = c.shape.first_entry(next.pose(), start, to)?;
    let point = start + (to - start) * share;
    let depth = normal.dot(&(to - point)).min(0.0);
    Some((SurfacePoint { point: to, normal, distance_m: depth }, SurfacePoint { point, normal, distance_m: 0.0 }))
}

/// Cosine between a face's normal and its motion below which the face
/// slides past a particle rather than advancing on it (see [`side_of`]).
const SLIDING_COS: f64 = 1e-3;

/// The surface point of solid `c` (posed `next` at the end of a step of
/// `h` s) that a particle at `from` (its position at the start of the
/// step) goes back to: the closest to `from` when `from` is outside (the
/// side it comes from: a thin solid is then not crossed), else
/// `fallback` (the point nearest where it ends). When a moving solid swept
/// over `from`, the face closest to where the particle sat relative to the
/// solid at the start (`from + h v_solid(from)` in the new pose: the face
/// that swept it) if that is the shorter way out (for a solid that
/// yields, a body, always: the way the particle came does no work the
/// body did not), and also when `from` is
/// outside but the solid passed over it within the step (a slab rising
/// faster than its thickness per step): the fallback pushed a skirt particle of
/// the Table-1 dress, swept over by a striding thigh and carried deep
/// into it by the solve, 5 cm out through the thigh's far end in one
/// step. Only the solid's pose and velocity at the end of the step are
/// used, as a co-simulation master gives them.
pub(crate) fn side_of(
    c: &crate::Collider,
    (next, h): (&SolidPose, f64),
    from: Vec3,
    fallback: SurfacePoint,
    queries: &mut usize,
) -> SurfacePoint {
    let side = c.shape.closest(next.pose(), from);
    *queries += 1;
    if side.distance_m > 0.0 && c.is_moving() {
        // A solid faster than its thickness per step may have passed the
        // particle: then it comes from where it sat relative to the
        // solid, on the far side of it now.
        let moved = next.velocity_at(from) * h;
        if moved.norm() > side.distance_m {
            let entered = c.shape.first_entry(next.pose(), from + moved, from).is_some();
            // A particle on the plane of a body's face that slides past it
            // (a cloth particle under a box's edge as the box lands) is
            // not met by that face but by the one that advances on it.
            // Pushed out through the sliding face, the 24 particles under
            // a landing box's rim stretched their links by 2.4 J that no
            // work put in. Only faces sliding within `SLIDING_COS` of
            // parallel: beside a ball, the closest point is the one met.
            let sliding = c.yielding && side.normal.dot(&moved).abs() <= SLIDING_COS * moved.norm();
            if entered || sliding {
                let swept = c.shape.closest(next.pose(), from + moved);
                *queries += 2;
                if entered || (swept.normal.dot(&moved) > 0.0 && swept.distance_m > 0.0) {
                    return swept;
                }
            }
        }
    }
    if side.distance_m > 0.0 {
        return side;
    }
    if !c.is_moving() {
        return fallback;
    }
    // The solid moved by about `h v` since: relative to it, the particle
    // sat `h v` further along.
    let swept = c.shape.closest(next.pose(), from + next.velocity_at(from) * h);
    *queries += 1;
    // How far `from` must move along each normal to reach each surface.
    let way_out = |s: &SurfacePoint| s.normal.dot(&(s.point - from));
    if swept.distance_m > 0.0 && (c.yielding || way_out(&swept) < way_out(&fallback)) { swept } else { fallback }
}

/// Whether particle `i` moves as prescribed this step, pinned by the
/// model or held by hand (`held`, sorted: `Contacts::held`): solid
/// contacts leave it to its path.
pub(crate) fn prescribed(model: &ClothModel, held: &[usize], i: usize) -> bool {
    model.is_pinned(i) || (!held.is_empty() && held.binary_search(&i).is_ok())
}

/// The entries of `contacts` (sorted by particle) that belong to one
/// particle each, in order.
pub(crate) fn groups(contacts: &[SolidContact]) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
    contacts.chunk_by(same_particle).scan(0, |start, group| {
        let range = *start..*start + group.len();
        *start = range.end;
        Some(range)
    })
}

/// Whether two contact entries belong to the same particle (entries are
/// sorted by particle, so a particle's entries are consecutive).
pub(crate) fn same_particle(a: &SolidContact, b: &SolidContact) -> bool {
    a.particle == b.particle
}

impl Clearance {
    /// Nothing learnt yet.
    pub(crate) const UNKNOWN: Self = Self { from: Vec3::new(0.0, 0.0, 0.0), distance_m: f64::NEG_INFINITY };

    /// Slack on the bound, m, for the rounding of two distance queries
    /// (about 1e-16 of the coordinates): with it, a skipped query would
    /// have answered "beyond" however it rounds.
    pub(crate) const SLACK_M: f64 = 1e-9;

    /// Whether every Lipschitz solid is surely not closer than `limit` to
    /// `p`: the distance at `from`, less how far `p` is from there, is
    /// still beyond the limit (a distance changes no faster than its point
    /// moves).
    pub(crate) fn clears(&self, p: &Vec3, limit: f64) -> bool {
        self.distance_m - (p - self.from).norm() > limit + Self::SLACK_M
    }
}
