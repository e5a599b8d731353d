//! The committed corpus (`fuzz/corpus/<target>/`: fixtures, inputs that
//! reached new code under libFuzzer, and every input that once crashed)
//! replayed, then mutated a fixed number of times: no input may panic.
//! The fast tier replays the seeds and the inputs that once crashed; the
//! slow tier all of it (about 10,000 inputs, 40 s).

use cloth_fuzz::driver::{Budget, Report, fuzz};
use cloth_fuzz::{Corpus, Target};

fn run(corpus: Corpus, runs: usize, seed: u64) -> Vec<(Target, Report)> {
    cloth_fuzz::quiet_panics();
    Target::ALL.into_iter().map(|t| (t, fuzz(t, corpus, Budget::Runs(runs), seed))).collect()
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

/// The slow tier: the whole corpus, and 1,000 mutations on another sequence.
#[test]
#[ignore = "slow tier: the whole corpus and 1,000 mutated inputs per target"]
fn the_whole_corpus_and_longer_mutation_runs() {
    check(&run(Corpus::All, 1000, 2));
}
