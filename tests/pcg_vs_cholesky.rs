//! PCG against faer's sparse Cholesky on random SPD block systems, with and
//! without Baraff-Witkin filters.

use cloth_linalg::{
    Aggregation, BlockPattern, BlockSparseMatrix, Constraint, ConstraintFilter, Coupling, Couplings, Cycle, Mat3,
    Multigrid, MultigridError, Pcg, PcgError, PcgParams, PreconditionerKind, SMOOTHED_MIN_NODES, Vec3,
};
use cloth_tests::{Rng, same_bits};
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};

/// A = diag(m_i I) + sum_e L_e (x) B_e with random PSD B_e: the structure of
/// the cloth system matrix. Returns A and the pair list.
fn random_system(rng: &mut Rng, n: usize, pairs_per_node: usize, mass: f64) -> BlockSparseMatrix {
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for i in 0..n {
        pairs.push((i, (i + 1) % n)); // a ring keeps it connected
        for _ in 1..pairs_per_node {
            let j = (((rng.uniform() + 1.0) * 0.5 * n as f64) as usize).min(n - 1);
            if j != i {
                pairs.push((i, j));
            }
        }
    }
    let blocks: Vec<Mat3> = pairs
        .iter()
        .map(|_| {
            let r = Mat3::from_fn(|_, _| rng.uniform());
            r * r.transpose() * 10.0
        })
        .collect();
    let pattern = BlockPattern::from_pairs(n, pairs.iter().copied()).unwrap();
    let mut a = BlockSparseMatrix::new(pattern);
    for i in 0..n {
        let d = a.pattern().diag_slot(i);
        a.values_mut()[d] = Mat3::identity() * mass;
    }
    for (&(i, j), b) in pairs.iter().zip(&blocks) {
        let p = a.pattern().clone();
        let v = a.values_mut();
        v[p.diag_slot(i)] += b;
        v[p.diag_slot(j)] += b;
        v[p.slot(i, j).unwrap()] -= b;
        v[p.slot(j, i).unwrap()] -= b;
    }
    a
}

/// Orthonormal basis (columns) of the free directions of a projector.
fn free_basis(s: &Mat3) -> Vec<Vec3> {
    let eig = s.symmetric_eigen();
    (0..3).filter(|&k| eig.eigenvalues[k] > 0.5).map(|k| eig.eigenvectors.column(k).into_owned()).collect()
}

/// Reference: eliminate the constrained components (x_i = z_i + T_i y_i) and
/// solve T^T A T y = T^T (b - A z) with faer's sparse Cholesky.
fn cholesky_reference(a: &BlockSparseMatrix, b: &[Vec3], filter: &ConstraintFilter) -> Vec<Vec3> {
    let n = a.n();
    let bases: Vec<Vec<Vec3>> = (0..n).map(|i| free_basis(&filter.projector(i))).collect();
    let mut offset = vec![0usize; n + 1];
    for i in 0..n {
        offset[i + 1] = offset[i] + bases[i].len();
    }
    let dof = offset[n];
    let z: Vec<Vec3> = (0..n).map(|i| filter.prescribed(i)).collect();
    let mut az = vec![Vec3::zeros(); n];
    a.mul_vec(&z, &mut az);
    let mut triplets = Vec::new();
    for (i, j, blk) in a.blocks() {
        for (p, ti) in bases[i].iter().enumerate() {
            for (q, tj) in bases[j].iter().enumerate() {
                triplets.push(Triplet::new(offset[i] + p, offset[j] + q, ti.dot(&(blk * tj))));
            }
        }
    }
    let mut rhs = Mat::<f64>::zeros(dof, 1);
    for i in 0..n {
        for (p, ti) in bases[i].iter().enumerate() {
            rhs[(offset[i] + p, 0)] = ti.dot(&(b[i] - az[i]));
        }
    }
    let mat = SparseColMat::<usize, f64>::try_new_from_triplets(dof, dof, &triplets).unwrap();
    let llt = mat.as_ref().sp_cholesky(Side::Lower).expect("reference system is SPD");
    let y = llt.solve(&rhs);
    (0..n).map(|i| z[i] + bases[i].iter().enumerate().map(|(p, t)| t * y[(offset[i] + p, 0)]).sum::<Vec3>()).collect()
}

fn max_rel_diff(a: &[Vec3], b: &[Vec3]) -> f64 {
    let scale = b.iter().map(|v| v.norm()).fold(0.0, f64::max);
    a.iter().zip(b).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max) / scale
}

fn solve(a: &BlockSparseMatrix, b: &[Vec3], f: &ConstraintFilter, kind: PreconditionerKind) -> (Vec<Vec3>, usize) {
    let params = PcgParams { rel_tol: 1e-12, max_iter: 5000, preconditioner: kind };
    let mut x = vec![Vec3::zeros(); a.n()];
    let info = Pcg::new(a.n()).solve(a, b, f, &params, &mut x).expect("PCG converges");
    assert!(info.rel_residual <= 1e-12);
    (x, info.iterations)
}

#[test]
fn unfiltered_pcg_matches_sparse_cholesky_for_every_preconditioner() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let a = random_system(&mut rng, 700, 4, 0.05);
    let b: Vec<Vec3> = (0..a.n()).map(|_| rng.vec3()).collect();
    let filter = ConstraintFilter::new(a.n());
    let reference = cholesky_reference(&a, &b, &filter);
    let mut iters = Vec::new();
    for kind in [PreconditionerKind::None, PreconditionerKind::Diagonal, PreconditionerKind::BlockJacobi] {
        let (x, it) = solve(&a, &b, &filter, kind);
        let err = max_rel_diff(&x, &reference);
        assert!(err < 1e-9, "{kind:?}: relative difference {err:e}");
        iters.push(it);
    }
    // Block-Jacobi must not be worse than no preconditioning on this system.
    assert!(iters[2] <= iters[0], "iterations none/diag/block: {iters:?}");
}

