//! Interaction laws: small pure functions, one per law, each with its formula
//! and source. The force terms that apply them are in [`crate::terms`].
//!
//! Convention for a pair `(i, j)`: `x_ij = x_j - x_i`, `d = |x_ij|`,
//! `u = x_ij / d`, `P = u u^T`. A central law with energy `E(d)` has
//! `phi(d) = dE/dd`, force on `i` `f_i = phi u` (positive `phi` pulls `i`
//! towards `j`), `f_j = -f_i`, and
//! `df_i/dx_j = phi' P + (phi / d)(I - P)` (`df_i/dx_i = -df_i/dx_j`).

use crate::{Mat3, Vec3};
use std::f64::consts::PI;

/// A central pair law evaluated at one chord length: energy (J), force
/// magnitude `phi = dE/dd` (N) and its derivative `dphi = d phi / dd` (N/m).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ScalarLaw {
    /// Energy stored in the pair, J.
    pub energy: f64,
    /// `phi = dE/dd`, N (positive: attraction).
    pub phi: f64,
    /// `d phi / dd`, N/m.
    pub dphi: f64,
}

/// Type-1 spring with a compressive stiffness of its own:
/// `E = k (d - L)^2 / 2`, `phi = k (d - L)` with `k = k_s` for `d >= L` and
/// `k = k_c` below. `k_c = 0` is Choi & Ko's tension-only type-1 spring
/// (Eq. 2-3): in compression a linear spring's orthogonal stiffness
/// `k_s (1 - L/d)` would be negative and unbounded, and their type-2 ramp
/// `c_b (L - d)` (Eq. 11) holds the membrane's compression. (With the
/// arc-path law the type-1 links take that ramp's role through
/// [`BucklingLaw`] instead, `crate::Compression`.) `k_c = k_s` is Provot's
/// linear spring.
///
/// `d`, `rest` in m; `k_s`, `k_c` in N/m.
pub fn bilinear_spring(d: f64, rest: f64, k_s: f64, k_c: f64) -> ScalarLaw {
    linear_spring(d, rest, if d >= rest { k_s } else { k_c })
}

/// Linear spring in tension and compression (Provot 1995):
/// `E = k (d - L)^2 / 2`, `phi = k (d - L)`.
pub fn linear_spring(d: f64, rest: f64, k: f64) -> ScalarLaw {
    let e = d - rest;
    ScalarLaw { energy: 0.5 * k * e * e, phi: k * e, dphi: k }
}

/// `sinc(t) = sin(t) / t` (1 at 0).
pub fn sinc(t: f64) -> f64 {
    if t.abs() < 1e-4 { 1.0 - t * t / 6.0 * (1.0 - t * t / 20.0) } else { t.sin() / t }
}

/// `g(t) = cos t - sinc t` (negative on (0, pi]), accurate for small `t`.
fn cos_minus_sinc(t: f64) -> f64 {
    if t.abs() <= 0.1 {
        let t2 = t * t;
        // -t^2/3 (1 - t^2/10 + t^4/280 - t^6/15120)
        -t2 / 3.0 * (1.0 - t2 / 10.0 * (1.0 - t2 / 28.0 * (1.0 - t2 / 54.0)))
    } else {
        t.cos() - t.sin() / t
    }
}

/// `h(t) = 3 g(t) + t sin t`, accurate for small `t` (it is O(t^4)).
fn three_g_plus_t_sin(t: f64) -> f64 {
    if t.abs() <= 0.1 {
        let t2 = t * t;
        // -t^4/15 + t^6/210 - t^8/7560 + t^10/498960
        -t2 * t2 / 15.0 * (1.0 - t2 / 14.0 * (1.0 - t2 / 36.0 * (1.0 - t2 / 66.0)))
    } else {
        3.0 * cos_minus_sinc(t) + t * t.sin()
    }
}

