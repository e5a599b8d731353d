//! Broad phase for swept elements: axis-aligned boxes registered in the
//! cubic cells of a uniform grid (stored sorted by cell, no hash map), so
//! elements whose boxes share a cell become candidate pairs.

use crate::cell::cell_index;
use crate::{BroadPhaseError, Vec3};

/// An axis-aligned box, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The box around `points`, grown by `margin` (m) on every side.
    pub fn around(points: impl IntoIterator<Item = Vec3>, margin: f64) -> Self {
        let mut b = Aabb { min: Vec3::repeat(f64::INFINITY), max: Vec3::repeat(f64::NEG_INFINITY) };
        for p in points {
            b.min = b.min.inf(&p);
            b.max = b.max.sup(&p);
        }
        b.min.add_scalar_mut(-margin);
        b.max.add_scalar_mut(margin);
        b
    }

    /// Whether the two boxes overlap (touching counts).
    pub fn overlaps(&self, o: &Aabb) -> bool {
        (0..3).all(|k| self.min[k] <= o.max[k] && o.min[k] <= self.max[k])
    }
}

/// Boxes registered each in the one cell holding its smallest corner,
/// with cells at least as large as the boxes (larger ones are kept apart,
/// "wide"). Two boxes can then only overlap when their cells are equal or
/// next to each other, so overlapping pairs are found cell by cell.
#[derive(Debug, Clone)]
pub struct BoxGrid {
    /// Cell edge, m.
    cell: f64,
    /// `(cell key, box)`, sorted: the boxes grouped by cell.
    sorted: Vec<(u64, u32)>,
    /// The boxes in the order of `sorted`, with their numbers: the inner
    /// loop of the pair search reads them contiguously.
    grouped: Vec<(Aabb, u32)>,
    /// The occupied cells in key order: the cell and its range in `sorted`.
    runs: Vec<([i64; 3], u32, u32)>,
    /// Open-addressed table from cell key to run (`u32::MAX`: empty).
    table: Vec<(u64, u32)>,
    /// Boxes larger than a cell.
    wide: Vec<u32>,
    boxes: Vec<Aabb>,
}

/// Cells hold the largest box, unless it is more than `WIDE` times the
/// extent that this fraction of the boxes stays within (a few fast
/// elements): then they are that large and the larger boxes are wide.
const CELL_QUANTILE: f64 = 0.99;
const WIDE: f64 = 3.0;

impl Default for BoxGrid {
    fn default() -> Self {
        Self {
            cell: 1.0,
            sorted: Vec::new(),
            grouped: Vec::new(),
            runs: Vec::new(),
            table: Vec::new(),
            wide: Vec::new(),
            boxes: Vec::new(),
        }
    }
}