#[test]
fn filtered_pcg_matches_reduced_cholesky_and_holds_constraints_exactly() {
    let mut rng = Rng(42);
    let a = random_system(&mut rng, 500, 3, 0.02);
    let n = a.n();
    let b: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
    let mut filter = ConstraintFilter::new(n);
    for i in (0..n).step_by(7) {
        let c = match i % 4 {
            0 => Constraint::Fixed,
            1 => Constraint::OneDirection { normal: rng.vec3() },
            2 => Constraint::TwoDirections { n: rng.vec3(), m: rng.vec3() },
            _ => Constraint::Free,
        };
        filter.set(i, c, rng.vec3()).unwrap();
    }
    assert!(filter.constrained_count() > 40);
    let reference = cholesky_reference(&a, &b, &filter);
    for kind in [PreconditionerKind::None, PreconditionerKind::Diagonal, PreconditionerKind::BlockJacobi] {
        let (x, _) = solve(&a, &b, &filter, kind);
        let err = max_rel_diff(&x, &reference);
        assert!(err < 1e-9, "{kind:?}: relative difference {err:e}");
        for (i, s, z) in filter.iter() {
            // Constrained components are exactly the prescribed ones (bitwise
            // up to the projection's own rounding).
            let constrained = x[i] - s * x[i];
            assert!((constrained - z).norm() <= 1e-14 * (1.0 + z.norm()), "particle {i}");
        }
    }
}

#[test]
fn warm_start_from_the_solution_takes_no_iteration() {
    let mut rng = Rng(7);
    let a = random_system(&mut rng, 300, 3, 0.1);
    let b: Vec<Vec3> = (0..a.n()).map(|_| rng.vec3()).collect();
    let filter = ConstraintFilter::new(a.n());
    let (mut x, cold) = solve(&a, &b, &filter, PreconditionerKind::BlockJacobi);
    let params = PcgParams { rel_tol: 1e-10, ..Default::default() };
    let info = Pcg::new(a.n()).solve(&a, &b, &filter, &params, &mut x).unwrap();
    assert_eq!(info.iterations, 0);
    assert!(cold > 5);
}

#[test]
fn reports_non_convergence_and_indefiniteness() {
    let mut rng = Rng(3);
    let a = random_system(&mut rng, 200, 3, 0.01);
    let b: Vec<Vec3> = (0..a.n()).map(|_| rng.vec3()).collect();
    let filter = ConstraintFilter::new(a.n());
    let params = PcgParams { rel_tol: 1e-12, max_iter: 3, preconditioner: PreconditionerKind::None };
    let mut x = vec![Vec3::zeros(); a.n()];
    match Pcg::new(a.n()).solve(&a, &b, &filter, &params, &mut x) {
        Err(PcgError::NotConverged { info }) => {
            assert_eq!(info.iterations, 3);
            assert!(info.rel_residual > 1e-12 && info.rel_residual < 1.0);
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
    // -A is negative definite: the first curvature is negative.
    let mut neg = a.clone();
    neg.values_mut().iter_mut().for_each(|v| *v = -*v);
    let mut x = vec![Vec3::zeros(); a.n()];
    let r = Pcg::new(a.n()).solve(
        &neg,
        &b,
        &filter,
        &PcgParams { preconditioner: PreconditionerKind::None, ..Default::default() },
        &mut x,
    );
    assert!(matches!(r, Err(PcgError::NotPositiveDefinite { iteration: 1, .. })), "{r:?}");
    let mut bad = b.clone();
    bad[5].x = f64::NAN;
    let r = Pcg::new(a.n()).solve(&a, &bad, &filter, &PcgParams::default(), &mut x);
    assert!(matches!(r, Err(PcgError::NonFinite { iteration: 0 })), "{r:?}");
}

#[test]
fn solve_is_bit_identical_across_thread_counts() {
    let mut rng = Rng(11);
    let a = random_system(&mut rng, 2000, 4, 0.05);
    let b: Vec<Vec3> = (0..a.n()).map(|_| rng.vec3()).collect();
    let filter = ConstraintFilter::new(a.n());
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| solve(&a, &b, &filter, PreconditionerKind::BlockJacobi).0)
    };
    let one = run(1);
    let two = run(2);
    let four = run(4);
    assert!(one.iter().zip(&two).all(|(p, q)| p.x.to_bits() == q.x.to_bits()
        && p.y.to_bits() == q.y.to_bits()
        && p.z.to_bits() == q.z.to_bits()));
    assert_eq!(two, four);
}

/// Aggregates of `size` consecutive nodes per level, down to at most 40 nodes.
fn chunk_aggregations(n: usize, size: usize) -> Vec<Aggregation> {
    let mut levels = Vec::new();
    let mut n = n;
    while n > 40 {
        let n_coarse = n.div_ceil(size);
        levels.push(Aggregation { coarse_of: (0..n).map(|i| (i / size) as u32).collect(), n_coarse });
        n = n_coarse;
    }
    levels
}

