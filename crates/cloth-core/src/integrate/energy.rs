//! The energy balance of one step: what the cloth's mechanical energy did
//! against the work done on it, so that a step that creates energy is seen.
//!
//! `E = kinetic + elastic + gravitational`; `W` the work of pins, held
//! particles, external forces (wind, the control's forces, self-collision
//! repulsion) and of solids through their contacts; `D` the work the
//! link dampers, stitch dashpots and drag took out, each force at the new
//! velocity over the step's displacement (`v'^T C dx`, as the other
//! works are `f . dx`). The step's `growth = dE - W` is what the cloth
//! gained beyond the work done on it; a step is flagged when it exceeds
//! [`GAIN_TOLERANCE`] of the energy in play. Its `gain = dE + D - W` is
//! the balance with the dampers: negative is numerical dissipation, and a
//! positive gain that is not growth (the dampers took out more than the
//! energy fell: the single linearised step of a stiff seam closing) is
//! reported, not flagged.
//!
//! A solid's work on the cloth is what its surface did: `J . v_s`, the
//! contact's impulse over the step (normal force and friction, as the
//! coupling hands it to a body) times the solid's velocity there. What the
//! contact force does beyond that, `J . (v - v_s)`, is the contact's own:
//! zero for a constraint that holds, negative for friction and for an
//! inelastic normal (both dissipate in the solid's frame). A contact
//! response that throws a particle (a friction jump, an overshooting push)
//! therefore shows as growth, while a solid that drags, lifts or strikes
//! cloth does not: a floor that carries a resting cloth off at `v` does
//! work `m v^2`, half of it the cloth's kinetic energy, half lost to the
//! friction that accelerated it. A linearised step that stores more in
//! the links than the solid's impulse put in (a cloth landing flat, whose
//! links have no transverse stiffness in the linear model) is flagged too:
//! that energy is created.
//!
//! The explicit integrators balance windows of [`crate::ENERGY_WINDOW`]
//! steps instead of single steps, without the dissipation (see
//! `explicit::balance_window`): what they must show is a step past its
//! stability limit, whose energy grows by a factor every step.

use crate::forces::{EnergyBuffers, elastic_energy};
use crate::{ClothModel, Vec3};

/// Relative energy growth of one step (of the energy in play) above which
/// the step is flagged. Measured with it: BDF2 flags 0-3 steps per run on
/// the fixtures at h = 1/90 s without solid contacts, 0-10 with them (a
/// cloth landing flat), and 174 of 540 steps of the runaway after issue
/// 10's pin jump.
pub const GAIN_TOLERANCE: f64 = 0.05;

/// Relative energy growth of one step above which a step is flagged when
/// bodies are in the solve and the cloth touches no other solid (retaken as backward Euler with Newton
/// corrections that carry them). What the cloth creates goes into the
/// bodies, and [`GAIN_TOLERANCE`] let through steps that raised the
/// energy of cloth plus body by up to 2.7e-3 of theirs: a 2 kg box landing
/// on a trampoline (the linear step's links have no stiffness across
/// them) at 1e-2 of the cloth's energy in play, and a cloth recoiling
/// after a 36 kg ball tore through it at 2.9e-2.
pub const BODY_GAIN_TOLERANCE: f64 = 1e-3;

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
    /// Work of solids through their contacts over the step,
    /// `sum J_c . v_solid`: the contact impulse (normal and friction)
    /// times the solid's surface velocity at the contact.
    pub contact_work_j: f64,
    /// Dissipated by link dampers, stitch dashpots and drag, `v'^T C dx`.
    pub dissipated_j: f64,
    /// `dE + D - W`: energy the step created (negative: numerical
    /// dissipation).
    pub gain_j: f64,
    /// The growth `dE - W` over the energy in play (the kinetic and
    /// elastic energies before and after, the works' magnitudes and the
    /// dissipation); 0 when nothing is in play.
    pub growth_share: f64,
    /// Whether `growth_share` exceeded [`GAIN_TOLERANCE`].
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
    /// Contacts with solids, their impulses set.
    pub contacts: &'a [crate::contacts::SolidContact],
    /// The stitches' states over the step.
    pub stitches_closed: &'a [bool],
}

impl StepEnergy<'_> {
    /// The balance; `after` is [`mechanical`] of the new state.
    pub(crate) fn report(&self, model: &ClothModel, after: (f64, f64, f64)) -> EnergyReport {
        let dx = |i: usize| self.new_x[i] - self.x[i];
        let works = works((self.x, self.new_x), (self.pins, self.pin_forces), self.external, self.contacts);
        // The dampers' and drag's work over the step's displacement, at
        // the new velocity they are evaluated at: `v'^T C dx`.
        let v = self.new_v;
        let mut dissipated: f64 = (0..v.len()).map(|i| model.drag(i) * v[i].dot(&dx(i))).sum();
        for l in model.stretch_links().iter().filter(|l| l.k_d > 0.0) {
            let (i, j) = (l.i as usize, l.j as usize);
            let e = (self.new_x[j] - self.new_x[i]).normalize();
            let along = e.dot(&(v[j] - v[i])) * e.dot(&(dx(j) - dx(i)));
            if along.is_finite() {
                dissipated += l.k_d * along;
            }
        }
        for (s, &closed) in model.stitches().iter().zip(self.stitches_closed) {
            let (i, j) = (s.i as usize, s.j as usize);
            dissipated += s.dashpot(closed) * (v[j] - v[i]).dot(&(dx(j) - dx(i)));
        }
        balance(self.before, after, works, dissipated)
    }
}

