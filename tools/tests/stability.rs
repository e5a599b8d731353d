//! The hard-case suite in CI: every case's requirement holds,
//! and every known defect still fails as described (when one is fixed,
//! this test says so, and its note must go).

use cloth_tools::stability::{markdown, run_suite};

#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn every_hard_case_meets_its_requirement() {
    let rows = run_suite(false);
    println!("{}", markdown(&rows));
    let unexpected: Vec<String> = rows
        .iter()
        .filter(|r| !r.as_expected())
        .map(|r| {
            format!(
                "{} / {} / {}: {:?} (known defect: {:?})",
                r.case, r.variant, r.integrator, r.verdict, r.known_defect
            )
        })
        .collect();
    assert!(unexpected.is_empty(), "{} rows not as expected:\n{}", unexpected.len(), unexpected.join("\n"));
    // The suite covers every kind of hard case.
    for case in [
        "step size",
        "stiffness ratio",
        "crumpled to a point",
        "pins yanked at 50 m/s",
        "stretched 10x, released",
        "shaken at 100 Hz",
        "ball through a curtain",
        "1 mm and 1 km cloths",
        "coincident particles",
        "coupled ball, mass ratios",
    ] {
        assert!(rows.iter().any(|r| r.case == case), "no row for {case}");
    }
}