#[test]
fn multigrid_pcg_matches_cholesky_with_and_without_filters() {
    let mut rng = Rng(0x5eed);
    let a = random_system(&mut rng, 900, 3, 0.02);
    let n = a.n();
    let b: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
    let mut filter = ConstraintFilter::new(n);
    for i in (0..n).step_by(11) {
        filter
            .set(
                i,
                if i % 2 == 0 { Constraint::Fixed } else { Constraint::OneDirection { normal: rng.vec3() } },
                rng.vec3(),
            )
            .unwrap();
    }
    // `f64` operators on every level (these are small), and the `f32`
    // copies that large levels get.
    // The W-cycle and the K-cycle (a nonlinear preconditioner: flexible PCG).
    let cases = [(ConstraintFilter::new(n), usize::MAX), (filter.clone(), usize::MAX), (filter, 0)];
    let aggregations = chunk_aggregations(n, 4);
    for (f, single_from) in cases {
        let reference = cholesky_reference(&a, &b, &f);
        let (_, block_jacobi_iters) = solve(&a, &b, &f, PreconditionerKind::BlockJacobi);
        let plain = |cycle| {
            Multigrid::with_single_precision_from(a.pattern(), &aggregations, single_from)
                .map(|mg| mg.with_cycle(cycle))
        };
        let smoothed = Multigrid::smoothed_with_single_precision_from(a.pattern(), &aggregations, single_from);
        for (label, mg) in [("W-cycle", plain(Cycle::W)), ("K-cycle", plain(Cycle::K)), ("smoothed", smoothed)] {
            let mg = mg.unwrap();
            assert_eq!(mg.is_nonlinear(), label != "W-cycle");
            let mut pcg = Pcg::new(n);
            pcg.set_multigrid(mg);
            let params = PcgParams { rel_tol: 1e-12, max_iter: 5000, preconditioner: PreconditionerKind::Multigrid };
            let mut x = vec![Vec3::zeros(); n];
            let info = pcg.solve(&a, &b, &f, &params, &mut x).expect("multigrid PCG converges");
            let err = max_rel_diff(&x, &reference);
            assert!(err < 1e-9, "{label}: relative difference {err:e}");
            assert!(
                info.iterations < block_jacobi_iters,
                "{label}: multigrid {} vs block-Jacobi {block_jacobi_iters}",
                info.iterations
            );
            // In place: the same iterates to the last bit, and A comes back unchanged.
            let mut a_in_place = a.clone();
            let mut y = vec![Vec3::zeros(); n];
            let info2 = pcg.solve_in_place(&mut a_in_place, &b, &f, &params, &mut y).unwrap();
            assert_eq!(info2.iterations, info.iterations);
            assert!(same_bits(&x, &y), "{label}: solve_in_place differs from solve");
            assert_eq!(a_in_place.values(), a.values(), "the matrix was not restored");
        }
    }
    // A smoothed hierarchy is refilled whole, never in part.
    let mut smoothed = Multigrid::smoothed(a.pattern(), &aggregations).unwrap();
    smoothed.update(&a);
    assert!(!smoothed.update_rows(&a, &[0]));
}

/// PCG needs a symmetric positive definite preconditioner: check the
/// The cycle is symmetric and positive on random vectors.
#[test]
fn multigrid_cycle_is_symmetric_positive_definite() {
    let mut rng = Rng(99);
    let a = random_system(&mut rng, 700, 4, 0.01);
    let n = a.n();
    // With `f64` operators on every level (these are small), and with
    // the `f32` copies that large levels get.
    for single_from in [usize::MAX, 0] {
        let mut mg =
            Multigrid::with_single_precision_from(a.pattern(), &chunk_aggregations(n, 3), single_from).unwrap();
        assert!(mg.depth() >= 3);
        mg.update(&a);
        assert_cycle_is_spd(&mut mg, &a, &mut rng, 5);
    }
}

/// `v^T M u = u^T M v` and `u^T M u > 0` for the cycle `M` on `tries`
/// pairs of random vectors.
fn assert_cycle_is_spd(mg: &mut Multigrid, a: &BlockSparseMatrix, rng: &mut Rng, tries: usize) {
    let n = a.n();
    for _ in 0..tries {
        let u: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
        let v: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
        let (mut mu, mut mv) = (vec![Vec3::zeros(); n], vec![Vec3::zeros(); n]);
        mg.apply(a, &u, &mut mu);
        mg.apply(a, &v, &mut mv);
        let dot = |p: &[Vec3], q: &[Vec3]| p.iter().zip(q).map(|(x, y)| x.dot(y)).sum::<f64>();
        let (vmu, umv) = (dot(&v, &mu), dot(&u, &mv));
        // Roundoff against the products' Cauchy-Schwarz bound, not against
        // `v.Mu` itself (a sum of mixed signs that may cancel): measured up
        // to 2.2e-15 on the random system and 3.7e-13 with 1e4-stiff ties
        // (the W-cycle's second coarse pass forms `r - A_c e` with `A_c e`
        // close to `r`, and the cycle's condition amplifies its roundoff).
        let scale = (dot(&v, &v) * dot(&mu, &mu)).sqrt().max((dot(&u, &u) * dot(&mv, &mv)).sqrt());
        assert!((vmu - umv).abs() <= 1e-12 * scale, "{vmu} vs {umv} (|v| |Mu| = {scale})");
        assert!(dot(&u, &mu) > 0.0);
    }
}

#[test]
fn multigrid_without_a_hierarchy_is_an_error() {
    let mut rng = Rng(5);
    let a = random_system(&mut rng, 50, 2, 0.1);
    let b = vec![Vec3::x(); a.n()];
    let params = PcgParams { preconditioner: PreconditionerKind::Multigrid, ..PcgParams::default() };
    let mut x = vec![Vec3::zeros(); a.n()];
    let r = Pcg::new(a.n()).solve(&a, &b, &ConstraintFilter::new(a.n()), &params, &mut x);
    assert_eq!(r, Err(PcgError::NoMultigridHierarchy));
    let nan_tol = PcgParams { rel_tol: f64::NAN, ..PcgParams::default() };
    let r = Pcg::new(a.n()).solve(&a, &b, &ConstraintFilter::new(a.n()), &nan_tol, &mut x);
    assert!(matches!(r, Err(PcgError::InvalidTolerance { .. })), "{r:?}");
    let bad = Aggregation { coarse_of: vec![0; 7], n_coarse: 1 };
    assert!(Multigrid::new(a.pattern(), std::slice::from_ref(&bad)).is_err());
    assert!(Multigrid::smoothed(a.pattern(), &[bad]).is_err());
    // A level below the first that does not fit is refused before the
    // smoothed level's first update would build the hierarchy below it.
    let pairs = Aggregation { coarse_of: (0..a.n()).map(|i| (i / 2) as u32).collect(), n_coarse: a.n().div_ceil(2) };
    let wrong_size = Aggregation { coarse_of: vec![0; 3], n_coarse: 1 };
    let r = Multigrid::smoothed(a.pattern(), &[pairs.clone(), wrong_size]);
    assert!(matches!(r, Err(MultigridError::SizeMismatch { level: 1, expected: 25, got: 3 })), "{r:?}");
    let empty = Aggregation { coarse_of: vec![0; a.n().div_ceil(2)], n_coarse: 2 };
    let r = Multigrid::smoothed(a.pattern(), &[pairs, empty]);
    assert!(matches!(r, Err(MultigridError::BadAggregate { level: 1 })), "{r:?}");
}