/// `(g(t), h(t))`: [`cos_minus_sinc`] and [`three_g_plus_t_sin`] bit for
/// bit, from one sine and cosine (each function alone takes its own).
fn arc_g_h(t: f64) -> (f64, f64) {
    if t.abs() <= 0.1 {
        return (cos_minus_sinc(t), three_g_plus_t_sin(t));
    }
    let (sin, cos) = t.sin_cos();
    let g = cos - sin / t;
    (g, 3.0 * g + t * sin)
}

/// Where `1 - sinc t` stops increasing: `s* = 1 - sinc(t*)` at the first
/// positive root `t* = 4.4934...` of `tan t = t`.
const INVERSE_SINC_BRANCH: f64 = 1.217_233_628_211_221_7;
/// `sqrt(s* - 1)` and `sqrt(s*)`: the range of `w = sqrt(s* - s)` over
/// `s` in `[0, 1]`.
const INVERSE_SINC_W: (f64, f64) = (0.466_083_284_629_712_55, 1.103_283_113_353_604);
/// Chebyshev coefficients of `q(w) = t / sqrt(6 s)`, `s = s* - w^2`, over
/// `INVERSE_SINC_W` (interpolated at 17 Chebyshev points in 50-digit
/// arithmetic).
const INVERSE_SINC_CHEBYSHEV: [f64; 17] = [
    1.130_855_547_248_207_6,
    -0.140_451_945_143_299_5,
    0.010_351_690_318_310_819,
    -8.172_398_863_615_369e-4,
    6.718_061_781_071_42e-5,
    -5.686_032_996_711_038_5e-6,
    4.929_186_778_640_872e-7,
    -4.365_185_600_755_674e-8,
    3.943_543_995_409_474e-9,
    -3.631_342_419_884_041e-10,
    3.406_209_105_023_994e-11,
    -3.252_540_088_412_569_5e-12,
    3.159_315_542_352_078e-13,
    -3.118_768_405_312_693e-14,
    3.125_535_090_985_239_5e-15,
    -3.175_743_256_868_732e-16,
    3.232_734_958_654_81e-17,
];

/// Below this `s = 1 - sinc t`, [`inverse_sinc`] takes `t^2` from its
/// power series in `s`.
const SMALL_ARC_S: f64 = 0.01;
/// `t^2 = sum_k b_k s^k`, `k = 1..8`, the reversion of
/// `s = t^2/3! - t^4/5! + t^6/7! - ...` (exact fractions: 6, 9/5, 144/175,
/// 78/175, 89226/336875, ...). The next term is below 1e-18 of the first
/// for `s <= SMALL_ARC_S`.
const SMALL_ARC_SERIES: [f64; 8] = [
    6.0,
    9.0 / 5.0,
    144.0 / 175.0,
    78.0 / 175.0,
    89226.0 / 336875.0,
    522063.0 / 3128125.0,
    83924688.0 / 766390625.0,
    438337548.0 / 5922109375.0,
];

/// Solves `sinc(t) = r` for `t` in `[0, pi]`, given `s = 1 - r` in `[0, 1]`
/// (passing `1 - r` keeps full precision when `r` is close to 1).
///
/// Two series, no trigonometric function and no iteration (the Newton
/// solve they replace took 3-5 sines and cosines a call, 8-10% of a
/// crumpled cloth's step):
/// - up to `SMALL_ARC_S`, `t^2` as a power series in `s`;
/// - above, `t = sqrt(6 s) q(w)` with `w = sqrt(s* - s)`. The inverse's
///   only singularities near `[0, 1]` are the square roots at `s = 0`
///   (`t^2 = 6 s + ...`) and at the branch point `s* = 1.2172` where
///   `d sinc / dt = 0`, so `q` is analytic in `w`, and a degree-16
///   Chebyshev series gives it to about 2 ulp.
///
/// `t` is within 1e-15 relative of 40-digit roots over `s` in `(0, 1)`.
pub fn inverse_sinc(s: f64) -> f64 {
    if s.is_nan() || s <= 0.0 {
        return 0.0;
    }
    if s >= 1.0 {
        return PI;
    }
    if s <= SMALL_ARC_S {
        // t^2 as a series in s: cheaper than the Chebyshev series where
        // most links of a cloth at rest are, barely compressed.
        let t2 = s * SMALL_ARC_SERIES.iter().rev().fold(0.0, |acc, &b| b + s * acc);
        return t2.sqrt();
    }
    let (lo, hi) = INVERSE_SINC_W;
    let w = (INVERSE_SINC_BRANCH - s).sqrt();
    let x = (2.0 * w - lo - hi) / (hi - lo);
    // Clenshaw's recurrence.
    let (mut b1, mut b2) = (0.0_f64, 0.0_f64);
    for &c in INVERSE_SINC_CHEBYSHEV[1..].iter().rev() {
        (b1, b2) = (c + 2.0 * x * b1 - b2, b1);
    }
    let q = INVERSE_SINC_CHEBYSHEV[0] + x * b1 - b2;
    ((6.0 * s).sqrt() * q).min(PI)
}

