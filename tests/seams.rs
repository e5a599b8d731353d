//! Seams: panels sewn along their edges (`[[seams]]`, `cloth_core::SeamSpec`).
//! A stitch's force and Jacobian against finite differences, a seam laid
//! open closing at a bounded pull without moving the centre of mass, and
//! two panels sewn edge to edge moving as the one panel they make.

use cloth_core::scene::Scene;
use cloth_core::testing::{eval_link, link_force};
use cloth_core::{ClothModel, LinkType, Mat3, Simulation, Vec3};

fn build(text: &str, overrides: &[&str]) -> (Simulation, f64, usize) {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let scene = Scene::parse(text, &o).unwrap_or_else(|e| panic!("{e}"));
    let (model, cfg) = scene.build().unwrap_or_else(|e| panic!("{e}"));
    (cfg.simulation(model), cfg.dt_s, cfg.steps as usize)
}

/// Two 5 x 5 panels 10 cm square in the plane z = 0, `gap` m apart along
/// x, panel 0's i_max edge sewn to panel 1's i_min edge; no gravity.
fn open_seam(gap: f64) -> String {
    format!(
        r#"
[simulation]
integrator = "bdf2"
dt_s = 0.011111111111111112
duration_s = 1.0
effects = ["bending", "damping"]

[solver]
rel_tol = 1e-10

{MATERIAL}
[[panels]]
particles = [5, 5]
size_m = [0.1, 0.1]

[[panels]]
particles = [5, 5]
size_m = [0.1, 0.1]
origin_m = [{x1}, 0.0, 0.0]

[[seams]]
a = {{ panel = 0, edge = "i_max" }}
b = {{ panel = 1, edge = "i_min" }}
"#,
        x1 = 0.1 + gap
    )
}

/// The cotton of both scenes.
const MATERIAL: &str = "[material]
areal_density_kg_m2 = 0.1
tensile_stiffness_n_m = 200.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 200.0
damping_n_s_m = 0.02
";

fn centre(model: &ClothModel, x: &[Vec3]) -> Vec3 {
    let m = model.masses();
    m.iter().zip(x).fold(Vec3::zeros(), |a, (mi, xi)| a + xi * *mi) / m.iter().sum::<f64>()
}

#[test]
fn a_stitch_force_and_jacobian_match_finite_differences() {
    let (sim, _, _) = build(&open_seam(0.0), &[]);
    let model = sim.model();
    let stitches: Vec<usize> = (0..model.link_count()).filter(|&k| model.link_ends(k).2 == LinkType::Seam).collect();
    assert_eq!(stitches.len(), 5);
    let s = model.stitches()[0];
    // 10 x E and E s (s = 2.5 cm): a closed stitch's cap starts at 2.5 mm;
    // an open one pulls with a quarter of that, its dashpot closing it at 0.5 m/s.
    assert_eq!((s.k, s.pull, s.sewing), (2000.0, 5.0, 1.25));
    assert_eq!((s.dashpot(false), s.dashpot(true)), (s.sewing / 0.5, s.pull / 0.5));
    let d_c = s.pull / s.k;
    let x0 = model.rest_positions().to_vec();
    let k = stitches[0];
    let (i, j, _) = model.link_ends(k);
    // Within and beyond each state's cap, in a direction off every axis.
    for (closed, gap, cap) in [
        (true, 0.3 * d_c, s.pull),
        (true, 40.0 * d_c, s.pull),
        (false, 0.1 * d_c, s.sewing),
        (false, 40.0 * d_c, s.sewing),
    ] {
        let flags = vec![closed; stitches.len()];
        let regime = format!("closed {closed}, gap {gap} m");
        let mut x = x0.clone();
        x[j] = x[i] + Vec3::new(0.6, -0.48, 0.64) * gap;
        let e = eval_link(model, k, &x, &flags);
        let h = 1e-4 * d_c;
        let mut fd_stiffness = Mat3::zeros();
        for c in 0..3 {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[j][c] += h;
            xm[j][c] -= h;
            let (ep, em) = (eval_link(model, k, &xp, &flags), eval_link(model, k, &xm, &flags));
            // The force on i is the energy's gradient with respect to x_j.
            let grad = (ep.energy - em.energy) / (2.0 * h);
            assert!((e.force[c] - grad).abs() <= 1e-7 * s.pull, "{regime}: force {} vs {grad}", e.force[c]);
            fd_stiffness.set_column(c, &((ep.force - em.force) / (2.0 * h)));
        }
        let err = (e.stiffness - fd_stiffness).norm() / s.k;
        assert!(err < 1e-8, "{regime}: Jacobian error {err:e}");
        // The dashpot: df_i/dv_j = c I, the force's derivative in v_j.
        let mut v = vec![Vec3::zeros(); x.len()];
        v[j] = Vec3::new(0.3, 0.1, -0.2);
        let still = vec![Vec3::zeros(); x.len()];
        let dashpot = link_force(model, k, &x, &v, &flags) - link_force(model, k, &x, &still, &flags);
        let c = s.dashpot(closed);
        assert!((dashpot - v[j] * c).norm() < 1e-15 && e.damping == Mat3::identity() * c);
        let pull = e.force.norm();
        if gap * s.k > cap {
            assert!((pull - cap).abs() < 1e-14, "{regime}: capped at {pull}");
        } else {
            assert!((pull - s.k * gap).abs() < 1e-12 * pull, "{regime}: linear: {pull}");
        }
    }
}

