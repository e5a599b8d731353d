use super::*;
use crate::segment_crosses_triangle;

/// A sheet of `nu` x `nv` vertices placed by `place(u, v)` (`u`, `v` in
/// [0, 1]), each quad split in two triangles wound the same way.
fn sheet(nu: usize, nv: usize, place: impl Fn(f64, f64) -> Vec3) -> (Vec<[u32; 3]>, Vec<Vec3>) {
    let id = |i: usize, j: usize| (j * nu + i) as u32;
    let mut triangles = Vec::new();
    for j in 0..nv - 1 {
        for i in 0..nu - 1 {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let x = (0..nv)
        .flat_map(|j| (0..nu).map(move |i| (i as f64 / (nu - 1) as f64, j as f64 / (nv - 1) as f64)))
        .map(|(u, v)| place(u, v))
        .collect();
    (triangles, x)
}

/// Whether an edge of one triangle passes through the other.
fn cross(triangles: &[[u32; 3]], x: &[Vec3], s: usize, t: usize) -> bool {
    let through = |s: usize, t: usize| {
        let [i, j, k] = triangles[t].map(|v| x[v as usize]);
        (0..3).any(|e| {
            let (a, b) = (triangles[s][e], triangles[s][(e + 1) % 3]);
            segment_crosses_triangle(x[a as usize], x[b as usize], i, j, k)
        })
    };
    through(s, t) || through(t, s)
}

/// The pairs the tree visits at `x` (tree made at `rest`), checked to be
/// unique, of overlapping boxes and, with `skip_adjacent`, corner-free.
fn visited(triangles: &[[u32; 3]], rest: &[Vec3], x: &[Vec3], skip_adjacent: bool) -> Vec<(u32, u32)> {
    let mut tree = PatchTree::new(triangles, rest);
    assert_eq!(tree.triangles(), triangles.len());
    tree.refit(triangles, x).unwrap();
    let mut tasks = Vec::new();
    tree.tasks(x, 16, &mut tasks);
    let mut pairs = Vec::new();
    for &task in &tasks {
        tree.run(task, triangles, x, skip_adjacent, &mut |s, t| pairs.push((s.min(t), s.max(t))));
    }
    let box_of = |t: u32| Aabb::around(triangles[t as usize].map(|v| x[v as usize]), 0.0);
    for &(s, t) in &pairs {
        assert!(!(skip_adjacent && share_a_corner(triangles[s as usize], triangles[t as usize])), "({s}, {t})");
        assert!(box_of(s).overlaps(&box_of(t)), "({s}, {t})");
    }
    let count = pairs.len();
    pairs.sort_unstable();
    pairs.dedup();
    assert_eq!(pairs.len(), count, "a pair was visited twice");
    pairs
}

/// Every pair of triangles that pass through each other (no corner in
/// common), testing all pairs.
fn crossing_pairs(triangles: &[[u32; 3]], x: &[Vec3]) -> Vec<(u32, u32)> {
    let mut pairs = Vec::new();
    for s in 0..triangles.len() {
        for t in s + 1..triangles.len() {
            if !share_a_corner(triangles[s], triangles[t]) && cross(triangles, x, s, t) {
                pairs.push((s as u32, t as u32));
            }
        }
    }
    pairs
}

/// A strip wound 1.5 times round a vertical axis, its two ends tilted
/// across opposite ways so that the last half turn passes through the
/// first: every normal is within 45 degrees of the axis, so only the
/// outline test tells the strip (which overlaps itself) from its half
/// turns (which do not). The tree visits every crossing pair and skips
/// all but a few of the strip's overlapping boxes.
#[test]
fn a_wound_strip_through_itself_is_searched_and_its_half_turns_skipped() {
    let turns = 1.5;
    let place = |u: f64, v: f64| {
        let theta = turns * std::f64::consts::TAU * u;
        let r = 1.0 + 0.5 * v;
        Vec3::new(r * theta.cos(), r * theta.sin(), 0.02 * theta + 0.5 * (1.0 - 2.0 * u) * (v - 0.5))
    };
    let (triangles, x) = sheet(121, 9, place);
    let crossing = crossing_pairs(&triangles, &x);
    // Measured: 165 pairs.
    assert!(crossing.len() > 150, "the strip should pass through itself: {} pairs", crossing.len());
    // The tree shaped at the wound strip, and at the strip laid flat.
    let (_, flat) = sheet(121, 9, |u, v| Vec3::new(8.0 * u, v, 0.0));
    for rest in [&x, &flat] {
        let pairs = visited(&triangles, rest, &x, true);
        let missed: Vec<_> = crossing.iter().filter(|p| pairs.binary_search(p).is_err()).collect();
        assert!(missed.is_empty(), "{} of {} crossing pairs missed", missed.len(), crossing.len());
    }
    // Shaped flat, its nodes are patches of the strip: of the 11,703 pairs
    // of overlapping boxes, adjacent ones included, it visits 935
    // (measured), along the half turns' borders and where they cross.
    let all = visited(&triangles, &flat, &x, false);
    assert!(all.len() < 1_050, "{} pairs visited", all.len());
}

/// A sheet that lies flat, or waves gently, has no pair to visit: the
/// root is one patch; folded over onto itself, with the fold passing
/// through the lower half, every crossing pair is visited.
#[test]
fn a_smooth_sheet_is_skipped_whole_and_a_folded_one_searched() {
    let wave = |u: f64, v: f64| Vec3::new(u, v, 0.1 * (6.0 * u).sin() * (4.0 * v).cos());
    let (triangles, x) = sheet(30, 30, wave);
    assert!(visited(&triangles, &x, &x, false).is_empty());
    // The half u > 0.5 folded back over the other at a height that
    // climbs through it.
    let fold = |u: f64, v: f64| {
        if u <= 0.5 {
            Vec3::new(u, v, 0.0)
        } else {
            let a = (u - 0.5) * 3.0;
            Vec3::new(0.5 - 0.15 * a.sin(), v, 0.15 * (1.0 - a.cos()) - 0.2 * v * a)
        }
    };
    let (_, folded) = sheet(30, 30, fold);
    let crossing = crossing_pairs(&triangles, &folded);
    assert!(crossing.len() > 55, "{} crossing pairs (61 measured)", crossing.len());
    let pairs = visited(&triangles, &x, &folded, true);
    assert!(crossing.iter().all(|p| pairs.binary_search(p).is_ok()));
}

/// Closed polygons: simple ones pass; a bow tie, a spike folding back on
/// its side, a corner touching a side, and a loop wound twice do not.
#[test]
fn only_simple_outlines_pass() {
    let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    assert!(simple_polygon(&square));
    let star: Vec<[f64; 2]> = (0..10)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 10.0;
            let r = if k % 2 == 0 { 1.0 } else { 0.4 };
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    assert!(simple_polygon(&star));
    assert!(!simple_polygon(&[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]));
    assert!(!simple_polygon(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.5, 0.0], [0.0, 1.0]]));
    assert!(!simple_polygon(&[[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [1.0, 0.0], [0.0, 2.0]]));
    let twice: Vec<[f64; 2]> = (0..12)
        .map(|k| {
            let a = k as f64 * 2.0 * std::f64::consts::TAU / 12.0;
            let r = 1.0 + 0.01 * k as f64;
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    assert!(!simple_polygon(&twice));
}

/// Outlines from the mesh: a patch of a grid has one loop round its
/// boundary; two triangles meeting at a corner, a ring, and triangles
/// wound against each other have none.
#[test]
fn outlines_are_single_loops_of_the_boundary() {
    let (triangles, _) = sheet(3, 3, |u, v| Vec3::new(u, v, 0.0));
    let edges = cancel_edges(triangles.iter().flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]]).collect()).unwrap();
    let outline = one_loop(&edges).unwrap();
    let mut sorted = outline.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, [0, 1, 2, 3, 5, 6, 7, 8]);
    // A corner in common only.
    assert!(one_loop(&[[0, 1], [1, 2], [2, 0], [0, 3], [3, 4], [4, 0]]).is_none());
    // A ring: two loops.
    assert!(one_loop(&[[0, 1], [1, 2], [2, 0], [5, 4], [4, 3], [3, 5]]).is_none());
    // Two triangles on one edge, wound against each other.
    assert!(cancel_edges(vec![[0, 1], [1, 2], [2, 0], [1, 2], [2, 3], [3, 1]]).is_none());
}

