//! The last net of self-collision: no piece of cloth passes through
//! another within a step. After the repulsion and the separation, every
//! point-triangle and edge-edge pair is tested along its straight path
//! through the step (continuous detection, `cloth_collide::ccd`); the
//! particles of each pair that meets are gathered into an impact zone
//! that moves as one rigid body over the step (Provot 1997; Bridson,
//! Fedkiw & Anderson 2002 §7.4). Zones that meet merge, until nothing
//! meets. A rigid motion of a start that does not intersect itself does
//! not make it intersect. The exceptions: pairs the test skips (close in
//! the mesh), and zones holding pinned particles or particles a solid
//! pushed, which follow those particles' mean displacement, a
//! translation (`docs/contacts.md`).

use super::contacts::{Contacts, CrossingBuffers};
use super::self_collision::build_exclusions;
use crate::colliders::SelfCollision;
use crate::{ClothModel, Mat3, Vec3};
use cloth_collide::{Aabb, BoxGrid, edge_edge_impact, point_triangle_impact, share_a_corner};
use nalgebra::Rotation3;
use rayon::prelude::*;

/// Two elements meet when they come within this fraction of the
/// self-collision thickness: a crossing passes through zero distance,
/// while the separation keeps touching pairs at `MIN_SELF_GAP` thicknesses.
pub const MEETING_FRACTION: f64 = 1e-3;

/// The motion is sparse, and the broad phase pairs only moving triangles
/// with all, when fewer than one triangle in this many moves.
const SPARSE_SHARE: usize = 4;

/// Resting triangles per parallel chunk of a sparse motion's broad phase.
const REST_CHUNK: usize = 512;

/// Rounds of zone merging in one step before the crossings left are
/// reported (`ContactStats::crossings_left`).
const ZONE_ROUNDS: usize = 64;

/// Occupied grid cells per parallel chunk of the narrow phase.
const CELL_CHUNK: usize = 64;

impl CrossingBuffers {
    /// Starts a step of `n` particles: none held.
    pub(crate) fn start_step(&mut self, n: usize) {
        self.held.clear();
        self.held.resize(n, false);
    }

    /// Remembers the positions `x` before a projection out of the solids.
    pub(crate) fn before_projection(&mut self, x: &[Vec3]) {
        self.before.clear();
        self.before.extend_from_slice(x);
    }

    /// Holds every particle the projection moved from where
    /// `before_projection` saw it.
    pub(crate) fn hold_projected(&mut self, x: &[Vec3]) {
        for ((held, before), x) in self.held.iter_mut().zip(&self.before).zip(x) {
            *held |= before != x;
        }
    }
}

/// Moves the end of the step `new_x` (from the start `x0`) so that no
/// particle crosses a triangle and no edge crosses an edge during it;
/// velocities change by the position change over `tau`, as for the
/// separation. Particles pinned or held (`CrossingBuffers::hold_projected`)
/// keep their end; a zone holding some carries its other particles with
/// them. Returns the meetings found at first and those left (0 unless
/// zones with held particles, or a start already tangled, keep some).
pub(crate) fn untangle_step(
    model: &ClothModel,
    sc: &SelfCollision,
    x0: &[Vec3],
    tau: f64,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
    bufs: &mut Contacts,
) -> (usize, usize) {
    let eta = MEETING_FRACTION * sc.thickness_m;
    if bufs.excluded_ptr.len() != model.triangles().len() + 1 {
        build_exclusions(model, &mut bufs.excluded_ptr, &mut bufs.excluded);
    }
    let cb = &mut bufs.crossings;
    if cb.owned.len() != model.triangles().len() {
        cb.owned = owned_features(model.triangles(), model.particle_count());
        cb.ring = ring_edge_pairs(model, &cb.owned);
    }
    let found = |cb: &mut CrossingBuffers, x1: &[Vec3]| {
        find_meetings(model, sc.voxel_m, eta, x0, x1, (&bufs.excluded_ptr, &bufs.excluded), cb)
    };
    found(cb, new_x);
    let first = cb.meetings.len();
    if first == 0 {
        return (0, 0);
    }
    cb.end.clear();
    cb.end.extend_from_slice(new_x);
    cb.parent.clear();
    cb.parent.extend(0..new_x.len() as u32);
    for _ in 0..ZONE_ROUNDS {
        let mut merged = false;
        for k in 0..cb.meetings.len() {
            let [a, rest @ ..] = cb.meetings[k];
            for b in rest {
                merged |= union(&mut cb.parent, a, b);
            }
        }
        // Meetings within zones only: a start already tangled there.
        if !merged {
            break;
        }
        let held = |i: usize| model.is_pinned(i) || cb.held.get(i).copied().unwrap_or(false);
        move_zones(model, held, x0, &cb.end, &mut cb.parent, &mut cb.members, tau, new_x, new_v);
        found(cb, new_x);
        if cb.meetings.is_empty() {
            break;
        }
    }
    (first, cb.meetings.len())
}