/// Smallest eigenvalue of the cycle operator `P^-1` of `a` (built
/// column by column; `a` small).
fn smallest_cycle_eigenvalue(a: &BlockSparseMatrix, mg: &mut Multigrid) -> f64 {
    let n = a.n();
    let mut dense = nalgebra::DMatrix::<f64>::zeros(3 * n, 3 * n);
    let mut z = vec![Vec3::zeros(); n];
    for col in 0..3 * n {
        let mut e = vec![Vec3::zeros(); n];
        e[col / 3][col % 3] = 1.0;
        mg.apply(a, &e, &mut z);
        for (i, zi) in z.iter().enumerate() {
            dense.fixed_view_mut::<3, 1>(3 * i, col).copy_from(zi);
        }
    }
    let asymmetry = (&dense - dense.transpose()).amax();
    assert!(asymmetry <= 1e-12 * dense.amax(), "cycle not symmetric: {asymmetry:e}");
    dense.symmetric_eigen().eigenvalues.min()
}

/// The BDF2 step matrix of a narrow Volino strip (21 x 3 particles at
/// 0.5 cm, E = 1e4 N/m, B = 1.2e-4 N m, h = 5 ms) at rest: its bending
/// triangles (six-node elements) break the links' smoother damping (0.7), the
/// cycle is indefinite and PCG stops with "preconditioner not positive
/// definite"; damped for six-node elements (`ClothModel::multigrid`) the
/// cycle is positive definite (proof in `cloth_linalg::multigrid`) and
/// PCG agrees with block-Jacobi.
#[test]
fn multigrid_damped_for_its_elements_stays_positive_definite() {
    let overrides = [
        "panels.0.particles=[21, 3]",
        "panels.0.size_m=[0.1, 0.01]",
        "pins=[{ nodes = [[0, 0], [0, 1], [0, 2], [1, 0], [1, 1], [1, 2]], motion = { kind = \"fixed\" } }]",
    ];
    let (sim, cfg) = cloth_tests::simulation("cantilever.toml", &overrides);
    let model = sim.model();
    let h = cfg.dt_s;
    let terms = cloth_core::terms::SystemTerms::new(4.0 * h * h / 9.0, 2.0 * h / 3.0, 0.0, &[]);
    let mut bufs = cloth_core::testing::SystemBuffers::new(model);
    cloth_core::testing::assemble(model, model.rest_positions(), &terms, &mut bufs);
    let a = &bufs.matrix;
    let n = a.n();
    let mut filter = ConstraintFilter::new(n);
    for pin in model.pins() {
        filter.set(pin.particle, Constraint::Fixed, Vec3::zeros()).unwrap();
    }
    let mut rng = Rng(21);
    let b: Vec<Vec3> = (0..n).map(|_| rng.vec3() * 1e-6).collect();
    let params = PcgParams { rel_tol: 1e-10, max_iter: 2000, preconditioner: PreconditionerKind::Multigrid };
    let solve_with = |mg: Multigrid| {
        let mut pcg = Pcg::new(n);
        pcg.set_multigrid(mg);
        let mut x = vec![Vec3::zeros(); n];
        pcg.solve(a, &b, &filter, &params, &mut x).map(|_| x)
    };
    let links = solve_with(model.multigrid().for_element_size(2));
    assert!(matches!(links, Err(PcgError::PreconditionerNotPositive { .. })), "{links:?}");
    let x = solve_with(model.multigrid()).expect("the cycle damped for its elements is positive definite");
    let (reference, _) = solve(a, &b, &filter, PreconditionerKind::BlockJacobi);
    let err = max_rel_diff(&x, &reference);
    assert!(err < 1e-8, "multigrid vs block-Jacobi: {err:e}");
    let (mut elements, mut links) = (model.multigrid(), model.multigrid().for_element_size(2));
    elements.update(a);
    links.update(a);
    let (with_elements, with_links) =
        (smallest_cycle_eigenvalue(a, &mut elements), smallest_cycle_eigenvalue(a, &mut links));
    println!("smallest eigenvalue of the cycle: damped for its elements {with_elements:e}, for links {with_links:e}");
    assert!(with_elements > 0.0 && with_links < 0.0);
}

