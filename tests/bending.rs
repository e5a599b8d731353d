//! Peirce's cantilever (ASTM D1388) against the heavy elastica: does
//! `flexural_rigidity_n_m` mean flexural rigidity? Issue 10 asks for 2
//! degrees at 1, 0.5 and 0.25 cm for `choi-ko` and `volino`; these tests
//! hold what is reached so far (`cloth study bending` prints the table).

use cloth_core::reference::CantileverStrip;
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

/// Runs the cantilever fixture as a 10 cm strip at 1 cm spacing with
/// `model` for its 3 s and checks it has come to rest (every particle
/// slower than 1e-5 m/s).
fn settle(model: &str) -> Settled {
    settle_at(model, 0.01, &[])
}

/// [`settle`] at grid `spacing` (m) with more overrides.
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
    assert!(speed < 1e-5, "{model} {extra:?} at {spacing} m: not settled, {speed} m/s");
    let x = &sim.state().x;
    let [nx, ny] = strip.particles();
    Settled {
        chord_deg: strip.measure(x).chord_angle_deg(),
        drop: strip.measure(x).tip_drop,
        exact_chord_deg: strip.exact(sim.model()).0.chord_angle_deg(),
        rows: (0..ny).map(|j| x[j * nx + nx - 1].z).collect(),
    }
}

/// Volino's hinges at 1 cm: within 2 degrees of the elastica (measured
/// 43.07 against 41.49), and the strip does not twist (its edges' tips
/// level to 1e-9 m). With every cell split along the same diagonal the mesh is
/// chiral and the tip twisted by 2.5 mm across the 2 cm width; with the
/// clamp hinge as compliant as a free one the chord was 48.1 degrees.
#[test]
fn volino_cantilever_is_level_and_within_two_degrees_at_1_cm() {
    let s = settle("volino");
    assert!((s.chord_deg - s.exact_chord_deg).abs() < 2.0, "chord {} deg, exact {}", s.chord_deg, s.exact_chord_deg);
    let twist = s.rows[0] - s.rows[s.rows.len() - 1];
    assert!(twist.abs() < 1e-9, "tip twisted: rows at {:?}", s.rows);
}

/// Choi & Ko's links at 1 cm: the type-2 links across the clamp line count
/// double: 4.7 degrees from the elastica (46.17 against 41.49; 9.9 degrees
/// when they counted as free links).
/// Still soft: the ramp's soft zone and the 3/4 of `k_b` (material docs).
#[test]
fn choi_ko_cantilever_clamp_counts_half_a_link_at_1_cm() {
    let s = settle("choi-ko");
    assert!((s.chord_deg - s.exact_chord_deg).abs() < 5.0, "chord {} deg, exact {}", s.chord_deg, s.exact_chord_deg);
    assert!(s.rows.iter().all(|z| (z - s.rows[0]).abs() < 1e-4), "{:?}", s.rows);
}

/// Choi & Ko's arc law read against the path through the middle particle
/// (`bending_law = "arc-path"`): 41.82 and 41.69 degrees at 1 and 0.5 cm
/// against the exact 41.49 (41.88 at 0.25 cm, `cloth study bending`), and
/// the tip drop at the two spacings within 0.4% of each other (measured
/// 0.38%), untwisted. The paper's pair law gives 46.2 and 59.6 degrees;
/// without the path's 4/3 on `k_b` the strip sags to 48.7 and 48.5; with
/// boundary links counting a full cell it is too stiff, 38.1 and 39.7.
#[test]
fn arc_path_cantilever_holds_the_elastica_at_1_and_0_5_cm() {
    let law = ["simulation.bending_law=\"arc-path\""];
    let (coarse, fine) = (settle_at("choi-ko", 0.01, &law), settle_at("choi-ko", 0.005, &law));
    for (s, spacing) in [(&coarse, 1.0), (&fine, 0.5)] {
        let error = s.chord_deg - s.exact_chord_deg;
        assert!(error.abs() < 0.4, "{spacing} cm: chord {} deg, exact {}", s.chord_deg, s.exact_chord_deg);
        let twist = s.rows[0] - s.rows[s.rows.len() - 1];
        assert!(twist.abs() < 1e-9, "{spacing} cm: twisted {:?}", s.rows);
    }
    let change = (fine.drop / coarse.drop - 1.0).abs();
    assert!(change < 4e-3, "tip drop {} m at 1 cm, {} m at 0.5 cm", coarse.drop, fine.drop);
}