/// Every point-triangle and edge-edge pair that meets between `x0` and
/// `x1`, into `cb.meetings` in a fixed order. Pairs a triangle never
/// repels (`excluded`: its corners, particles linked or sewn to them) and
/// edges with such ends are skipped.
///
/// The broad phase pairs triangles whose swept boxes overlap; each vertex
/// and each edge is tested from the one triangle that owns it
/// (`owned_features`), so every vertex-triangle and edge-edge pair is
/// tested once (a vertex's box lies in its owner's, so no pair is missed).
/// Triangles that share a vertex are skipped: their vertex-triangle pairs
/// are linked, and the edge pairs they own that may cross are listed once
/// per model (`ring_edge_pairs`) and tested after the grid's.
pub(crate) fn find_meetings(
    model: &ClothModel,
    min_cell: f64,
    eta: f64,
    x0: &[Vec3],
    x1: &[Vec3],
    (excluded_ptr, excluded): (&[u32], &[u32]),
    cb: &mut CrossingBuffers,
) {
    let triangles = model.triangles();
    // A motion of a few particles (the deformation constraints' corrections):
    // only pairs with a moving triangle can meet anew, and the grid pairs
    // those alone.
    cb.moving.clear();
    cb.resting.clear();
    for (t, corners) in triangles.iter().enumerate() {
        let list =
            if corners.iter().any(|&i| x1[i as usize] != x0[i as usize]) { &mut cb.moving } else { &mut cb.resting };
        list.push(t as u32);
    }
    let sparse = cb.moving.len() * SPARSE_SHARE < triangles.len();
    // Meetings do not change under a motion common to all particles: take
    // out the mean displacement, so the swept boxes shrink to the motion
    // of the cloth's parts relative to each other (not from a few moving
    // ones, which would set the resting ones in motion).
    let common = if sparse {
        Vec3::zeros()
    } else {
        x0.iter().zip(x1).map(|(a, b)| b - a).sum::<Vec3>() / x0.len().max(1) as f64
    };
    let path = |i: u32| [x0[i as usize], x1[i as usize] - common];
    cb.meetings.clear();
    cb.boxes.clear();
    cb.boxes.extend(triangles.iter().map(|t| Aabb::around(t.iter().flat_map(|&i| path(i)), eta)));
    // Per triangle: its box at the start, and how far its corners can move
    // relative to its mean displacement `c`: `(box, c, r)`.
    cb.starts.clear();
    cb.starts.extend(triangles.iter().map(|t| {
        let moved = t.map(|i| x1[i as usize] - x0[i as usize]);
        let c = (moved[0] + moved[1] + moved[2]) / 3.0;
        let r = moved.iter().map(|m| (m - c).norm()).fold(0.0, f64::max);
        (Aabb::around(t.iter().map(|&i| x0[i as usize]), 0.0), c, r)
    }));
    let cell = BoxGrid::cell_for(&cb.boxes, min_cell, &mut cb.extents);
    // Positions are finite here: the step checked them. Sparse: the grid
    // holds the moving triangles; the pairs are those of two moving ones
    // and of a moving one with each resting one it overlaps.
    let built = if sparse {
        let boxes = &cb.boxes;
        cb.grid.build(cb.moving.iter().map(|&t| boxes[t as usize]), cell)
    } else {
        cb.grid.build(cb.boxes.iter().copied(), cell)
    };
    if built.is_err() {
        return;
    }
    let (grid, owned, starts, boxes) = (&cb.grid, &cb.owned, &cb.starts, &cb.boxes);
    let (moving, resting) = (&cb.moving, &cb.resting);
    // Two triangles' points close in by at most `r_s + r_t + |c_s - c_t|`
    // over the step: pairs farther apart at the start cannot meet.
    let can_meet = |s: usize, t: usize| {
        let ((bs, cs, rs), (bt, ct, rt)) = (&starts[s], &starts[t]);
        let gap = (bs.min - bt.max).sup(&(bt.min - bs.max)).sup(&Vec3::zeros()).norm();
        gap < rs + rt + (cs - ct).norm() + eta
    };
    let point_triangle = |p: u32, t: usize| {
        let [a, b, c] = triangles[t];
        let never = || &excluded[excluded_ptr[t] as usize..excluded_ptr[t + 1] as usize];
        (p != a
            && p != b
            && p != c
            && never().binary_search(&p).is_err()
            && point_triangle_impact(path(p), path(a), path(b), path(c), eta).is_some())
        .then_some([p, a, b, c])
    };
    // The cheap test first; most pairs that reach the costly one are not linked.
    let edge_edge = |e @ [a, b]: [u32; 2], f @ [c, d]: [u32; 2]| {
        (!share_an_end(e, f)
            && edge_edge_impact(path(a), path(b), path(c), path(d), eta).is_some()
            && !ends_linked(model, e, f))
        .then_some([a, b, c, d])
    };
    let edge = |t: usize, k: usize| [triangles[t][k], triangles[t][(k + 1) % 3]];
    let pair = |s: usize, t: usize, found: &mut Vec<[u32; 4]>| {
        let ([ps, es], [pt, et]) = (owned[s], owned[t]);
        for (k, (&vs, &vt)) in triangles[s].iter().zip(&triangles[t]).enumerate() {
            if ps & (1 << k) != 0 {
                found.extend(point_triangle(vs, t));
            }
            if pt & (1 << k) != 0 {
                found.extend(point_triangle(vt, s));
            }
        }
        for ks in (0..3).filter(|&k| es & (1 << k) != 0) {
            for kt in (0..3).filter(|&k| et & (1 << k) != 0) {
                found.extend(edge_edge(edge(s, ks), edge(t, kt)));
            }
        }
    };
    // Chunks of occupied cells, one for the wide boxes, then (sparse)
    // chunks of resting triangles.
    let cell_chunks = grid.cells().div_ceil(CELL_CHUNK) + 1;
    let rest_chunks = if sparse { resting.len().div_ceil(REST_CHUNK) } else { 0 };
    let chunks = cell_chunks + rest_chunks;
    cb.chunks.resize_with(chunks, Default::default);
    cb.chunks.par_iter_mut().enumerate().for_each(|(k, (candidates, found))| {
        found.clear();
        candidates.clear();
        if k < cell_chunks - 1 {
            grid.pairs(grid, k * CELL_CHUNK..((k + 1) * CELL_CHUNK).min(grid.cells()), true, candidates);
        } else if k == cell_chunks - 1 {
            grid.wide_pairs(grid, true, candidates);
        }
        if sparse && k < cell_chunks {
            for (s, t) in candidates.iter_mut() {
                (*s, *t) = (moving[*s as usize], moving[*t as usize]);
            }
        } else if sparse {
            let first = (k - cell_chunks) * REST_CHUNK;
            for &r in &resting[first..(first + REST_CHUNK).min(resting.len())] {
                grid.for_each_overlapping(&boxes[r as usize], |m| candidates.push((moving[m as usize], r)));
            }
        }
        for &(s, t) in candidates.iter() {
            let (s, t) = (s as usize, t as usize);
            // Triangles round one vertex first (nine in ten candidates, for
            // nine integer comparisons): their pairs are `cb.ring`'s.
            if !share_a_corner(triangles[s], triangles[t]) && can_meet(s, t) {
                pair(s, t, found);
            }
        }
    });
    cb.meetings.extend(cb.chunks.iter().flat_map(|(_, found)| found));
    let ring_meets = |&[a, b, c, d]: &[u32; 4]| {
        let (e, f) = (path(a).into_iter().chain(path(b)), path(c).into_iter().chain(path(d)));
        Aabb::around(e, eta).overlaps(&Aabb::around(f, eta))
            && edge_edge_impact(path(a), path(b), path(c), path(d), eta).is_some()
    };
    cb.meetings.extend(cb.ring.iter().filter(|p| ring_meets(p)));
}

