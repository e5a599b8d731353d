//! Volino's membrane on one triangle: a linear orthotropic (St
//! Venant-Kirchhoff) law on the Green strain, and the tension-field law
//! that lets a triangle wrinkle instead of holding compression.

use super::{ElementForces, ElementResponse};
use crate::{Mat3, Vec3};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Rest data of a membrane triangle, from its rest-shape parameterisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleRest {
    /// Gradient operator: `F = sum_k x_k g_k^T` (3x2) is the deformation
    /// gradient from the (u, v) parameter plane; `g_0 = -g_1 - g_2`.
    pub g: [Vector2<f64>; 3],
    /// Rest area, m^2.
    pub area: f64,
    /// Plane-stress stiffness in Voigt form `(e_uu, e_vv, gamma_uv)`, N/m.
    pub c: Matrix3Voigt,
    /// `Some(sigma_b)`: the membrane wrinkles instead of holding a
    /// compressive principal stress beyond `sigma_b` (N/m, >= 0; tension
    /// field theory, [`tension_field_response`]); `c` is then isotropic.
    /// `None`: linear in compression too.
    pub buckling_stress: Option<f64>,
}

/// A symmetric 3x3 Voigt stiffness `[[c11, c12, 0], [c12, c22, 0], [0, 0, g]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Matrix3Voigt {
    /// Warp stiffness term, N/m.
    pub c11: f64,
    /// Coupling (Poisson) term, N/m.
    pub c12: f64,
    /// Weft stiffness term, N/m.
    pub c22: f64,
    /// Shear modulus, N/m.
    pub g: f64,
}

impl Matrix3Voigt {
    /// Orthotropic plane stress from warp (u) and weft (v) Young's moduli
    /// `e_u`, `e_v` (N/m, i.e. modulus times thickness), shear modulus `g`
    /// (N/m) and Poisson ratio `nu_uv` (`nu_vu = nu_uv e_v / e_u`).
    pub fn orthotropic(e_u: f64, e_v: f64, g: f64, nu_uv: f64) -> Self {
        let nu_vu = nu_uv * e_v / e_u;
        let d = 1.0 - nu_uv * nu_vu;
        Self { c11: e_u / d, c12: nu_uv * e_v / d, c22: e_v / d, g }
    }

    /// Isotropic plane stress of modulus `e` (N/m) and Poisson ratio `nu`
    /// (shear modulus `e / (2 (1 + nu))`).
    pub fn isotropic(e: f64, nu: f64) -> Self {
        Self::orthotropic(e, e, e / (2.0 * (1.0 + nu)), nu)
    }

    fn mul(&self, e: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(self.c11 * e.x + self.c12 * e.y, self.c12 * e.x + self.c22 * e.y, self.g * e.z)
    }
}

impl TriangleRest {
    /// Rest data from the parameter-plane coordinates `uv` (m) of the three
    /// corners; None if the triangle is degenerate.
    pub fn new(uv: [Vector2<f64>; 3], c: Matrix3Voigt) -> Option<Self> {
        let dm = Matrix2::from_columns(&[uv[1] - uv[0], uv[2] - uv[0]]);
        let area = 0.5 * dm.determinant().abs();
        let inv = dm.try_inverse()?;
        if !(area > 0.0 && area.is_finite()) {
            return None;
        }
        let g1 = Vector2::new(inv[(0, 0)], inv[(0, 1)]);
        let g2 = Vector2::new(inv[(1, 0)], inv[(1, 1)]);
        Some(Self { g: [-g1 - g2, g1, g2], area, c, buckling_stress: None })
    }

    /// An isotropic membrane (modulus `e` in N/m, Poisson ratio `nu` in
    /// (-1, 1)) that wrinkles beyond the compressive stress `sigma_b` (N/m)
    /// ([`tension_field_response`]); None if the triangle is degenerate.
    pub fn tension_field(uv: [Vector2<f64>; 3], e: f64, nu: f64, sigma_b: f64) -> Option<Self> {
        Some(Self { buckling_stress: Some(sigma_b), ..Self::new(uv, Matrix3Voigt::isotropic(e, nu))? })
    }
}

/// A membrane's response to a Green strain `(e_uu, e_vv, gamma_uv)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressResponse {
    /// Energy per rest area, J/m^2.
    pub energy: f64,
    /// Second Piola-Kirchhoff stress `(S_uu, S_vv, S_uv)`, N/m.
    pub stress: Vector3<f64>,
    /// `dS / de` (positive semi-definite), N/m.
    pub tangent: Matrix3<f64>,
}

