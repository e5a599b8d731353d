//! The voxel hash against brute force.

use cloth_collide::{BroadPhaseError, Vec3, VoxelHash};

struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A crumpled sheet: a grid with random heights, plus negative coordinates.
fn cloud(n: usize, rng: &mut Rng) -> Vec<Vec3> {
    (0..n)
        .map(|k| {
            let (i, j) = ((k % 40) as f64, (k / 40) as f64);
            Vec3::new(i * 0.01 - 0.2, j * 0.01 - 0.1, 0.02 * rng.uniform() - 0.01)
                + Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 0.004
        })
        .collect()
}

#[test]
fn point_pairs_match_brute_force() {
    let mut rng = Rng(17);
    let points = cloud(1600, &mut rng);
    let mut hash = VoxelHash::new(0.012).unwrap();
    hash.insert_points(&points).unwrap();
    let skip = |i: u32, j: u32| (i + j).is_multiple_of(7); // an arbitrary exclusion, honoured by both
    let got = hash.pairs_within(0.012, skip);
    let mut expect = Vec::new();
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            if (points[i] - points[j]).norm() < 0.012 && !skip(i as u32, j as u32) {
                expect.push((i as u32, j as u32));
            }
        }
    }
    assert!(expect.len() > 1000, "a meaningful number of pairs: {}", expect.len());
    assert_eq!(got, expect);
    // The table split in uneven ranges (threads' shares) finds them once.
    let slots = hash.table_slots();
    let mut split = Vec::new();
    for cut in [0, 1, slots / 7, slots / 3, slots / 3 + 5, slots - 2, slots].windows(2) {
        hash.pairs_from_slots(cut[0]..cut[1], 0.012, skip, &mut split);
    }
    split.sort_unstable();
    assert_eq!(split, expect);
    // Rebuilding with moved points gives the new answer.
    let moved: Vec<Vec3> = points.iter().map(|p| p * 1.5).collect();
    hash.insert_points(&moved).unwrap();
    let n_moved = hash.pairs_within(0.012, |_, _| false).len();
    let brute = (0..moved.len())
        .flat_map(|i| (i + 1..moved.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| (moved[i] - moved[j]).norm() < 0.012)
        .count();
    assert_eq!(n_moved, brute);
}

/// Exact point-triangle distance (Ericson's closest point on a triangle).
fn distance_to_triangle(p: &Vec3, t: &[Vec3; 3]) -> f64 {
    let (a, b, c) = (t[0], t[1], t[2]);
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.norm();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.norm();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).norm();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.norm();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).norm();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return (p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))))).norm();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm()
}

#[test]
fn triangle_candidates_contain_every_close_pair() {
    let mut rng = Rng(5);
    let points = cloud(1200, &mut rng);
    let triangles: Vec<[Vec3; 3]> = (0..300)
        .map(|_| {
            let o = Vec3::new(rng.uniform() * 0.4 - 0.2, rng.uniform() * 0.3 - 0.1, rng.uniform() * 0.04 - 0.02);
            let e = |r: &mut Rng| Vec3::new(r.uniform() - 0.5, r.uniform() - 0.5, r.uniform() - 0.5) * 0.06;
            [o, o + e(&mut rng), o + e(&mut rng)]
        })
        .collect();
    let margin = 0.005;
    let mut hash = VoxelHash::new(0.01).unwrap();
    hash.insert_points(&points).unwrap();
    let mut candidates = hash.point_triangle_candidates(&triangles, margin).unwrap();
    // Triangle order, no duplicates.
    assert!(candidates.windows(2).all(|w| w[0].1 <= w[1].1));
    candidates.sort_unstable();
    assert!(candidates.windows(2).all(|w| w[0] != w[1]), "duplicate candidates");
    let mut close = 0;
    for (p, point) in points.iter().enumerate() {
        for (t, tri) in triangles.iter().enumerate() {
            if distance_to_triangle(point, tri) < margin {
                close += 1;
                assert!(candidates.binary_search(&(p as u32, t as u32)).is_ok(), "missed point {p}, triangle {t}");
            }
        }
    }
    assert!(close > 50, "{close} close pairs");
    // And far fewer candidates than all pairs.
    assert!(candidates.len() < points.len() * triangles.len() / 10);
}

#[test]
fn bad_input_is_an_error() {
    assert_eq!(VoxelHash::new(0.0).unwrap_err(), BroadPhaseError::InvalidVoxelSize(0.0));
    assert!(VoxelHash::new(f64::NAN).is_err());
    let mut hash = VoxelHash::new(0.1).unwrap();
    let bad = [Vec3::zeros(), Vec3::new(f64::INFINITY, 0.0, 0.0)];
    assert_eq!(hash.insert_points(&bad).unwrap_err(), BroadPhaseError::NonFinite { what: "point", index: 1 });
    hash.insert_points(&[Vec3::zeros()]).unwrap();
    let tri = [[Vec3::zeros(), Vec3::x(), Vec3::new(0.0, f64::NAN, 0.0)]];
    assert!(matches!(
        hash.point_triangle_candidates(&tri, 0.1),
        Err(BroadPhaseError::NonFinite { what: "triangle", .. })
    ));
}

