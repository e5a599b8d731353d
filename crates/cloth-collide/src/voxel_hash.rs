//! The voxel spatial hash.

use crate::Vec3;
use crate::cell::cell_index;

/// Why a broad-phase query cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BroadPhaseError {
    /// The voxel size is not a finite positive length.
    #[error("voxel size must be finite and > 0, got {0} m")]
    InvalidVoxelSize(f64),
    /// A point or triangle corner is not finite.
    #[error("{what} {index} has a non-finite coordinate")]
    NonFinite {
        /// "point", "triangle" or "box".
        what: &'static str,
        /// Its index.
        index: usize,
    },
}

/// A voxel grid of cubic cells of edge `voxel` (m): the occupied cells in
/// an open-addressed hash table (linear probing, at most half full), each
/// holding the range of its points in a cell-grouped copy of the points.
/// A query visits cells, not buckets: a cell found in the table hands over
/// exactly its points, contiguous in memory, and an empty cell costs one
/// probe or two. Rebuilding reuses every allocation: call
/// [`VoxelHash::insert_points`] each step.
#[derive(Debug, Clone)]
pub struct VoxelHash {
    voxel: f64,
    /// Position of each inserted point (input order), m.
    point_pos: Vec<Vec3>,
    /// Table slot of each inserted point's cell.
    point_slot: Vec<u32>,
    /// The cell table: a probe reads one slot (32 bytes, half a cache
    /// line) for the cell, its points and whether the slot is empty.
    slots: Vec<Slot>,
    /// Point indices grouped by cell, increasing within a cell.
    sorted: Vec<u32>,
    /// `point_pos` in the order of `sorted`, m.
    sorted_pos: Vec<Vec3>,
}

/// A slot of [`VoxelHash`]'s cell table: an occupied cell and where its
/// points are in the cell-grouped arrays.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Slot {
    /// The cell (meaningful when `len > 0`).
    cell: [i64; 3],
    /// The cell's points are `sorted[start..start + len]`.
    start: u32,
    /// 0 marks an empty slot.
    len: u32,
}

impl Slot {
    const EMPTY: Self = Self { cell: [0; 3], start: 0, len: 0 };

    fn points(&self) -> std::ops::Range<usize> {
        self.start as usize..(self.start + self.len) as usize
    }
}

/// Prime multipliers of the classic spatial hash (Teschner et al. 2003).
const P1: i64 = 73_856_093;
const P2: i64 = 19_349_663;
const P3: i64 = 83_492_791;

impl VoxelHash {
    /// An empty hash with cells of edge `voxel` (m). Choose it near the
    /// interaction distance: pairs closer than `voxel` always share or
    /// neighbour a cell.
    pub fn new(voxel: f64) -> Result<Self, BroadPhaseError> {
        if !(voxel.is_finite() && voxel > 0.0) {
            return Err(BroadPhaseError::InvalidVoxelSize(voxel));
        }
        Ok(Self {
            voxel,
            point_pos: Vec::new(),
            point_slot: Vec::new(),
            slots: vec![Slot::EMPTY],
            sorted: Vec::new(),
            sorted_pos: Vec::new(),
        })
    }

    /// Cell edge, m.
    pub fn voxel(&self) -> f64 {
        self.voxel
    }

    fn cell_of(&self, p: &Vec3) -> [i64; 3] {
        [cell_index(p.x, self.voxel), cell_index(p.y, self.voxel), cell_index(p.z, self.voxel)]
    }

    /// The table's first probe for cell `c`. The table's length is a power
    /// of two, so this is the hash's low bits: a mask, where a remainder
    /// cost an integer division per voxel visited.
    fn home(&self, c: [i64; 3]) -> usize {
        let h = (c[0].wrapping_mul(P1)) ^ (c[1].wrapping_mul(P2)) ^ (c[2].wrapping_mul(P3));
        (h as u64 & (self.slots.len() as u64 - 1)) as usize
    }

    /// The slot holding cell `c`, or the empty slot where it would go.
    /// Terminates: the table is at most half full.
    fn probe(&self, c: [i64; 3]) -> usize {
        let mask = self.slots.len() - 1;
        let mut s = self.home(c);
        while self.slots[s].len != 0 && self.slots[s].cell != c {
            s = (s + 1) & mask;
        }
        s
    }

    /// The slot range of `sorted` holding cell `c`'s points (empty if none).
    fn cell_range(&self, c: [i64; 3]) -> std::ops::Range<usize> {
        self.slots[self.probe(c)].points()
    }

