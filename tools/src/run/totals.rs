//! What a run adds up over its steps: the Newton iterations, the energy
//! monitor's balance, the contacts.

use crate::output::{EnergySummary, NewtonSummary};
use cloth_core::{ContactStats, StepReport};

/// Newton counters over a run.
#[derive(Default)]
pub(super) struct NewtonTotals {
    pub(super) steps: u64,
    /// Steps whose iterations the run engaged itself, and when it did, s.
    pub(super) automatic: u64,
    pub(super) engaged_at_s: Option<f64>,
    /// Steps that took them alone, their linear step misjudging a tension.
    pub(super) struck: u64,
    pub(super) corrections: u64,
    pub(super) corrections_max: usize,
    pub(super) backtracks: u64,
    pub(super) unconverged: u64,
    pub(super) residual_max_m: f64,
}

impl NewtonTotals {
    pub(super) fn add(&mut self, r: Option<&cloth_core::NewtonReport>, t_s: f64) {
        let Some(r) = r else { return };
        self.steps += 1;
        if r.automatic {
            self.automatic += 1;
            self.engaged_at_s.get_or_insert(t_s);
        }
        self.struck += u64::from(r.struck);
        self.corrections += r.corrections as u64;
        self.corrections_max = self.corrections_max.max(r.corrections);
        self.backtracks += r.backtracks as u64;
        self.unconverged += u64::from(!r.converged);
        self.residual_max_m = self.residual_max_m.max(r.residual_m);
    }

    pub(super) fn summary(&self) -> Option<NewtonSummary> {
        (self.steps > 0).then(|| NewtonSummary {
            automatic_steps: self.automatic,
            engaged_at_s: self.engaged_at_s,
            struck_steps: self.struck,
            corrections_total: self.corrections,
            corrections_max: self.corrections_max,
            corrections_mean: self.corrections as f64 / self.steps as f64,
            backtracks_total: self.backtracks,
            unconverged_steps: self.unconverged,
            residual_max_m: self.residual_max_m,
        })
    }
}

/// The energy monitor over a run.
#[derive(Default)]
pub(super) struct EnergyTotals {
    pub(super) steps: u64,
    pub(super) last: cloth_core::EnergyReport,
    pub(super) pin_work: f64,
    pub(super) external_work: f64,
    pub(super) contact_work: f64,
    pub(super) dissipated: f64,
    pub(super) gain: f64,
    pub(super) gain_max: f64,
    pub(super) flagged: u64,
    pub(super) retaken: u64,
    pub(super) retaken_with_newton: u64,
}

impl EnergyTotals {
    pub(super) fn add(&mut self, r: &StepReport) {
        let Some(e) = r.energy else { return };
        self.steps += 1;
        self.last = e;
        self.pin_work += e.pin_work_j;
        self.external_work += e.external_work_j;
        self.contact_work += e.contact_work_j;
        self.dissipated += e.dissipated_j;
        self.gain += e.gain_j;
        self.gain_max = self.gain_max.max(e.gain_j);
        self.flagged += u64::from(e.flagged);
        self.retaken += u64::from(r.retaken_as_backward_euler);
        self.retaken_with_newton += u64::from(r.retaken_with_newton);
    }

    pub(super) fn summary(&self) -> Option<EnergySummary> {
        (self.steps > 0).then_some(EnergySummary {
            kinetic_j: self.last.kinetic_j,
            elastic_j: self.last.elastic_j,
            gravitational_j: self.last.gravitational_j,
            pin_work_total_j: self.pin_work,
            external_work_total_j: self.external_work,
            contact_work_total_j: self.contact_work,
            dissipated_total_j: self.dissipated,
            gain_total_j: self.gain,
            gain_max_j: self.gain_max,
            flagged_steps: self.flagged,
            retaken_as_backward_euler_steps: self.retaken,
            retaken_with_newton_steps: self.retaken_with_newton,
        })
    }
}

/// Collision counters over a run.
#[derive(Default)]
pub(super) struct ContactTotals {
    pub(super) contacts_max: usize,
    pub(super) max_penetration_m: f64,
    pub(super) self_contacts_max: usize,
    pub(super) released: u64,
    pub(super) queries: u64,
    pub(super) hash_builds: u64,
    pub(super) crossings: u64,
    pub(super) crossings_left: u64,
    pub(super) crossing_steps: u64,
}

impl ContactTotals {
    pub(super) fn add(&mut self, c: &ContactStats) {
        self.contacts_max = self.contacts_max.max(c.contacts);
        self.max_penetration_m = self.max_penetration_m.max(c.max_penetration_m);
        self.self_contacts_max = self.self_contacts_max.max(c.self_contacts);
        self.released += c.released as u64;
        self.queries += c.narrow_phase_queries as u64;
        self.hash_builds += c.hash_builds as u64;
        self.crossings += c.self_crossings as u64;
        self.crossings_left += c.crossings_left as u64;
        self.crossing_steps += u64::from(c.self_crossings > 0);
    }
}

impl crate::output::TangleSummary {
    /// Counts the state after one step.
    pub(super) fn add(&mut self, c: cloth_core::TangleCounts) {
        self.self_crossings_max = self.self_crossings_max.max(c.self_crossings);
        self.self_crossings_end = c.self_crossings;
        self.self_crossing_steps += u64::from(c.self_crossings > 0);
        self.deep_in_solids_max = self.deep_in_solids_max.max(c.deep_in_solids);
        self.deep_in_solids_end = c.deep_in_solids;
        self.deepest_in_solids_m = self.deepest_in_solids_m.max(c.deepest_in_solid_m);
    }

    /// Keeps the first tangle of its kind, in `words` and its time.
    pub(super) fn record(&mut self, event: &cloth_core::TangleEvent, words: &str) {
        match *event {
            cloth_core::TangleEvent::LastingCrossing { since, .. } => {
                self.lasting_crossing = Some(words.to_string());
                self.lasting_crossing_from_s = Some(since.1);
            }
            cloth_core::TangleEvent::ThroughSolid { at, .. } => {
                self.through_solid = Some(words.to_string());
                self.through_solid_at_s = Some(at.1);
            }
        }
    }
}

impl crate::output::StrainLimitSummary {
    /// The watch for a model with these deformation constraints.
    pub(super) fn new(limit: &cloth_core::StrainLimit) -> Self {
        Self { limit_ratio: limit.limit_ratio(), worst_ratio: limit.limit_ratio(), ..Self::default() }
    }

    /// Counts the state after the step `at` (its number and time, s) with
    /// the link `over` past the limit, if any; returns the words of the
    /// first such step of the run, once. `passes` is the scene's
    /// `constraints.passes`.
    pub(super) fn add(
        &mut self,
        over: Option<cloth_core::OverStretch>,
        (step, time_s): (u64, f64),
        passes: usize,
    ) -> Option<String> {
        let over = over?;
        self.steps_over += 1;
        self.worst_ratio = self.worst_ratio.max(over.ratio);
        if self.first_over.is_some() {
            return None;
        }
        let words = format!(
            "the deformation constraints left a link past their limit at t = {time_s:.4} s (step {step}): \
             link {}-{} at {:.3} times its rest length, the limit {:.3} (constraints.passes = {passes})",
            over.link[0], over.link[1], over.ratio, over.limit_ratio
        );
        (self.first_over, self.first_over_at_s) = (Some(words.clone()), Some(time_s));
        Some(words)
    }
}
