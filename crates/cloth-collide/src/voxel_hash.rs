//! The voxel spatial hash.

use crate::Vec3;

/// Why a broad-phase query cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BroadPhaseError {
    /// The voxel size is not a finite positive length.
    #[error("voxel size must be finite and > 0, got {0} m")]
    InvalidVoxelSize(f64),
    /// A point or triangle corner is not finite.
    #[error("{what} {index} has a non-finite coordinate")]
    NonFinite {
        /// "point" or "triangle".
        what: &'static str,
        /// Its index.
        index: usize,
    },
}

/// A voxel grid of cubic cells of edge `voxel` (m), hashed into a table of
/// buckets. Rebuilding reuses every allocation: call
/// [`VoxelHash::insert_points`] each step.
#[derive(Debug, Clone)]
pub struct VoxelHash {
    voxel: f64,
    /// Bucket of each inserted point.
    point_bucket: Vec<u32>,
    /// Integer cell of each inserted point.
    point_cell: Vec<[i64; 3]>,
    /// Position of each inserted point, m.
    point_pos: Vec<Vec3>,
    /// CSR: points of bucket b are `sorted[start[b]..start[b + 1]]`.
    start: Vec<u32>,
    sorted: Vec<u32>,
    /// Counting-sort cursor, kept to avoid allocating on rebuild.
    fill: Vec<u32>,
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
            point_bucket: Vec::new(),
            point_cell: Vec::new(),
            point_pos: Vec::new(),
            start: Vec::new(),
            sorted: Vec::new(),
            fill: Vec::new(),
        })
    }

    /// Cell edge, m.
    pub fn voxel(&self) -> f64 {
        self.voxel
    }

    fn cell_of(&self, p: &Vec3) -> [i64; 3] {
        [(p.x / self.voxel).floor() as i64, (p.y / self.voxel).floor() as i64, (p.z / self.voxel).floor() as i64]
    }

    /// The table's length is a power of two, so the bucket is the hash's
    /// low bits: a mask, where a remainder cost an integer division per
    /// voxel visited (most of a self-collision query's time).
    fn bucket(&self, c: [i64; 3]) -> u32 {
        let h = (c[0].wrapping_mul(P1)) ^ (c[1].wrapping_mul(P2)) ^ (c[2].wrapping_mul(P3));
        (h as u64 & (self.table_len() as u64 - 1)) as u32
    }

    fn table_len(&self) -> usize {
        self.start.len().saturating_sub(1).max(1)
    }

    /// Registers `points` (replacing any earlier set): a counting sort into
    /// `2 n` buckets or more (a power of two), O(n).
    pub fn insert_points(&mut self, points: &[Vec3]) -> Result<(), BroadPhaseError> {
        if let Some(index) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(BroadPhaseError::NonFinite { what: "point", index });
        }
        let table = (2 * points.len()).next_power_of_two();
        self.start.clear();
        self.start.resize(table + 1, 0);
        self.point_cell.clear();
        self.point_bucket.clear();
        self.point_pos.clear();
        self.point_pos.extend_from_slice(points);
        for p in points {
            let c = self.cell_of(p);
            self.point_cell.push(c);
        }
        for k in 0..points.len() {
            let b = self.bucket(self.point_cell[k]);
            self.point_bucket.push(b);
            self.start[b as usize + 1] += 1;
        }
        for b in 0..table {
            self.start[b + 1] += self.start[b];
        }
        self.sorted.clear();
        self.sorted.resize(points.len(), 0);
        self.fill.clear();
        self.fill.extend_from_slice(&self.start[..table]);
        for (k, &b) in self.point_bucket.iter().enumerate() {
            self.sorted[self.fill[b as usize] as usize] = k as u32;
            self.fill[b as usize] += 1;
        }
        Ok(())
    }

    /// Points registered in the cell `c` (and any cell hashing to the same
    /// bucket: callers filter by distance).
    fn bucket_points(&self, c: [i64; 3]) -> &[u32] {
        let b = self.bucket(c) as usize;
        &self.sorted[self.start[b] as usize..self.start[b + 1] as usize]
    }

    /// Every pair `(i, j)`, `i < j`, of the inserted `points` closer than
    /// `radius` (<= the voxel size), sorted. `skip(i, j)` drops pairs that
    /// should not collide (neighbours in the mesh).
    pub fn pairs_within(&self, points: &[Vec3], radius: f64, skip: impl Fn(u32, u32) -> bool) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        self.pairs_within_into(points, radius, skip, &mut out);
        out
    }

    /// [`VoxelHash::pairs_within`] into a reused buffer (cleared first), so
    /// a simulation step does not allocate.
    pub fn pairs_within_into(
        &self,
        points: &[Vec3],
        radius: f64,
        skip: impl Fn(u32, u32) -> bool,
        out: &mut Vec<(u32, u32)>,
    ) {
        out.clear();
        assert!(radius <= self.voxel, "pairs_within: radius {radius} exceeds the voxel size {}", self.voxel);
        assert_eq!(points.len(), self.point_cell.len(), "pairs_within: points differ from the inserted set");
        let r2 = radius * radius;
        for (i, c) in self.point_cell.iter().enumerate() {
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let n = [c[0] + dx, c[1] + dy, c[2] + dz];
                        let me = i as u32;
                        for &j in self.bucket_points(n) {
                            // Each pair once, from its lower index, and only from
                            // the cell j really is in (buckets may collide).
                            if j <= me || self.point_cell[j as usize] != n {
                                continue;
                            }
                            // Distance first: `skip` may be the costlier test.
                            if (points[j as usize] - points[i]).norm_squared() < r2 && !skip(me, j) {
                                out.push((me, j));
                            }
                        }
                    }
                }
            }
        }
        out.sort_unstable();
    }

    /// Candidate `(point, triangle)` pairs: every inserted point inside a
    /// triangle's bounding box grown by `margin` (m), found through the
    /// voxels the box touches; in triangle order (then voxel and point
    /// order: deterministic), without duplicates (a point lies in one voxel,
    /// each voxel is visited once per triangle). A box that spans more
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
        for (t, tri) in triangles.iter().enumerate() {
            if !tri.iter().all(|p| p.iter().all(|c| c.is_finite())) {
                return Err(BroadPhaseError::NonFinite { what: "triangle", index: t });
            }
            let lo = tri[0].inf(&tri[1]).inf(&tri[2]).add_scalar(-margin);
            let hi = tri[0].sup(&tri[1]).sup(&tri[2]).add_scalar(margin);
            let (a, b) = (self.cell_of(&lo), self.cell_of(&hi));
            let inside = |q: &Vec3| (0..3).all(|k| q[k] >= lo[k] && q[k] <= hi[k]);
            // A box over more voxels than there are points (a triangle torn
            // across the scene by a blown-up step) is cheaper to test point
            // by point: walking its voxels took minutes per step.
            let cells = (0..3).map(|k| (b[k] as f64 - a[k] as f64 + 1.0).max(1.0)).product::<f64>();
            if cells > self.point_pos.len() as f64 {
                let found = self.point_pos.iter().enumerate().filter(|(_, q)| inside(q));
                out.extend(found.map(|(p, _)| (p as u32, t as u32)));
                continue;
            }
            for x in a[0]..=b[0] {
                for y in a[1]..=b[1] {
                    for z in a[2]..=b[2] {
                        let c = [x, y, z];
                        for &p in self.bucket_points(c) {
                            if self.point_cell[p as usize] == c && inside(&self.point_pos[p as usize]) {
                                out.push((p, t as u32));
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }
}