/// Nodes tied by a coupling far stiffer than the rest (a seam's stitches)
/// are smoothed as pairs (`Multigrid::with_pairs`): the cycle stays
/// symmetric positive definite, PCG still matches Cholesky, and it takes
/// far fewer iterations than with point blocks, whose diagonals the stiff
/// coupling inflates.
#[test]
fn multigrid_smoothing_stiff_pairs_together_stays_spd_and_converges_faster() {
    let mut rng = Rng(0xfeed);
    let (stiff, ties) = tied_system(&mut rng, 800);
    let (n, pattern) = (stiff.n(), stiff.pattern().clone());
    let b: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
    let f = ConstraintFilter::new(n);
    let reference = cholesky_reference(&stiff, &b, &f);
    let params = PcgParams { rel_tol: 1e-10, max_iter: 5000, preconditioner: PreconditionerKind::Multigrid };
    let mut iterations = Vec::new();
    for (paired, single_from) in [(false, usize::MAX), (true, usize::MAX), (true, 0)] {
        let mg = Multigrid::with_single_precision_from(&pattern, &chunk_aggregations(n, 4), single_from).unwrap();
        let mut mg = if paired { mg.with_pairs(&ties) } else { mg };
        mg.update(&stiff);
        assert_cycle_is_spd(&mut mg, &stiff, &mut rng, 3);
        let mut pcg = Pcg::new(n);
        pcg.set_multigrid(mg);
        let mut x = vec![Vec3::zeros(); n];
        let info = pcg.solve(&stiff, &b, &f, &params, &mut x).expect("converges");
        let err = max_rel_diff(&x, &reference);
        assert!(err < 1e-7, "paired {paired}: relative difference {err:e}");
        iterations.push(info.iterations);
    }
    println!("iterations (point, paired, paired f32): {iterations:?}");
    // Measured: 126 iterations with point blocks, 24 with the pairs (`f64`
    // operators), 24 with the pairs on `f32` copies.
    assert!(iterations[1] * 4 < iterations[0], "iterations (point, paired, paired f32): {iterations:?}");
    assert!(iterations[2] * 4 < iterations[0], "iterations (point, paired, paired f32): {iterations:?}");
}

/// A random system of `n` nodes with node `i` tied to node `i + n/2`
/// (never in the same aggregate) for every tenth `i`, 1000 times stiffer
/// than a typical coupling; returns it and the ties.
fn tied_system(rng: &mut Rng, n: usize) -> (BlockSparseMatrix, Vec<(usize, usize)>) {
    let a = random_system(rng, n, 3, 0.02);
    let ties: Vec<(usize, usize)> = (0..n / 2).step_by(10).map(|i| (i, i + n / 2)).collect();
    let pairs = (0..n).flat_map(|i| a.pattern().row_cols(i).iter().map(move |&j| (i, j as usize)));
    let pattern = BlockPattern::from_pairs(n, pairs.chain(ties.iter().copied())).unwrap();
    let mut stiff = BlockSparseMatrix::new(pattern.clone());
    for (i, j, b) in a.blocks() {
        stiff.values_mut()[pattern.slot(i, j).unwrap()] = *b;
    }
    for &(i, j) in &ties {
        let k = Mat3::identity() * 1e4;
        let v = stiff.values_mut();
        v[pattern.diag_slot(i)] += k;
        v[pattern.diag_slot(j)] += k;
        v[pattern.slot(i, j).unwrap()] -= k;
        v[pattern.slot(j, i).unwrap()] -= k;
    }
    (stiff, ties)
}

/// A contact pass solves the same matrix again under a changed filter:
/// the hierarchy is then refilled only where the filter changed, and every
/// solve's answer and iterations are those of a solver whose hierarchy was
/// built from scratch, to the last bit. Over a sequence of filters (none;
/// fixed and one-direction particles, on tied pairs too; some released,
/// turned, added; most particles at once, which refills everything; the
/// matrix changed, which must not be refilled in part), with `f64` and
/// `f32` coarse operators, point and paired smoothing, W- and K-cycles,
/// without couplings and with couplings (a partial refill remakes only
/// the terms that reach a changed particle, and recomputes a coupled
/// node's smoother block only where its row or its pair partner's
/// changed).
#[test]
fn re_solves_under_a_changed_filter_refill_the_hierarchy_to_the_same_bits() {
    let mut rng = Rng(0xa11ce);
    let (mut a, ties) = tied_system(&mut rng, 800);
    let n = a.n();
    // Couplings over two or three nodes, each node's own block in `A` (so
    // `A + E` stays positive definite): spread over the cloth, and on tied
    // nodes whose partner's filter changes while their own does not.
    let mut couplings = Couplings::default();
    let spread = (0..n as u32).step_by(37).map(|i| [i, (i + 101) % n as u32, (i + 202) % n as u32]);
    let on_ties = [ties[5].0, ties[7].1].map(|i| [i as u32, i as u32 + 1, i as u32 + 1]);
    for nodes in spread.chain(on_ties) {
        let weights = if nodes[1] == nodes[2] { [1.0, -1.0, 0.0, 0.0] } else { [1.0, -0.5, -0.5, 0.0] };
        let direction = rng.vec3().normalize();
        let c = Coupling { nodes: [nodes[0], nodes[1], nodes[2], 0], weights, direction, stiffness: 30.0 };
        for (&node, &g) in c.nodes.iter().zip(&c.weights).filter(|(_, g)| **g != 0.0) {
            let slot = a.pattern().diag_slot(node as usize);
            a.values_mut()[slot] += direction * direction.transpose() * (c.stiffness * g * g);
        }
        couplings.push(c);
    }
    let b: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
    let mut constrain = |f: &mut ConstraintFilter, i: usize| {
        let c = if i.is_multiple_of(3) { Constraint::Fixed } else { Constraint::OneDirection { normal: rng.vec3() } };
        f.set(i, c, rng.vec3()).unwrap();
    };
    let mut filters = vec![ConstraintFilter::new(n)];
    let mut f = ConstraintFilter::new(n);
    for i in (0..n).step_by(23).chain([ties[3].0, ties[3].1, ties[7].0]) {
        constrain(&mut f, i);
    }
    filters.push(f.clone());
    // Some released (a new filter without them), some turned, some added.
    let mut g = ConstraintFilter::new(n);
    for (i, s, z) in f.iter() {
        match i % 4 {
            0 => {}
            1 => constrain(&mut g, i),
            _ => {
                let turned = if *s == Mat3::zeros() {
                    Constraint::OneDirection { normal: Vec3::new(1.0, 2.0, 3.0) }
                } else {
                    Constraint::Fixed
                };
                g.set(i, turned, *z).unwrap();
            }
        }
    }
    for i in (5..n).step_by(41).chain([ties[5].1]) {
        constrain(&mut g, i);
    }
    filters.push(g.clone());
    filters.push(f);
    let mut most = ConstraintFilter::new(n);
    for i in (0..n).filter(|i| !i.is_multiple_of(5)) {
        constrain(&mut most, i);
    }
    filters.push(most);
    filters.push(g);
    let params = PcgParams { rel_tol: 1e-9, max_iter: 5000, preconditioner: PreconditionerKind::Multigrid };
    let configurations =
        [(usize::MAX, false, Cycle::W), (0, true, Cycle::W), (usize::MAX, true, Cycle::K), (0, false, Cycle::K)];
    for ((single_from, paired, cycle), coupled) in configurations.into_iter().flat_map(|c| [(c, false), (c, true)]) {
        let terms = if coupled { couplings.clone() } else { Couplings::default() };
        let hierarchy = || {
            let mg =
                Multigrid::with_single_precision_from(a.pattern(), &chunk_aggregations(n, 4), single_from).unwrap();
            let mg = if paired { mg.with_pairs(&ties) } else { mg };
            mg.with_cycle(cycle)
        };
        let mut reused = Pcg::new(n);
        reused.set_multigrid(hierarchy());
        *reused.couplings_mut() = terms.clone();
        let mut matrix = a.clone();
        let mut partial = Vec::new();
        for (k, filter) in filters.iter().enumerate() {
            if k == filters.len() - 1 {
                // A new matrix (same pattern): the hierarchy must be rebuilt.
                matrix.values_mut().iter_mut().for_each(|v| *v *= 1.5);
            }
            let (mut x, mut y) = (vec![Vec3::zeros(); n], vec![Vec3::zeros(); n]);
            let got = reused.solve_in_place(&mut matrix, &b, filter, &params, &mut x).unwrap();
            let mut fresh = Pcg::new(n);
            fresh.set_multigrid(hierarchy());
            *fresh.couplings_mut() = terms.clone();
            let want = fresh.solve_in_place(&mut matrix.clone(), &b, filter, &params, &mut y).unwrap();
            let case = format!("{cycle:?} (f32 from {single_from}, paired {paired}, coupled {coupled}): filter {k}");
            assert_eq!(got.iterations, want.iterations, "{case}");
            assert!(same_bits(&x, &y), "{case} differs");
            partial.push(got.partial_refill);
            // Started from its own answer the solve is done before any set-up
            // (the hierarchy stays the one it describes: the next filter's
            // solve must still match a fresh solver's). The guess only gets
            // its prescribed values imposed again.
            let mut before = x.clone();
            filter.impose(&mut before);
            let again = reused.solve_in_place(&mut matrix, &b, filter, &params, &mut x).unwrap();
            assert_eq!((again.iterations, again.partial_refill), (0, false), "{cycle:?}, filter {k}");
            assert!(same_bits(&x, &before), "{cycle:?}, filter {k}");
        }
        // In part where only the filter changed, and only a few particles.
        assert_eq!(partial, [false, true, true, true, false, false], "{cycle:?}");
    }
}

