//! Where the cloth passes through itself: every mesh edge that pierces a
//! triangle it could collide with (not one whose corners are the edge's
//! ends, or linked or sewn to them). A check of a state, not a force: a run
//! counts its crossings each step to say when a garment tangles.

use super::impact_zones::owned_features;
use super::self_collision::build_exclusions;
use crate::{ClothModel, Vec3};
use cloth_collide::{Aabb, PatchTask, PatchTree, segment_crosses_triangle};
use rayon::prelude::*;

/// Pieces of the tree search to split into for the parallel tasks.
const TASKS: usize = 64;

/// One crossing: the mesh edge `[a, b]` (`a < b`) through triangle `t`.
pub type Crossing = ([u32; 2], u32);

/// Finds a model's self-crossings, step after step: what depends on the
/// model alone (which edges each triangle tests, which corners never count
/// against which triangle) is built once, and the broad phase's buffers
/// are reused.
///
/// The broad phase ([`PatchTree`]) pairs triangles whose boxes overlap,
/// outside patches that cannot pass through themselves; each edge is
/// tested from the one triangle that owns it (`owned_features`) against
/// the other triangle of the pair. An edge's box lies in its owner's, and
/// an edge of a skipped patch cannot cross the patch's other triangles, so
/// no crossing is missed, and each (edge, triangle) is tested once.
#[derive(Debug, Clone)]
pub struct CrossingCheck {
    owned: Vec<[u8; 2]>,
    /// Whether every triangle excludes (see `build_exclusions`) all the
    /// corners of each triangle it shares a corner with: then no edge of
    /// such a neighbour can count against it, and triangles that share a
    /// corner are not tested (every model links its mesh edges, so this
    /// holds for all of them).
    skip_adjacent: bool,
    excluded_ptr: Vec<u32>,
    excluded: Vec<u32>,
    tree: PatchTree,
    tasks: Vec<PatchTask>,
    /// The crossings each task found.
    chunks: Vec<Vec<Crossing>>,
    found: Vec<Crossing>,
}

impl CrossingCheck {
    /// The check for `model`'s mesh.
    pub fn new(model: &ClothModel) -> Self {
        let (mut excluded_ptr, mut excluded) = (Vec::new(), Vec::new());
        build_exclusions(model, &mut excluded_ptr, &mut excluded);
        let triangles = model.triangles();
        let skip_adjacent = triangles.iter().enumerate().all(|(t, corners)| {
            let never = &excluded[excluded_ptr[t] as usize..excluded_ptr[t + 1] as usize];
            let neighbours = corners.iter().flat_map(|&v| model.particle_triangles(v as usize));
            neighbours.flat_map(|&s| triangles[s as usize]).all(|c| never.binary_search(&c).is_ok())
        });
        Self {
            owned: owned_features(triangles, model.particle_count()),
            skip_adjacent,
            excluded_ptr,
            excluded,
            tree: PatchTree::new(triangles, model.rest_positions()),
            tasks: Vec::new(),
            chunks: Vec::new(),
            found: Vec::new(),
        }
    }

    /// Whether triangles that share a corner are left untested.
    #[cfg(test)]
    pub(crate) fn skips_adjacent(&self) -> bool {
        self.skip_adjacent
    }

    /// The check that tests triangles sharing a corner too, as for a mesh
    /// whose edges are not all linked.
    #[cfg(test)]
    pub(crate) fn testing_adjacent(mut self) -> Self {
        self.skip_adjacent = false;
        self
    }

    /// The crossings of `model` (the one this check was made for) at
    /// positions `x`, sorted; empty when a position is not finite.
    pub fn find(&mut self, model: &ClothModel, x: &[Vec3]) -> &[Crossing] {
        self.found.clear();
        let triangles = model.triangles();
        if self.tree.refit(triangles, x).is_err() {
            return &self.found;
        }
        let (owned, ptr, excluded) = (&self.owned, &self.excluded_ptr, &self.excluded);
        let box_of = |ids: &[u32]| Aabb::around(ids.iter().map(|&i| x[i as usize]), 0.0);
        // The edges that triangle `s` owns, tested against triangle `t`.
        let crossings = |s: usize, t: usize, out: &mut Vec<Crossing>| {
            let never = &excluded[ptr[t] as usize..ptr[t + 1] as usize];
            let [i, j, k] = triangles[t].map(|i| x[i as usize]);
            let t_box = box_of(&triangles[t]);
            for e in (0..3).filter(|&e| owned[s][1] & (1 << e) != 0) {
                let (a, b) = (triangles[s][e], triangles[s][(e + 1) % 3]);
                // Lower end first, as the crossing names it: the test's
                // rounding depends on the direction.
                let edge @ [a, b] = [a.min(b), a.max(b)];
                // The geometry first: it rejects most pairs (an edge with
                // an end on the triangle at once), the exclusions few.
                if box_of(&edge).overlaps(&t_box)
                    && segment_crosses_triangle(x[a as usize], x[b as usize], i, j, k)
                    && never.binary_search(&a).is_err()
                    && never.binary_search(&b).is_err()
                {
                    out.push((edge, t as u32));
                }
            }
        };
        // The tree's tasks in parallel; the result is sorted, so the same
        // for any thread count.
        self.tree.tasks(x, TASKS, &mut self.tasks);
        self.chunks.resize_with(self.tasks.len(), Vec::new);
        let (tree, skip_adjacent) = (&self.tree, self.skip_adjacent);
        self.chunks.par_iter_mut().zip(&self.tasks).for_each(|(found, &task)| {
            found.clear();
            tree.run(task, triangles, x, skip_adjacent, &mut |s, t| {
                crossings(s as usize, t as usize, found);
                crossings(t as usize, s as usize, found);
            });
        });
        self.found.extend(self.chunks.iter().flatten());
        self.found.sort_unstable();
        &self.found
    }
}

/// Where the cloth at positions `x` passes through itself, as
/// `(edge, triangle)`, sorted (see [`CrossingCheck`], which a run that
/// checks every step keeps).
pub fn self_intersections(model: &ClothModel, x: &[Vec3]) -> Vec<Crossing> {
    CrossingCheck::new(model).find(model, x).to_vec()
}