/// The linear law `S = C e`.
pub fn linear_response(e: Vector3<f64>, c: &Matrix3Voigt) -> StressResponse {
    let stress = c.mul(&e);
    let tangent = Matrix3::new(c.c11, c.c12, 0.0, c.c12, c.c22, 0.0, 0.0, 0.0, c.g);
    StressResponse { energy: 0.5 * e.dot(&stress), stress, tangent }
}

/// Tension field theory (Wagner; the relaxed energy of Pipkin 1986) with a
/// compressive yield: cloth buckles out of its plane at a small compressive
/// stress, so its membrane holds no principal stress below `-sigma_b`.
/// With principal strains `e1 >= e2` and the isotropic law `sigma_i = C
/// (e_i + nu e_j)`, `C = E / (1 - nu^2)`:
/// - taut (`sigma_2 >= -sigma_b`): the linear law;
/// - wrinkled along `n_2`: `sigma_2 = -sigma_b`, the elastic strain across
///   `e2' = -sigma_b / C - nu e1`, `sigma_1 = E e1 - nu sigma_b`, energy
///   `W(e1, e2') + sigma_b (e2' - e2)` (the wrinkles' shortening worked
///   against `sigma_b`);
/// - slack (`sigma_1 <= -sigma_b` too): `S = -sigma_b I`.
///
/// The energy is convex in the strain and continuous with its stress
/// across the regimes. Wrinkled, the tangent in the principal frame is `E`
/// along `n_1` and `(sigma_1 - sigma_2) / (2 (e1 - e2))` in shear. It is
/// Choi & Ko's (2002) premise, that fabric buckles rather than resists
/// compression, for a triangle: a triangle network of links that go slack
/// in compression is a mechanism. `iso` the isotropic law
/// ([`Matrix3Voigt::isotropic`]: `C = c11`, `nu = c12 / c11`), N/m;
/// `sigma_b` in N/m.
pub fn tension_field_response(strain: Vector3<f64>, iso: &Matrix3Voigt, sigma_b: f64) -> StressResponse {
    let (c, nu) = (iso.c11, iso.c12 / iso.c11);
    let e = c * (1.0 - nu * nu);
    let (exx, eyy, exy) = (strain.x, strain.y, 0.5 * strain.z);
    let mean = 0.5 * (exx + eyy);
    let radius = (0.25 * (exx - eyy).powi(2) + exy * exy).sqrt();
    let (e1, e2) = (mean + radius, mean - radius);
    if c * (e2 + nu * e1) >= -sigma_b {
        return linear_response(strain, iso);
    }
    let angle = 0.5 * (2.0 * exy).atan2(exx - eyy);
    let (co, si) = (angle.cos(), angle.sin());
    // Principal strains (e1, e2, gamma_12) = q (e_uu, e_vv, gamma_uv).
    let q = Matrix3::new(
        co * co,
        si * si,
        co * si,
        si * si,
        co * co,
        -co * si,
        -2.0 * co * si,
        2.0 * co * si,
        co * co - si * si,
    );
    let wrinkled_s1 = e * e1 - nu * sigma_b;
    let (energy, principal, tangent) = if wrinkled_s1 > -sigma_b {
        let across = -sigma_b / c - nu * e1;
        let elastic = 0.5 * c * (e1 * e1 + across * across + 2.0 * nu * e1 * across);
        let shear = (wrinkled_s1 + sigma_b) / (2.0 * (e1 - e2));
        let tangent = Matrix3::new(e, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, shear);
        (elastic + sigma_b * (across - e2), Vector3::new(wrinkled_s1, -sigma_b, 0.0), tangent)
    } else {
        let elastic = -sigma_b / (c * (1.0 + nu));
        let energy = c * (1.0 + nu) * elastic * elastic + sigma_b * (2.0 * elastic - e1 - e2);
        (energy, Vector3::new(-sigma_b, -sigma_b, 0.0), Matrix3::zeros())
    };
    StressResponse { energy, stress: q.transpose() * principal, tangent: q.transpose() * tangent * q }
}