/// Circular-arc post-buckling law, Choi & Ko (2002) §3.2 ("type 2"): the
/// beam of arc length `L` between two particles bends into a circular arc
/// of curvature `kappa` with chord `d`, `d / L = sinc(kappa L / 2)`;
/// `E = k_b L kappa^2 / 2` and
/// `phi = f_b(d) = k_b kappa^2 / (cos(kappa L/2) - sinc(kappa L/2))` (< 0, repulsive),
/// with `f_b -> -12 k_b / L^2` as `d -> L` and `-4 pi^2 k_b / L^2` as `d -> 0`.
/// Zero for `d >= L`.
///
/// `d`, `rest` in m; `k_b` (flexural rigidity of the link) in N m^2.
pub fn buckling_arc(d: f64, rest: f64, k_b: f64) -> ScalarLaw {
    let Some(t) = arc_half_angle(d, rest) else {
        return ScalarLaw::default();
    };
    let energy = arc_energy(t, rest, k_b);
    if t < 1e-6 {
        return ScalarLaw { energy, ..buckling_arc_onset(rest, k_b) };
    }
    let (g, h) = arc_g_h(t);
    let l2 = rest * rest;
    // phi = (4 k_b / L^2) t^2 / g, and with dd/dt = L g / t:
    // dphi/dd = (4 k_b / L^3) t^2 (3 g + t sin t) / g^3.
    ScalarLaw { energy, phi: 4.0 * k_b / l2 * t * t / g, dphi: 4.0 * k_b / (l2 * rest) * t * t * h / (g * g * g) }
}

/// [`buckling_arc`]'s energy alone, J, bit for bit: an energy monitor or
/// a line search needs no force, and skips the force's and the
/// stiffness's trigonometric functions.
pub fn buckling_arc_energy(d: f64, rest: f64, k_b: f64) -> f64 {
    arc_half_angle(d, rest).map_or(0.0, |t| arc_energy(t, rest, k_b))
}

/// The arc's half angle `t = kappa L / 2` at chord `d < L` (m), from
/// `sinc(t) = d / L`; `None` for `d >= L`.
fn arc_half_angle(d: f64, rest: f64) -> Option<f64> {
    (d < rest).then(|| inverse_sinc(((rest - d) / rest).min(1.0)))
}

/// `E = k_b L kappa^2 / 2` with `kappa = 2 t / L`, J.
fn arc_energy(t: f64, rest: f64, k_b: f64) -> f64 {
    let kappa = 2.0 * t / rest;
    0.5 * k_b * rest * kappa * kappa
}

/// The limits of [`buckling_arc`] as `d -> L` from below (zero energy):
/// `phi = -12 k_b / L^2`, `dphi = 7.2 k_b / L^3`.
pub fn buckling_arc_onset(rest: f64, k_b: f64) -> ScalarLaw {
    let l2 = rest * rest;
    ScalarLaw { energy: 0.0, phi: -12.0 * k_b / l2, dphi: 7.2 * k_b / (l2 * rest) }
}

