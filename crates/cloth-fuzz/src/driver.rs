//! The stable mutation driver: mutates corpus inputs, runs them, keeps
//! the inputs whose outcome is new (a refusal not seen before), and
//! records every input that panicked.

use crate::mutate::{Rng, mutate};
use crate::{Corpus, Target};
use std::collections::BTreeSet;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::{Duration, Instant};

/// How long a driver runs each target.
#[derive(Clone, Copy, Debug)]
pub enum Budget {
    /// This many mutated inputs (a fixed sequence: the tests).
    Runs(usize),
    /// Until this much time has passed (the long runs).
    Time(Duration),
}

/// What one target's run found.
#[derive(Debug, Default)]
pub struct Report {
    /// Inputs run, the corpus's replay included.
    pub executions: usize,
    /// Distinct outcomes seen.
    pub outcomes: BTreeSet<String>,
    /// Inputs kept because their outcome was new.
    pub kept: Vec<Vec<u8>>,
    /// Inputs that panicked, with the corpus file or mutation they came from.
    pub panics: Vec<(String, Vec<u8>)>,
    /// The slowest input, s.
    pub slowest_s: f64,
}

/// Runs `data`, catching a panic.
fn run_one(target: Target, data: &[u8], report: &mut Report) -> Option<String> {
    let start = Instant::now();
    let outcome = catch_unwind(AssertUnwindSafe(|| target.run(data))).ok();
    report.executions += 1;
    report.slowest_s = report.slowest_s.max(start.elapsed().as_secs_f64());
    outcome
}

/// Replays the corpus, then mutates it within `budget`. Seeded by
/// `seed`, so a run of `Budget::Runs` replays exactly.
pub fn fuzz(target: Target, corpus: Corpus, budget: Budget, seed: u64) -> Report {
    let mut report = Report::default();
    let mut pool: Vec<Vec<u8>> = Vec::new();
    for (path, data) in target.corpus(corpus) {
        match run_one(target, &data, &mut report) {
            Some(outcome) => {
                report.outcomes.insert(outcome);
            }
            None => report.panics.push((path.display().to_string(), data.clone())),
        }
        pool.push(data);
    }
    if pool.is_empty() {
        pool.push(Vec::new());
    }
    let mut rng = Rng(seed | 1);
    let start = Instant::now();
    for round in 0.. {
        let done = match budget {
            Budget::Runs(n) => round >= n,
            Budget::Time(d) => start.elapsed() >= d,
        };
        if done {
            break;
        }
        let others: Vec<&[u8]> = pool.iter().map(Vec::as_slice).collect();
        let parent = pool[rng.below(pool.len())].clone();
        let input = mutate(target, &parent, &others, &mut rng);
        match run_one(target, &input, &mut report) {
            Some(outcome) => {
                if report.outcomes.insert(outcome) {
                    report.kept.push(input.clone());
                    pool.push(input);
                }
            }
            None => report.panics.push((format!("mutation {round} (seed {seed})"), input)),
        }
    }
    report
}