    /// Registers `points` (replacing any earlier set): each point's cell
    /// found or added in a table of at least `2 n` slots (a power of two),
    /// then a counting sort of the points by slot, stable in point order.
    /// O(n).
    pub fn insert_points(&mut self, points: &[Vec3]) -> Result<(), BroadPhaseError> {
        if let Some(index) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(BroadPhaseError::NonFinite { what: "point", index });
        }
        let table = (2 * points.len()).next_power_of_two();
        self.slots.clear();
        self.slots.resize(table, Slot::EMPTY);
        self.point_pos.clear();
        self.point_pos.extend_from_slice(points);
        self.point_slot.clear();
        for p in points {
            let c = self.cell_of(p);
            let s = self.probe(c);
            self.slots[s].cell = c;
            self.slots[s].len += 1;
            self.point_slot.push(s as u32);
        }
        let mut next = 0;
        for slot in &mut self.slots {
            slot.start = next;
            next += slot.len;
        }
        // Scatter in point order with `start` as the cursor, then
        // step each cursor back by its count.
        self.sorted.clear();
        self.sorted.resize(points.len(), 0);
        self.sorted_pos.clear();
        self.sorted_pos.resize(points.len(), Vec3::zeros());
        for (k, &s) in self.point_slot.iter().enumerate() {
            let at = self.slots[s as usize].start as usize;
            self.sorted[at] = k as u32;
            self.sorted_pos[at] = points[k];
            self.slots[s as usize].start += 1;
        }
        for slot in &mut self.slots {
            slot.start -= slot.len;
        }
        Ok(())
    }

    /// Every pair `(i, j)`, `i < j`, of the inserted points closer than
    /// `radius` (<= the voxel size), sorted. `skip(i, j)` drops pairs that
    /// should not collide (neighbours in the mesh).
    pub fn pairs_within(&self, radius: f64, skip: impl Fn(u32, u32) -> bool) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        self.pairs_within_into(radius, skip, &mut out);
        out
    }

    /// [`VoxelHash::pairs_within`] into a reused buffer (cleared first), so
    /// a simulation step does not allocate.
    pub fn pairs_within_into(&self, radius: f64, skip: impl Fn(u32, u32) -> bool, out: &mut Vec<(u32, u32)>) {
        out.clear();
        self.pairs_from_slots(0..self.table_slots(), radius, skip, out);
        out.sort_unstable();
    }

    /// Slots of the cell table: [`VoxelHash::pairs_from_slots`] takes
    /// ranges of `0..table_slots()`.
    pub fn table_slots(&self) -> usize {
        self.slots.len()
    }

    /// Appends, unsorted, the pairs of [`VoxelHash::pairs_within`] that
    /// the cells in table slots `slots` own: a cell owns the pairs within
    /// it and those with a point in the 13 neighbours after it (x
    /// slowest, z fastest). Ranges that cover `0..table_slots()` once find
    /// every pair once, so callers may split the table among threads and
    /// sort the union. Each occupied cell looks up 14 cells, not 27.
    pub fn pairs_from_slots(
        &self,
        slots: std::ops::Range<usize>,
        radius: f64,
        skip: impl Fn(u32, u32) -> bool,
        out: &mut Vec<(u32, u32)>,
    ) {
        assert!(radius <= self.voxel, "pairs_within: radius {radius} exceeds the voxel size {}", self.voxel);
        let r2 = radius * radius;
        let mut keep = |i: u32, j: u32, d2: f64| {
            let (i, j) = (i.min(j), i.max(j));
            // Distance first: `skip` may be the costlier test.
            if d2 < r2 && !skip(i, j) {
                out.push((i, j));
            }
        };
        for slot in self.slots[slots].iter().filter(|slot| slot.len != 0) {
            let (c, mine) = (slot.cell, slot.points());
            for a in mine.clone() {
                for b in a + 1..mine.end {
                    keep(self.sorted[a], self.sorted[b], (self.sorted_pos[b] - self.sorted_pos[a]).norm_squared());
                }
            }
            for [dx, dy, dz] in FORWARD {
                let theirs = self.cell_range([c[0] + dx, c[1] + dy, c[2] + dz]);
                for a in mine.clone() {
                    let (i, pi) = (self.sorted[a], &self.sorted_pos[a]);
                    for b in theirs.clone() {
                        keep(i, self.sorted[b], (self.sorted_pos[b] - pi).norm_squared());
                    }
                }
            }
        }
    }

    /// Candidate `(point, triangle)` pairs: every inserted point inside a
    /// triangle's bounding box grown by `margin` (m), found through the
    /// voxels the box touches; in triangle order, then voxel order (x
    /// slowest, z fastest), then point order: deterministic, and the order
    /// callers accumulate forces in. Without duplicates (a point lies in
    /// one voxel, each voxel is visited once per triangle). A box that spans more
    /// voxels than there are points is searched point by point instead (in
    /// point order), so the cost per triangle stays O(points). A superset of
    /// the pairs closer than `margin`.
    pub fn point_triangle_candidates(
        &self,
        triangles: &[[Vec3; 3]],
        margin: f64,
    ) -> Result<Vec<(u32, u32)>, BroadPhaseError> {
        let mut out = Vec::new();
        self.point_triangle_candidates_into(triangles, margin, &mut out)?;
        Ok(out)
    }

    /// [`VoxelHash::point_triangle_candidates`] into a reused buffer
    /// (cleared first), so a simulation step does not allocate.
    pub fn point_triangle_candidates_into(
        &self,
        triangles: &[[Vec3; 3]],
        margin: f64,
        out: &mut Vec<(u32, u32)>,
    ) -> Result<(), BroadPhaseError> {
        out.clear();
        let points = self.point_pos.len() as f64;
        for (g, group) in triangles.chunks(TRIANGLE_GROUP).enumerate() {
            let first = g * TRIANGLE_GROUP;
            let mut boxes = [CellBox::default(); TRIANGLE_GROUP];
            for (j, tri) in group.iter().enumerate() {
                if !tri.iter().all(|p| p.iter().all(|c| c.is_finite())) {
                    return Err(BroadPhaseError::NonFinite { what: "triangle", index: first + j });
                }
                let lo = tri[0].inf(&tri[1]).inf(&tri[2]).add_scalar(-margin);
                let hi = tri[0].sup(&tri[1]).sup(&tri[2]).add_scalar(margin);
                boxes[j] = self.cell_box(lo, hi);
            }
            let boxes = &boxes[..group.len()];
            let union = boxes[1..].iter().fold(boxes[0], |u, b| self.cell_box(u.lo.inf(&b.lo), u.hi.sup(&b.hi)));
            let separate: f64 = boxes.iter().map(CellBox::cells).sum();
            if union.cells() > points.min(separate) {
                for (j, cell_box) in boxes.iter().enumerate() {
                    self.candidates_in(cell_box, (first + j) as u32, out);
                }
                continue;
            }
            // The group's box walked once, its points parked at the end
            // of `out` (slot, MAX); each triangle then takes those in its
            // own box, in the same (voxel, point) order as its own walk.
            let parked = out.len();
            union.walk(|c| {
                let inside = self.cell_range(c).filter(|&k| union.contains(&self.sorted_pos[k]));
                out.extend(inside.map(|k| (k as u32, u32::MAX)));
            });
            let end = out.len();
            for (j, cell_box) in boxes.iter().enumerate() {
                for at in parked..end {
                    let k = out[at].0 as usize;
                    if cell_box.contains(&self.sorted_pos[k]) {
                        out.push((self.sorted[k], (first + j) as u32));
                    }
                }
            }
            out.drain(parked..end);
        }
        Ok(())
    }

    /// The cells of the box `[lo, hi]` (m).
    fn cell_box(&self, lo: Vec3, hi: Vec3) -> CellBox {
        CellBox { lo, hi, first: self.cell_of(&lo), last: self.cell_of(&hi) }
    }

    /// Appends `(point, triangle)` for every point in `cell_box`, by its
    /// voxels (then point order) or, for a box over more voxels than there
    /// are points (a triangle torn across the scene by a blown-up step:
    /// walking its voxels took minutes per step), point by point.
    fn candidates_in(&self, cell_box: &CellBox, triangle: u32, out: &mut Vec<(u32, u32)>) {
        if cell_box.cells() > self.point_pos.len() as f64 {
            let found = self.point_pos.iter().enumerate().filter(|(_, q)| cell_box.contains(q));
            out.extend(found.map(|(p, _)| (p as u32, triangle)));
            return;
        }
        cell_box.walk(|c| {
            let inside = self.cell_range(c).filter(|&k| cell_box.contains(&self.sorted_pos[k]));
            out.extend(inside.map(|k| (self.sorted[k], triangle)));
        });
    }
}