/// Choi & Ko's final type-2 law (Eq. 11): the arc force capped by a linear
/// ramp, `|phi| = min(|f_b(d)|, c_b (L - d))` for `d < L`, zero for `d >= L`.
/// Real fabric deflects from the onset of load; the ramp removes the
/// arc law's jump to `-12 k_b / L^2` at `d = L`.
///
/// The two branches meet at a single chord `d_c` (where
/// `c_b (L - d_c) = |f_b(d_c)|`; the difference is strictly monotone since
/// both `c_b` and `d f_b/dd` are positive), found once at construction, so
/// an evaluation costs one comparison on the ramp and one inverse sinc on
/// the arc. The energy `E(d) = integral_d^L |phi|` is continuous at `d_c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BucklingLaw {
    /// Rest length (arc length), m.
    pub rest: f64,
    /// Link flexural rigidity, N m^2.
    pub k_b: f64,
    /// Ramp slope, N/m.
    pub c_b: f64,
    /// Switch chord `d_c`, m (0 when the ramp is weaker everywhere).
    pub switch: f64,
    /// Energy at the switch, J: `c_b (L - d_c)^2 / 2`.
    switch_energy: f64,
    /// Arc energy at the switch, J.
    switch_arc_energy: f64,
}

impl BucklingLaw {
    /// The law for one link; `rest` in m, `k_b` in N m^2, `c_b` in N/m.
    pub fn new(rest: f64, k_b: f64, c_b: f64) -> Self {
        let switch = ramp_switch_point(rest, k_b, c_b);
        Self {
            rest,
            k_b,
            c_b,
            switch,
            switch_energy: 0.5 * c_b * (rest - switch) * (rest - switch),
            switch_arc_energy: buckling_arc(switch, rest, k_b).energy,
        }
    }

    /// Energy, force magnitude and stiffness at chord `d` (m).
    #[inline]
    pub fn eval(&self, d: f64) -> ScalarLaw {
        if d >= self.rest {
            return ScalarLaw::default();
        }
        if d > self.switch {
            let e = self.rest - d;
            return ScalarLaw { energy: 0.5 * self.c_b * e * e, phi: -self.c_b * e, dphi: self.c_b };
        }
        let arc = buckling_arc(d, self.rest, self.k_b);
        ScalarLaw { energy: self.switch_energy + arc.energy - self.switch_arc_energy, ..arc }
    }
}

/// [`BucklingLaw::new`] remembered by its arguments' bits. A panel's links
/// share a few rest lengths and constants (3 distinct laws for the 257 x
/// 257 hanging cloth, 186 for the Table-1 one-piece's four panels), and
/// each law's switch point costs a bisection of some 50 arc solves:
/// building the 257 x 257 cloth spent 70% of its first step's run there
/// (the 513 x 513 one 20 s). The same arguments give the same law, so a
/// remembered one is the same bits.
#[derive(Debug, Default)]
pub(crate) struct BucklingLaws(std::collections::HashMap<[u64; 3], BucklingLaw>);

impl BucklingLaws {
    /// `BucklingLaw::new(rest, k_b, c_b)`, built once per distinct triple.
    pub(crate) fn law(&mut self, rest: f64, k_b: f64, c_b: f64) -> BucklingLaw {
        let key = [rest, k_b, c_b].map(f64::to_bits);
        *self.0.entry(key).or_insert_with(|| BucklingLaw::new(rest, k_b, c_b))
    }
}

/// [`BucklingLaw`] evaluated once, for callers with a single chord.
pub fn buckling_ramped(d: f64, rest: f64, k_b: f64, c_b: f64) -> ScalarLaw {
    BucklingLaw::new(rest, k_b, c_b).eval(d)
}