/// Merged cones hold every normal below them; normals spread over more
/// than a half-space give no cone.
#[test]
fn merged_cones_hold_their_normals() {
    let mut seed = 5u64;
    let mut rand = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for spread in [0.1, 0.5, 1.0, 1.4] {
        let normals: Vec<Vec3> = (0..64)
            .map(|_| {
                let (a, b) = (spread * rand(), std::f64::consts::TAU * rand());
                Vec3::new(a.sin() * b.cos(), a.sin() * b.sin(), a.cos())
            })
            .collect();
        let mut cones: Vec<Cone> = normals.iter().map(|&axis| Cone { axis, cos: 1.0, sin: 0.0 }).collect();
        while cones.len() > 1 {
            cones = cones.chunks(2).map(|c| Cone::merge(&c[0], &c[1])).collect();
        }
        let cone = cones[0];
        if cone.holds_a_patch() {
            for n in &normals {
                assert!(n.dot(&cone.axis) >= cone.cos - 1e-12, "spread {spread}");
            }
        } else {
            assert!(spread > 0.7, "normals within {spread} rad of one axis need a cone");
        }
    }
    let up = Cone { axis: Vec3::z(), cos: 1.0, sin: 0.0 };
    let down = Cone { axis: -Vec3::z(), cos: 1.0, sin: 0.0 };
    assert!(!Cone::merge(&up, &down).holds_a_patch());
}

