//! Contact laws as pure functions (sign convention of [`crate::laws`]):
//! the squeeze between two solids, sliding friction, the Newton path's
//! contact penalty and the smoothed Coulomb friction of IPC (Li et al. 2020).

use crate::{Mat3, Vec3};

/// Stiffness of a squeezed contact per unit particle mass and per `1/h^2`:
/// the pressing solid meets a particle `SQUEEZE` times stiffer than the
/// particle's own inertia over one step (`m / h^2`). Any value gives the
/// same forces once a coupled step converges (the overlap adjusts); this
/// one keeps the overlap below a thousandth of the load's free-fall
/// distance over a step and an explicitly coupled body of the particle's
/// mass stable (`k h^2 / m < 4` fails only for bodies 25 times lighter
/// than the particles they press).
pub(crate) const SQUEEZE: f64 = 100.0;

/// Force with which a solid presses a particle that a solid on the other
/// side holds (N, >= 0): a penalty `f = k max(0, e - g)` on the particle's
/// gap `g` (m) to the pressing solid below the thickness `e` (m), with
/// `k = SQUEEZE m / h^2` (N/m) for particle mass `m` (kg) and step `h`
/// (s). Choi & Ko (2002, §5) hold particles on solids with constraints;
/// a particle between two solids (their normals opposite) can only be
/// held by one, and the other's push must be a force the holding solid
/// carries (Baraff & Witkin 1998 filter one direction once).
pub fn squeeze_force(gap_m: f64, thickness_m: f64, mass_kg: f64, h: f64) -> f64 {
    SQUEEZE * mass_kg / (h * h) * (thickness_m - gap_m).max(0.0)
}

/// The overlap (m) behind a squeezed contact's force `force_n` (N) on a
/// particle of mass `mass_kg` (kg) at step `h` (s): [`squeeze_force`]'s
/// `max(0, e - g)` back from its force.
pub(crate) fn squeeze_overlap(force_n: f64, mass_kg: f64, h: f64) -> f64 {
    force_n.max(0.0) * h * h / (SQUEEZE * mass_kg)
}

/// Slip speed above which a squeezed particle's friction goes into the
/// solve (m/s); slower ones stick or slip under `apply_friction` alone.
/// Sliding friction linearised near the point of sticking overshoots and
/// reverses: on the tablecloth fixture pulled slowly (0.1 m/s), a
/// threshold of 1 cm/s let the box alternate between slipping forwards
/// and back and lag 3 cm after 1 s; at 5 cm/s it follows within 5 mm.
pub(crate) const SLIDE_SPEED: f64 = 5e-2;

/// Coulomb friction of a sliding contact (Choi & Ko 2002, §5): the force
/// `f = -mu N u` against the slip direction `u = w / |w|` (`w` the slip
/// velocity in the tangent plane, m/s), with `limit = mu N` (N).
pub fn sliding_friction(slip: Vec3, limit_n: f64) -> Vec3 {
    -slip * (limit_n / slip.norm())
}

/// `-d f / d w` of [`sliding_friction`] within the tangent plane `P`
/// (projector), N s/m: `limit / |w| (P - u u^T)`. The force keeps its
/// magnitude and only turns with the slip.
pub(crate) fn sliding_friction_damping(slip: Vec3, limit_n: f64, tangent: &Mat3) -> Mat3 {
    let speed = slip.norm();
    let u = slip / speed;
    (tangent - u * u.transpose()) * (limit_n / speed)
}

/// Stiffness of a solid's penalty on a particle in Newton iterations, per
/// unit particle mass and per `1/h^2`: a particle meets the solid this
/// many times stiffer than its own inertia over one step (`m / h^2`). At
/// rest under its weight it sinks `g h^2 / CONTACT_PENALTY` into the
/// thickness: 0.4 mm at `h = 0.2 s`, a micrometre at 1/90 s. The
/// penalty adds `(4/9) CONTACT_PENALTY` times the mass to the matrix
/// diagonal (BDF2), which the block preconditioner takes in its stride.
pub(crate) const CONTACT_PENALTY: f64 = 1e3;

/// The penalty stiffness `k = CONTACT_PENALTY m / h^2` of a solid on a
/// particle of mass `m` (kg) in a step `h` (s), N/m.
pub fn contact_penalty_stiffness(mass_kg: f64, h: f64) -> f64 {
    CONTACT_PENALTY * mass_kg / (h * h)
}

/// A solid's penalty on a particle at gap `g` (m) from its surface, below
/// the contact thickness `e` (m): energy `k/2 (e - g)^2` (J), force
/// `k (e - g)` along the outward normal (N); zero beyond `e`. A penalty in
/// an implicit step's incremental potential, where Choi & Ko (2002, §5)
/// hold particles with constraints (see the `newton` module for why).
pub fn contact_penalty(gap_m: f64, thickness_m: f64, stiffness_n_m: f64) -> (f64, f64) {
    let depth = (thickness_m - gap_m).max(0.0);
    (0.5 * stiffness_n_m * depth * depth, stiffness_n_m * depth)
}

/// Slip speed below which [`smoothed_friction`] turns viscous, m/s. A
/// particle held by static friction creeps at most half of it while the
/// Newton iterations run; `apply_friction` then stops it exactly.
pub const FRICTION_SMOOTHING_M_S: f64 = 1e-3;

/// `F0(s)` of the smoothed Coulomb dissipation potential (Li et al. 2020,
/// "Incremental Potential Contact", §5.1), m/s: `s` for `s >= eps`,
/// `-s^3 / (3 eps^2) + s^2 / eps + eps / 3` below (C^1 at `eps`, convex).
pub(crate) fn smoothed_slip(s: f64, eps: f64) -> f64 {
    if s >= eps { s } else { -s * s * s / (3.0 * eps * eps) + s * s / eps + eps / 3.0 }
}

/// The dissipation potential of a contact's Coulomb friction, W:
/// `D(w) = mu N F0(|w|)` for the slip velocity `w` (m/s, in the tangent
/// plane) with `limit = mu N` (N). Its negative gradient is
/// [`smoothed_friction`]'s force.
pub fn smoothed_friction_potential(slip: Vec3, limit_n: f64, eps: f64) -> f64 {
    limit_n * smoothed_slip(slip.norm(), eps)
}

/// Coulomb friction smoothed at small slip (Li et al. 2020, §5.1):
/// `f = -mu N f1(s) w / s`, `s = |w|`, with `f1(s) = 1` for `s >= eps`
/// (Coulomb's sliding friction, [`sliding_friction`]) and
/// `2 s / eps - s^2 / eps^2` below (viscous at rest: `-2 mu N w / eps`).
/// Returns the force (N) and `C = -df/dv` within the tangent plane `P`
/// (projector), N s/m: `mu N [f1/s (P - u u^T) + f1' u u^T]`, `u = w / s`,
/// positive semidefinite. `limit = mu N`, N; `eps`, m/s.
pub fn smoothed_friction(slip: Vec3, limit_n: f64, eps: f64, tangent: &Mat3) -> (Vec3, Mat3) {
    let s = slip.norm();
    if s >= eps {
        return (sliding_friction(slip, limit_n), sliding_friction_damping(slip, limit_n, tangent));
    }
    let (f1_over_s, df1) = (2.0 / eps - s / (eps * eps), 2.0 / eps - 2.0 * s / (eps * eps));
    let uu = if s > 0.0 { slip * slip.transpose() / (s * s) } else { Mat3::zeros() };
    let damping = ((tangent - uu) * f1_over_s + uu * df1) * limit_n;
    (-slip * (limit_n * f1_over_s), damping)
}
