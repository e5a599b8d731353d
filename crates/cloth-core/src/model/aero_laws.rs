//! The air's laws: Provot's (1995) viscous fluid force on a particle and
//! aerodynamic drag and lift on a flat triangle, with the latter's
//! derivative for the implicit steps. Forces on the cloth, N; the wind's
//! velocity and coefficients are [`crate::Wind`]'s.

use crate::{Mat3, Vec3};

/// Provot's (1995) viscous fluid force on a particle of area `area` (m^2)
/// with unit surface normal `n`: `F = C_v area [n . (u - v)] n`, N.
pub fn provot_fluid_force(n: &Vec3, area: f64, c_v: f64, wind: &Vec3, v: &Vec3) -> Vec3 {
    n * (c_v * area * n.dot(&(wind - v)))
}

/// Aerodynamic force on a flat triangle of area `area` and unit normal
/// `n` moving at `v` in air of velocity `wind`, with `w = wind - v` and
/// `cos = w.n / |w|`: drag `rho C_d area |cos| |w| w / 2` along the flow
/// and lift `rho C_l area cos (|w|^2 n - (w.n) w) / 2` across it (zero
/// edge-on and face-on, largest at 45 degrees). N.
pub fn triangle_aero_force(n: &Vec3, area: f64, wind: &Vec3, v: &Vec3, rho: f64, c_d: f64, c_l: f64) -> Vec3 {
    let w = wind - v;
    let speed = w.norm();
    if speed == 0.0 {
        return Vec3::zeros();
    }
    let wn = w.dot(n);
    let cos = wn / speed;
    let drag = w * (0.5 * rho * c_d * area * cos.abs() * speed);
    let lift = (n * (speed * speed) - w * wn) * (0.5 * rho * c_l * area * cos);
    drag + lift
}

/// `d F / d w` of [`triangle_aero_force`] with respect to the relative
/// air velocity `w = wind - v`, N s/m. With `k_d = rho C_d area / 2`,
/// `k_l = rho C_l area / 2`, `s = |w|`, `c = w.n`: the drag `k_d |c| w`
/// gives `k_d (|c| I + sign(c) w n^T)`; the lift `k_l (c s n - c^2 w / s)`
/// gives `k_l (n (s n + c w / s)^T - 2 c w n^T / s - c^2 (I - w w^T / s^2) / s)`.
/// Zero in still air.
pub fn triangle_aero_derivative(n: &Vec3, area: f64, w: &Vec3, rho: f64, c_d: f64, c_l: f64) -> Mat3 {
    let s = w.norm();
    if s == 0.0 {
        return Mat3::zeros();
    }
    let c = w.dot(n);
    let (k_d, k_l) = (0.5 * rho * c_d * area, 0.5 * rho * c_l * area);
    let drag = (Mat3::identity() * c.abs() + w * n.transpose() * c.signum()) * k_d;
    let ww = w * w.transpose() / (s * s);
    let lift = n * (n * s + w * (c / s)).transpose()
        - w * n.transpose() * (2.0 * c / s)
        - (Mat3::identity() - ww) * (c * c / s);
    drag + lift * k_l
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn provot_force_acts_along_the_normal_only() {
        let n = Vec3::z();
        let f = provot_fluid_force(&n, 0.01, 2.0, &Vec3::new(5.0, 0.0, 3.0), &Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(f, Vec3::new(0.0, 0.0, 2.0 * 0.01 * 2.0));
    }

    #[test]
    fn plate_drag_and_lift_have_their_textbook_values() {
        let (rho, cd, cl, area) = (1.2, 1.0, 0.5, 0.5);
        let wind = Vec3::new(10.0, 0.0, 0.0);
        // Face-on: pure drag, rho Cd A U^2 / 2 = 30 N.
        let f = triangle_aero_force(&Vec3::x(), area, &wind, &Vec3::zeros(), rho, cd, cl);
        assert!((f - Vec3::new(30.0, 0.0, 0.0)).norm() < 1e-12);
        // Edge-on: nothing.
        assert_eq!(triangle_aero_force(&Vec3::y(), area, &wind, &Vec3::zeros(), rho, cd, cl), Vec3::zeros());
        // 45 degrees: drag 30 cos45 along x, lift 30 Cl/Cd cos45 sin45 across the flow.
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        let f = triangle_aero_force(&n, area, &wind, &Vec3::zeros(), rho, cd, cl);
        let c = std::f64::consts::FRAC_1_SQRT_2;
        assert!((f.x - 30.0 * c).abs() < 1e-12 && (f.y - 15.0 * c * c).abs() < 1e-12 && f.z == 0.0, "{f:?}");
        // Moving with the air: no force.
        assert_eq!(triangle_aero_force(&n, area, &wind, &wind, rho, cd, cl), Vec3::zeros());
    }
}