#[test]
fn a_seam_laid_open_closes_at_a_bounded_pull_and_keeps_the_centre_of_mass() {
    // Solved to 1e-12: the centre of mass moves by what the solves leave
    // unbalanced, which the tolerance bounds (at the scene's 1e-10 it moved
    // 2.4e-10 m in 90 steps; a preconditioner exact on this small system,
    // as the multigrid was before its levels' residuals were rounded to
    // f32, left it at roundoff).
    let (mut sim, h, steps) = build(&open_seam(0.05), &["solver.rel_tol=1e-12"]);
    let model = sim.model().clone();
    let c0 = centre(&model, &sim.state().x);
    assert!((model.max_seam_gap(&sim.state().x) - 0.05).abs() < 1e-15);
    let mut stretch = 0.0f64;
    let mut closed_at = None;
    for n in 0..steps {
        sim.step(h).unwrap();
        let x = &sim.state().x;
        stretch = stretch.max(model.max_stretch_ratio(x));
        if closed_at.is_none() && model.max_seam_gap(x) < 1e-3 {
            closed_at = Some(n);
        }
    }
    let x = &sim.state().x;
    let gap = model.max_seam_gap(x);
    let drift = (centre(&model, x) - c0).norm();
    // Measured: the stitches close at their 0.5 m/s (5.55 mm a step),
    // within 1 mm after 9 steps; 1 s later the gap is 2e-20 m, the centre
    // moved 1.25e-11 m (the linear solves' tolerance), the links stretched
    // at most 1.002 on the way.
    assert_eq!(closed_at, Some(8));
    assert!(gap < 1e-9, "gap {gap:e} m");
    assert!(drift < 1.5e-11, "centre of mass moved {drift:e} m");
    assert!(stretch < 1.0021, "stretch {stretch}");
}

