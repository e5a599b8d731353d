//! Broad phase for a triangle mesh against itself: a binary tree over the
//! triangles, shaped once from the mesh and refitted at each state, that
//! skips whole patches which cannot pass through themselves.
//!
//! A patch is skipped when its normals lie in a cone of half-angle under
//! 90 degrees (Volino & Magnenat-Thalmann 1994, "Efficient self-collision
//! detection on smoothly discretized surface animations using geometrical
//! shape regularity") and its outline, projected along the cone's axis,
//! is a simple polygon. Then every triangle projects with positive area,
//! so the number of triangles over a point of the plane is the winding
//! number of the projected outline round it, at most one: the projection
//! is one to one, and no two triangles of the patch meet except where
//! they share corners.
//!
//! Adjacent triangles' boxes always overlap, so a box search spends most
//! of its tests on them; a skipped patch takes them all at once.

use rayon::prelude::*;

use crate::{Aabb, BroadPhaseError, Vec3};

/// A cone's cosine under this is taken as 90 degrees: a triangle seen
/// nearly edge-on along the axis does not count as facing it.
const MIN_CONE_COS: f64 = 1e-6;

/// Outline segments closer than this fraction of their lengths count as
/// meeting: the outline test errs towards not skipping.
const OUTLINE_TOLERANCE: f64 = 1e-9;

/// Nodes a parallel task of the refit takes: a depth with fewer is
/// refitted on one thread.
const REFIT_CHUNK: usize = 4096;

/// A node: a triangle (a leaf) or two children.
#[derive(Debug, Clone, Copy)]
enum Node {
    Leaf(u32),
    Split(u32, u32),
}

/// A cone of directions: the unit axis and the cosine and sine of the
/// half-angle (`cos <= 0`: no cone under 90 degrees holds the normals).
#[derive(Debug, Clone, Copy)]
struct Cone {
    axis: Vec3,
    cos: f64,
    sin: f64,
}

impl Cone {
    const NONE: Cone = Cone { axis: Vec3::new(0.0, 0.0, 0.0), cos: -1.0, sin: 0.0 };

    fn holds_a_patch(&self) -> bool {
        self.cos > MIN_CONE_COS
    }

    /// A cone holding both `a` and `b`, about the bisector of their axes
    /// (no trigonometric calls: the angles are added as cosines and sines).
    fn merge(a: &Cone, b: &Cone) -> Cone {
        if !(a.holds_a_patch() && b.holds_a_patch()) {
            return Cone::NONE;
        }
        let sum = a.axis + b.axis;
        let norm = sum.norm();
        if norm.is_nan() || norm <= 0.0 {
            return Cone::NONE;
        }
        let axis = sum / norm;
        // The half-angle round `axis` that holds cone `c`: its axis' angle
        // from `axis` plus its own, as long as both are under 90 degrees.
        let widened = |c: &Cone| {
            let (cos_phi, sin_phi) = (axis.dot(&c.axis), axis.cross(&c.axis).norm());
            if cos_phi <= 0.0 {
                return (-1.0, 0.0);
            }
            (cos_phi * c.cos - sin_phi * c.sin, sin_phi * c.cos + cos_phi * c.sin)
        };
        let (wa, wb) = (widened(a), widened(b));
        let (cos, sin) = if wa.0 <= wb.0 { wa } else { wb };
        if cos > MIN_CONE_COS { Cone { axis, cos, sin } } else { Cone::NONE }
    }
}

/// The tree: its shape and outlines, made once from the mesh, and the
/// boxes and normal cones of the last refit.
#[derive(Debug, Clone, Default)]
pub struct PatchTree {
    /// Nodes, each parent before its children; node 0 is the root.
    nodes: Vec<Node>,
    /// How many triangles each node holds.
    sizes: Vec<u32>,
    /// Each node's outline as a closed loop of vertices in the mesh's
    /// winding (`outline[outline_ptr[n]..outline_ptr[n + 1]]`); empty where
    /// the node's triangles are not bounded by one loop (then it is never
    /// skipped).
    outline_ptr: Vec<u32>,
    outline: Vec<u32>,
    /// Where each depth of the tree starts in `nodes`, and the end:
    /// `nodes[depths[d]..depths[d + 1]]` are the nodes `d` splits below
    /// the root.
    depths: Vec<u32>,
    boxes: Vec<Aabb>,
    cones: Vec<Cone>,
}

