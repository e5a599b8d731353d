//! The two single-Newton-iteration implicit schemes, by what distinguishes
//! them: their linear system, their unknown, and how the unknown updates
//! the state ([`Linearised`]).

use crate::system::SystemTerms;
use crate::{ClothState, Vec3};

/// Backward Euler (Baraff & Witkin 1998, Eq. 16):
/// `[M - h D - h^2 K] dv = h (f + h K v)`, `x' = x + h (v + dv)`.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct EulerScheme;

/// Second-order BDF (Choi & Ko 2002, Eq. 20, multiplied by `M` to keep
/// the matrix symmetric), with `dx = x' - x`, `delta = x - x_prev`:
/// `[M - (2h/3) D - (4h^2/9) K] dx = M (delta/3 + h (8 v - 2 v_prev)/9)
///   + (4h^2/9)(f - D v) - (2h/9) D delta`,  `v' = (3 dx - delta) / (2h)`.
/// `f - D v` is the undamped force, since damping is linear in `v`.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Bdf2Scheme;

/// What distinguishes one single-Newton-iteration implicit scheme from
/// another: its linear system, its unknown, and how the unknown updates
/// the state. The implicit integrators ([`super`]) do the rest.
pub(crate) trait Linearised {
    /// Fills the scheme's auxiliary vectors from the state.
    fn prepare(&self, state: &ClothState, h: f64, aux: &mut [Vec3], aux2: &mut [Vec3]);
    /// The system's coefficients and right-hand-side terms.
    fn terms<'a>(&self, state: &'a ClothState, aux: &'a [Vec3], aux2: &'a [Vec3], h: f64) -> SystemTerms<'a>;
    /// The unknown of particle `i` when its position at `t + h` is `target`.
    fn pinned(&self, state: &ClothState, h: f64, target: Vec3, i: usize) -> Vec3;
    /// Initial PCG guess for particle `i` (from the state only, so a
    /// restored snapshot solves from the same guess).
    fn guess(&self, state: &ClothState, aux: &[Vec3], i: usize) -> Vec3;
    /// New `(x, v)` of particle `i` from the solved unknown.
    fn advance(&self, state: &ClothState, aux: &[Vec3], h: f64, i: usize, unknown: Vec3) -> (Vec3, Vec3);
    /// For a Newton correction at iterate `u`: the `y` of the `M y` term of
    /// the negative residual, particle `i`.
    fn newton_mass_term(&self, aux2: &[Vec3], i: usize, u: Vec3) -> Vec3;
    /// The time over which a force acting during the step changes the new
    /// velocity, s (`h` for backward Euler, `2h/3` for BDF2); also the
    /// position change per velocity change of the new state.
    fn response_time(&self, h: f64) -> f64;
    /// The coefficient `c_f` of the forces in the step equation
    /// `M (u - y0) = c_f f(x(u), v(u))` (`h` for backward Euler, `4h^2/9`
    /// for BDF2), s or s^2.
    fn force_coefficient(&self, h: f64) -> f64;
    /// `dx'/du`: how the new positions move with the unknown (`h`, `1`).
    fn position_per_unknown(&self, h: f64) -> f64;
    /// `dv'/du`: how the new velocities move with the unknown (`1`, `3/(2h)`).
    fn velocity_per_unknown(&self, h: f64) -> f64;
    /// The system of a Newton correction at an iterate with velocities `v_k`
    /// (positions are passed to the assembly): same matrix, right-hand side
    /// the negative residual `c_f f(x_k, v_k) + M y`.
    fn newton_terms<'a>(&self, h: f64, v_k: &'a [Vec3], y: &'a [Vec3], stitches_closed: &'a [bool]) -> SystemTerms<'a>;
}

impl Linearised for EulerScheme {
    fn prepare(&self, _: &ClothState, _: f64, _: &mut [Vec3], _: &mut [Vec3]) {}

