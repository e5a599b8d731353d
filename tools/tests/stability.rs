//! The hard-case suite in CI, one test per group of cases so that the
//! harness runs two at a time: every case's requirement holds, and every
//! known defect still fails as described (when one is fixed, this test
//! says so, and its note must go).

use cloth_tools::stability::{GROUPS, Group, markdown};

/// Runs the group named `name` and fails on any row not as expected;
/// returns the case names its rows cover.
fn group_meets_its_requirements(name: &str) -> Vec<String> {
    let Group { run, .. } = GROUPS.iter().find(|g| g.name == name).expect("a group of the suite");
    let rows = run(false);
    println!("{}", markdown(&rows));
    assert!(!rows.is_empty(), "{name}: no rows");
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
    rows.into_iter().map(|r| r.case.to_string()).collect()
}

macro_rules! group_tests {
    ($($test:ident: $group:literal covers $case:literal;)*) => {
        $(
            #[test]
            #[ignore = "slow tier: cargo test --release -- --ignored"]
            fn $test() {
                let cases = group_meets_its_requirements($group);
                assert!(cases.iter().any(|c| c == $case), "{}: no row for {}", $group, $case);
            }
        )*

        /// Every group of the suite has its test, and every kind of hard
        /// case is covered by one.
        #[test]
        fn every_group_of_the_suite_is_tested() {
            let tested = [$($group),*];
            for g in GROUPS {
                assert!(tested.contains(&g.name), "no test for the group {:?}", g.name);
            }
        }
    };
}

group_tests! {
    step_sizes_hold: "step sizes" covers "step size";
    the_explicit_stability_limit_is_where_it_is_stated: "explicit stability limit" covers "explicit step";
    stiffness_ratios_hold: "stiffness ratios" covers "stiffness ratio";
    a_cloth_crumpled_to_a_point_recovers: "crumpled" covers "crumpled to a point";
    pins_yanked_at_50_m_s_hold: "yanked" covers "pins yanked at 50 m/s";
    a_cloth_stretched_ten_times_recovers: "released from ten times" covers "stretched 10x, released";
    a_cloth_shaken_at_100_hz_holds: "shaken" covers "shaken at 100 Hz";
    a_ball_through_a_curtain_holds: "ball through a curtain" covers "ball through a curtain";
    a_cloth_pulled_across_a_table_holds: "pulled across a table" covers "pulled across a table";
    tiny_and_huge_cloths_hold: "scales" covers "1 mm and 1 km cloths";
    coincident_particles_hold: "coincident particles" covers "coincident particles";
    coupled_balls_of_every_mass_ratio_hold: "coupled mass ratios" covers "coupled ball, mass ratios";
    a_box_resting_on_cloth_comes_to_rest: "body resting on cloth" covers "box resting on a trampoline";
}