/// A piece of the search that can run apart from the others.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PatchTask {
    /// The pairs within one node.
    Within(u32),
    /// The pairs between two nodes.
    Between(u32, u32),
}

impl PatchTree {
    /// The tree over `triangles` (corner indices into `rest`): triangles
    /// grouped by connected piece, each node halved at the median of its
    /// triangles' centroids at `rest` along their widest axis, so that
    /// nodes are compact patches; a node holding several pieces is split
    /// between pieces first.
    pub fn new(triangles: &[[u32; 3]], rest: &[Vec3]) -> Self {
        let mut tree = PatchTree::default();
        if triangles.is_empty() {
            return tree;
        }
        let piece = pieces(triangles, rest.len());
        let centroids: Vec<Vec3> =
            triangles.iter().map(|t| t.iter().map(|&v| rest[v as usize]).sum::<Vec3>() / 3.0).collect();
        let mut order: Vec<(u32, u32)> =
            triangles.iter().enumerate().map(|(t, tri)| (piece[tri[0] as usize], t as u32)).collect();
        order.sort_unstable();
        tree.build(&mut order, &centroids, triangles);
        tree.boxes = vec![Aabb { min: Vec3::zeros(), max: Vec3::zeros() }; tree.nodes.len()];
        tree.cones = vec![Cone::NONE; tree.nodes.len()];
        tree
    }

    /// Shapes the nodes over `order` (piece, triangle) and finds their
    /// outlines from the children's.
    fn build(&mut self, order: &mut [(u32, u32)], centroids: &[Vec3], triangles: &[[u32; 3]]) {
        // Node ranges, parents first.
        let mut ranges = vec![(0usize, order.len(), 0u32)];
        let mut i = 0;
        while i < ranges.len() {
            let (lo, hi, depth) = ranges[i];
            // Breadth first: the nodes of one depth are consecutive.
            if depth as usize == self.depths.len() {
                self.depths.push(i as u32);
            }
            if hi - lo == 1 {
                self.nodes.push(Node::Leaf(order[lo].1));
            } else {
                let mid = (lo + hi) / 2;
                let split = if order[lo].0 != order[hi - 1].0 {
                    // The piece boundary nearest the middle.
                    let below = (lo + 1..=mid).rev().find(|&k| order[k - 1].0 != order[k].0);
                    let above = (mid + 1..hi).find(|&k| order[k - 1].0 != order[k].0);
                    match (below, above) {
                        (Some(b), Some(a)) if mid - b > a - mid => a,
                        (Some(b), _) => b,
                        (None, Some(a)) => a,
                        (None, None) => unreachable!("the range holds two pieces"),
                    }
                } else {
                    // The median along the widest axis (ties by triangle).
                    let range = &mut order[lo..hi];
                    let bounds = Aabb::around(range.iter().map(|&(_, t)| centroids[t as usize]), 0.0);
                    let axis = (bounds.max - bounds.min).imax();
                    let key = |&(_, t): &(u32, u32)| (centroids[t as usize][axis], t);
                    range.select_nth_unstable_by(mid - lo, |a, b| {
                        let (ka, kb) = (key(a), key(b));
                        ka.0.total_cmp(&kb.0).then(ka.1.cmp(&kb.1))
                    });
                    mid
                };
                let first = ranges.len() as u32;
                ranges.push((lo, split, depth + 1));
                ranges.push((split, hi, depth + 1));
                self.nodes.push(Node::Split(first, first + 1));
            }
            self.sizes.push((hi - lo) as u32);
            i += 1;
        }
        self.depths.push(self.nodes.len() as u32);
        // Each node's boundary: its directed edges that no opposite edge of
        // the node cancels, children before parents. `None`: a node with an
        // edge met twice the same way or by more than two triangles.
        let mut boundary: Vec<Option<Vec<[u32; 2]>>> = vec![None; self.nodes.len()];
        for n in (0..self.nodes.len()).rev() {
            boundary[n] = match self.nodes[n] {
                Node::Leaf(t) => {
                    let [a, b, c] = triangles[t as usize];
                    Some(vec![[a, b], [b, c], [c, a]])
                }
                Node::Split(l, r) => match (&boundary[l as usize], &boundary[r as usize]) {
                    (Some(l), Some(r)) => cancel_edges(l.iter().chain(r).copied().collect()),
                    _ => None,
                },
            };
        }
        self.outline_ptr.push(0);
        for edges in &boundary {
            if let Some(edges) = edges
                && let Some(outline) = one_loop(edges)
            {
                self.outline.extend(outline);
            }
            self.outline_ptr.push(self.outline.len() as u32);
        }
    }

