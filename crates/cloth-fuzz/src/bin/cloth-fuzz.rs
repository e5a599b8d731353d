//! `cloth-fuzz`: the stable mutation runner, for runs of minutes to hours.
//!
//! `cargo run --release -p cloth-fuzz -- --seconds 600` fuzzes every
//! target for ten minutes each; inputs that panic are written to
//! `target/fuzz-crashes/<target>/`, and `--grow` adds the inputs that
//! reached a new outcome to `fuzz/corpus/<target>/`.

use anyhow::{Context, Result, bail};
use clap::Parser;
use cloth_fuzz::driver::{Budget, fuzz};
use cloth_fuzz::{Corpus, Target};
use std::path::PathBuf;
use std::time::Duration;

#[derive(Parser)]
#[command(name = "cloth-fuzz", about = "Fuzz the readers and the FMU's C API on stable Rust")]
struct Args {
    /// Targets to run (default: all): scene_toml, overrides, obj, gltf, urdf, bvh, gltf_writer, fmi_calls.
    #[arg(long = "target")]
    targets: Vec<String>,
    /// Seconds per target.
    #[arg(long, conflicts_with = "runs")]
    seconds: Option<f64>,
    /// Mutated inputs per target (a fixed sequence for a given seed).
    #[arg(long, default_value_t = 1000)]
    runs: usize,
    /// The mutation sequence's seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Add inputs that reached a new outcome to the corpus.
    #[arg(long)]
    grow: bool,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let targets: Vec<Target> = if args.targets.is_empty() {
        Target::ALL.to_vec()
    } else {
        args.targets
            .iter()
            .map(|name| {
                Target::from_name(name).with_context(|| {
                    let names: Vec<&str> = Target::ALL.iter().map(|t| t.name()).collect();
                    format!("--target {name}: no such target (targets: {})", names.join(", "))
                })
            })
            .collect::<Result<_>>()?
    };
    let budget = match args.seconds {
        Some(s) if s.is_finite() && s > 0.0 => Budget::Time(Duration::from_secs_f64(s)),
        Some(s) => bail!("--seconds {s}: must be a positive number"),
        None => Budget::Runs(args.runs),
    };
    cloth_fuzz::quiet_panics();
    let mut failed = false;
    println!("| target | executions | outcomes | kept | panics | slowest input (s) |\n|---|---|---|---|---|---|");
    for target in targets {
        let report = fuzz(target, Corpus::All, budget, args.seed);
        println!(
            "| {} | {} | {} | {} | {} | {:.3} |",
            target.name(),
            report.executions,
            report.outcomes.len(),
            report.kept.len(),
            report.panics.len(),
            report.slowest_s
        );
        if args.grow {
            let dir = target.corpus_dir();
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
            for input in &report.kept {
                let path = dir.join(format!("stable-{:016x}", hash(input)));
                std::fs::write(&path, input).with_context(|| format!("writing {}", path.display()))?;
            }
        }
        if !report.panics.is_empty() {
            failed = true;
            let dir = PathBuf::from("target/fuzz-crashes").join(target.name());
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
            for (from, input) in &report.panics {
                let path = dir.join(format!("{:016x}", hash(input)));
                std::fs::write(&path, input).with_context(|| format!("writing {}", path.display()))?;
                eprintln!("{}: panicked on {} (from {from})", target.name(), path.display());
            }
        }
    }
    if failed {
        bail!("inputs panicked; they are in target/fuzz-crashes");
    }
    Ok(())
}

/// FNV-1a: a file name for an input.
fn hash(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3))
}