/// The edge pairs that triangles round one vertex own (`owned`) and that
/// may cross: no corner shared, no end linked to an end of the other. The
/// broad phase skips triangles that share a vertex, whose vertex-triangle
/// pairs are all linked; a fold of a vertex's ring can still pass one of
/// these edges through the other.
pub(crate) fn ring_edge_pairs(model: &ClothModel, owned: &[[u8; 2]]) -> Vec<[u32; 4]> {
    let triangles = model.triangles();
    let edge = |t: usize, k: usize| [triangles[t][k], triangles[t][(k + 1) % 3]];
    let mut pairs = Vec::new();
    for (s, corners) in triangles.iter().enumerate() {
        let mut round: Vec<usize> =
            corners.iter().flat_map(|&v| model.particle_triangles(v as usize)).map(|&t| t as usize).collect();
        round.sort_unstable();
        round.dedup();
        for t in round.into_iter().filter(|&t| t > s) {
            if triangles[t].iter().filter(|v| corners.contains(v)).count() != 1 {
                continue;
            }
            for ks in (0..3).filter(|&k| owned[s][1] & (1 << k) != 0) {
                for kt in (0..3).filter(|&k| owned[t][1] & (1 << k) != 0) {
                    let (e @ [a, b], f @ [c, d]) = (edge(s, ks), edge(t, kt));
                    if !share_an_end(e, f) && !ends_linked(model, e, f) {
                        pairs.push([a, b, c, d]);
                    }
                }
            }
        }
    }
    pairs
}