/// The chord `d_c` where the ramp `c_b (L - d)` meets `|f_b(d)|`, found by
/// bisection (the difference is strictly decreasing in `d`). Returns 0 when
/// the ramp stays below the arc force for every `d` in `[0, L]`.
fn ramp_switch_point(rest: f64, k_b: f64, c_b: f64) -> f64 {
    let excess = |d: f64| c_b * (rest - d) + buckling_arc(d, rest, k_b).phi;
    if excess(0.0) <= 0.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, rest);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if excess(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-15 * rest {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Self-collision repulsion between two pieces of cloth closer than the
/// thickness `h_c` (Choi & Ko 2002 §5 repel particle pairs closer than a
/// threshold without giving the law; this penalty is ours):
/// `E = k_r (h_c - d)^2 / 2`, `phi = -k_r (h_c - d)` (repulsive) for
/// `d < h_c`, zero beyond. Its orthogonal stiffness `phi/d` is negative,
/// so like type-2 links only `dphi P` goes into the matrix.
///
/// `d`, `thickness` in m; `k_r` in N/m.
pub fn repulsion(d: f64, thickness: f64, k_r: f64) -> ScalarLaw {
    if d >= thickness {
        return ScalarLaw::default();
    }
    let gap = thickness - d;
    ScalarLaw { energy: 0.5 * k_r * gap * gap, phi: -k_r * gap, dphi: k_r }
}

/// A seam's stitch ([`crate::SeamSpec`]): a thread of zero rest length whose
/// pull is capped at `pull` while the seam is open, so panels laid out
/// apart are drawn together at a bounded force (a garment tool's sewing):
/// `phi = min(k d, pull)`; `E = k d^2 / 2` for `d <= d_c = pull / k`,
/// `pull (d - d_c / 2)` beyond (continuous with its slope). Ours, not the
/// papers'. Closed, it is a linear spring, `df_i/dx_j = k I`.
///
/// `d` in m; `k` in N/m; `pull` in N.
pub fn stitch(d: f64, k: f64, pull: f64) -> ScalarLaw {
    let d_c = pull / k;
    if d <= d_c {
        ScalarLaw { energy: 0.5 * k * d * d, phi: k * d, dphi: k }
    } else {
        ScalarLaw { energy: pull * (d - 0.5 * d_c), phi: pull, dphi: 0.0 }
    }
}

/// The 3x3 block `df_i/dx_j` of a central law at `x_ij = d u`:
/// `dphi P + (phi/d)(I - P)`, or `dphi P` alone when `keep_orthogonal` is
/// false (Choi & Ko drop the orthogonal term of type-2 links from the system
/// matrix because `phi/d < 0` would make it indefinite; the force keeps it).
pub fn pair_stiffness(u: &Vec3, d: f64, law: &ScalarLaw, keep_orthogonal: bool) -> Mat3 {
    let p = u * u.transpose();
    if keep_orthogonal && d > 0.0 {
        let ortho = law.phi / d;
        p * (law.dphi - ortho) + Mat3::identity() * ortho
    } else {
        p * law.dphi
    }
}

/// Directional damping, Choi & Ko (2002) Eq. 13: `f_i = -k_d P (v_i - v_j)`,
/// only along the link, so out-of-plane motion is not filtered.
/// Returns `df_i/dv_j = k_d P`. `k_d` in N s/m.
pub fn directional_damping(u: &Vec3, k_d: f64) -> Mat3 {
    u * u.transpose() * k_d
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `1 - sinc(t)`, accurate for small `t` (series below 0.1).
    fn one_minus_sinc(t: f64) -> f64 {
        if t.abs() <= 0.1 {
            let t2 = t * t;
            // t^2/6 - t^4/120 + t^6/5040 - t^8/362880
            t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0)))
        } else {
            1.0 - t.sin() / t
        }
    }

    /// Central finite difference of a scalar function.
    fn fd(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
        (f(x + h) - f(x - h)) / (2.0 * h)
    }

    #[test]
    fn remembered_buckling_laws_are_built_once_per_distinct_triple_and_equal_fresh_ones() {
        let mut laws = BucklingLaws::default();
        // Each argument varies alone (the second rest length differs from
        // the first in its last bit, as two links of a panel can).
        let rests = [0.01, f64::from_bits(0.01f64.to_bits() + 1), 0.02];
        let triples: Vec<[f64; 3]> =
            rests.iter().flat_map(|&l| [[l, 3e-6, 200.0], [l, 6e-6, 200.0], [l, 3e-6, 400.0]]).collect();
        for _ in 0..3 {
            for &[l, k_b, c_b] in &triples {
                assert_eq!(laws.law(l, k_b, c_b), BucklingLaw::new(l, k_b, c_b));
            }
        }
        assert_eq!(laws.0.len(), 9, "one law per distinct triple");
    }

    #[test]
    fn inverse_sinc_matches_high_precision_roots() {
        // `1 - sin(t)/t = s` solved in 40-digit arithmetic.
        let roots = [
            (1e-12, 2.4494897427835456e-06),
            (1e-6, 0.002_449_490_110_206_78),
            (0.001, 0.077_471_290_316_498_03),
            (0.01, 0.245_317_808_854_025_3),
            (0.1, 0.786_683_072_049_212),
            (0.3, 1.410_185_376_648_157_8),
            (0.5, 1.895_494_267_033_981),
            (0.7, 2.356_441_149_856_161),
            (0.9, 2.852_341_894_450_092),
            (0.99, 3.110_482_807_621_505_4),
            (0.999_999, 3.141_589_512_000_281),
        ];
        for (s, t) in roots {
            let got = inverse_sinc(s);
            assert!((got - t).abs() <= 1e-15 * t, "s={s}: {got} against {t}");
        }
        assert_eq!(inverse_sinc(0.0), 0.0);
        assert_eq!(inverse_sinc(-1.0), 0.0);
        assert_eq!(inverse_sinc(1.0), PI);
        assert_eq!(inverse_sinc(f64::NAN), 0.0);
    }

    #[test]
    fn inverse_sinc_round_trips_over_the_whole_range() {
        let mut worst = 0.0_f64;
        for k in 1..20_000 {
            let t = PI * k as f64 / 20_000.0;
            let back = inverse_sinc(one_minus_sinc(t));
            worst = worst.max((back - t).abs() / t);
        }
        for k in 0..2_000 {
            let t = 10f64.powf(-7.0 + 7.0 * k as f64 / 2_000.0);
            let back = inverse_sinc(one_minus_sinc(t));
            worst = worst.max((back - t).abs() / t);
        }
        // 3.2e-14 measured: the forward `1 - sin(t)/t` loses up to
        // `eps / s` of `s` to cancellation just above `t = 0.1`.
        assert!(worst <= 5e-14, "worst relative error {worst}");
        // The two series meet: the next float above the seam.
        let (below, above) = (inverse_sinc(SMALL_ARC_S), inverse_sinc(SMALL_ARC_S.next_up()));
        assert!(above >= below && above - below <= 4.0 * f64::EPSILON * below, "{below} then {above}");
        // Monotone, as the law's force needs.
        let mut last = 0.0;
        for k in 1..=100_000 {
            let t = inverse_sinc(k as f64 / 100_000.0);
            assert!(t >= last, "not monotone at s = {}", k as f64 / 100_000.0);
            last = t;
        }
    }

    /// The arc law's `g` and `h` from one sine and cosine are the two
    /// functions' own, to the bit, on both sides of the series' branch.
    #[test]
    fn g_and_h_together_are_each_alone() {
        for k in 0..=3_000 {
            let t = k as f64 * PI / 3_000.0;
            let (g, h) = arc_g_h(t);
            assert_eq!(g.to_bits(), cos_minus_sinc(t).to_bits(), "g at {t}");
            assert_eq!(h.to_bits(), three_g_plus_t_sin(t).to_bits(), "h at {t}");
        }
    }

    #[test]
    fn series_branches_match_direct_formulas() {
        // h(0.1) to 16 digits (computed with 40-digit arithmetic).
        assert!((three_g_plus_t_sin(0.1) + 6.661_906_084_455_687e-6).abs() < 1e-14 * 6.7e-6);
        for t in [0.099_999_f64, 0.100_001] {
            let direct_g = t.cos() - t.sin() / t;
            assert!((cos_minus_sinc(t) - direct_g).abs() < 1e-14);
            // The direct h formula loses ~5 digits here to cancellation.
            let direct_h = 3.0 * direct_g + t * t.sin();
            assert!((three_g_plus_t_sin(t) - direct_h).abs() < 1e-10 * direct_h.abs());
            assert!((one_minus_sinc(t) - (1.0 - t.sin() / t)).abs() < 1e-16);
        }
    }

    /// Choi & Ko's buckling curve: f_b L^2 / k_b at three chord ratios.
    #[test]
    fn arc_force_matches_the_analytic_curve() {
        for (ratio, expect) in [(0.99, -12.07), (0.5, -17.55), (0.2, -25.55)] {
            let v = buckling_arc(ratio, 1.0, 1.0).phi;
            assert!((v - expect).abs() < 0.006, "d/L={ratio}: {v}");
        }
        // Limits: -12 at d -> L (arc critical load), -4 pi^2 at d -> 0.
        assert!((buckling_arc(1.0 - 1e-12, 1.0, 1.0).phi + 12.0).abs() < 1e-6);
        assert!((buckling_arc(1e-9, 1.0, 1.0).phi + 4.0 * PI * PI).abs() < 1e-6);
        // Scaling: phi ~ k_b / L^2.
        let a = buckling_arc(0.3, 0.5, 2e-5).phi;
        assert!((a - buckling_arc(0.6, 1.0, 1.0).phi * 2e-5 / 0.25).abs() < 1e-15);
    }

    #[test]
    fn laws_are_derivatives_of_their_energies() {
        let rest = 0.02;
        for &d in &[0.001, 0.005, 0.01, 0.0150, 0.0199, 0.019_999_9] {
            let h = 1e-7 * rest;
            let arc = buckling_arc(d, rest, 3e-6);
            let e = |x| buckling_arc(x, rest, 3e-6).energy;
            let p = |x| buckling_arc(x, rest, 3e-6).phi;
            assert!((fd(e, d, h) - arc.phi).abs() <= 1e-6 * arc.phi.abs(), "arc phi at {d}");
            assert!((fd(p, d, h) - arc.dphi).abs() <= 1e-5 * arc.dphi.abs(), "arc dphi at {d}");
            for c_b in [0.1, 10.0, 1000.0] {
                let law = buckling_ramped(d, rest, 3e-6, c_b);
                let e = |x| buckling_ramped(x, rest, 3e-6, c_b).energy;
                let p = |x| buckling_ramped(x, rest, 3e-6, c_b).phi;
                assert!((fd(e, d, h) - law.phi).abs() <= 1e-6 * law.phi.abs() + 1e-12, "ramped phi at {d}, c_b {c_b}");
                assert!((fd(p, d, h) - law.dphi).abs() <= 1e-5 * law.dphi.abs(), "ramped dphi at {d}, c_b {c_b}");
            }
        }
        for d in [0.9, 1.0001, 1.3] {
            let s = bilinear_spring(d, 1.0, 50.0, 0.0);
            assert!((fd(|x| bilinear_spring(x, 1.0, 50.0, 0.0).energy, d, 1e-6) - s.phi).abs() < 1e-6);
            let l = linear_spring(d, 1.0, 50.0);
            assert!((fd(|x| linear_spring(x, 1.0, 50.0).energy, d, 1e-6) - l.phi).abs() < 1e-6);
            let b = bilinear_spring(d, 1.0, 50.0, 7.0);
            assert!((fd(|x| bilinear_spring(x, 1.0, 50.0, 7.0).energy, d, 1e-6) - b.phi).abs() < 1e-6);
            assert_eq!(b.dphi, if d < 1.0 { 7.0 } else { 50.0 });
        }
        assert_eq!(bilinear_spring(0.9, 1.0, 50.0, 0.0), ScalarLaw::default());
        for d in [0.001, 0.004, 0.0099] {
            let r = repulsion(d, 0.01, 80.0);
            assert!(r.phi < 0.0, "repulsive at {d}");
            assert!((fd(|x| repulsion(x, 0.01, 80.0).energy, d, 1e-7) - r.phi).abs() < 1e-9);
            assert!((fd(|x| repulsion(x, 0.01, 80.0).phi, d, 1e-7) - r.dphi).abs() < 1e-6);
        }
        assert_eq!(repulsion(0.0101, 0.01, 80.0), ScalarLaw::default());
    }

    #[test]
    fn ramped_law_is_continuous_and_never_stronger_than_either_branch() {
        let (rest, k_b, c_b) = (0.02, 3e-6, 50.0);
        let d_c = ramp_switch_point(rest, k_b, c_b);
        assert!(d_c > 0.0 && d_c < rest);
        let eps = 1e-10 * rest;
        let below = buckling_ramped(d_c - eps, rest, k_b, c_b);
        let above = buckling_ramped(d_c + eps, rest, k_b, c_b);
        // No jump: the energy changes by no more than |phi| times the distance.
        assert!((below.energy - above.energy).abs() <= 1.01 * above.phi.abs() * 2.0 * eps);
        assert!((below.phi - above.phi).abs() < 1e-6 * above.phi.abs());
        for k in 1..100 {
            let d = rest * k as f64 / 100.0;
            let law = buckling_ramped(d, rest, k_b, c_b);
            assert!(law.phi <= 0.0 && law.dphi > 0.0);
            let arc = buckling_arc(d, rest, k_b).phi;
            let ramp = c_b * (d - rest);
            // |phi| = min(|f_b|, c_b (L - d)) exactly, away from the switch.
            if (d - d_c).abs() > 1e-9 * rest {
                assert_eq!(law.phi, arc.max(ramp), "d = {d}");
            }
        }
    }

    #[test]
    fn pair_stiffness_is_the_derivative_of_the_force() {
        let xi = Vec3::new(0.1, -0.2, 0.05);
        let xj = Vec3::new(0.112, -0.19, 0.049);
        let rest = 0.02;
        let force = |xi: &Vec3, xj: &Vec3, law: &dyn Fn(f64) -> ScalarLaw| {
            let xij = xj - xi;
            let d = xij.norm();
            law(d).phi * xij / d
        };
        let laws: [(&dyn Fn(f64) -> ScalarLaw, f64); 2] =
            [(&|d| bilinear_spring(d, 0.012, 80.0, 0.0), 1e-6), (&|d| buckling_ramped(d, rest, 3e-6, 50.0), 1e-5)];
        for (law, tol) in laws {
            let xij = xj - xi;
            let d = xij.norm();
            let k = pair_stiffness(&(xij / d), d, &law(d), true);
            let h = 1e-8;
            for c in 0..3 {
                let mut p = xj;
                let mut m = xj;
                p[c] += h;
                m[c] -= h;
                let col = (force(&xi, &p, law) - force(&xi, &m, law)) / (2.0 * h);
                assert!((col - k.column(c)).norm() <= tol * k.norm(), "column {c}");
            }
            // Dropping the orthogonal term keeps only the P part, which is PSD.
            let dropped = pair_stiffness(&(xij / d), d, &law(d), false);
            assert!(dropped.symmetric_eigen().eigenvalues.min() >= -1e-12);
        }
    }
    #[test]
    fn stitch_force_is_the_derivative_of_its_energy_and_is_capped() {
        let (k, pull) = (2000.0, 0.2);
        for d in [0.0, 2e-5, 9.9e-5, 1.01e-4, 0.01, 0.3] {
            let s = stitch(d, k, pull);
            assert!(
                (fd(|x| stitch(x, k, pull).energy, d.max(1e-9), 1e-9) - stitch(d.max(1e-9), k, pull).phi).abs() < 1e-6,
                "{d}"
            );
            assert!(s.phi <= pull && s.phi >= 0.0);
            if d > 1.01e-4 {
                assert!((fd(|x| stitch(x, k, pull).phi, d, 1e-7) - s.dphi).abs() < 1e-9);
            }
        }
        assert_eq!(stitch(0.3, k, pull).phi, pull);
        assert_eq!(stitch(5e-5, k, pull).phi, 0.1);
        // The energy is continuous where the cap starts.
        let d_c = pull / k;
        assert!((stitch(d_c * (1.0 + 1e-12), k, pull).energy - stitch(d_c, k, pull).energy).abs() < 1e-15);
    }
}