/// The work done on the cloth over a step from `x` to `new_x`, J: by the
/// pins (each particle's mean pin force over its displacement), by the
/// external forces (when present, over the displacement) and by the solids
/// through `contacts` (each impulse times the solid's velocity there), as
/// `(pins, external, contacts)`.
pub(crate) fn works(
    (x, new_x): (&[Vec3], &[Vec3]),
    (pins, pin_forces): (crate::control::PinPaths<'_>, &[Vec3]),
    external: Option<&[Vec3]>,
    contacts: &[crate::contacts::SolidContact],
) -> (f64, f64, f64) {
    let dx = |i: usize| new_x[i] - x[i];
    let pin_work: f64 = pins.particles().zip(pin_forces).map(|(i, f)| f.dot(&dx(i))).sum();
    let external_work = external.map_or(0.0, |f| (0..f.len()).map(|i| f[i].dot(&dx(i))).sum());
    let contact_work: f64 = contacts.iter().map(|c| c.impulse_n_s.dot(&c.solid_velocity)).sum();
    (pin_work, external_work, contact_work)
}

/// The balance of mechanical energies `before` and `after` (kinetic,
/// elastic, gravitational), J, against the works `(pins, external,
/// contacts)` done meanwhile and what the dampers took out, J.
pub(crate) fn balance(
    before: (f64, f64, f64),
    after: (f64, f64, f64),
    (pin_work, external_work, contact_work): (f64, f64, f64),
    dissipated: f64,
) -> EnergyReport {
    let (k0, e0, g0) = before;
    let (k1, e1, g1) = after;
    let work = pin_work + external_work + contact_work;
    let growth = (k1 + e1 + g1) - (k0 + e0 + g0) - work;
    let gain = growth + dissipated;
    let in_play = k0 + k1 + e0 + e1 + pin_work.abs() + external_work.abs() + contact_work.abs() + dissipated.abs();
    EnergyReport {
        kinetic_j: k1,
        elastic_j: e1,
        gravitational_j: g1,
        pin_work_j: pin_work,
        external_work_j: external_work,
        contact_work_j: contact_work,
        dissipated_j: dissipated,
        gain_j: gain,
        growth_share: if in_play > 0.0 { growth / in_play } else { 0.0 },
        flagged: growth > GAIN_TOLERANCE * in_play,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contacts::SolidContact;
    use crate::{Control, Effects, GridPanel, Material, ModelSpec};

    /// A 2 x 2 patch (1 cm, no gravity) at rest, each particle on a floor
    /// moving at `floor` (m/s), thrown to `v` (m/s) in one step of `h` by
    /// its contact's impulse `m v` (the patch translates rigidly: no
    /// elastic energy).
    fn moved_by_contacts(floor: Vec3, v: Vec3) -> EnergyReport {
        let panel = GridPanel {
            particles: [2, 2],
            size_m: [0.01, 0.01],
            origin_m: [0.0; 3],
            u_axis: [1.0, 0.0, 0.0],
            v_axis: [0.0, 1.0, 0.0],
            wrap_u: false,
        };
        let spec = ModelSpec { panels: vec![panel], material: Material::default(), ..ModelSpec::default() };
        let spec = ModelSpec { effects: Effects { gravity: None, ..spec.effects }, ..spec };
        let model = ClothModel::build(&spec).unwrap();
        let h = 0.01;
        let x = model.rest_positions().to_vec();
        let new_x: Vec<Vec3> = x.iter().map(|p| p + v * h).collect();
        let (still, moving) = (vec![Vec3::zeros(); 4], vec![v; 4]);
        let contacts: Vec<SolidContact> = (0..4)
            .map(|i| SolidContact {
                impulse_n_s: v * model.masses()[i],
                ..SolidContact::new(i, 0, x[i], Vec3::z(), floor, 0.5)
            })
            .collect();
        let control = Control::for_model(&model);
        let balance = StepEnergy {
            before: mechanical_with(&model, &x, &still, 0.0),
            x: &x,
            new_x: &new_x,
            new_v: &moving,
            pins: crate::control::PinPaths::new(&model, &control, &x, 0.0, h),
            pin_forces: &[],
            external: None,
            contacts: &contacts,
            stitches_closed: &[],
        };
        let mut bufs = EnergyBuffers::new(&model);
        balance.report(&model, mechanical(&model, &new_x, &moving, &[], &mut bufs))
    }

    /// A contact impulse that throws a resting particle off a floor at
    /// rest creates its kinetic energy: flagged. The same impulse from a
    /// floor moving at that velocity (a belt carrying the cloth off) is
    /// the floor's work `m v^2`: half of it the kinetic energy, half lost
    /// (the inelastic start), not flagged.
    #[test]
    fn a_contact_that_throws_cloth_is_flagged_and_a_solid_that_carries_it_is_not() {
        let v = Vec3::new(3.0, 0.0, 0.0);
        // The patch's mass.
        let mass: f64 = 0.01 * 0.01 * Material::default().areal_density_kg_m2;
        let thrown = moved_by_contacts(Vec3::zeros(), v);
        assert!((thrown.kinetic_j - 0.5 * mass * 9.0).abs() < 1e-12 * mass, "{thrown:?}");
        assert_eq!(thrown.contact_work_j, 0.0);
        assert!((thrown.gain_j - thrown.kinetic_j).abs() < 1e-12 * mass, "{thrown:?}");
        assert!(thrown.flagged);
        let carried = moved_by_contacts(v, v);
        assert!((carried.contact_work_j - mass * 9.0).abs() < 1e-12 * mass, "{carried:?}");
        assert!((carried.gain_j + 0.5 * mass * 9.0).abs() < 1e-12 * mass, "{carried:?}");
        assert!(!carried.flagged);
    }
}