impl BoxGrid {
    /// A cell edge for grids of `boxes`, at least `min_cell` (m): the
    /// largest box's extent, or `WIDE` times the 99th percentile when that
    /// is smaller. `scratch` is reused.
    pub fn cell_for<'a>(boxes: impl IntoIterator<Item = &'a Aabb>, min_cell: f64, scratch: &mut Vec<f64>) -> f64 {
        scratch.clear();
        scratch.extend(boxes.into_iter().map(|b| (b.max - b.min).max()));
        if scratch.is_empty() {
            return min_cell;
        }
        let largest = scratch.iter().copied().fold(0.0, f64::max);
        let k = ((scratch.len() - 1) as f64 * CELL_QUANTILE) as usize;
        let (_, &mut quantile, _) = scratch.select_nth_unstable_by(k, f64::total_cmp);
        min_cell.max(largest.min(WIDE * quantile))
    }

    /// Registers `boxes` (numbered in order) in cells of edge `cell` (m),
    /// replacing what was there. Fails on a box that is not finite, or a
    /// cell that is not a finite positive length.
    pub fn build(&mut self, boxes: impl IntoIterator<Item = Aabb>, cell: f64) -> Result<(), BroadPhaseError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(BroadPhaseError::InvalidVoxelSize(cell));
        }
        self.cell = cell;
        self.boxes.clear();
        self.boxes.extend(boxes);
        self.sorted.clear();
        self.wide.clear();
        for (i, b) in self.boxes.iter().enumerate() {
            if !(b.min.iter().chain(b.max.iter()).all(|x| x.is_finite())) {
                return Err(BroadPhaseError::NonFinite { what: "box", index: i });
            }
            if (b.max - b.min).max() > cell {
                self.wide.push(i as u32);
            } else {
                self.sorted.push((key(cell_of(b.min, cell)), i as u32));
            }
        }
        self.sorted.sort_unstable();
        self.grouped.clear();
        self.grouped.extend(self.sorted.iter().map(|&(_, i)| (self.boxes[i as usize], i)));
        self.runs.clear();
        let mut first = 0;
        for run in self.sorted.chunk_by(|a, b| a.0 == b.0) {
            let c = cell_of(self.boxes[run[0].1 as usize].min, cell);
            self.runs.push((c, first as u32, (first + run.len()) as u32));
            first += run.len();
        }
        let slots = (2 * self.runs.len()).next_power_of_two().max(16);
        self.table.clear();
        self.table.resize(slots, (0, u32::MAX));
        for (r, &(c, _, _)) in self.runs.iter().enumerate() {
            let k = key(c);
            let mut slot = slot_of(k, slots);
            while self.table[slot].1 != u32::MAX {
                slot = (slot + 1) & (slots - 1);
            }
            self.table[slot] = (k, r as u32);
        }
        Ok(())
    }

    /// Occupied cells; [`BoxGrid::pairs`] takes ranges of them.
    pub fn cells(&self) -> usize {
        self.runs.len()
    }

    /// Appends to `out` every pair `(i, j)` of a box `i` of this grid
    /// registered in one of the occupied cells `cells` and a box `j` of
    /// `other` (built with the same cell edge) whose boxes overlap. With
    /// `same` (`other` is this grid) each pair comes once, `i < j`. Wide
    /// boxes are left to [`BoxGrid::wide_pairs`].
    pub fn pairs(&self, other: &BoxGrid, cells: std::ops::Range<usize>, same: bool, out: &mut Vec<(u32, u32)>) {
        for &(ci, first, end) in &self.runs[cells] {
            // The runs of `other` in the 27 cells round this one, looked up
            // once for all its boxes, when first needed.
            let mut near = [NOT_LOOKED_UP; 27];
            for &(ref bi, i) in &self.grouped[first as usize..end as usize] {
                // A box of `other` meeting this one has its smallest corner
                // within [min - cell, max] on each axis.
                let lo = cell_of(bi.min.add_scalar(-other.cell), other.cell);
                let hi = cell_of(bi.max, other.cell);
                for x in lo[0]..=hi[0] {
                    for y in lo[1]..=hi[1] {
                        for z in lo[2]..=hi[2] {
                            let c = [x, y, z];
                            // Within one grid, a pair is taken from the box in
                            // the lower cell (or, in one cell, the lower box):
                            // the other finds it too, its range reaching here.
                            if same && c < ci {
                                continue;
                            }
                            let (o_first, o_end) = match neighbour(ci, c) {
                                Some(n) => {
                                    if near[n] == NOT_LOOKED_UP {
                                        near[n] = other.run_at(c).unwrap_or((0, 0));
                                    }
                                    near[n]
                                }
                                None => other.run_at(c).unwrap_or((0, 0)),
                            };
                            for &(ref bj, j) in &other.grouped[o_first..o_end] {
                                if (!same || c != ci || i < j) && bi.overlaps(bj) {
                                    out.push(if same { (i.min(j), i.max(j)) } else { (i, j) });
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// Appends to `out` the overlapping pairs `(i, j)` that involve a wide
    /// box of either grid, as [`BoxGrid::pairs`] would list them.
    pub fn wide_pairs(&self, other: &BoxGrid, same: bool, out: &mut Vec<(u32, u32)>) {
        let wide_in = |g: &BoxGrid, i: u32| g.wide.binary_search(&i).is_ok();
        for &i in &self.wide {
            for j in 0..other.boxes.len() as u32 {
                // With `same`, a pair of two wide boxes is listed once.
                let listed = !same || (i != j && (!wide_in(self, j) || i < j));
                if listed && self.boxes[i as usize].overlaps(&other.boxes[j as usize]) {
                    out.push(if same { (i.min(j), i.max(j)) } else { (i, j) });
                }
            }
        }
        if !same {
            for &j in &other.wide {
                for i in (0..self.boxes.len() as u32).filter(|&i| !wide_in(self, i)) {
                    if self.boxes[i as usize].overlaps(&other.boxes[j as usize]) {
                        out.push((i, j));
                    }
                }
            }
        }
    }

    /// Calls `f` with each box of this grid that overlaps `b` (any size),
    /// cell by cell, then the wide ones: a fixed order.
    pub fn for_each_overlapping(&self, b: &Aabb, mut f: impl FnMut(u32)) {
        let lo = cell_of(b.min.add_scalar(-self.cell), self.cell);
        let hi = cell_of(b.max, self.cell);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    let (first, end) = self.run_at([x, y, z]).unwrap_or((0, 0));
                    self.grouped[first..end].iter().filter(|(bj, _)| b.overlaps(bj)).for_each(|&(_, j)| f(j));
                }
            }
        }
        self.wide.iter().filter(|&&j| b.overlaps(&self.boxes[j as usize])).for_each(|&j| f(j));
    }

    /// The range in `sorted` of the boxes registered in cell `c`.
    fn run_at(&self, c: [i64; 3]) -> Option<(usize, usize)> {
        let k = key(c);
        let slots = self.table.len();
        if slots == 0 {
            return None;
        }
        let mut slot = slot_of(k, slots);
        loop {
            let (found, r) = self.table[slot];
            if r == u32::MAX {
                return None;
            }
            // Keys alias far cells: the cell itself decides.
            let (cell, first, end) = self.runs[r as usize];
            if found == k && cell == c {
                return Some((first as usize, end as usize));
            }
            slot = (slot + 1) & (slots - 1);
        }
    }
}

/// A cell's place among the 27 round `centre` (x slowest), if it is one.
fn neighbour(centre: [i64; 3], c: [i64; 3]) -> Option<usize> {
    let d = [0, 1, 2].map(|k| c[k] - centre[k] + 1);
    d.iter().all(|&d| (0..3).contains(&d)).then(|| (d[0] * 9 + d[1] * 3 + d[2]) as usize)
}

/// A run not yet looked up in [`BoxGrid::pairs`].
const NOT_LOOKED_UP: (usize, usize) = (usize::MAX, usize::MAX);

fn cell_of(p: Vec3, cell: f64) -> [i64; 3] {
    [0, 1, 2].map(|k| cell_index(p[k], cell))
}

/// A cell's key: 21 bits of each coordinate. Far cells can share a key.
fn key([x, y, z]: [i64; 3]) -> u64 {
    const MASK: i64 = (1 << 21) - 1;
    (((x & MASK) << 42) | ((y & MASK) << 21) | (z & MASK)) as u64
}

fn slot_of(key: u64, slots: usize) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - slots.trailing_zeros())) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid finds exactly the overlapping pairs that a comparison of
    /// every pair finds, between two sets and within one, and for one box
    /// against a set, small and wide boxes alike.
    #[test]
    fn finds_the_overlaps_of_every_pair() {
        let mut seed = 3u64;
        let mut rand = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut set = |n: usize| -> Vec<Aabb> {
            (0..n)
                .map(|k| {
                    let c = Vec3::new(rand(), rand(), rand()) * 2.0 - Vec3::repeat(1.0);
                    let size = if k % 40 == 0 { 0.9 } else { 0.1 * rand() };
                    Aabb::around([c, c + Vec3::new(rand(), rand(), rand()) * size], 0.0)
                })
                .collect()
        };
        let (a, b) = (set(400), set(300));
        let mut scratch = Vec::new();
        let cell = BoxGrid::cell_for(a.iter().chain(&b), 0.01, &mut scratch);
        let (mut ga, mut gb) = (BoxGrid::default(), BoxGrid::default());
        ga.build(a.iter().copied(), cell).unwrap();
        gb.build(b.iter().copied(), cell).unwrap();
        for (other, g_other, same) in [(&b, &gb, false), (&a, &ga, true)] {
            let mut found = Vec::new();
            ga.pairs(g_other, 0..ga.cells(), same, &mut found);
            ga.wide_pairs(g_other, same, &mut found);
            found.sort_unstable();
            let mut expected = Vec::new();
            for i in 0..a.len() as u32 {
                for j in 0..other.len() as u32 {
                    if (!same || i < j) && a[i as usize].overlaps(&other[j as usize]) {
                        expected.push((i, j));
                    }
                }
            }
            assert_eq!(found, expected, "same = {same}");
        }
        // One box at a time, small or wide: the grid's boxes it overlaps.
        for q in &b {
            let mut found = Vec::new();
            ga.for_each_overlapping(q, |j| found.push(j));
            found.sort_unstable();
            let expected: Vec<u32> = (0..a.len() as u32).filter(|&i| a[i as usize].overlaps(q)).collect();
            assert_eq!(found, expected);
        }
        assert!(ga.build([], 0.0).is_err());
        let bad = Aabb::around([Vec3::new(f64::NAN, 0.0, 0.0)], 0.0);
        assert!(matches!(ga.build([bad], 0.1), Err(BroadPhaseError::NonFinite { index: 0, .. })));
    }
}
