//! One timer for every stage of a step: each stage runs inside
//! [`StageTimer::time`] (or between [`StageTimer::start`] and
//! [`StageTimer::stop`]), which adds its wall time to the stage's field of
//! [`crate::StageTimes`]. A stage timed inside another counts once: its
//! time is taken out of the outer stage's.

use crate::StageTimes;
use std::time::Instant;

/// A stage of a step, as [`StageTimes`] reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Evaluating interaction laws (forces and Jacobian blocks), and the
    /// loads from outside the cloth.
    Forces,
    /// Gathering into the matrix and right-hand side; pin constraints.
    Assembly,
    /// The linear solves, or the vertex solver's sweeps.
    Solve,
    /// The new state, the contacts' response, the energy balance, the
    /// commit and the step's finish.
    Update,
    /// Cloth-solid detection and projection.
    Collision,
    /// Self-collision detection, separation and the continuous test.
    SelfCollision,
}

/// Adds up each stage's wall time over a step.
#[derive(Debug, Clone, Copy, Default)]
pub struct StageTimer {
    times: StageTimes,
    /// Seconds timed so far, all stages (what an outer stage takes out).
    timed_s: f64,
}

/// A stage started with [`StageTimer::start`].
#[derive(Debug, Clone, Copy)]
#[must_use = "a started stage is timed when stopped"]
pub struct Lap {
    at: Instant,
    timed_before_s: f64,
}

impl StageTimer {
    /// Runs `f` as part of `stage`.
    pub fn time<T>(&mut self, stage: Stage, f: impl FnOnce() -> T) -> T {
        let lap = self.start();
        let out = f();
        self.stop(lap, stage);
        out
    }

    /// Starts timing a stage that times others inside it.
    pub fn start(&self) -> Lap {
        Lap { at: Instant::now(), timed_before_s: self.timed_s }
    }

    /// Ends `lap` as part of `stage`, less the stages timed inside it.
    pub fn stop(&mut self, lap: Lap, stage: Stage) {
        self.record(lap.timed_before_s, lap.at.elapsed().as_secs_f64(), stage);
    }

    /// A stage that took `total` seconds and began when `timed_before`
    /// seconds had been timed.
    fn record(&mut self, timed_before: f64, total: f64, stage: Stage) {
        let inside = self.timed_s - timed_before;
        self.add(stage, (total - inside).max(0.0));
        self.timed_s = timed_before + total;
    }

    /// Adds `seconds` measured elsewhere to `stage` (an outer stage takes
    /// them out of its own).
    pub fn add(&mut self, stage: Stage, seconds: f64) {
        self.timed_s += seconds;
        let t = &mut self.times;
        let field = match stage {
            Stage::Forces => &mut t.forces_s,
            Stage::Assembly => &mut t.assembly_s,
            Stage::Solve => &mut t.solve_s,
            Stage::Update => &mut t.update_s,
            Stage::Collision => &mut t.collision_s,
            Stage::SelfCollision => &mut t.self_collision_s,
        };
        *field += seconds;
    }

    /// The times so far.
    pub fn times(&self) -> StageTimes {
        self.times
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stage timed inside another counts once: the outer stage gets its
    /// own time only, and the stages add up to the wall time.
    #[test]
    fn a_stage_inside_another_is_counted_once() {
        let mut timer = StageTimer::default();
        // Update runs 10 s, with 4 s of self-collision inside (from its
        // third second), then a 1 s solve.
        let update_from = timer.timed_s;
        let inner_from = timer.timed_s;
        timer.record(inner_from, 4.0, Stage::SelfCollision);
        timer.record(update_from, 10.0, Stage::Update);
        let solve_from = timer.timed_s;
        timer.record(solve_from, 1.0, Stage::Solve);
        let t = timer.times();
        assert_eq!((t.update_s, t.self_collision_s, t.solve_s), (6.0, 4.0, 1.0));
        assert_eq!(timer.timed_s, 11.0);
    }
}