/// The cycle's iterations on the cloth it was tuned on: the 65 x 65
/// hanging cloth (`hang.toml`, BDF2 at 1/90 s, PCG to 1e-3) for 0.2 s.
/// Measured 10.7 CG a step with the W-cycle below the first coarse level;
/// the V-cycle took 13.1 and two cycles on every coarse problem 9.6.
#[test]
fn the_w_cycle_keeps_the_hanging_cloths_iterations_down() {
    let mean = hanging_cloth_cg_per_step(65);
    assert!(mean < 11.0, "{mean} CG a step");
}

/// Mean CG iterations a step of the `n x n` hanging cloth (`hang.toml`,
/// pinned at its top corners) over 0.2 s.
fn hanging_cloth_cg_per_step(n: usize) -> f64 {
    let (particles, pins) =
        (format!("panels.0.particles=[{n}, {n}]"), format!("pins.0.nodes=[[0, {0}], [{0}, {0}]]", n - 1));
    let (mut sim, cfg) =
        cloth_tests::simulation("hang.toml", &[particles.as_str(), pins.as_str(), "simulation.duration_s=0.2"]);
    let total: usize = (0..cfg.steps).map(|_| sim.step(cfg.dt_s).unwrap().cg_iterations).sum();
    total as f64 / cfg.steps as f64
}

/// A flat square grid of `n x n` nodes tied to their four neighbours and
/// the two diagonals by links stiff along themselves (`k u u^T`, a
/// thousandth of it across), with unit masses: the hanging cloth's system
/// in miniature. `k = 1.2 n^2` as `h^2 k / m` grows for a fixed material
/// and time step (5,000 at 65 x 65 for the fixtures' cloth at 1/90 s).
fn grid_system(n: usize) -> (BlockSparseMatrix, Vec<Aggregation>) {
    let id = |i: usize, j: usize| j * n + i;
    let mut links = Vec::new();
    for j in 0..n {
        for i in 0..n {
            for (di, dj) in [(1, 0), (0, 1), (1, 1)] {
                if i + di < n && j + dj < n {
                    links.push((id(i, j), id(i + di, j + dj), Vec3::new(di as f64, dj as f64, 0.0).normalize()));
                }
            }
            if i > 0 && j + 1 < n {
                links.push((id(i, j), id(i - 1, j + 1), Vec3::new(-1.0, 1.0, 0.0).normalize()));
            }
        }
    }
    let pattern = BlockPattern::from_pairs(n * n, links.iter().map(|&(a, b, _)| (a, b))).unwrap();
    let mut a = BlockSparseMatrix::new(pattern.clone());
    let k = 1.2 * (n * n) as f64;
    let v = a.values_mut();
    for i in 0..n * n {
        v[pattern.diag_slot(i)] = Mat3::identity();
    }
    for &(p, q, u) in &links {
        let b = (u * u.transpose() + Mat3::identity() * 1e-3) * k;
        v[pattern.diag_slot(p)] += b;
        v[pattern.diag_slot(q)] += b;
        v[pattern.slot(p, q).unwrap()] -= b;
        v[pattern.slot(q, p).unwrap()] -= b;
    }
    // 2 x 2 aggregates a level, down to at most 40 nodes.
    let (mut levels, mut m) = (Vec::new(), n);
    while m * m > 40 {
        let c = m.div_ceil(2);
        let coarse_of = (0..m * m).map(|p| ((p / m / 2) * c + (p % m) / 2) as u32).collect();
        levels.push(Aggregation { coarse_of, n_coarse: c * c });
        m = c;
    }
    (a, levels)
}

