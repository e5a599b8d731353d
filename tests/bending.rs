//! Peirce's cantilever (ASTM D1388) against the heavy elastica: does
//! `flexural_rigidity_n_m` mean flexural rigidity? The target is 2
//! degrees at 1, 0.5 and 0.25 cm for `choi-ko` and `volino`; these tests
//! hold what is reached (`cloth study bending` prints the table).

use cloth_core::testing::reference::CantileverStrip;
use cloth_tests::simulation;

/// What a settled cantilever shows: its chord angle and the exact one for
/// its material (degrees), its tip drop (m), and the tip heights of its
/// rows (m).
struct Settled {
    chord_deg: f64,
    exact_chord_deg: f64,
    drop: f64,
    rows: Vec<f64>,
}

/// Runs the cantilever fixture as a 10 cm strip at grid `spacing` (m)
/// with `model` and `extra` overrides for its 3 s and checks it has come
/// to rest: every particle slower than 5e-5 m/s, so that what is left of
/// its swing (period about 0.9 s) moves the tip by less than 1e-5 m, 0.02%
/// of its drop.
fn settle_at(model: &str, spacing: f64, extra: &[&str]) -> Settled {
    let strip = CantileverStrip { spacing, overhang: 0.10, width: 0.02 };
    let mut o = strip.overrides();
    o.push(format!("simulation.model=\"{model}\""));
    o.extend(extra.iter().map(|s| s.to_string()));
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let (mut sim, cfg) = simulation("cantilever.toml", &o);
    for _ in 0..cfg.steps {
        sim.step(cfg.dt_s).unwrap();
    }
    let speed = sim.state().v.iter().map(|v| v.norm()).fold(0.0, f64::max);
    assert!(speed < 5e-5, "{model} {extra:?} at {spacing} m: not settled, {speed} m/s");
    let x = &sim.state().x;
    let [nx, ny] = strip.particles();
    Settled {
        chord_deg: strip.measure(x).chord_angle_deg(),
        drop: strip.measure(x).tip_drop,
        exact_chord_deg: strip.exact(sim.model()).0.chord_angle_deg(),
        rows: (0..ny).map(|j| x[j * nx + nx - 1].z).collect(),
    }
}

/// Choi & Ko's pair law (`bending_law = "arc-chord"`) at 1 cm: the type-2 links across the clamp line count
/// double: 4.9 degrees from the elastica (46.37 against 41.49; 9.9 degrees
/// when they counted as free links).
/// Still soft: the ramp's soft zone and the 3/4 of `k_b` (material docs).
#[test]
fn paper_law_cantilever_clamp_counts_half_a_link_at_1_cm() {
    let s = settle_at("choi-ko", 0.01, &["simulation.bending_law=\"arc-chord\""]);
    assert!((s.chord_deg - s.exact_chord_deg).abs() < 5.0, "chord {} deg, exact {}", s.chord_deg, s.exact_chord_deg);
    assert!(s.rows.iter().all(|z| (z - s.rows[0]).abs() < 1e-4), "{:?}", s.rows);
}

/// Choi & Ko's arc law read against the path through the middle particle
/// (`bending_law = "arc-path"`, the default): 41.81 and 41.68 degrees at 1 and 0.5 cm
/// against the exact 41.49 (41.86 at 0.25 cm, `cloth study bending`), and
/// the tip drop at the two spacings within 0.4% of each other (measured
/// 0.38%), untwisted. The paper's pair law gives 46.4 and 60.1 degrees;
/// without the path's 4/3 on `k_b` the strip sags to 48.7 and 48.5; with
/// boundary links counting a full cell it is too stiff, 38.1 and 39.7.
#[test]
fn arc_path_cantilever_holds_the_elastica_at_1_and_0_5_cm() {
    holds_the_elastica_at_1_and_0_5_cm("choi-ko", &[], 0.4, 1e-9, 4e-3);
}

/// Volino's bending triangles (`element_laws::curvature_stiffness`): 41.80
/// and 41.57 degrees at 1 and 0.5 cm against the exact 41.49 (41.51 at
/// 0.25 cm, `cloth study bending`), the tip drop at the two spacings
/// within 0.6% of each other (measured 0.56%). The grid's diagonals all
/// run one way (the bending triangles need it), so the strip is chiral:
/// its tip twists by 1.6e-8 m across its 2 cm at 1 cm and 1.5e-8 m at 0.5 cm.
/// With a hinge per edge instead (0.8 of the
/// rigidity against a twist) it sagged to 43.1 and 45.2 degrees.
#[test]
fn volino_cantilever_holds_the_elastica_at_1_and_0_5_cm() {
    holds_the_elastica_at_1_and_0_5_cm("volino", &[], 0.4, 2e-8, 6e-3);
}

/// `model` with `extra` overrides at 1 and 0.5 cm: the chord within
/// `chord_deg` of the elastica, the tip's rows level to `twist_m`, and the
/// tip drops at the two spacings within `drop_change` (relative).
fn holds_the_elastica_at_1_and_0_5_cm(model: &str, extra: &[&str], chord_deg: f64, twist_m: f64, drop_change: f64) {
    let (coarse, fine) = (settle_at(model, 0.01, extra), settle_at(model, 0.005, extra));
    for (s, spacing) in [(&coarse, 1.0), (&fine, 0.5)] {
        let error = s.chord_deg - s.exact_chord_deg;
        let twist = s.rows[0] - s.rows[s.rows.len() - 1];
        println!("{model} {spacing} cm: chord {} deg (exact {}), twist {twist:e} m", s.chord_deg, s.exact_chord_deg);
        assert!(error.abs() < chord_deg, "{spacing} cm: chord {} deg, exact {}", s.chord_deg, s.exact_chord_deg);
        assert!(twist.abs() < twist_m, "{spacing} cm: twisted {:?}", s.rows);
    }
    let change = (fine.drop / coarse.drop - 1.0).abs();
    println!("{model}: tip drop {} m at 1 cm, {} m at 0.5 cm", coarse.drop, fine.drop);
    assert!(change < drop_change, "tip drop {} m at 1 cm, {} m at 0.5 cm", coarse.drop, fine.drop);
}