    fn terms<'a>(&self, state: &'a ClothState, _: &'a [Vec3], _: &'a [Vec3], h: f64) -> SystemTerms<'a> {
        let v = &state.v;
        let closed = &state.stitches_closed;
        SystemTerms { k_times: Some((h * h, v)), d_times: Some((h, v)), ..SystemTerms::new(h * h, h, h, closed) }
    }

    /// `dv = (p(t + h) - x) / h - v`.
    fn pinned(&self, state: &ClothState, h: f64, target: Vec3, i: usize) -> Vec3 {
        (target - state.x[i]) / h - state.v[i]
    }

    /// The previous change of velocity.
    fn guess(&self, state: &ClothState, _: &[Vec3], i: usize) -> Vec3 {
        if state.has_history { state.v[i] - state.v_prev[i] } else { Vec3::zeros() }
    }

    fn advance(&self, state: &ClothState, _: &[Vec3], h: f64, i: usize, dv: Vec3) -> (Vec3, Vec3) {
        let v = state.v[i] + dv;
        (state.x[i] + v * h, v)
    }

    fn response_time(&self, h: f64) -> f64 {
        h
    }

    fn force_coefficient(&self, h: f64) -> f64 {
        h
    }

    fn position_per_unknown(&self, h: f64) -> f64 {
        h
    }

    fn velocity_per_unknown(&self, _: f64) -> f64 {
        1.0
    }

    /// Residual `M dv - h f(x + h (v + dv), v + dv)`: `y = -dv`.
    fn newton_mass_term(&self, _: &[Vec3], _: usize, dv: Vec3) -> Vec3 {
        -dv
    }

    fn newton_terms<'a>(&self, h: f64, v_k: &'a [Vec3], y: &'a [Vec3], closed: &'a [bool]) -> SystemTerms<'a> {
        SystemTerms { d_times: Some((h, v_k)), mass_times: Some(y), ..SystemTerms::new(h * h, h, h, closed) }
    }
}

impl Linearised for Bdf2Scheme {
    /// `aux = delta = x - x_prev`; `aux2 = delta/3 + h (8 v - 2 v_prev)/9`.
    fn prepare(&self, state: &ClothState, h: f64, aux: &mut [Vec3], aux2: &mut [Vec3]) {
        for i in 0..state.len() {
            let delta = state.x[i] - state.x_prev[i];
            aux[i] = delta;
            aux2[i] = delta / 3.0 + (state.v[i] * 8.0 - state.v_prev[i] * 2.0) * (h / 9.0);
        }
    }

    fn terms<'a>(&self, state: &'a ClothState, aux: &'a [Vec3], aux2: &'a [Vec3], h: f64) -> SystemTerms<'a> {
        SystemTerms {
            d_times: Some((-2.0 * h / 9.0, aux)),
            mass_times: Some(aux2),
            ..SystemTerms::new(4.0 * h * h / 9.0, 2.0 * h / 3.0, 4.0 * h * h / 9.0, &state.stitches_closed)
        }
    }

    /// `dx = p(t + h) - x`.
    fn pinned(&self, state: &ClothState, _: f64, target: Vec3, i: usize) -> Vec3 {
        target - state.x[i]
    }

    /// The previous displacement.
    fn guess(&self, _: &ClothState, aux: &[Vec3], i: usize) -> Vec3 {
        aux[i]
    }

    fn advance(&self, state: &ClothState, aux: &[Vec3], h: f64, i: usize, dx: Vec3) -> (Vec3, Vec3) {
        (state.x[i] + dx, (dx * 3.0 - aux[i]) / (2.0 * h))
    }

    /// `v' = (3 dx - delta) / (2h)` and `dx` moves by `(4h^2/9) f / m`.
    fn response_time(&self, h: f64) -> f64 {
        2.0 * h / 3.0
    }

    fn force_coefficient(&self, h: f64) -> f64 {
        4.0 * h * h / 9.0
    }

    fn position_per_unknown(&self, _: f64) -> f64 {
        1.0
    }

    fn velocity_per_unknown(&self, h: f64) -> f64 {
        1.5 / h
    }

    /// Residual `M (dx - y0) - (4h^2/9) f(x + dx, v'(dx))` with `y0 = aux2`: `y = y0 - dx`.
    fn newton_mass_term(&self, aux2: &[Vec3], i: usize, dx: Vec3) -> Vec3 {
        aux2[i] - dx
    }

    fn newton_terms<'a>(&self, h: f64, v_k: &'a [Vec3], y: &'a [Vec3], closed: &'a [bool]) -> SystemTerms<'a> {
        let c = 4.0 * h * h / 9.0;
        SystemTerms { d_times: Some((c, v_k)), mass_times: Some(y), ..SystemTerms::new(c, 2.0 * h / 3.0, c, closed) }
    }
}
