//! Tests of the continuous self-collision test and the crossing check:
//! impact zones, every meeting and every crossing found.

use super::*;

/// Linear and angular momentum (about the origin) of displacements `dx`
/// from `x`, per unit time.
fn momenta(model: &ClothModel, x: &[Vec3], dx: &[Vec3]) -> (Vec3, Vec3) {
    let m = model.masses();
    (0..x.len()).fold((Vec3::zeros(), Vec3::zeros()), |(p, l), i| (p + dx[i] * m[i], l + x[i].cross(&dx[i]) * m[i]))
}

/// A small sheet driven through a larger one in one step (2 cm down, the
/// pair turning) is caught by an impact zone: both move as one rigid
/// body, so the small one stays 6 mm above the other's plane, and the
/// zone keeps the step's linear momentum exactly and its angular momentum
/// to the rotation's second order. Measured: 6.000 mm; linear momentum
/// off by 5.8e-16 of it, angular by 2.6e-5. Without the zone the small
/// sheet ends 14 mm below.
#[test]
fn an_impact_zone_stops_a_sheet_passing_through_another() {
    let model = stacked_sheets((7, 0.06), (4, 0.03), 0.006, [0.015, 0.015]);
    let sc = *model.self_collision().unwrap();
    let x0 = model.rest_positions().to_vec();
    let n = 49;
    let turn = nalgebra::Rotation3::new(Vec3::new(0.0, 0.0, 0.05));
    let mut new_x: Vec<Vec3> = x0.iter().map(|p| turn * p).collect();
    for p in &mut new_x[n..] {
        p.z -= 0.02;
    }
    // Lowest height of the small sheet's particles over the large sheet:
    // along the normal of the large sheet's triangle closest to each.
    let below: Vec<[u32; 3]> =
        model.triangles().iter().copied().filter(|t| t.iter().all(|&i| (i as usize) < n)).collect();
    let gap = |x: &[Vec3]| {
        let height = |p: Vec3| {
            let over = |t: &[u32; 3]| {
                let [a, b, c] = t.map(|i| x[i as usize]);
                let (q, _) = cloth_collide::closest_point_on_triangle(p, a, b, c);
                ((p - q).norm(), (p - q).dot(&(b - a).cross(&(c - a)).normalize()))
            };
            below.iter().map(over).min_by(|u, v| u.0.total_cmp(&v.0)).unwrap().1
        };
        x[n..].iter().map(|&p| height(p)).fold(f64::INFINITY, f64::min)
    };
    assert!(gap(&new_x) < -0.01, "the step should pass through: {}", gap(&new_x));
    let dx: Vec<Vec3> = x0.iter().zip(&new_x).map(|(a, b)| b - a).collect();
    let (p0, l0) = momenta(&model, &x0, &dx);
    let tau = 0.01;
    let mut new_v: Vec<Vec3> = dx.iter().map(|d| d / tau).collect();
    let (v_start, step_end) = (new_v.clone(), new_x.clone());
    let mut bufs = Contacts::default();
    let (met, left) = untangle_step(&model, &sc, &x0, tau, &mut new_x, &mut new_v, &mut bufs);
    let dx: Vec<Vec3> = x0.iter().zip(&new_x).map(|(a, b)| b - a).collect();
    let (p1, l1) = momenta(&model, &x0, &dx);
    let (dp, dl) = ((p1 - p0).norm() / p0.norm(), (l1 - l0).norm() / l0.norm());
    eprintln!("{met} meetings, {left} left; gap {:.3e} m; momentum off by {dp:.1e}, angular {dl:.1e}", gap(&new_x));
    assert!(met > 0 && left == 0, "{met} meetings, {left} left");
    assert!((gap(&new_x) - 0.006).abs() < 1e-12, "the sheets should keep their 6 mm: {}", gap(&new_x));
    assert!(dp < 1e-14, "linear momentum off by {dp}");
    assert!(dl < 5e-5, "angular momentum off by {dl}");
    // Velocities follow the positions: v changes by the position change over tau.
    for i in 0..x0.len() {
        let change = (new_x[i] - step_end[i]) / tau;
        assert!((new_v[i] - v_start[i] - change).norm() < 1e-12, "particle {i}");
    }
}

