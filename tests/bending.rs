//! Peirce's cantilever (ASTM D1388) against the heavy elastica: does
//! `flexural_rigidity_n_m` mean flexural rigidity? Issue 10 asks for 2
//! degrees at 1, 0.5 and 0.25 cm for `choi-ko` and `volino`; these tests
//! hold what is reached so far (`cloth study bending` prints the table).

use cloth_core::reference::{CantileverStrip, TipMeasure, bending_length, heavy_elastica};
use cloth_tests::simulation;

/// Runs the cantilever fixture as `strip` with `model` for its 3 s; returns
/// the tip, the rows' tip heights (m) and the fastest particle's speed (m/s).
fn settle(model: &str, strip: &CantileverStrip) -> (TipMeasure, Vec<f64>, f64) {
    let mut o = strip.overrides();
    o.push(format!("simulation.model=\"{model}\""));
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let (mut sim, cfg) = simulation("cantilever.toml", &o);
    for _ in 0..cfg.steps {
        sim.step(cfg.dt_s).unwrap();
    }
    let x = &sim.state().x;
    let [nx, ny] = strip.particles();
    let rows = (0..ny).map(|j| x[j * nx + nx - 1].z).collect();
    let speed = sim.state().v.iter().map(|v| v.norm()).fold(0.0, f64::max);
    (strip.measure(x, 0.5), rows, speed)
}

/// The exact chord angle of the fixture's 10 cm overhang, degrees.
fn exact_chord_deg() -> f64 {
    heavy_elastica(0.10 / bending_length(1.226e-4, 0.1, 9.81)).chord_angle_deg()
}

/// Volino's hinges at 1 cm: within 2 degrees of the elastica (measured
/// 43.07 against 41.49), and the strip does not twist (its edges' tips
/// level to 1e-9 m). With every cell split along the same diagonal the mesh is
/// chiral and the tip twisted by 2.5 mm across the 2 cm width; with the
/// clamp hinge as compliant as a free one the chord was 48.1 degrees.
#[test]
fn volino_cantilever_is_level_and_within_two_degrees_at_1_cm() {
    let strip = CantileverStrip { spacing: 0.01, overhang: 0.10, width: 0.02 };
    let (tip, rows, speed) = settle("volino", &strip);
    assert!(speed < 1e-5, "not settled: {speed} m/s");
    let chord = tip.chord_angle_deg();
    assert!((chord - exact_chord_deg()).abs() < 2.0, "chord {chord} deg, exact {}", exact_chord_deg());
    let twist = rows[0] - rows[rows.len() - 1];
    assert!(twist.abs() < 1e-9, "tip twisted: rows at {rows:?}");
}

/// Choi & Ko's links at 1 cm: the type-2 links across the clamp line count
/// double: 4.7 degrees from the elastica (46.17 against 41.49; 9.9 degrees
/// when they counted as free links).
/// Still soft: the ramp's soft zone and the 3/4 of `k_b` (material docs).
#[test]
fn choi_ko_cantilever_clamp_counts_half_a_link_at_1_cm() {
    let strip = CantileverStrip { spacing: 0.01, overhang: 0.10, width: 0.02 };
    let (tip, rows, speed) = settle("choi-ko", &strip);
    assert!(speed < 1e-5, "not settled: {speed} m/s");
    let chord = tip.chord_angle_deg();
    assert!((chord - exact_chord_deg()).abs() < 5.0, "chord {chord} deg, exact {}", exact_chord_deg());
    assert!(rows.iter().all(|z| (z - rows[0]).abs() < 1e-4), "{rows:?}");
}
