//! The energy balance of one step: what the cloth's mechanical energy did
//! against the work done on it, so that a step that creates energy is seen.
//!
//! `gain = dE + D - W` with `E = kinetic + elastic + gravitational`, `D`
//! the dissipation of link dampers and drag over the step and `W` the work
//! of pins, held particles and external forces (wind, the control's forces, self-collision
//! repulsion). A stable implicit step has `gain <= 0` up to the per-step
//! fluctuation of a multistep method (BDF2's energy is not monotone step by
//! step); a step is flagged when `gain` exceeds
//! [`GAIN_TOLERANCE`] times the energy in play. Contacts with solids do
//! work that is not measured here (moving solids, friction, projections),
//! so steps with active contacts are never flagged.

use crate::forces::{EnergyBuffers, elastic_energy};
use crate::{ClothModel, Vec3};

/// Relative energy gain of one step (of the energy in play) above which
/// the step is flagged. Measured with it: BDF2 flags 0-3 steps per run on
/// the fixtures at h = 1/90 s, and 152 of 540 steps of the runaway after
/// issue 10's pin jump.
pub const GAIN_TOLERANCE: f64 = 0.05;

/// Energies after a step and the step's balance, J.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EnergyReport {
    /// `1/2 sum m |v|^2` after the step.
    pub kinetic_j: f64,
    /// Elastic energy of links and elements after the step.
    pub elastic_j: f64,
    /// `-sum m g.x` after the step (zero at the origin).
    pub gravitational_j: f64,
    /// Work of the pins over the step, `sum f_pin . dx`.
    pub pin_work_j: f64,
    /// Work of external forces over the step, `sum f_ext . dx`.
    pub external_work_j: f64,
    /// Dissipated by link dampers and drag, `h v'^T C v'`.
    pub dissipated_j: f64,
    /// `dE + D - W`: energy the step created (negative: numerical
    /// dissipation).
    pub gain_j: f64,
    /// Whether `gain_j` exceeded [`GAIN_TOLERANCE`] of the energy in play.
    pub flagged: bool,
}

/// Mechanical energy of a state: `(kinetic, elastic, gravitational)`, J,
/// with the elastic energy given (from an assembly at `x`).
pub(crate) fn mechanical_with(model: &ClothModel, x: &[Vec3], v: &[Vec3], elastic: f64) -> (f64, f64, f64) {
    let m = model.masses();
    let kinetic = 0.5 * m.iter().zip(v).map(|(m, v)| m * v.norm_squared()).sum::<f64>();
    let gravity = model.effects().gravity.map_or(0.0, |g| -m.iter().zip(x).map(|(m, x)| m * g.dot(x)).sum::<f64>());
    (kinetic, elastic, gravity)
}

/// Mechanical energy of a state: `(kinetic, elastic, gravitational)`, J,
/// the stitches in the states `stitches_closed`.
pub(crate) fn mechanical(
    model: &ClothModel,
    x: &[Vec3],
    v: &[Vec3],
    stitches_closed: &[bool],
    bufs: &mut EnergyBuffers,
) -> (f64, f64, f64) {
    mechanical_with(model, x, v, elastic_energy(model, x, stitches_closed, bufs))
}

/// What a step did to the energy, from the states before and after it.
pub(crate) struct StepEnergy<'a> {
    pub before: (f64, f64, f64),
    pub x: &'a [Vec3],
    pub new_x: &'a [Vec3],
    pub new_v: &'a [Vec3],
    /// The step's pinned and held particles.
    pub pins: crate::control::PinPaths<'a>,
    /// Force of each pin (and hold) on its particle over the step, N.
    pub pin_forces: &'a [Vec3],
    /// External forces of the step, N (when present).
    pub external: Option<&'a [Vec3]>,
    pub h: f64,
    /// Active contacts with solids (their work is not measured).
    pub contacts: usize,
    /// The stitches' states over the step.
    pub stitches_closed: &'a [bool],
}

impl StepEnergy<'_> {
    /// The balance; `after` is [`mechanical`] of the new state.
    pub(crate) fn report(&self, model: &ClothModel, after: (f64, f64, f64)) -> EnergyReport {
        let dx = |i: usize| self.new_x[i] - self.x[i];
        let pin_work: f64 = self.pins.particles().zip(self.pin_forces).map(|(i, f)| f.dot(&dx(i))).sum();
        let external_work = self.external.map_or(0.0, |f| (0..f.len()).map(|i| f[i].dot(&dx(i))).sum());
        let v = self.new_v;
        let mut rate: f64 = (0..v.len()).map(|i| model.drag(i) * v[i].norm_squared()).sum();
        for l in model.stretch_links().iter().filter(|l| l.k_d > 0.0) {
            let (i, j) = (l.i as usize, l.j as usize);
            let e = (self.new_x[j] - self.new_x[i]).normalize();
            let dv = e.dot(&(v[j] - v[i]));
            if dv.is_finite() {
                rate += l.k_d * dv * dv;
            }
        }
        for (s, &closed) in model.stitches().iter().zip(self.stitches_closed) {
            rate += s.dashpot(closed) * (v[s.j as usize] - v[s.i as usize]).norm_squared();
        }
        let dissipated = rate * self.h;
        let (k0, e0, g0) = self.before;
        let (k1, e1, g1) = after;
        let gain = (k1 + e1 + g1) - (k0 + e0 + g0) + dissipated - pin_work - external_work;
        let in_play = k0 + k1 + e0 + e1 + pin_work.abs() + external_work.abs() + dissipated;
        EnergyReport {
            kinetic_j: k1,
            elastic_j: e1,
            gravitational_j: g1,
            pin_work_j: pin_work,
            external_work_j: external_work,
            dissipated_j: dissipated,
            gain_j: gain,
            flagged: self.contacts == 0 && gain > GAIN_TOLERANCE * in_play,
        }
    }
}
