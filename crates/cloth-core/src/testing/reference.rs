//! Analytic references the tests and studies measure the simulator against.
//!
//! ## Peirce's cantilever (ASTM D1388)
//! A strip of flexural rigidity `B` (N m) and areal density `rho` (kg/m^2),
//! clamped horizontal, overhangs a length `l` and bends under its own
//! weight. Its centre line is the heavy elastica: with `theta(s)` the angle
//! below horizontal at arc length `s` from the clamp, the moment balance
//! `B theta'(s) = M(s)` and `M'(s) = -rho g (l - s) cos theta` give
//!
//! `theta'' = -(l - s) cos(theta) / c^3`, `theta(0) = 0`, `theta'(l) = 0`,
//!
//! with the bending length `c = (B / (rho g))^(1/3)` (Peirce 1930). The shape
//! depends on `l / c` alone. [`heavy_elastica`] solves this two-point
//! problem by shooting on the clamp curvature `theta'(0)` (classical
//! Runge-Kutta in `s`, bisection on the end condition); nothing is
//! tabulated. At `l / c = 2` the tip drops `1.2815 c` and the chord from
//! clamp to tip falls `41.49` degrees below horizontal.
//!
//! ## A strip hanging under its weight
//! A strip of length `L` (m), areal density `rho` and uniaxial modulus `E`
//! (N/m) hangs from its top edge. The tension per width at a distance `s`
//! below the top is `rho g (L - s)` in the reference length, so a Hookean
//! strip (stress proportional to engineering strain) stretches by
//! `eps(s) = rho g (L - s) / E` and its bottom drops `rho g L^2 / (2 E)
//! = eps_top L / 2`, at any strain. [`HangingStrip`] picks `rho` for a
//! given strain at the top; [`settle`] finds the static shape.

/// The heavy elastica of one overhang, in units of the bending length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Elastica {
    /// Overhang over bending length, `l / c`.
    pub overhang: f64,
    /// Tip's horizontal distance from the clamp over `c`.
    pub tip_x: f64,
    /// Tip's drop below the clamp over `c`.
    pub tip_drop: f64,
    /// Clamp curvature times `c`.
    pub clamp_curvature: f64,
}

impl Elastica {
    /// Angle of the chord from clamp to tip below horizontal, degrees.
    pub fn chord_angle_deg(&self) -> f64 {
        chord_angle_deg(self.tip_x, self.tip_drop)
    }
}

/// Angle below horizontal of the chord to a tip `tip_x` along and
/// `tip_drop` below the clamp (any one unit), degrees.
fn chord_angle_deg(tip_x: f64, tip_drop: f64) -> f64 {
    tip_drop.atan2(tip_x).to_degrees()
}

/// Bending length `c = (B / (rho g))^(1/3)`, m, of a strip of flexural
/// rigidity `b` (N m) and areal density `rho` (kg/m^2) under gravity `g`
/// (m/s^2).
pub fn bending_length(b: f64, rho: f64, g: f64) -> f64 {
    (b / (rho * g)).cbrt()
}

/// Runge-Kutta steps along the overhang: the tip position's error is below
/// 1e-12 of `c` for `l / c <= 4` (halving the step changes it less).
const ELASTICA_STEPS: usize = 4000;

/// The heavy elastica of overhang `l / c = overhang` (> 0), by shooting.
pub fn heavy_elastica(overhang: f64) -> Elastica {
    // State (theta, theta', x, z) against s, all over c.
    let rhs = |s: f64, y: [f64; 4]| -> [f64; 4] {
        let (sin, cos) = y[0].sin_cos();
        [y[1], -(overhang - s) * cos, cos, sin]
    };
    let shoot = |kappa0: f64| -> [f64; 4] {
        let h = overhang / ELASTICA_STEPS as f64;
        let mut y = [0.0, kappa0, 0.0, 0.0];
        let axpy = |y: [f64; 4], a: f64, k: [f64; 4]| std::array::from_fn(|i| y[i] + a * k[i]);
        for n in 0..ELASTICA_STEPS {
            let s = n as f64 * h;
            let k1 = rhs(s, y);
            let k2 = rhs(s + h / 2.0, axpy(y, h / 2.0, k1));
            let k3 = rhs(s + h / 2.0, axpy(y, h / 2.0, k2));
            let k4 = rhs(s + h, axpy(y, h, k3));
            y = std::array::from_fn(|i| y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
        }
        y
    };
    // theta'(l) grows with the clamp curvature: negative at 0 (the strip
    // would curl up), positive at the moment of the horizontal strip.
    let (mut lo, mut hi) = (0.0, overhang * overhang / 2.0 * (1.0 + 1e-9));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if shoot(mid)[1] > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
        if hi - lo <= 1e-15 * hi {
            break;
        }
    }
    let kappa0 = 0.5 * (lo + hi);
    let end = shoot(kappa0);
    Elastica { overhang, tip_x: end[2], tip_drop: end[3], clamp_curvature: kappa0 }
}

