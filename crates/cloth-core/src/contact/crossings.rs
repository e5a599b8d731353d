//! Where the cloth passes through itself: every mesh edge that pierces a
//! triangle it could collide with (not one whose corners are the edge's
//! ends, or linked or sewn to them). A check of a state, not a force: a run
//! counts its crossings each step to say when a garment tangles.

use super::self_collision::build_exclusions;
use crate::{ClothModel, Vec3};
use cloth_collide::{Aabb, BoxGrid, segment_crosses_triangle};
use rayon::prelude::*;

/// Occupied cells of the edge grid per parallel task.
const CELL_CHUNK: usize = 64;

/// One crossing: the mesh edge `[a, b]` (`a < b`) through triangle `t`.
pub type Crossing = ([u32; 2], u32);

/// Finds a model's self-crossings, step after step: what depends on the
/// model alone (its edges, which corners never count against which
/// triangle) is built once, and the broad phase's buffers are reused.
#[derive(Debug, Clone)]
pub struct CrossingCheck {
    edges: Vec<[u32; 2]>,
    excluded_ptr: Vec<u32>,
    excluded: Vec<u32>,
    triangle_boxes: Vec<Aabb>,
    edge_boxes: Vec<Aabb>,
    extents: Vec<f64>,
    triangle_grid: BoxGrid,
    edge_grid: BoxGrid,
    pairs: Vec<(u32, u32)>,
    found: Vec<Crossing>,
}

impl CrossingCheck {
    /// The check for `model`'s mesh.
    pub fn new(model: &ClothModel) -> Self {
        let (mut excluded_ptr, mut excluded) = (Vec::new(), Vec::new());
        build_exclusions(model, &mut excluded_ptr, &mut excluded);
        Self {
            edges: mesh_edges(model.triangles()),
            excluded_ptr,
            excluded,
            triangle_boxes: Vec::new(),
            edge_boxes: Vec::new(),
            extents: Vec::new(),
            triangle_grid: BoxGrid::default(),
            edge_grid: BoxGrid::default(),
            pairs: Vec::new(),
            found: Vec::new(),
        }
    }

    /// The crossings of `model` (the one this check was made for) at
    /// positions `x`, sorted; empty when a position is not finite.
    pub fn find(&mut self, model: &ClothModel, x: &[Vec3]) -> &[Crossing] {
        self.found.clear();
        let triangles = model.triangles();
        let box_of = |ids: &[u32]| Aabb::around(ids.iter().map(|&i| x[i as usize]), 0.0);
        self.triangle_boxes.clear();
        self.triangle_boxes.extend(triangles.iter().map(|t| box_of(t)));
        self.edge_boxes.clear();
        self.edge_boxes.extend(self.edges.iter().map(|e| box_of(e)));
        let cell = BoxGrid::cell_for(self.triangle_boxes.iter().chain(&self.edge_boxes), 1e-6, &mut self.extents);
        let built = self.triangle_grid.build(self.triangle_boxes.iter().copied(), cell).is_ok()
            && self.edge_grid.build(self.edge_boxes.iter().copied(), cell).is_ok();
        if !built {
            return &self.found;
        }
        let (edges, ptr, excluded) = (&self.edges, &self.excluded_ptr, &self.excluded);
        let crosses = |&(e, t): &(u32, u32)| {
            let [a, b] = edges[e as usize];
            let never = &excluded[ptr[t as usize] as usize..ptr[t as usize + 1] as usize];
            let [i, j, k] = triangles[t as usize].map(|i| x[i as usize]);
            never.binary_search(&a).is_err()
                && never.binary_search(&b).is_err()
                && segment_crosses_triangle(x[a as usize], x[b as usize], i, j, k)
        };
        let crossing = |&(e, t): &(u32, u32)| (edges[e as usize], t);
        // The cells in parallel chunks; the result is sorted, so the same
        // for any thread count.
        let (edge_grid, triangle_grid) = (&self.edge_grid, &self.triangle_grid);
        let cells = edge_grid.cells();
        let chunks: Vec<Vec<Crossing>> = (0..cells.div_ceil(CELL_CHUNK))
            .into_par_iter()
            .map(|c| {
                let mut pairs = Vec::new();
                edge_grid.pairs(triangle_grid, c * CELL_CHUNK..((c + 1) * CELL_CHUNK).min(cells), false, &mut pairs);
                pairs.iter().filter(|p| crosses(p)).map(crossing).collect()
            })
            .collect();
        self.found.extend(chunks.into_iter().flatten());
        self.pairs.clear();
        edge_grid.wide_pairs(triangle_grid, false, &mut self.pairs);
        self.found.extend(self.pairs.iter().filter(|p| crosses(p)).map(crossing));
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

/// The distinct edges of `triangles`, each `[a, b]` with `a < b`, sorted.
fn mesh_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> =
        triangles.iter().flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]]).map(|[a, b]| [a.min(b), a.max(b)]).collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}