/// The branch-free corner test agrees with comparing corner by corner on
/// every pair of triangles over six vertices, sharing corners or not.
#[test]
fn triangles_share_a_corner_exactly_when_one_corner_is_in_both() {
    let triangles: Vec<[u32; 3]> = (0..6)
        .flat_map(|a| (0..6).flat_map(move |b| (0..6).map(move |c| [a, b, c])))
        .filter(|[a, b, c]| a != b && b != c && a != c)
        .collect();
    let (mut shared, mut apart) = (0, 0);
    for &s in &triangles {
        for &t in &triangles {
            let expected = s.iter().any(|v| t.contains(v));
            assert_eq!(share_a_corner(s, t), expected, "{s:?} {t:?}");
            if expected { shared += 1 } else { apart += 1 }
        }
    }
    assert!(shared > 0 && apart > 0);
}

/// A refit in parallel fits every node: on a rippled sheet whose deepest
/// depths are split into tasks, each node's box is exactly the union of
/// its triangles' boxes and its cone (where there is one) holds their
/// normals, with one thread and with two; a corner that is not finite
/// names a triangle that holds it.
#[test]
fn a_parallel_refit_fits_every_node_below_the_root() {
    let (triangles, rest) = sheet(120, 120, |u, v| Vec3::new(u, v, 0.0));
    let x: Vec<Vec3> = rest.iter().map(|p| Vec3::new(p.x, p.y, 0.05 * (9.0 * p.x).sin() * (7.0 * p.y).cos())).collect();
    let mut tree = PatchTree::new(&triangles, &rest);
    let widest = tree.depths.windows(2).map(|d| d[1] - d[0]).max().unwrap() as usize;
    assert!(widest > 2 * REFIT_CHUNK, "the sheet should need parallel tasks ({widest} nodes)");
    // Each split's children lie in the next depth.
    for d in tree.depths.windows(3) {
        for n in d[0]..d[1] {
            if let Node::Split(l, r) = tree.nodes[n as usize] {
                assert!((d[1]..d[2]).contains(&l) && (d[1]..d[2]).contains(&r), "node {n}");
            }
        }
    }
    // The triangles under each node, children before parents.
    let mut under: Vec<Vec<u32>> = vec![Vec::new(); tree.nodes.len()];
    for n in (0..tree.nodes.len()).rev() {
        under[n] = match tree.nodes[n] {
            Node::Leaf(t) => vec![t],
            Node::Split(l, r) => [under[l as usize].clone(), under[r as usize].clone()].concat(),
        };
    }
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| tree.refit(&triangles, &x)).unwrap();
        for (n, ts) in under.iter().enumerate() {
            let corners = ts.iter().flat_map(|&t| triangles[t as usize].map(|v| x[v as usize]));
            let expected = Aabb::around(corners, 0.0);
            assert_eq!((tree.boxes[n].min, tree.boxes[n].max), (expected.min, expected.max), "node {n}");
            let cone = tree.cones[n];
            if cone.holds_a_patch() {
                for &t in ts {
                    let [i, j, k] = triangles[t as usize].map(|v| x[v as usize]);
                    let normal = (j - i).cross(&(k - i)).normalize();
                    assert!(normal.dot(&cone.axis) >= cone.cos - 1e-12, "node {n}, triangle {t}");
                }
            }
        }
        // The ripples bend the whole sheet less than 90 degrees.
        assert!(tree.cones[0].holds_a_patch(), "{threads} threads");
    }
    let mut broken = x.clone();
    broken[7_000].z = f64::NAN;
    match tree.refit(&triangles, &broken) {
        Err(BroadPhaseError::NonFinite { what: "triangle", index }) => {
            assert!(triangles[index].contains(&7_000), "triangle {index}")
        }
        other => panic!("{other:?}"),
    }
}