    /// How many triangles the tree holds.
    pub fn triangles(&self) -> usize {
        self.sizes.first().map_or(0, |&s| s as usize)
    }

    /// Refits the boxes and cones to positions `x` (the triangles those
    /// the tree was made from). Fails on a corner that is not finite.
    ///
    /// Each depth of the tree is one range of nodes whose children all lie
    /// in the next, so a depth is refitted in parallel once the one below
    /// it is done: every node's box and cone are found alone from its
    /// children's, the same for any thread count.
    pub fn refit(&mut self, triangles: &[[u32; 3]], x: &[Vec3]) -> Result<(), BroadPhaseError> {
        let nodes = &self.nodes;
        let mut all_finite = true;
        for depth in self.depths.windows(2).rev() {
            let (start, end) = (depth[0] as usize, depth[1] as usize);
            let (boxes, child_boxes) = self.boxes.split_at_mut(end);
            let (cones, child_cones) = self.cones.split_at_mut(end);
            let children = (&*child_boxes, &*child_cones, end);
            let fit = |(k, (b, c)): (usize, (&mut [Aabb], &mut [Cone]))| {
                let first = start + k * REFIT_CHUNK;
                let mut finite = true;
                for (i, (b, c)) in b.iter_mut().zip(c.iter_mut()).enumerate() {
                    let fitted = fit_node(nodes[first + i], triangles, x, children);
                    finite &= fitted.is_some();
                    (*b, *c) = fitted.unwrap_or((Aabb { min: Vec3::zeros(), max: Vec3::zeros() }, Cone::NONE));
                }
                finite
            };
            let (boxes, cones) = (&mut boxes[start..], &mut cones[start..]);
            all_finite &= if end - start > REFIT_CHUNK {
                let chunks = boxes.par_chunks_mut(REFIT_CHUNK).zip(cones.par_chunks_mut(REFIT_CHUNK));
                chunks.enumerate().map(fit).reduce(|| true, |a, b| a & b)
            } else {
                fit((0, (boxes, cones)))
            };
        }
        if all_finite {
            return Ok(());
        }
        // The leaf a serial refit, last node first, would have stopped at.
        let index = (0..self.nodes.len())
            .rev()
            .find_map(|n| match self.nodes[n] {
                Node::Leaf(t) if fit_node(self.nodes[n], triangles, x, (&[], &[], 0)).is_none() => Some(t as usize),
                _ => None,
            })
            .unwrap_or_default();
        Err(BroadPhaseError::NonFinite { what: "triangle", index })
    }