/// Whether edges `[a, b]` and `[c, d]` have an end in common.
fn share_an_end([a, b]: [u32; 2], [c, d]: [u32; 2]) -> bool {
    a == c || a == d || b == c || b == d
}

/// Whether an end of one edge never repels an end of the other (linked or
/// sewn: [`ClothModel::never_repel`]); the continuous test skips them.
fn ends_linked(model: &ClothModel, [a, b]: [u32; 2], [c, d]: [u32; 2]) -> bool {
    let near = |p: u32, q: u32| model.never_repel(p as usize, q as usize);
    near(a, c) || near(a, d) || near(b, c) || near(b, d)
}

/// For each triangle, the corners (bit k: corner k) and edges (bit k: from
/// corner k to the next) it owns: each vertex and each edge belongs to the
/// first triangle that has it.
pub(crate) fn owned_features(triangles: &[[u32; 3]], particles: usize) -> Vec<[u8; 2]> {
    let mut vertex_owner = vec![u32::MAX; particles];
    let mut edge_owner = std::collections::BTreeMap::new();
    let mut owned = vec![[0u8; 2]; triangles.len()];
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            if vertex_owner[tri[k] as usize] == u32::MAX {
                vertex_owner[tri[k] as usize] = t as u32;
                owned[t][0] |= 1 << k;
            }
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if edge_owner.insert((a.min(b), a.max(b)), t).is_none() {
                owned[t][1] |= 1 << k;
            }
        }
    }
    owned
}

/// Sets every zone's particles to the zone's rigid motion over the step,
/// from the start `x0` and the unmoved end `end`: the translation of its
/// centre of mass and the rotation of its angular momentum about it,
/// `theta = I^-1 L` (Bridson et al. 2002 §7.4). A zone with `held`
/// particles (pinned, or pushed out of a solid) cannot move as a free
/// body: its other particles follow the held ones' mean displacement, so
/// a leg pushing one layer into another pushes both.
#[allow(clippy::too_many_arguments)]
fn move_zones(
    model: &ClothModel,
    held: impl Fn(usize) -> bool,
    x0: &[Vec3],
    end: &[Vec3],
    parent: &mut [u32],
    members: &mut Vec<(u32, u32)>,
    tau: f64,
    new_x: &mut [Vec3],
    new_v: &mut [Vec3],
) {
    members.clear();
    for i in 0..parent.len() as u32 {
        let root = find(parent, i);
        if root != i {
            members.extend([(root, i), (root, root)]);
        }
    }
    members.sort_unstable();
    members.dedup();
    let masses = model.masses();
    for zone in members.chunk_by(|a, b| a.0 == b.0) {
        let ids = || zone.iter().map(|&(_, i)| i as usize);
        let mut moved = |i: usize, x: Vec3| {
            new_v[i] += (x - new_x[i]) / tau;
            new_x[i] = x;
        };
        let pinned = ids().filter(|&i| held(i)).count();
        if pinned > 0 {
            let shift = ids().filter(|&i| held(i)).map(|i| end[i] - x0[i]).sum::<Vec3>() / pinned as f64;
            for i in ids() {
                moved(i, if held(i) { end[i] } else { x0[i] + shift });
            }
            continue;
        }
        let mass: f64 = ids().map(|i| masses[i]).sum();
        let centre = ids().map(|i| x0[i] * masses[i]).sum::<Vec3>() / mass;
        let shift = ids().map(|i| (end[i] - x0[i]) * masses[i]).sum::<Vec3>() / mass;
        let (mut inertia, mut momentum) = (Mat3::zeros(), Vec3::zeros());
        for i in ids() {
            let r = x0[i] - centre;
            inertia += (Mat3::identity() * r.norm_squared() - r * r.transpose()) * masses[i];
            momentum += r.cross(&(end[i] - x0[i])) * masses[i];
        }
        // A zone on one line cannot be turned about it: no rotation then.
        let theta = inertia.try_inverse().map_or(Vec3::zeros(), |inv| inv * momentum);
        let turn = Rotation3::new(theta);
        for i in ids() {
            moved(i, centre + shift + turn * (x0[i] - centre));
        }
    }
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let up = parent[parent[i as usize] as usize];
        parent[i as usize] = up;
        i = up;
    }
    i
}

/// Joins the zones of `a` and `b`; the smaller root leads, so the zones
/// do not depend on the order of the meetings. Returns whether they were
/// apart.
fn union(parent: &mut [u32], a: u32, b: u32) -> bool {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
    ra != rb
}