/// PCG iterations to `1e-8` from zero with `cycle` on the `n x n` grid.
fn grid_iterations(n: usize, cycle: Cycle) -> (usize, Vec<Vec3>) {
    grid_iterations_with(n, |pattern, levels| Multigrid::new(pattern, levels).unwrap().with_cycle(cycle))
}

/// PCG iterations to `1e-8` from zero on the `n x n` grid with the
/// hierarchy `build` makes from its pattern and aggregations.
fn grid_iterations_with(n: usize, build: impl Fn(&BlockPattern, &[Aggregation]) -> Multigrid) -> (usize, Vec<Vec3>) {
    let (a, levels) = grid_system(n);
    let mut rng = Rng(n as u64);
    let b: Vec<Vec3> = (0..a.n()).map(|_| rng.vec3()).collect();
    let mut pcg = Pcg::new(a.n());
    pcg.set_multigrid(build(a.pattern(), &levels));
    let params = PcgParams { rel_tol: 1e-8, max_iter: 500, preconditioner: PreconditionerKind::Multigrid };
    let mut x = vec![Vec3::zeros(); a.n()];
    let info = pcg.solve(&a, &b, &ConstraintFilter::new(a.n()), &params, &mut x).expect("converges");
    (info.iterations, x)
}

/// The K-cycle's iterations stay flat as the grid grows, where the
/// W-cycle's grow (the cloth's hierarchy: 2 x 2 aggregates a level).
/// Measured (32 / 64 / 128 / 256): W 38 / 45 / 52 / 59, K 32 / 35 / 35 / 37.
#[test]
fn the_k_cycles_iterations_stay_flat_as_the_grid_grows() {
    let sizes = [32, 64, 128];
    let w: Vec<usize> = sizes.iter().map(|&n| grid_iterations(n, Cycle::W).0).collect();
    let k: Vec<usize> = sizes.iter().map(|&n| grid_iterations(n, Cycle::K).0).collect();
    assert!(k[2] <= k[0] + 4, "K-cycle: {k:?}");
    assert!(w[2] >= w[0] + 12 && k[2] + 12 <= w[2], "W {w:?} against K {k:?}");
}

/// The K-cycle's and the smoothed level's dot products are summed in a
/// fixed order: the same bits with 1 and 2 threads.
#[test]
fn k_cycle_and_smoothed_solves_are_bit_identical_across_thread_counts() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| grid_iterations(48, Cycle::K).1)
    };
    assert!(same_bits(&run(1), &run(2)));
    let smoothed = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| grid_smoothed_iterations(48).1)
    };
    assert!(same_bits(&smoothed(1), &smoothed(2)));
}

/// The 129 x 129 hanging cloth (16,641 particles, beyond
/// `K_CYCLE_MIN_NODES`) gets the K-cycle: 8.7 CG a step where the W-cycle
/// takes 13.1 and the 65 x 65 cloth's W-cycle 10.7 (above).
#[test]
fn the_k_cycle_keeps_the_finer_hanging_cloths_iterations_down() {
    let mean = hanging_cloth_cg_per_step(129);
    assert!(mean < 9.0, "{mean} CG a step");
}

/// The smoothed first level (`Multigrid::smoothed`) interpolates the
/// coarse correction without the jumps between aggregates that cost the
/// plain K-cycle its iterations on stiff grids. Measured (32 / 64 / 128 /
/// 256): smoothed 19 / 20 / 19 / 20, plain K-cycle 32 / 35 / 35 / 37.
#[test]
fn a_smoothed_first_level_takes_fewer_iterations_and_they_stay_flat() {
    let sizes = [32, 64, 128];
    let smoothed: Vec<usize> = sizes.iter().map(|&n| grid_smoothed_iterations(n).0).collect();
    let plain: Vec<usize> = sizes.iter().map(|&n| grid_iterations(n, Cycle::K).0).collect();
    assert!(smoothed.iter().all(|&s| s <= smoothed[0] + 1), "smoothed: {smoothed:?}");
    assert!(smoothed.iter().zip(&plain).all(|(s, k)| s + 12 <= *k), "smoothed {smoothed:?} against plain {plain:?}");
}

fn grid_smoothed_iterations(n: usize) -> (usize, Vec<Vec3>) {
    grid_iterations_with(n, |pattern, levels| Multigrid::smoothed(pattern, levels).unwrap())
}

/// Models without solids take the smoothed first level from
/// `SMOOTHED_MIN_NODES` particles (their matrix is solved once a step);
/// with solids, whose contact passes refill the hierarchy in part, or
/// below it, the plain one.
#[test]
fn models_without_solids_take_the_smoothed_level_from_its_threshold() {
    let side = (SMOOTHED_MIN_NODES as f64).sqrt().ceil() as usize;
    let hierarchy = |scene: &str, n: usize| {
        let (particles, pins) =
            (format!("panels.0.particles=[{n}, {n}]"), format!("pins.0.nodes=[[0, {0}], [{0}, {0}]]", n - 1));
        let (sim, _) = cloth_tests::simulation(scene, &[particles.as_str(), pins.as_str()]);
        sim.model().multigrid()
    };
    assert!(hierarchy("hang.toml", side).is_smoothed());
    assert!(!hierarchy("hang.toml", side - 1).is_smoothed());
    let (sim, _) = cloth_tests::simulation("drape-sphere.toml", &[&format!("panels.0.particles=[{side}, {side}]")]);
    assert!(!sim.model().multigrid().is_smoothed());
}