/// The same 20 x 20 cm sheet, level at first, hung by two corners: one 9 x 9 panel,
/// or two 9 x 5 panels sewn along the middle row (each with half of that
/// row's cells and mass).
fn sheet(sewn: bool, model: &str) -> String {
    let panels = if sewn {
        r#"
[[panels]]
particles = [9, 5]
size_m = [0.2, 0.1]
origin_m = [0.0, 0.0, 1.0]
v_axis = [0.0, 1.0, 0.0]

[[panels]]
particles = [9, 5]
size_m = [0.2, 0.1]
origin_m = [0.0, 0.1, 1.0]
v_axis = [0.0, 1.0, 0.0]

[[seams]]
a = { panel = 0, edge = "j_max" }
b = { panel = 1, edge = "j_min" }
"#
    } else {
        r#"
[[panels]]
particles = [9, 9]
size_m = [0.2, 0.2]
origin_m = [0.0, 0.0, 1.0]
v_axis = [0.0, 1.0, 0.0]
"#
    };
    format!(
        r#"
[simulation]
integrator = "bdf2"
model = "{model}"
dt_s = 0.011111111111111112
duration_s = 1.0
effects = ["gravity", "damping"]
gravity_m_s2 = [0.0, 0.0, -9.81]

[solver]
rel_tol = 1e-12

{MATERIAL}{panels}
[[pins]]
nodes = [[0, 0], [8, 0]]
"#
    )
}

/// Largest distance between the whole sheet's particles and their twins
/// in the sewn one over the run, and how far the whole sheet swung, m.
fn sewn_against_whole(model: &str, stitch_stiffness: f64) -> (f64, f64) {
    let (mut one, h, steps) = build(&sheet(false, model), &[]);
    let (mut two, _, _) = build(&sheet(true, model), &[&format!("seams.0.stiffness_n_m={stitch_stiffness:e}")]);
    let (mut worst, mut swing) = (0.0f64, 0.0f64);
    for _ in 0..steps {
        one.step(h).unwrap();
        two.step(h).unwrap();
        let (a, b) = (&one.state().x, &two.state().x);
        for (n, p) in a.iter().enumerate() {
            swing = swing.max((p - one.model().rest_positions()[n]).norm());
            let (i, j) = (n % 9, n / 9);
            // Row 4 is panel 0's last and panel 1's first.
            let twins = [(j <= 4).then_some(n), (j >= 4).then(|| 45 + 9 * (j - 4) + i)];
            for t in twins.into_iter().flatten() {
                worst = worst.max((b[t] - p).norm());
            }
        }
    }
    (worst, swing)
}

#[test]
fn two_panels_sewn_edge_to_edge_move_as_one_panel() {
    // Bending off: a seam is a hinge, so only the membrane is the same.
    for model in ["choi-ko", "provot", "volino"] {
        let (worst, swing) = sewn_against_whole(model, 2e3);
        let (stiffer, _) = sewn_against_whole(model, 2e4);
        // Measured: 1.68e-5 / 1.72e-5 / 1.96e-5 m (choi-ko / provot /
        // volino) while the sheet swings 0.33 m, and 9.4x less with 10x
        // stiffer stitches: the stitches' compliance is the difference.
        assert!(swing > 0.3, "{model}: the sheet swung {swing} m");
        assert!(worst < 2.0e-5, "{model}: the sewn sheet is {worst:e} m from the whole one");
        assert!(stiffer < 0.11 * worst, "{model}: 10x stiffer stitches: {stiffer:e} m (from {worst:e})");
    }
}

/// A fixed-step explicit integrator with stitches: above the stitches'
/// stability limit the step is refused with a typed error that gives the
/// limit (at 1e-4 s the run blew up within 86 steps before); below it the
/// seam closes at its speed as under BDF2.
#[test]
fn explicit_steps_above_the_stitch_limit_are_refused() {
    let (mut sim, _, _) = build(&open_seam(0.01), &["simulation.integrator=\"symplectic-euler\""]);
    let limit = sim.model().explicit_stitch_step_limit();
    let s = sim.model().stitches()[0];
    let m = sim.model().masses()[s.i as usize];
    // Two edge particles of equal mass: mu = m / 2, so 2 mu / c = m / c.
    // The closed stitch's dashpot, the stronger.
    let c = s.dashpot(true);
    assert!((limit - m / c).abs() < 1e-15 * limit, "{limit} vs {}", m / c);
    match sim.step(1e-4) {
        Err(cloth_core::StepError::StitchesNeedSmallerStep { limit_s, .. }) => assert_eq!(limit_s, limit),
        other => panic!("expected the stitch limit, got {other:?}"),
    }
    let h = 0.9 * limit;
    let steps = (0.01 / h).ceil() as usize;
    for _ in 0..steps {
        sim.step(h).unwrap();
    }
    // 1 cm at 0.5 m/s closes in 20 ms: half way after 10 ms (measured
    // 5.029 mm, 7112 steps of 1.4 us: the limit is 1.56 us; the open
    // stitches reach their speed in a few times m / c).
    let gap = sim.model().max_seam_gap(&sim.state().x);
    assert!((gap - 0.005).abs() < 3.5e-5, "gap {gap} m after {steps} steps of {h:e} s");
}