/// A strip on the Peirce cantilever fixture (`fixtures/scenes/cantilever.toml`):
/// grid `spacing`, `overhang` and `width`, all m and multiples of the
/// spacing. Particle columns run from `x = -spacing` to `x = overhang`; the
/// first two columns are clamped, so the clamp line is `x = 0` and the
/// strip is horizontal there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CantileverStrip {
    /// Grid spacing, m.
    pub spacing: f64,
    /// Free length beyond the clamp line, m.
    pub overhang: f64,
    /// Strip width, m.
    pub width: f64,
}

/// Where a simulated strip's tip ended, against the clamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipMeasure {
    /// Horizontal distance of the tip (mean of the last column) from the clamp line, m.
    pub tip_x: f64,
    /// Drop of the tip below the clamp, m.
    pub tip_drop: f64,
}

impl TipMeasure {
    /// Angle of the chord from clamp to tip below horizontal, degrees.
    pub fn chord_angle_deg(&self) -> f64 {
        chord_angle_deg(self.tip_x, self.tip_drop)
    }
}

impl CantileverStrip {
    /// Height of the clamp (the strip's rest plane), m.
    pub const CLAMP_Z: f64 = 0.5;

    /// Particles along the strip and across it.
    pub fn particles(&self) -> [usize; 2] {
        let cells = |len: f64| (len / self.spacing).round() as usize;
        [cells(self.overhang) + 2, cells(self.width) + 1]
    }

    /// Scene overrides that turn the cantilever fixture into this strip.
    pub fn overrides(&self) -> Vec<String> {
        let [nx, ny] = self.particles();
        let clamp: Vec<String> = (0..2).flat_map(|i| (0..ny).map(move |j| format!("[{i}, {j}]"))).collect();
        vec![
            format!("panels.0.particles=[{nx}, {ny}]"),
            format!("panels.0.size_m=[{}, {}]", self.overhang + self.spacing, self.width),
            format!("panels.0.origin_m=[{}, {}, {}]", -self.spacing, -self.width / 2.0, Self::CLAMP_Z),
            format!("pins.0.nodes=[{}]", clamp.join(", ")),
        ]
    }

    /// The tip of positions `x` (the strip's particles, row-major), against
    /// the clamp.
    pub fn measure(&self, x: &[crate::Vec3]) -> TipMeasure {
        let [nx, ny] = self.particles();
        let tip = (0..ny).map(|j| x[j * nx + nx - 1]).sum::<crate::Vec3>() / ny as f64;
        TipMeasure { tip_x: tip.x, tip_drop: Self::CLAMP_Z - tip.z }
    }

    /// The exact shape of this strip when made of `model`'s material under
    /// its gravity, and the bending length `c` (m) its values are in units of.
    pub fn exact(&self, model: &crate::ClothModel) -> (Elastica, f64) {
        let m = model.material();
        let g = model.effects().gravity.map_or(0.0, |g| g.norm());
        let c = bending_length(m.flexural_rigidity_n_m, m.areal_density_kg_m2, g);
        (heavy_elastica(self.overhang / c), c)
    }
}

/// A vertical strip `size_m` (width, length; m) of `particles` (across,
/// along) hanging from its pinned top row under `g = 9.81 m/s^2`, loaded
/// so that its top is strained by `top_strain` in a Hookean strip of the
/// material's `tensile_stiffness_n_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HangingStrip {
    /// Particles across and along the strip.
    pub particles: [usize; 2],
    /// Width and length, m.
    pub size_m: [f64; 2],
    /// Strain at the top of a Hookean strip, dimensionless.
    pub top_strain: f64,
}

impl HangingStrip {
    /// Gravitational acceleration, m/s^2.
    pub const G: f64 = 9.81;

    /// The areal density (kg/m^2) that strains the top by
    /// [`HangingStrip::top_strain`]: `eps E / (g L)`.
    pub fn areal_density(&self, tensile_stiffness_n_m: f64) -> f64 {
        self.top_strain * tensile_stiffness_n_m / (Self::G * self.size_m[1])
    }