/// A triangle torn across the scene (a blown-up step: corners 1 km apart
/// with 1 cm voxels, 1e15 voxels in its box) is searched point by point:
/// the same candidates as a brute-force box test, at once.
#[test]
fn a_huge_triangle_is_searched_point_by_point() {
    let mut rng = Rng(11);
    let points = cloud(500, &mut rng);
    let huge = [Vec3::new(-500.0, -500.0, -500.0), Vec3::new(500.0, 0.0, 500.0), Vec3::new(0.0, 500.0, 0.0)];
    let small = [Vec3::zeros(), Vec3::new(0.03, 0.0, 0.0), Vec3::new(0.0, 0.03, 0.0)];
    let mut hash = VoxelHash::new(0.01).unwrap();
    hash.insert_points(&points).unwrap();
    let candidates = hash.point_triangle_candidates(&[huge, small], 0.005).unwrap();
    let in_box = |tri: &[Vec3; 3], q: &Vec3| {
        let lo = tri[0].inf(&tri[1]).inf(&tri[2]).add_scalar(-0.005);
        let hi = tri[0].sup(&tri[1]).sup(&tri[2]).add_scalar(0.005);
        (0..3).all(|k| q[k] >= lo[k] && q[k] <= hi[k])
    };
    for (t, tri) in [huge, small].iter().enumerate() {
        let mut expected: Vec<u32> = (0..points.len() as u32).filter(|&p| in_box(tri, &points[p as usize])).collect();
        let mut got: Vec<u32> = candidates.iter().filter(|c| c.1 == t as u32).map(|c| c.0).collect();
        expected.sort_unstable();
        got.sort_unstable();
        assert_eq!(got, expected, "triangle {t}");
    }
    assert_eq!(candidates.iter().filter(|c| c.1 == 0).count(), points.len());
}

/// The candidates come in the order their consumers sum forces in, so it
/// is part of the contract: by triangle, then by voxel (x slowest, z
/// fastest), then by point; a box over more voxels than there are points
/// point by point. Checked against brute force for ordinary triangles
/// (walked in groups), a group whose joint box is too large to walk while
/// each of its boxes is not, and a torn triangle.
#[test]
fn triangle_candidates_come_by_triangle_voxel_and_point() {
    let mut rng = Rng(23);
    let points = cloud(500, &mut rng);
    let (voxel, margin) = (0.01, 0.004);
    let mut triangles: Vec<[Vec3; 3]> = (0..37)
        .map(|_| {
            let o = Vec3::new(rng.uniform() * 0.4 - 0.2, rng.uniform() * 0.12 - 0.1, rng.uniform() * 0.02 - 0.01);
            let e = |r: &mut Rng| Vec3::new(r.uniform() - 0.5, r.uniform() - 0.5, r.uniform() - 0.5) * 0.03;
            [o, o + e(&mut rng), o + e(&mut rng)]
        })
        .collect();
    // Two boxes of 7 x 7 x 7 voxels (under the 500 points) 30 cm apart:
    // together they span thousands.
    let cube = |o: Vec3| [o, o + Vec3::new(0.06, 0.0, 0.03), o + Vec3::new(0.0, 0.06, 0.06)];
    triangles.splice(8..10, [cube(Vec3::new(-0.2, -0.1, -0.03)), cube(Vec3::new(0.1, -0.1, -0.03))]);
    triangles[20] = [Vec3::new(-50.0, -50.0, -5.0), Vec3::new(50.0, 0.0, 5.0), Vec3::new(0.0, 50.0, 0.0)];
    let mut hash = VoxelHash::new(voxel).unwrap();
    hash.insert_points(&points).unwrap();
    let got = hash.point_triangle_candidates(&triangles, margin).unwrap();
    let cell = |q: &Vec3| q.map(|c| (c / voxel).floor() as i64);
    let mut expected = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        let lo = tri[0].inf(&tri[1]).inf(&tri[2]).add_scalar(-margin);
        let hi = tri[0].sup(&tri[1]).sup(&tri[2]).add_scalar(margin);
        let mut inside: Vec<u32> = (0..points.len() as u32)
            .filter(|&p| (0..3).all(|k| (lo[k]..=hi[k]).contains(&points[p as usize][k])))
            .collect();
        let voxels = (0..3).map(|k| (cell(&hi)[k] - cell(&lo)[k] + 1) as f64).product::<f64>();
        if voxels <= points.len() as f64 {
            inside.sort_by_key(|&p| {
                let c = cell(&points[p as usize]);
                (c.x, c.y, c.z, p)
            });
        }
        expected.extend(inside.into_iter().map(|p| (p, t as u32)));
    }
    assert_eq!(got.iter().filter(|c| c.1 == 20).count(), points.len(), "the torn triangle's box holds every point");
    assert!(got.iter().filter(|c| c.1 == 8 || c.1 == 9).count() > 30, "the two far boxes find points");
    assert!(got.len() > 650, "{} candidates", got.len());
    assert_eq!(got, expected);
}