/// A small sheet whose one side dips through a larger one: the zones
/// grow until nothing meets, and the end has no edge through a triangle
/// (`self_intersections`), where the raw step has 28. Particles far from
/// the dip keep their step: zones are local (measured: 90 of 162).
#[test]
fn a_partly_crossing_sheet_ends_untangled_and_far_particles_keep_their_step() {
    let model = stacked_sheets((9, 0.16), (9, 0.16), 0.006, [0.04, 0.04]);
    let sc = *model.self_collision().unwrap();
    let x0 = model.rest_positions().to_vec();
    let n = x0.len() / 2;
    let mut new_x = x0.clone();
    // The top sheet's side at x = 0.2 dips 12 mm, its side at x = 0.04 stays.
    for p in &mut new_x[n..] {
        p.z -= 0.012 * (p.x - 0.04) / 0.16;
    }
    // The lower sheet drifts sideways, unhurried.
    for p in &mut new_x[..n] {
        p.y += 0.001;
    }
    let raw = self_intersections(&model, &new_x).len();
    let mut new_v = vec![Vec3::zeros(); x0.len()];
    let mut bufs = Contacts::default();
    let before = new_x.clone();
    let (met, left) = untangle_step(&model, &sc, &x0, 0.01, &mut new_x, &mut new_v, &mut bufs);
    let after = self_intersections(&model, &new_x).len();
    let kept = (0..x0.len()).filter(|&i| new_x[i] == before[i]).count();
    eprintln!(
        "raw step: {raw} edges through triangles; {met} meetings, {left} left; after: {after}; {kept} particles kept their step"
    );
    assert!(raw > 0, "the raw step should cross");
    assert_eq!((after, left), (0, 0));
    assert!(kept >= 85, "only {kept} particles kept their step");
}

/// The crossing check's broad phase misses nothing and adds nothing: on
/// two sheets crumpled through each other (a few hundred crossings), it
/// finds exactly the crossings of every mesh edge against every triangle
/// whose corners are neither the edge's ends nor linked to them, for each
/// model, with triangles that share a corner skipped (every model links
/// its mesh edges) and tested (as for a mesh whose edges are not all
/// linked).
#[test]
fn the_crossing_check_finds_what_testing_every_edge_against_every_triangle_finds() {
    for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
        let mut spec = stacked_sheets_spec((12, 0.2), (10, 0.16), 0.004, [0.02, 0.02]);
        spec.kind = kind;
        let model = ClothModel::build(&spec).unwrap();
        assert!(CrossingCheck::new(&model).skips_adjacent(), "{kind:?}: mesh edges should be linked");
        let expected = if kind == ModelKind::Volino { 253 } else { 270 };
        every_crossing_is_found(&model, expected);
    }
}

/// Compares the crossing check with testing every edge against every
/// triangle, on `model` crumpled (at least `expected` crossings,
/// measured) and waved smoothly, each sheet its own way, so that the
/// sheets pass through each other (the check then skips patches whole).
fn every_crossing_is_found(model: &ClothModel, expected: usize) {
    let mut seed = 11u64;
    let mut rand = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let crumpled: Vec<Vec3> =
        model.rest_positions().iter().map(|p| p + Vec3::new(0.01 * rand(), 0.01 * rand(), 0.03 * rand())).collect();
    let waved: Vec<Vec3> = model
        .rest_positions()
        .iter()
        .map(|p| {
            let phase = if p.z > 0.0 { 1.5 } else { 0.0 };
            p + Vec3::new(0.0, 0.0, 0.01 * (40.0 * p.x + phase).sin() * (25.0 * p.y).cos())
        })
        .collect();
    let triangles = model.triangles();
    let mut edges: Vec<[u32; 2]> =
        triangles.iter().flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]]).map(|[a, b]| [a.min(b), a.max(b)]).collect();
    edges.sort_unstable();
    edges.dedup();
    let never = |p: u32, tri: &[u32; 3]| tri.iter().any(|&c| c == p || model.never_repel(p as usize, c as usize));
    for (x, expected) in [(crumpled, expected), (waved, 85)] {
        let mut every = Vec::new();
        for (t, tri) in triangles.iter().enumerate() {
            let [i, j, k] = tri.map(|c| x[c as usize]);
            for &[a, b] in edges.iter().filter(|&&[a, b]| !never(a, tri) && !never(b, tri)) {
                if cloth_collide::segment_crosses_triangle(x[a as usize], x[b as usize], i, j, k) {
                    every.push(([a, b], t as u32));
                }
            }
        }
        every.sort_unstable();
        eprintln!("{} crossings", every.len());
        assert!(every.len() >= expected, "the sheets should cross often, {} crossings", every.len());
        assert_eq!(self_intersections(model, &x), every);
        assert_eq!(CrossingCheck::new(model).testing_adjacent().find(model, &x), every);
    }
}