/// Linear orthotropic membrane (St Venant-Kirchhoff) on one triangle:
/// Green strain `E = (F^T F - I)/2`, Voigt `e = (E_uu, E_vv, 2 E_uv)`,
/// energy `A (e^T C e) / 2`, forces `f_k = -A B_k^T C e` with
/// `B_k = d e / d x_k`. The Hessian keeps the material term
/// `A B_a^T C B_b` and the geometric term `A (g_a^T S+ g_b) I` with the
/// stress `S` projected to its positive part, so it is PSD (and exact
/// whenever the stress is tensile).
pub fn membrane_triangle(x: [Vec3; 3], rest: &TriangleRest) -> ElementResponse<3> {
    membrane_triangle_with(x, rest, true)
}

/// [`membrane_triangle`], with the Hessian left zero when `hessian` is
/// false (explicit integrators need forces only).
pub fn membrane_triangle_with(x: [Vec3; 3], rest: &TriangleRest, hessian: bool) -> ElementResponse<3> {
    let mut h = [[Mat3::zeros(); 3]; 3];
    let ElementForces { energy, forces } = membrane_triangle_into(x, rest, hessian.then_some(&mut h));
    ElementResponse { energy, forces, hessian: h }
}

/// [`membrane_triangle_with`]'s energy and forces, and its matrix written
/// into `hessian` when given (every block).
pub fn membrane_triangle_into(
    x: [Vec3; 3],
    rest: &TriangleRest,
    hessian: Option<&mut [[Mat3; 3]; 3]>,
) -> ElementForces<3> {
    let g = &rest.g;
    let f0 = x[0] * g[0].x + x[1] * g[1].x + x[2] * g[2].x; // F column u
    let f1 = x[0] * g[0].y + x[1] * g[1].y + x[2] * g[2].y; // F column v
    let strain = Vector3::new(0.5 * (f0.dot(&f0) - 1.0), 0.5 * (f1.dot(&f1) - 1.0), f0.dot(&f1));
    let law = match rest.buckling_stress {
        Some(sigma_b) => tension_field_response(strain, &rest.c, sigma_b),
        None => linear_response(strain, &rest.c),
    };
    let stress = law.stress;
    let a = rest.area;
    // B_k rows: d e_uu/dx_k, d e_vv/dx_k, d gamma/dx_k.
    let b: [[Vec3; 3]; 3] = std::array::from_fn(|k| [f0 * g[k].x, f1 * g[k].y, f1 * g[k].x + f0 * g[k].y]);
    let forces = std::array::from_fn(|k| -(b[k][0] * stress.x + b[k][1] * stress.y + b[k][2] * stress.z) * a);
    let energy = a * law.energy;
    let Some(hessian) = hessian else { return ElementForces { energy, forces } };
    // Positive part of the 2x2 stress tensor [[s_uu, s_uv], [s_uv, s_vv]].
    let s = Matrix2::new(stress.x, stress.z, stress.z, stress.y);
    let eig = s.symmetric_eigen();
    let mut s_pos = Matrix2::zeros();
    for i in 0..2 {
        let lambda = eig.eigenvalues[i].max(0.0);
        let v = eig.eigenvectors.column(i);
        s_pos += v * v.transpose() * lambda;
    }
    let t = &law.tangent;
    // In place: a 3 x 3 array of blocks built and returned is copied.
    for (p, row) in hessian.iter_mut().enumerate() {
        for (q, block) in row.iter_mut().enumerate() {
            let (bp, bq) = (&b[p], &b[q]);
            // sum_ij T_ij bp_i bq_j^T with the Voigt tangent T.
            let material = (0..3).fold(Mat3::zeros(), |m, i| {
                m + bp[i] * (bq[0] * t[(i, 0)] + bq[1] * t[(i, 1)] + bq[2] * t[(i, 2)]).transpose()
            });
            let geometric = (g[p].transpose() * s_pos * g[q])[(0, 0)];
            *block = (material + Mat3::identity() * geometric) * a;
        }
    }
    ElementForces { energy, forces }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::element_laws::moved;

    fn rest() -> TriangleRest {
        let uv = [Vector2::new(0.0, 0.0), Vector2::new(0.02, 0.0), Vector2::new(0.0, 0.015)];
        TriangleRest::new(uv, Matrix3Voigt::orthotropic(50.0, 30.0, 8.0, 0.3)).unwrap()
    }

    fn deformed() -> [Vec3; 3] {
        [Vec3::new(0.001, -0.002, 0.0005), Vec3::new(0.0235, 0.001, 0.002), Vec3::new(-0.001, 0.017, -0.001)]
    }

    #[test]
    fn membrane_is_zero_at_rest_and_invariant_to_rotation() {
        let r = rest();
        let at_rest = [Vec3::zeros(), Vec3::new(0.02, 0.0, 0.0), Vec3::new(0.0, 0.015, 0.0)];
        let e = membrane_triangle(at_rest, &r);
        assert!(e.energy.abs() < 1e-18 && e.forces.iter().all(|f| f.norm() < 1e-15));
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0);
        let x = deformed();
        let a = membrane_triangle(x, &r);
        let b = membrane_triangle(x.map(|p| rot * p + Vec3::new(1.0, 2.0, 3.0)), &r);
        assert!((a.energy - b.energy).abs() < 1e-9 * a.energy);
        let net: Vec3 = a.forces.iter().sum();
        assert!(net.norm() < 1e-15);
    }

    #[test]
    fn membrane_forces_and_hessian_match_finite_differences() {
        // Stretched in both directions here, so the stress is tensile and
        // the PSD Hessian is the exact one.
        membrane_matches_finite_differences(deformed(), &rest());
    }

    /// The membrane's forces against central differences of its energy,
    /// and its matrix against central differences of its forces (exact
    /// where its stress is not compressive).
    fn membrane_matches_finite_differences(x: [Vec3; 3], r: &TriangleRest) {
        let e = membrane_triangle(x, r);
        let h = 1e-8;
        for k in 0..3 {
            for c in 0..3 {
                let (xp, xm) = (moved(x, k, c, h), moved(x, k, c, -h));
                let (ep, em) = (membrane_triangle(xp, r), membrane_triangle(xm, r));
                let grad = (ep.energy - em.energy) / (2.0 * h);
                assert!((e.forces[k][c] + grad).abs() < 1e-6 * e.forces[k].norm().max(1e-9), "force {k},{c}");
                for a in 0..3 {
                    let col = -(ep.forces[a] - em.forces[a]) / (2.0 * h);
                    let analytic = e.hessian[a][k].column(c);
                    assert!((col - analytic).norm() < 1e-5 * e.hessian[a][a].norm(), "H[{a}][{k}] col {c}");
                }
            }
        }
    }

    /// Three particles at spacing `h` on a circle of curvature `kappa`.
    /// Strains in each regime of the tension field (taut, wrinkled, slack),
    /// with shear so the principal axes are off the (u, v) axes.
    const FIELD_STRAINS: [[f64; 3]; 4] =
        [[0.01, 0.004, 0.003], [0.01, -0.006, 0.004], [0.003, -0.02, -0.011], [-0.004, -0.006, 0.001]];

    #[test]
    fn tension_field_stress_and_tangent_match_finite_differences() {
        let (e, nu, sigma_b) = (200.0, 0.3, 0.05);
        let iso = Matrix3Voigt::isotropic(e, nu);
        let law = |s: Vector3<f64>| tension_field_response(s, &iso, sigma_b);
        let h = 1e-8;
        for strain in FIELD_STRAINS.map(Vector3::from) {
            let r = law(strain);
            for i in 0..3 {
                let mut d = Vector3::zeros();
                d[i] = h;
                let (p, m) = (law(strain + d), law(strain - d));
                // The energy's derivative is the stress (gamma's conjugate is S_uv).
                let fd = (p.energy - m.energy) / (2.0 * h);
                assert!((fd - r.stress[i]).abs() < 1e-6 * r.stress.norm().max(1e-3), "{strain:?} stress {i}: {fd}");
                let column = (p.stress - m.stress) / (2.0 * h);
                assert!((column - r.tangent.column(i)).norm() < 1e-5 * e, "{strain:?} tangent {i}: {column:?}");
            }
            let eig = r.tangent.symmetric_eigen().eigenvalues;
            assert!(eig.iter().all(|&l| l > -1e-9 * e), "{strain:?}: tangent not PSD {eig:?}");
        }
        // Taut: the linear law. Uniaxial stress: no stress across, modulus E.
        let taut = Vector3::from(FIELD_STRAINS[0]);
        let linear = linear_response(taut, &iso);
        assert!((law(taut).stress - linear.stress).norm() < 1e-12);
        let uniaxial = law(Vector3::new(0.01, -nu * 0.01, 0.0));
        assert!((uniaxial.stress.x - e * 0.01).abs() < 1e-9 && uniaxial.stress.y.abs() < 1e-9);
        // Wrinkled and slack: nothing below -sigma_b, and a strip compressed
        // across holds only -sigma_b, whatever the compression.
        for strain in FIELD_STRAINS[1..].iter().map(|s| Vector3::from(*s)) {
            let s = law(strain).stress;
            let least = Matrix2::new(s.x, s.z, s.z, s.y).symmetric_eigen().eigenvalues.min();
            assert!((least + sigma_b).abs() < 1e-9, "{strain:?}: least principal stress {least}");
        }
    }

    /// Near the point where all three regimes meet (equal principal
    /// strains at the slack limit) the wrinkled shear tangent divides two
    /// vanishing quantities: it stays finite, non-negative and, for
    /// strains along the axes (no rotation to the principal frame), at most
    /// the taut shear modulus `G` (wrinkled, `(sigma_1 + sigma_b) / (2 (e1 -
    /// e2)) <= G`, equal where the wrinkles start).
    #[test]
    fn tension_field_is_finite_near_equal_principal_strains() {
        let (e, nu, sigma_b) = (200.0, 0.3, 0.05);
        let corner = -sigma_b * (1.0 - nu) / e;
        for k in 0..2000 {
            let t = k as f64 / 2000.0;
            let d = 1e-12 * (1.0 + 1e9 * t * t);
            for strain in [
                Vector3::new(corner + d, corner - d, 0.0),
                Vector3::new(corner + d, corner, d * t),
                Vector3::new(corner * (1.0 + t), corner * (1.0 - t), 1e-15),
            ] {
                let r = tension_field_response(strain, &Matrix3Voigt::isotropic(e, nu), sigma_b);
                let finite = r.energy.is_finite() && r.stress.iter().chain(r.tangent.iter()).all(|v| v.is_finite());
                assert!(finite && r.tangent[(2, 2)] >= 0.0, "{strain:?}: {r:?}");
                if strain.z.abs() < 1e-14 {
                    assert!(r.tangent[(2, 2)] <= e / (2.0 * (1.0 + nu)) * (1.0 + 1e-9), "{strain:?}: {r:?}");
                }
            }
        }
    }

    #[test]
    fn tension_field_energy_is_continuous_across_its_regimes() {
        let (e, nu, sigma_b) = (200.0, 0.3, 0.05);
        // From taut through wrinkled to slack along one path of strains.
        let path = |t: f64| Vector3::new(0.01 - 0.03 * t, -0.03 * t, 0.004);
        let n = 20_000;
        let mut worst: f64 = 0.0;
        let mut regimes = std::collections::BTreeSet::new();
        for k in 0..n {
            let (a, b) = (path(k as f64 / n as f64), path((k + 1) as f64 / n as f64));
            let iso = Matrix3Voigt::isotropic(e, nu);
            let (ra, rb) = (tension_field_response(a, &iso, sigma_b), tension_field_response(b, &iso, sigma_b));
            // The trapezoid of the stress along the step meets the energy's change.
            let work = 0.5 * (ra.stress + rb.stress).dot(&(b - a));
            worst = worst.max((rb.energy - ra.energy - work).abs());
            regimes.insert((ra.tangent.trace() / e * 10.0).round() as i64);
        }
        assert!(regimes.len() >= 3, "path crosses too few regimes: {regimes:?}");
        // The trapezoid's own error where the tangent jumps is 5e-11; a jump
        // of the energy at a regime boundary would be orders larger.
        assert!(worst < 1e-10, "energy jumps by {worst:e} J/m^2");
    }

    #[test]
    fn a_wrinkling_membrane_matches_finite_differences() {
        let uv = [Vector2::new(0.0, 0.0), Vector2::new(0.02, 0.0), Vector2::new(0.0, 0.015)];
        // sigma_b = 0: the stress is never compressive, so the matrix is exact.
        let r = TriangleRest::tension_field(uv, 200.0, 0.3, 0.0).unwrap();
        // Stretched along u, squeezed along v: wrinkled.
        let x = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0206, 0.001, 0.0005), Vec3::new(0.0005, 0.0142, -0.0003)];
        membrane_matches_finite_differences(x, &r);
        let strain = Vector3::new(0.5 * (0.0206f64.powi(2) / 4e-4 - 1.0), -0.05, 0.0);
        let s = tension_field_response(strain, &r.c, 0.0);
        assert!(s.stress.y.abs() < 1e-12, "wrinkled across v: {s:?}");
    }
}