    /// The strip as a model of `kind` and `material` (its areal density
    /// set by [`HangingStrip::areal_density`]), with gravity and bending.
    pub fn model(&self, kind: crate::ModelKind, material: crate::Material) -> crate::ClothModel {
        let material =
            crate::Material { areal_density_kg_m2: self.areal_density(material.tensile_stiffness_n_m), ..material };
        let effects = crate::Effects {
            gravity: Some(crate::Vec3::new(0.0, 0.0, -Self::G)),
            bending: true,
            ..crate::Effects::default()
        };
        crate::ClothModel::build(&crate::ModelSpec {
            kind,
            panels: vec![crate::GridPanel {
                particles: self.particles,
                size_m: self.size_m,
                origin_m: [0.0, 0.0, 0.0],
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 0.0, -1.0],
                wrap_u: false,
            }],
            material,
            pins: vec![crate::PinSpec { edge: Some(crate::Edge::JMin), ..crate::PinSpec::default() }],
            effects,
            ..crate::ModelSpec::default()
        })
        .expect("a hanging strip of valid constants builds")
    }

    /// The Hookean strip's drop of its bottom edge, m: `eps_top L / 2`.
    pub fn exact_sag(&self) -> f64 {
        self.top_strain * self.size_m[1] / 2.0
    }

    /// The mean drop of the bottom row from `rest` to `x`, m.
    pub fn sag(&self, rest: &[crate::Vec3], x: &[crate::Vec3]) -> f64 {
        let [nu, nv] = self.particles;
        let bottom = (nv - 1) * nu..nv * nu;
        bottom.map(|i| rest[i].z - x[i].z).sum::<f64>() / nu as f64
    }

    /// The settled strip's sag against [`HangingStrip::exact_sag`], as a
    /// fraction (`+0.32`: 32% too far).
    pub fn sag_error(&self, kind: crate::ModelKind, material: crate::Material) -> f64 {
        let model = self.model(kind, material);
        let rest = model.rest_positions().to_vec();
        let x = settle(model, crate::PreconditionerKind::BlockJacobi);
        self.sag(&rest, &x) / self.exact_sag() - 1.0
    }
}

/// A step that moves no particle farther than this has reached statics, m.
const STILL_M: f64 = 1e-12;

/// The static shape of `model` under its loads: backward Euler steps of
/// 1 s with Newton iterations to 1e-10 m (and PCG to 1e-10 with
/// `preconditioner`) until a step moves no particle by 1e-12 m, 20 at
/// most (a hanging strip gets there in about 8).
pub fn settle(model: crate::ClothModel, preconditioner: crate::PreconditionerKind) -> Vec<crate::Vec3> {
    let solver = crate::SolverParams {
        rel_tol: 1e-10,
        preconditioner,
        newton: crate::NewtonParams { iterations: 50, tolerance_m: 1e-10, ..Default::default() },
        ..crate::SolverParams::default()
    };
    let mut sim = crate::Simulation::new(model, crate::IntegratorKind::BackwardEuler, solver);
    for _ in 0..20 {
        sim.step(1.0).expect("a hanging cloth settles");
        let state = sim.state();
        if state.x.iter().zip(&state.x_prev).all(|(x, before)| (x - before).norm() < STILL_M) {
            break;
        }
    }
    sim.state().x.clone()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small overhangs: the linear cantilever under uniform load,
    /// `drop = l^4 / (8 c^3)`, clamp curvature `l^2 / 2`.
    #[test]
    fn short_overhang_is_the_linear_cantilever() {
        let e = heavy_elastica(0.1);
        assert!((e.tip_drop / (0.1f64.powi(4) / 8.0) - 1.0).abs() < 1e-3, "{e:?}");
        assert!((e.clamp_curvature / 0.005 - 1.0).abs() < 1e-3);
    }

    /// The figures (l / c = 2: drop 6.41 cm and 41.5 degrees at
    /// c = 5 cm), and the end condition met.
    #[test]
    fn peirce_overhang_of_two_bending_lengths() {
        let e = heavy_elastica(2.0);
        assert!((e.tip_drop * 0.05 - 0.0641).abs() < 5e-5, "{e:?}");
        assert!((e.chord_angle_deg() - 41.49).abs() < 0.01, "{}", e.chord_angle_deg());
    }
}