    /// Splits the search at the last refit into at least `wanted` pieces
    /// where the tree allows, in a fixed order, into `out` (cleared).
    pub fn tasks(&self, x: &[Vec3], wanted: usize, out: &mut Vec<PatchTask>) {
        out.clear();
        if self.nodes.is_empty() {
            return;
        }
        out.push(PatchTask::Within(0));
        let mut next = Vec::new();
        // Widen breadth first while any task can be split.
        while out.len() < wanted {
            next.clear();
            let mut split_any = false;
            for &task in out.iter() {
                match task {
                    PatchTask::Within(n) => match self.nodes[n as usize] {
                        Node::Leaf(_) => {}
                        Node::Split(..) if self.skipped(n, x) => {}
                        Node::Split(l, r) => {
                            next.extend([PatchTask::Within(l), PatchTask::Within(r), PatchTask::Between(l, r)]);
                            split_any = true;
                        }
                    },
                    PatchTask::Between(a, b) => {
                        if !self.boxes[a as usize].overlaps(&self.boxes[b as usize]) {
                            continue;
                        }
                        match self.halves(a, b) {
                            Some(pairs) => {
                                next.extend(pairs.map(|(a, b)| PatchTask::Between(a, b)));
                                split_any = true;
                            }
                            None => next.push(task),
                        }
                    }
                }
            }
            std::mem::swap(out, &mut next);
            if !split_any {
                break;
            }
        }
    }

    /// Calls `visit(s, t)` for each pair of triangles of `task` whose boxes
    /// overlap, outside the patches skipped, leaving out pairs that share
    /// a corner when `skip_adjacent`; each pair once, in a fixed order.
    pub fn run(
        &self,
        task: PatchTask,
        triangles: &[[u32; 3]],
        x: &[Vec3],
        skip_adjacent: bool,
        visit: &mut impl FnMut(u32, u32),
    ) {
        match task {
            PatchTask::Within(n) => self.within(n, triangles, x, skip_adjacent, visit),
            PatchTask::Between(a, b) => self.between(a, b, triangles, skip_adjacent, visit),
        }
    }

    fn within(
        &self,
        n: u32,
        triangles: &[[u32; 3]],
        x: &[Vec3],
        skip_adjacent: bool,
        visit: &mut impl FnMut(u32, u32),
    ) {
        if let Node::Split(l, r) = self.nodes[n as usize]
            && !self.skipped(n, x)
        {
            self.within(l, triangles, x, skip_adjacent, visit);
            self.within(r, triangles, x, skip_adjacent, visit);
            self.between(l, r, triangles, skip_adjacent, visit);
        }
    }

    fn between(&self, a: u32, b: u32, triangles: &[[u32; 3]], skip_adjacent: bool, visit: &mut impl FnMut(u32, u32)) {
        if !self.boxes[a as usize].overlaps(&self.boxes[b as usize]) {
            return;
        }
        match self.halves(a, b) {
            Some(pairs) => {
                for (a, b) in pairs {
                    self.between(a, b, triangles, skip_adjacent, visit);
                }
            }
            None => {
                let (Node::Leaf(s), Node::Leaf(t)) = (self.nodes[a as usize], self.nodes[b as usize]) else {
                    unreachable!("only two leaves have no halves")
                };
                if !(skip_adjacent && share_a_corner(triangles[s as usize], triangles[t as usize])) {
                    visit(s, t);
                }
            }
        }
    }

    /// The pairs that `(a, b)` splits into: the larger node's children with
    /// the other; `None` for two leaves.
    fn halves(&self, a: u32, b: u32) -> Option<[(u32, u32); 2]> {
        let split_a = self.sizes[a as usize] >= self.sizes[b as usize];
        match (self.nodes[a as usize], self.nodes[b as usize]) {
            (Node::Split(l, r), _) if split_a => Some([(l, b), (r, b)]),
            (_, Node::Split(l, r)) => Some([(a, l), (a, r)]),
            (Node::Split(l, r), _) => Some([(l, b), (r, b)]),
            (Node::Leaf(_), Node::Leaf(_)) => None,
        }
    }

    /// Whether node `n` is a patch that cannot pass through itself at
    /// positions `x`: its normals in a cone under 90 degrees and its
    /// outline, projected along the cone's axis, a simple polygon.
    fn skipped(&self, n: u32, x: &[Vec3]) -> bool {
        let cone = &self.cones[n as usize];
        let outline = &self.outline[self.outline_ptr[n as usize] as usize..self.outline_ptr[n as usize + 1] as usize];
        if !cone.holds_a_patch() || outline.is_empty() {
            return false;
        }
        let d = cone.axis;
        let helper = if d.x.abs() < 0.6 { Vec3::x() } else { Vec3::y() };
        let u = d.cross(&helper).normalize();
        let v = d.cross(&u);
        let flat: Vec<[f64; 2]> = outline.iter().map(|&i| [x[i as usize].dot(&u), x[i as usize].dot(&v)]).collect();
        simple_polygon(&flat)
    }
}