/// The 13 neighbours of a cell that come after it, x slowest and z
/// fastest: each pair of neighbouring cells is visited from one of them.
const FORWARD: [[i64; 3]; 13] = [
    [0, 0, 1],
    [0, 1, -1],
    [0, 1, 0],
    [0, 1, 1],
    [1, -1, -1],
    [1, -1, 0],
    [1, -1, 1],
    [1, 0, -1],
    [1, 0, 0],
    [1, 0, 1],
    [1, 1, -1],
    [1, 1, 0],
    [1, 1, 1],
];

/// Triangles whose boxes [`VoxelHash::point_triangle_candidates_into`]
/// walks together: consecutive triangles of a cloth share most of their
/// voxels (a quad's two triangles have the same box), and a voxel probed
/// once serves them all. A group whose union spans more voxels than its
/// boxes do one by one (triangles far apart in the list) is walked box by
/// box.
pub const TRIANGLE_GROUP: usize = 8;

/// An axis-aligned box (m) and the voxels it touches, `first..=last` on
/// each axis.
#[derive(Debug, Clone, Copy, Default)]
struct CellBox {
    lo: Vec3,
    hi: Vec3,
    first: [i64; 3],
    last: [i64; 3],
}

impl CellBox {
    fn contains(&self, q: &Vec3) -> bool {
        (0..3).all(|k| q[k] >= self.lo[k] && q[k] <= self.hi[k])
    }

    /// How many voxels it touches (a float: a torn box's count overflows).
    fn cells(&self) -> f64 {
        (0..3).map(|k| (self.last[k] as f64 - self.first[k] as f64 + 1.0).max(1.0)).product()
    }

    /// Calls `f` on each voxel, x slowest, z fastest.
    fn walk(&self, mut f: impl FnMut([i64; 3])) {
        for x in self.first[0]..=self.last[0] {
            for y in self.first[1]..=self.last[1] {
                for z in self.first[2]..=self.last[2] {
                    f([x, y, z]);
                }
            }
        }
    }
}
