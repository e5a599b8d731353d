//! The explicit simulation state, and a snapshot of a whole simulation:
//! the state with what the integrator carries from step to step.
//! Restoring a snapshot and stepping reproduces the same bits.

use std::borrow::Cow;

use crate::{ClothModel, StepError, Vec3};

/// Positions, velocities and the one-step history BDF2 needs.
#[derive(Debug, Clone, PartialEq)]
pub struct ClothState {
    /// Simulated time, s.
    pub time_s: f64,
    /// Steps taken.
    pub steps: u64,
    /// Positions, m.
    pub x: Vec<Vec3>,
    /// Velocities, m/s.
    pub v: Vec<Vec3>,
    /// Positions one step ago, m (meaningful when `has_history`).
    pub x_prev: Vec<Vec3>,
    /// Velocities one step ago, m/s (meaningful when `has_history`).
    pub v_prev: Vec<Vec3>,
    /// Whether `x_prev`, `v_prev` hold the previous step (false at the start
    /// and after a change of step size: multistep methods restart then).
    pub has_history: bool,
    /// The step size that produced the current state, s (0 before the first step).
    pub last_dt_s: f64,
    /// Of each stitch of the model's seams, whether it has closed: an open
    /// stitch pulls with its gentle sewing pull, a closed one holds with
    /// the seam's strength ([`crate::SeamSpec`]). Updated after each step.
    pub stitches_closed: Vec<bool>,
}

/// Everything a simulation needs to go on from a point of its run: the
/// cloth's state and what its integrator carries from step to step
/// ([`crate::Simulation::snapshot`], [`crate::Simulation::restore`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// The cloth's state.
    pub state: ClothState,
    /// The integrator's memory.
    pub integrator: IntegratorMemory,
}

impl ClothState {
    /// The model's initial shape at rest, at time 0.
    pub fn at_rest(model: &ClothModel) -> Self {
        let n = model.particle_count();
        Self {
            time_s: 0.0,
            steps: 0,
            x: model.rest_positions().to_vec(),
            v: vec![Vec3::zeros(); n],
            x_prev: vec![Vec3::zeros(); n],
            v_prev: vec![Vec3::zeros(); n],
            has_history: false,
            last_dt_s: 0.0,
            stitches_closed: Self::stitches_closed_at(model, model.rest_positions()),
        }
    }

    /// The stitches closed at positions `x` ([`ClothModel::close_stitches`]).
    pub fn stitches_closed_at(model: &ClothModel, x: &[Vec3]) -> Vec<bool> {
        let mut closed = vec![false; model.stitches().len()];
        model.close_stitches(x, &mut closed);
        closed
    }

    /// The rest shape with every free particle displaced by a deterministic
    /// pseudo-random offset of at most `amplitude` m per component.
    pub fn jittered(model: &ClothModel, amplitude: f64) -> Self {
        let mut s = Self::at_rest(model);
        for (i, x) in s.x.iter_mut().enumerate() {
            if !model.is_pinned(i) {
                *x += Vec3::new(unit_noise(3 * i), unit_noise(3 * i + 1), unit_noise(3 * i + 2)) * amplitude;
            }
        }
        s.stitches_closed = Self::stitches_closed_at(model, &s.x);
        s
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether the state has no particles.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// First particle whose position or velocity (or, when the state has
    /// a history, previous position or velocity) is not finite, with which.
    pub fn first_non_finite(&self) -> Option<(usize, &'static str)> {
        let bad = |v: &Vec3| !v.iter().all(|c| c.is_finite());
        let fields = [
            ("position", &self.x),
            ("velocity", &self.v),
            ("previous position", &self.x_prev),
            ("previous velocity", &self.v_prev),
        ];
        let checked = if self.has_history { 4 } else { 2 };
        (0..self.len())
            .find_map(|i| fields[..checked].iter().find(|(_, a)| a.get(i).is_some_and(bad)).map(|(q, _)| (i, *q)))
    }
}

/// A hash of `k` mapped to [-1, 1) (splitmix64): reproducible noise.
fn unit_noise(k: usize) -> f64 {
    let mut z = (k as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

/// What an integrator carries from one step to the next besides the
/// cloth's state, as named numbers (an adaptive integrator's suggested
/// substep, whether Newton iterations are engaged): part of a
/// [`crate::Snapshot`], so that a restored snapshot steps to the same bits.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IntegratorMemory {
    /// Names are owned when read back from bytes ([`Snapshot::from_bytes`]).
    entries: Vec<(Cow<'static, str>, f64)>,
}

impl IntegratorMemory {
    /// Memory of `entries` (name, value).
    pub fn new(entries: Vec<(&'static str, f64)>) -> Self {
        Self { entries: entries.into_iter().map(|(n, v)| (Cow::Borrowed(n), v)).collect() }
    }

    /// Memory of named entries read from elsewhere (a file).
    pub(crate) fn from_named(entries: Vec<(String, f64)>) -> Self {
        Self { entries: entries.into_iter().map(|(n, v)| (Cow::Owned(n), v)).collect() }
    }

    /// Every entry, in the integrator's order.
    pub fn entries(&self) -> &[(Cow<'static, str>, f64)] {
        &self.entries
    }

    /// The value named `name`.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.entries.iter().find(|(n, _)| *n == name).map(|(_, v)| *v)
    }

    /// The same names with `values` in their order (a memory read back
    /// from a serialised state); `None` when the count differs.
    pub fn with_values(&self, values: &[f64]) -> Option<Self> {
        (values.len() == self.entries.len())
            .then(|| Self { entries: self.entries.iter().zip(values).map(|((n, _), v)| (n.clone(), *v)).collect() })
    }

    /// Checks that `other` has this memory's names, in order.
    pub(crate) fn same_names(&self, other: &Self) -> Result<(), StepError> {
        fn names(m: &IntegratorMemory) -> Vec<&str> {
            m.entries.iter().map(|(n, _)| n.as_ref()).collect()
        }
        if names(self) == names(other) {
            Ok(())
        } else {
            Err(StepError::MemoryMismatch { expected: names(self).join(", "), got: names(other).join(", ") })
        }
    }
}