/// Node `node`'s box and normal cone at positions `x`, from its
/// triangle or from its children's (`children`: the boxes and cones of the
/// nodes from index `.2` on); `None` for a leaf with a corner that is not
/// finite.
fn fit_node(
    node: Node,
    triangles: &[[u32; 3]],
    x: &[Vec3],
    (boxes, cones, offset): (&[Aabb], &[Cone], usize),
) -> Option<(Aabb, Cone)> {
    match node {
        Node::Leaf(t) => {
            let [i, j, k] = triangles[t as usize].map(|v| x[v as usize]);
            let b = Aabb::around([i, j, k], 0.0);
            if !b.min.iter().chain(b.max.iter()).all(|c| c.is_finite()) {
                return None;
            }
            let normal = (j - i).cross(&(k - i));
            let norm = normal.norm();
            let cone = if norm > 0.0 { Cone { axis: normal / norm, cos: 1.0, sin: 0.0 } } else { Cone::NONE };
            Some((b, cone))
        }
        Node::Split(l, r) => {
            let (l, r) = (l as usize - offset, r as usize - offset);
            let (bl, br) = (&boxes[l], &boxes[r]);
            let b = Aabb { min: bl.min.inf(&br.min), max: bl.max.sup(&br.max) };
            Some((b, Cone::merge(&cones[l], &cones[r])))
        }
    }
}

/// Whether triangles `s` and `t` have a corner in common: all nine
/// comparisons, without a branch (most broad-phase candidates share one,
/// in no order a branch predictor could learn).
#[inline]
pub fn share_a_corner(s: [u32; 3], t: [u32; 3]) -> bool {
    s.iter().fold(false, |any, &v| any | (v == t[0]) | (v == t[1]) | (v == t[2]))
}

/// Each vertex's connected piece of the mesh (vertices joined by the
/// triangles), numbered by each piece's lowest vertex.
fn pieces(triangles: &[[u32; 3]], vertices: usize) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..vertices as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            parent[v as usize] = parent[parent[v as usize] as usize];
            v = parent[v as usize];
        }
        v
    }
    for t in triangles {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, t[0]), root(&mut parent, t[k]));
            let (lo, hi) = (a.min(b), a.max(b));
            parent[hi as usize] = lo;
        }
    }
    (0..vertices as u32).map(|v| root(&mut parent, v)).collect()
}

/// The directed edges left when each edge met both ways is taken out;
/// `None` when an edge is met twice the same way or more than twice.
fn cancel_edges(mut edges: Vec<[u32; 2]>) -> Option<Vec<[u32; 2]>> {
    edges.sort_unstable_by_key(|&[a, b]| (a.min(b), a.max(b), a));
    let mut kept = Vec::new();
    for group in edges.chunk_by(|p, q| p[0].min(p[1]) == q[0].min(q[1]) && p[0].max(p[1]) == q[0].max(q[1])) {
        match group {
            [e] => kept.push(*e),
            [p, q] if p[0] == q[1] => {}
            _ => return None,
        }
    }
    Some(kept)
}

/// The vertices of `edges` in order round one closed loop, or `None` when
/// they are not one loop through distinct vertices.
fn one_loop(edges: &[[u32; 2]]) -> Option<Vec<u32>> {
    if edges.len() < 3 {
        return None;
    }
    let mut from = edges.to_vec();
    from.sort_unstable();
    if from.windows(2).any(|w| w[0][0] == w[1][0]) {
        return None;
    }
    let mut heads: Vec<u32> = edges.iter().map(|e| e[1]).collect();
    heads.sort_unstable();
    if heads.windows(2).any(|w| w[0] == w[1]) {
        return None;
    }
    let start = from[0][0];
    let mut outline = vec![start];
    let mut at = from[0][1];
    while at != start {
        if outline.len() >= from.len() {
            return None;
        }
        outline.push(at);
        let k = from.binary_search_by_key(&at, |e| e[0]).ok()?;
        at = from[k][1];
    }
    (outline.len() == from.len()).then_some(outline)
}