/// The continuous test finds the point-triangle and edge-edge pairs that
/// meet between two states of crumpled sheets as testing every pair
/// does: when every particle moves (the grid holds all triangles), when
/// one in twelve does (moving triangles against resting ones), and when
/// an edge is carried through another edge of a triangle round one of its
/// vertices (`ring_edge_pairs`; the grid skips such triangle pairs).
#[test]
fn the_continuous_test_finds_every_meeting_of_a_dense_and_a_sparse_motion() {
    let model = stacked_sheets((10, 0.1), (8, 0.08), 0.004, [0.01, 0.01]);
    let sc = *model.self_collision().unwrap();
    let eta = MEETING_FRACTION * sc.thickness_m;
    let mut seed = 5u64;
    let mut rand = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut jiggle = |size: f64| Vec3::new(size * rand(), size * rand(), size * rand());
    let x0: Vec<Vec3> = model.rest_positions().iter().map(|p| p + jiggle(0.02)).collect();
    let dense: Vec<Vec3> = x0.iter().map(|p| p + jiggle(0.04)).collect();
    let sparse: Vec<Vec3> =
        x0.iter().enumerate().map(|(i, p)| if i % 12 == 0 { p + jiggle(0.04) } else { *p }).collect();
    let triangles = model.triangles();
    let mut edges: Vec<[u32; 2]> =
        triangles.iter().flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]]).map(|[a, b]| [a.min(b), a.max(b)]).collect();
    edges.sort_unstable();
    edges.dedup();
    let mut bufs = Contacts::default();
    build_exclusions(&model, &mut bufs.excluded_ptr, &mut bufs.excluded);
    bufs.crossings.owned = owned_features(triangles, model.particle_count());
    bufs.crossings.ring = ring_edge_pairs(&model, &bufs.crossings.owned);
    // One edge of a vertex's ring carried through another (ends a, b moved
    // twice the way from its middle to the other's).
    let [a, b, c, d] = bufs.crossings.ring[0];
    let mut ring = x0.clone();
    let across = x0[c as usize] + x0[d as usize] - x0[a as usize] - x0[b as usize];
    ring[a as usize] += across;
    ring[b as usize] += across;
    for (x1, expected) in [(&dense, 600), (&sparse, 75), (&ring, 1)] {
        find_meetings(&model, sc.voxel_m, eta, &x0, x1, (&bufs.excluded_ptr, &bufs.excluded), &mut bufs.crossings);
        let mut found: Vec<[u32; 4]> = bufs.crossings.meetings.iter().map(|m| sorted(*m)).collect();
        found.sort_unstable();
        let sparse_motion = bufs.crossings.moving.len() * 4 < triangles.len();
        let common = if sparse_motion {
            Vec3::zeros()
        } else {
            x0.iter().zip(x1.iter()).map(|(a, b)| b - a).sum::<Vec3>() / x0.len() as f64
        };
        let path = |i: u32| [x0[i as usize], x1[i as usize] - common];
        let mut every = Vec::new();
        for (t, &[a, b, c]) in triangles.iter().enumerate() {
            let never = &bufs.excluded[bufs.excluded_ptr[t] as usize..bufs.excluded_ptr[t + 1] as usize];
            for p in
                (0..model.particle_count() as u32).filter(|p| ![a, b, c].contains(p) && never.binary_search(p).is_err())
            {
                if cloth_collide::point_triangle_impact(path(p), path(a), path(b), path(c), eta).is_some() {
                    every.push(sorted([p, a, b, c]));
                }
            }
        }
        let near = |p: u32, q: u32| model.never_repel(p as usize, q as usize);
        for (k, &[a, b]) in edges.iter().enumerate() {
            for &[c, d] in &edges[k + 1..] {
                let apart = a != c && a != d && b != c && b != d;
                if apart
                    && !(near(a, c) || near(a, d) || near(b, c) || near(b, d))
                    && cloth_collide::edge_edge_impact(path(a), path(b), path(c), path(d), eta).is_some()
                {
                    every.push(sorted([a, b, c, d]));
                }
            }
        }
        every.sort_unstable();
        eprintln!("sparse {sparse_motion}: {} meetings", every.len());
        assert_eq!(sparse_motion, !std::ptr::eq(x1, &dense));
        assert!(every.len() >= expected, "the motion should meet often: {} meetings", every.len());
        assert_eq!(found, every);
    }
    assert!(bufs.crossings.meetings.contains(&[a, b, c, d]), "the ring's edges should meet");
}

fn sorted(mut quad: [u32; 4]) -> [u32; 4] {
    quad.sort_unstable();
    quad
}
