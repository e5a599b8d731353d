//! The committed corpus (`fuzz/corpus/<target>/`: fixtures, inputs that
//! reached new code under libFuzzer, and every input that once crashed)
//! replayed, then mutated a fixed number of times: no input may panic.
//! The fast tier replays the seeds and the inputs that once crashed; the
//! slow tier all of it (about 10,000 inputs, 40 s).

use cloth_fuzz::driver::{Budget, Report, fuzz};
use cloth_fuzz::{Corpus, Target};

fn run(corpus: Corpus, runs: usize, seed: u64) -> Vec<(Target, Report)> {
    Target::ALL.into_iter().map(|t| run_target(t, corpus, runs, seed)).collect()
}

fn run_target(target: Target, corpus: Corpus, runs: usize, seed: u64) -> (Target, Report) {
    cloth_fuzz::quiet_panics();
    (target, fuzz(target, corpus, Budget::Runs(runs), seed))
}

fn check(reports: &[(Target, Report)]) {
    for (target, r) in reports {
        println!(
            "{}: {} inputs, {} outcomes, slowest {:.3} s, {} panics",
            target.name(),
            r.executions,
            r.outcomes.len(),
            r.slowest_s,
            r.panics.len()
        );
    }
    let panicked: Vec<(&str, &str)> =
        reports.iter().flat_map(|(t, r)| r.panics.iter().map(|(from, _)| (t.name(), from.as_str()))).collect();
    assert!(panicked.is_empty(), "{panicked:?}");
}

#[test]
fn the_corpus_and_its_mutations_are_read_or_refused() {
    let reports = run(Corpus::Kept, 300, 1);
    check(&reports);
    // The corpus reaches both sides of every target: inputs accepted and
    // inputs refused (FMI calls that succeed, discard and fail).
    for (target, r) in &reports {
        let accepted = r.outcomes.iter().any(|o| !o.starts_with("refused"));
        let refused = r.outcomes.iter().any(|o| o.starts_with("refused") || o.contains("error"));
        assert!(accepted && refused, "{}: {:?}", target.name(), r.outcomes);
    }
    let fmi = &reports.iter().find(|(t, _)| *t == Target::FmiCalls).unwrap().1;
    for status in ["ok", "discard", "error"] {
        assert!(fmi.outcomes.iter().any(|o| o.split(' ').any(|s| s == status)), "{status}: {:?}", fmi.outcomes);
    }
}

/// The slow tier: the whole corpus, and 1,000 mutations on another
/// sequence, one test per target so that the harness runs two at a time.
macro_rules! whole_corpus {
    ($($test:ident: $target:ident,)*) => {
        $(
            #[test]
            #[ignore = "slow tier: the whole corpus and 1,000 mutated inputs per target"]
            fn $test() {
                check(&[run_target(Target::$target, Corpus::All, 1000, 2)]);
            }
        )*

        #[test]
        fn every_target_replays_its_whole_corpus_in_the_slow_tier() {
            let tested = [$(Target::$target),*];
            for t in Target::ALL {
                assert!(tested.contains(&t), "no slow test for {}", t.name());
            }
        }
    };
}

whole_corpus! {
    scene_toml_whole_corpus: SceneToml,
    overrides_whole_corpus: Overrides,
    obj_whole_corpus: Obj,
    gltf_whole_corpus: Gltf,
    urdf_whole_corpus: Urdf,
    bvh_whole_corpus: Bvh,
    gltf_writer_whole_corpus: GltfWriter,
    fmi_calls_whole_corpus: FmiCalls,
    snapshot_whole_corpus: Snapshot,
}
