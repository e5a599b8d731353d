//! The elastic catenary: a narrow strip held at both ends at its rest
//! length sags under its own weight only as far as its stretch lets it,
//! which Irvine's elastic catenary gives in closed form. A check of the
//! stretch under large rotations, where a linear model has no sag at all.

use cloth_core::{
    ClothModel, Edge, GridPanel, IntegratorKind, ModelKind, NewtonParams, PreconditionerKind, Simulation, SolverParams,
    VbdParams,
};

/// Rest length (m), width (m), areal density (kg/m^2), tension stiffness
/// (N/m) and gravity (m/s^2) of the strip.
const LENGTH: f64 = 1.0;
const WIDTH: f64 = 0.05;
const DENSITY: f64 = 0.1;
const STIFFNESS: f64 = 200.0;
const G: f64 = 9.81;

/// Irvine's (1981) elastic catenary: the mid-span sag (m) of a cable of
/// unstretched length `l0` (m), axial stiffness `ea` (N) and weight `w`
/// (N per m unstretched) between supports at one height `span` (m) apart.
/// The horizontal tension `H` solves
/// `span = H l0 / EA + (2 H / w) asinh(w l0 / (2 H))`; then
/// `sag = w l0^2 / (8 EA) + (H / w) (sqrt(1 + (w l0 / (2 H))^2) - 1)`.
fn irvine_sag(l0: f64, ea: f64, w: f64, span: f64) -> f64 {
    let span_at = |h: f64| h * l0 / ea + 2.0 * h / w * (w * l0 / (2.0 * h)).asinh();
    // span_at grows with H: bisect on log H.
    let (mut lo, mut hi) = (1e-9_f64, 1e9_f64);
    for _ in 0..200 {
        let mid = (lo * hi).sqrt();
        if span_at(mid) < span {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let h = (lo * hi).sqrt();
    let v = w * l0 / (2.0 * h);
    w * l0 * l0 / (8.0 * ea) + h / w * ((1.0 + v * v).sqrt() - 1.0)
}

/// The strip of `[along, across]` particles, lying along x, held along its
/// two short edges, no bending (a cable).
fn strip(kind: ModelKind, particles: [usize; 2]) -> ClothModel {
    strip_of_width(kind, particles, WIDTH)
}

fn strip_of_width(kind: ModelKind, particles: [usize; 2], width: f64) -> ClothModel {
    ClothModel::builder()
        .panel(GridPanel::flat(particles, [LENGTH, width]).axes([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
        .kind(kind)
        .material(cloth_core::Material {
            areal_density_kg_m2: DENSITY,
            tensile_stiffness_n_m: STIFFNESS,
            ..Default::default()
        })
        .gravity([0.0, 0.0, -G])
        .pin_edge(0, Edge::IMin)
        .pin_edge(0, Edge::IMax)
        .build()
        .unwrap()
}

/// The mean drop of the middle column (m) after `steps` steps of `h` s.
fn mid_sag(
    model: ClothModel,
    [along, across]: [usize; 2],
    (kind, solver): (IntegratorKind, SolverParams),
    steps: usize,
    h: f64,
) -> f64 {
    let mut sim = Simulation::new(model, kind, solver);
    for _ in 0..steps {
        sim.step(h).unwrap();
    }
    let mid = along / 2;
    -(0..across).map(|j| sim.state().x[j * along + mid].z).sum::<f64>() / across as f64
}

/// Backward Euler with Newton iterations to 1e-10 m: steps of 1 s settle.
fn statics() -> (IntegratorKind, SolverParams) {
    let solver = SolverParams {
        rel_tol: 1e-10,
        preconditioner: PreconditionerKind::Multigrid,
        newton: NewtonParams { iterations: 50, tolerance_m: 1e-9, ..Default::default() },
        ..SolverParams::default()
    };
    (IntegratorKind::BackwardEuler, solver)
}

fn exact() -> f64 {
    irvine_sag(LENGTH, STIFFNESS * WIDTH, DENSITY * WIDTH * G, LENGTH)
}

/// The closed form against its inextensible limit and a hand value: a
/// stiff cable barely sags, a soft one approaches the taut-string estimate
/// `(3 w l^4 / (64 EA))^(1/3)` (small sag, parabola).
#[test]
fn irvine_sag_has_its_limits() {
    let (l, w) = (1.0, 0.049);
    for ea in [1e2, 1e4, 1e6] {
        let sag = irvine_sag(l, ea, w, l);
        let taut = (3.0 * w * l.powi(4) / (64.0 * ea)).cbrt();
        println!("EA {ea:e} N: sag {sag:.6e} m, taut-string estimate {taut:.6e} m");
        assert!((sag / taut - 1.0).abs() < 0.02, "EA {ea}: {sag} against {taut}");
    }
    // Slack: a cable twice its span long hangs nearly as the rigid catenary,
    // whose sag for span 1 m and length 2 m is a (cosh(1/(2a)) - 1) with
    // 2 a sinh(1/(2a)) = 2, a = 0.229640 m: 0.796388 m.
    let sag = irvine_sag(2.0, 1e9, w, 1.0);
    assert!((sag - 0.796388).abs() < 1e-6, "slack catenary sag {sag}");
}

/// The strip of `particles` of `kind`, settled by backward Euler's Newton
/// iterations, against Irvine's cable (61.5 mm; no bending: a linear
/// model would not sag at all).
fn check_against_irvine(kind: ModelKind, particles: [usize; 2], tolerance: f64) {
    let exact = exact();
    let sag = mid_sag(strip(kind, particles), particles, statics(), 20, 1.0);
    println!(
        "{kind:?} {particles:?}: sag {:.4} mm, Irvine {:.4} mm ({:+.3}%)",
        sag * 1e3,
        exact * 1e3,
        (sag / exact - 1.0) * 100.0
    );
    assert!((sag / exact - 1.0).abs() < tolerance, "{kind:?} {particles:?}: {sag} m against {exact} m");
}

/// Square cells of 2.5 cm. Measured: Provot -0.20%, Volino -0.57%.
/// Choi & Ko's strip is left out here: it sags 7.4% too far (4.1% at
/// 1.67 cm), its lateral links buckling under the lattice's sideways
/// compression (`docs/results/catenary.md`).
#[test]
fn a_strip_held_at_both_ends_sags_as_the_elastic_catenary() {
    for kind in [ModelKind::Provot, ModelKind::Volino] {
        check_against_irvine(kind, [41, 3], 0.007);
    }
}

/// The sag's error on coarse and oblong cells, in every model, for
/// `docs/results/catenary.md`. Asserted: every model within 0.7% on square
/// cells of 1.25 cm (measured: Choi & Ko -0.17%, Provot -0.18%, Volino
/// -0.56%), and Volino's triangles everywhere (within 0.62%); the
/// lattices' other rows are printed (their constants are for square
/// cells, and Choi & Ko's lateral links buckle on coarse ones).
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_catenary_on_coarse_and_oblong_cells() {
    println!(
        "| width (m) | particles | cell along x across (cm) | choi-ko | provot | volino |\n|---|---|---|---|---|---|"
    );
    for (width, grids) in [(0.05, [[41, 3], [61, 4], [81, 5], [81, 3]]), (0.1, [[21, 3], [41, 5], [41, 3], [41, 9]])] {
        let exact = irvine_sag(LENGTH, STIFFNESS * width, DENSITY * width * G, LENGTH);
        for particles in grids {
            let cell = [LENGTH / (particles[0] - 1) as f64, width / (particles[1] - 1) as f64];
            let mut row = format!("| {width} | {particles:?} | {:.2} x {:.2} |", cell[0] * 100.0, cell[1] * 100.0);
            for kind in [ModelKind::ChoiKo, ModelKind::Provot, ModelKind::Volino] {
                let sag = mid_sag(strip_of_width(kind, particles, width), particles, statics(), 20, 1.0);
                row += &format!(" {:+.2}% |", (sag / exact - 1.0) * 100.0);
                if kind == ModelKind::Volino || particles == [81, 5] {
                    assert!((sag / exact - 1.0).abs() < 0.007, "{kind:?} {particles:?}: {sag} m against {exact} m");
                }
            }
            println!("{row}");
        }
    }
}

/// The vertex solver run to statics (30 steps of 0.5 s, up to 3000
/// sweeps each) meets backward Euler's statics of the same strip, and
/// with it the closed form where the model does (Provot; Choi & Ko's 2.5
/// cm cells above). Measured: Provot 6.4e-7 off backward Euler (whose
/// Newton stops at 1e-9 m) and -0.20% off Irvine, Choi & Ko 1.3e-7 off
/// backward Euler. With Chebyshev's
/// acceleration (0.99) Provot's strip ended 12 mm above its supports.
#[test]
fn the_vertex_solver_sags_as_the_elastic_catenary() {
    let exact = exact();
    let particles = [41, 3];
    for (kind, rho) in [(ModelKind::Provot, 0.0), (ModelKind::ChoiKo, 0.0)] {
        let vbd = VbdParams { iterations: 3000, tolerance_m: 1e-11, chebyshev_rho: rho, ..VbdParams::default() };
        let solver = SolverParams { vbd, ..Default::default() };
        let sag = mid_sag(strip(kind, particles), particles, (IntegratorKind::Vbd, solver), 30, 0.5);
        let reference = mid_sag(strip(kind, particles), particles, statics(), 20, 1.0);
        println!(
            "vbd {kind:?}: sag {:.5} mm, backward Euler {:.5} mm ({:+.1e}), Irvine {:.4} mm ({:+.3}%)",
            sag * 1e3,
            reference * 1e3,
            sag / reference - 1.0,
            exact * 1e3,
            (sag / exact - 1.0) * 100.0
        );
        assert!((sag / reference - 1.0).abs() < 1e-6, "{kind:?}: {sag} m against backward Euler's {reference} m");
        if kind == ModelKind::Provot {
            assert!((sag / exact - 1.0).abs() < 0.007, "{kind:?}: {sag} m against {exact} m");
        }
    }
}