/// A stitch closes once its gap is within `pull / k` (or half the contact
/// thickness, where that is wider) and stays closed; a
/// state whose stitch flags do not fit the model is refused.
#[test]
fn a_stitch_closes_once_its_gap_is_within_its_linear_range_and_stays_closed() {
    let (mut sim, h, _) = build(&open_seam(0.05), &[]);
    let model = sim.model().clone();
    let s = model.stitches()[0];
    let reach = model.stitch_closing_gap(&s);
    let mut ever_within = vec![false; model.stitches().len()];
    let mut switched = 0;
    for _ in 0..30 {
        let before = sim.state().stitches_closed.clone();
        sim.step(h).unwrap();
        let x = &sim.state().x;
        for (k, st) in model.stitches().iter().enumerate() {
            ever_within[k] |= (x[st.j as usize] - x[st.i as usize]).norm() <= reach;
        }
        assert_eq!(sim.state().stitches_closed, ever_within);
        switched += before.iter().zip(&sim.state().stitches_closed).filter(|(a, b)| a != b).count();
    }
    assert_eq!(switched, model.stitches().len(), "each stitch closed once");
    // Pulled 5 cm apart again, the closed stitches pull with the seam's
    // strength: four times the sewing pull that closed them.
    let mut apart = sim.state().clone();
    // Panel 1's particles come after panel 0's 25.
    for p in &mut apart.x[25..] {
        p.x += 0.05;
    }
    let open = cloth_core::ClothState { stitches_closed: vec![false; 5], ..apart.clone() };
    let k = model.link_count() - 1;
    let pull = |closed: &[bool]| eval_link(&model, k, &apart.x, closed).force.norm();
    assert_eq!((pull(&apart.stitches_closed), pull(&open.stitches_closed)), (s.pull, s.sewing));
    apart.stitches_closed.pop();
    assert!(matches!(sim.set_state(&apart), Err(cloth_core::StepError::StitchStateMismatch { expected: 5, got: 4 })));
}

/// Provot's deformation constraints shut the closed stitches along with
/// bounding the links: panel 1 pulled 3 cm off its seam ends with its
/// closed stitches shut (to rounding) and no link beyond 1.1 times its
/// length, its one open stitch left to its sewing pull. Without the
/// stitches in the constraints the closed ones stay 3 cm open.
#[test]
fn deformation_constraints_shut_closed_stitches() {
    let (sim, h, _) = build(&open_seam(0.0), &[]);
    let model = sim.model();
    let mut x = model.rest_positions().to_vec();
    // Panel 1's particles come after panel 0's 25.
    for p in &mut x[25..] {
        p.x += 0.03;
    }
    let mut v = vec![Vec3::zeros(); x.len()];
    let closed = [true, true, true, true, false];
    let limit = cloth_core::StrainLimit { max_strain: 0.1, passes: 2000, projections: 0 };
    let report = cloth_core::testing::apply_strain_limit(model, &limit, |_| false, &closed, (&mut x, &mut v), h);
    let gaps: Vec<f64> = model.stitches().iter().map(|s| (x[s.j as usize] - x[s.i as usize]).norm()).collect();
    println!("{} passes, {} corrections; gaps {gaps:?} m", report.passes, report.corrections);
    assert!(report.passes < 2000, "the constraints did not converge");
    assert!(gaps[..4].iter().all(|&g| g < 1e-9), "closed stitches open: {gaps:?}");
    assert!(gaps[4] > 1e-3, "the open stitch was shut too: {gaps:?}");
    assert!(model.max_stretch_ratio(&x) <= 1.1 * (1.0 + 1e-9), "a link at {}", model.max_stretch_ratio(&x));
}