/// Two `n x n` grids ([`grid_system`]) one over the other, every node of
/// the first pressed on its twin in the second by a contact of stiffness
/// `k_c` along `z`, across which each sheet is soft: a heap's layers in
/// miniature. Returns the matrix with each node's own block of its
/// contact (`k_c z z^T`, as the cloth's assembly makes it), the contacts
/// as couplings, the same operator assembled whole (`A + E`, its pattern
/// holding the pairs), and each sheet's aggregations side by side.
fn two_sheets(n: usize, k_c: f64) -> (BlockSparseMatrix, Couplings, BlockSparseMatrix, Vec<Aggregation>) {
    let (sheet, sheet_levels) = grid_system(n);
    let m = sheet.n();
    let blocks: Vec<(usize, usize, Mat3)> = sheet.blocks().map(|(i, j, b)| (i, j, *b)).collect();
    let own = Vec3::z() * Vec3::z().transpose() * k_c;
    let build = |with_pairs: bool| {
        let pairs = blocks.iter().flat_map(|&(i, j, _)| [(i, j), (i + m, j + m)]);
        let ties = (0..m).filter(move |_| with_pairs).map(|i| (i, i + m));
        let pattern = BlockPattern::from_pairs(2 * m, pairs.chain(ties)).unwrap();
        let mut a = BlockSparseMatrix::new(pattern.clone());
        let v = a.values_mut();
        for &(i, j, b) in &blocks {
            v[pattern.slot(i, j).unwrap()] += b;
            v[pattern.slot(i + m, j + m).unwrap()] += b;
        }
        for i in 0..2 * m {
            v[pattern.diag_slot(i)] += own;
        }
        if with_pairs {
            for i in 0..m {
                v[pattern.slot(i, i + m).unwrap()] -= own;
                v[pattern.slot(i + m, i).unwrap()] -= own;
            }
        }
        a
    };
    let mut couplings = Couplings::default();
    for i in 0..m as u32 {
        let (nodes, weights) = ([i, i + m as u32, 0, 0], [1.0, -1.0, 0.0, 0.0]);
        couplings.push(Coupling { nodes, weights, direction: Vec3::z(), stiffness: k_c });
    }
    let levels = sheet_levels
        .iter()
        .map(|l| {
            let n_coarse = l.n_coarse as u32;
            let second = l.coarse_of.iter().map(|&c| c + n_coarse);
            Aggregation { coarse_of: l.coarse_of.iter().copied().chain(second).collect(), n_coarse: 2 * l.n_coarse }
        })
        .collect();
    (build(false), couplings, build(true), levels)
}

/// Two sheets pressed together by contacts that are couplings outside the
/// matrix: with the couplings on every level of the hierarchy, PCG solves
/// `A + E` (the operator assembled whole gives the same solution, to
/// 1e-8), with and without a filter, W-cycle and K-cycle, in about half
/// the iterations the hierarchy of `A` alone took. Measured at 32 x 32
/// with `k_c` a twelfth of the links' stiffness, W / K, without and with
/// a filter: 154 / 154 and 102 / 100 iterations to 1e-10 with the
/// hierarchy of `A` alone, 69 / 68 and 58 / 55 with the couplings.
/// The W-cycle stays symmetric positive definite.
#[test]
fn couplings_on_every_level_keep_pressed_layers_iterations_down() {
    let (a, couplings, whole, levels) = two_sheets(32, 100.0);
    let n = a.n();
    let mut rng = Rng(17);
    let b: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
    let mut filter = ConstraintFilter::new(n);
    for i in (0..n).step_by(13) {
        let c = if i % 2 == 0 { Constraint::Fixed } else { Constraint::OneDirection { normal: rng.vec3() } };
        filter.set(i, c, rng.vec3()).unwrap();
    }
    for (cycle, f, most) in [
        (Cycle::W, ConstraintFilter::new(n), 75),
        (Cycle::W, filter.clone(), 64),
        (Cycle::K, ConstraintFilter::new(n), 75),
        (Cycle::K, filter, 61),
    ] {
        let exact = PcgParams { rel_tol: 1e-13, max_iter: 20_000, preconditioner: PreconditionerKind::BlockJacobi };
        let mut reference = vec![Vec3::zeros(); n];
        Pcg::new(n).solve(&whole, &b, &f, &exact, &mut reference).expect("block-Jacobi converges");
        let mut pcg = Pcg::new(n);
        pcg.set_multigrid(Multigrid::new(a.pattern(), &levels).unwrap().with_cycle(cycle));
        *pcg.couplings_mut() = couplings.clone();
        let params = PcgParams { rel_tol: 1e-10, max_iter: 1000, preconditioner: PreconditionerKind::Multigrid };
        let mut x = vec![Vec3::zeros(); n];
        let info = pcg.solve(&a, &b, &f, &params, &mut x).expect("multigrid PCG converges");
        let err = max_rel_diff(&x, &reference);
        assert!(err < 1e-8, "{cycle:?}: relative difference {err:e}");
        assert!(info.iterations <= most, "{cycle:?}: {} iterations", info.iterations);
    }
    let mut mg = Multigrid::new(a.pattern(), &levels).unwrap().with_cycle(Cycle::W);
    mg.set_couplings(&couplings, &ConstraintFilter::new(n));
    mg.update(&a);
    assert_cycle_is_spd(&mut mg, &a, &mut rng, 5);
}