/// Whether the closed polygon through `p` is simple: no two of its sides
/// meet except consecutive ones at their common corner, and none folds
/// back on the one before. Sides that come within a tolerance of meeting
/// count as meeting.
fn simple_polygon(p: &[[f64; 2]]) -> bool {
    let n = p.len();
    let side = |i: usize| (p[i], p[(i + 1) % n]);
    // Sides by their smallest x, swept along x.
    let mut order: Vec<(f64, f64, usize)> = (0..n)
        .map(|i| {
            let (a, b) = side(i);
            let slack = OUTLINE_TOLERANCE * ((b[0] - a[0]).abs() + (b[1] - a[1]).abs());
            (a[0].min(b[0]) - slack, a[0].max(b[0]) + slack, i)
        })
        .collect();
    order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
    for (k, &(_, hi, i)) in order.iter().enumerate() {
        for &(lo_j, _, j) in &order[k + 1..] {
            if lo_j > hi {
                break;
            }
            let consecutive = (i + 1) % n == j || (j + 1) % n == i;
            if consecutive {
                // The corner they share: the sides must not fold onto
                // each other.
                let (first, second) = if (i + 1) % n == j { (i, j) } else { (j, i) };
                let (a, corner) = side(first);
                let (_, c) = side(second);
                if folds_back(a, corner, c) {
                    return false;
                }
            } else if sides_meet(side(i), side(j)) {
                return false;
            }
        }
    }
    // Two sides (n = 2) or fewer never bound an area.
    n >= 3
}

fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

fn length(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Whether sides `a -> corner` and `corner -> c` lie along one line with
/// `c` turned back towards `a` (within the tolerance).
fn folds_back(a: [f64; 2], corner: [f64; 2], c: [f64; 2]) -> bool {
    let (la, lc) = (length(corner, a), length(corner, c));
    let across = orient(corner, a, c).abs();
    let along = (a[0] - corner[0]) * (c[0] - corner[0]) + (a[1] - corner[1]) * (c[1] - corner[1]);
    la == 0.0 || lc == 0.0 || (across <= OUTLINE_TOLERANCE * la * lc && along > 0.0)
}

/// Whether segments `(a, b)` and `(c, d)` meet or come within the
/// tolerance of meeting.
fn sides_meet((a, b): ([f64; 2], [f64; 2]), (c, d): ([f64; 2], [f64; 2])) -> bool {
    let (lab, lcd) = (length(a, b), length(c, d));
    let tol = OUTLINE_TOLERANCE * lab.max(lcd) * (lab + lcd);
    let (o1, o2) = (orient(a, b, c), orient(a, b, d));
    let (o3, o4) = (orient(c, d, a), orient(c, d, b));
    let straddles = |p: f64, q: f64| (p <= tol && q >= -tol) || (p >= -tol && q <= tol);
    if !(straddles(o1, o2) && straddles(o3, o4)) {
        return false;
    }
    // Along one line: they meet only if their spans along it overlap.
    let collinear = o1.abs() <= tol && o2.abs() <= tol;
    if collinear {
        let axis = if (b[0] - a[0]).abs() >= (b[1] - a[1]).abs() { 0 } else { 1 };
        let (lo1, hi1) = (a[axis].min(b[axis]), a[axis].max(b[axis]));
        let (lo2, hi2) = (c[axis].min(d[axis]), c[axis].max(d[axis]));
        let slack = OUTLINE_TOLERANCE * (lab + lcd);
        return lo1 <= hi2 + slack && lo2 <= hi1 + slack;
    }
    true
}

#[cfg(test)]
mod tests;