/// A snapshot written as bytes and read back in a new simulation of the
/// same scene steps to the same bits as the run it was taken from, with
/// closed and open stitches and BDF2's history in it. Bytes cut
/// short or changed anywhere are refused, and a snapshot that does not
/// fit (another integrator, another cloth) is refused at restore.
#[test]
fn a_snapshot_read_back_from_bytes_steps_to_the_same_bits() {
    use cloth_core::{Snapshot, SnapshotBytesError, StepError};
    let (mut sim, h, _) = build(&open_seam(0.05), &[]);
    // Until the stitches close (all in one step: the seam is straight),
    // then one opened again by hand, so that the bytes hold both states.
    while !sim.state().stitches_closed.iter().any(|&c| c) {
        sim.step(h).unwrap();
    }
    let mut one_open = sim.state().clone();
    one_open.stitches_closed[2] = false;
    sim.set_state(&one_open).unwrap();
    assert!(sim.state().stitches_closed.iter().any(|&c| !c) && sim.state().has_history);
    let taken = sim.snapshot();
    let bytes = taken.to_bytes();
    assert_eq!(Snapshot::from_bytes(&bytes).as_ref(), Ok(&taken));
    for _ in 0..10 {
        sim.step(h).unwrap();
    }
    let (mut again, _, _) = build(&open_seam(0.05), &[]);
    again.restore(&Snapshot::from_bytes(&bytes).unwrap()).unwrap();
    for _ in 0..10 {
        again.step(h).unwrap();
    }
    assert_eq!(again.snapshot(), sim.snapshot(), "the same bits after 10 steps");

    for k in 0..bytes.len() {
        let mut changed = bytes.clone();
        changed[k] ^= 0x10;
        assert!(Snapshot::from_bytes(&changed).is_err(), "byte {k} changed was read");
    }
    for cut in 0..bytes.len() {
        assert!(Snapshot::from_bytes(&bytes[..cut]).is_err(), "cut to {cut} bytes was read");
    }
    // Another version, its checksum made to match.
    let mut other = bytes[..bytes.len() - 4].to_vec();
    other[8..12].copy_from_slice(&7u32.to_le_bytes());
    let crc = crc32fast::hash(&other);
    other.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(Snapshot::from_bytes(&other), Err(SnapshotBytesError::Version { found: 7, reads: 1 }));
    // A flag other than 0 or 1.
    let mut values: Vec<f64> = taken.values().collect();
    values[2] = 0.5;
    let (n, stitches) = (sim.model().particle_count(), sim.model().stitches().len());
    assert!(matches!(
        Snapshot::from_values(&values, n, stitches, &taken.integrator),
        Err(SnapshotBytesError::Value { field: "has_history", .. })
    ));

    let (mut explicit, _, _) = build(&open_seam(0.05), &["simulation.integrator=\"symplectic-euler\""]);
    let refused = explicit.restore(&Snapshot::from_bytes(&bytes).unwrap());
    assert!(matches!(refused, Err(StepError::MemoryMismatch { .. })), "{refused:?}");
    let (mut larger, _, _) = build(&open_seam(0.05), &["panels.1.particles=[6, 5]"]);
    let refused = larger.restore(&Snapshot::from_bytes(&bytes).unwrap());
    assert!(matches!(refused, Err(StepError::StateMismatch { expected: 55, got: 50 })), "{refused:?}");
}
