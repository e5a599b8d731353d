//! The dihedral angle of a hinge of two triangles and its gradient: what
//! the bending elements on meshes read.

use crate::Vec3;

/// Signed dihedral angle of a hinge (radians, 0 when flat): corners 0 and 1
/// span the shared edge, 2 and 3 are the opposite corners of the two
/// triangles `(0, 1, 2)` and `(1, 0, 3)`.
pub fn dihedral_angle(x: &[Vec3; 4]) -> f64 {
    let e = x[1] - x[0];
    let n1 = e.cross(&(x[2] - x[0]));
    let n2 = (x[3] - x[0]).cross(&e);
    let sin = n1.cross(&n2).dot(&e) / e.norm();
    sin.atan2(n1.dot(&n2))
}

/// Gradient of [`dihedral_angle`] with respect to the four corners
/// (Bridson, Marino & Fedkiw 2003).
pub fn dihedral_gradient(x: &[Vec3; 4]) -> [Vec3; 4] {
    let e = x[1] - x[0];
    let len = e.norm();
    let n1 = e.cross(&(x[2] - x[0]));
    let n2 = (x[3] - x[0]).cross(&e);
    let (q1, q2) = (n1 / n1.norm_squared(), n2 / n2.norm_squared());
    let d2 = q1 * len;
    let d3 = q2 * len;
    let d0 = q1 * ((x[2] - x[1]).dot(&e) / len) + q2 * ((x[3] - x[1]).dot(&e) / len);
    let d1 = -q1 * ((x[2] - x[0]).dot(&e) / len) - q2 * ((x[3] - x[0]).dot(&e) / len);
    // The normals' orientation above makes theta grow against these directions.
    [-d0, -d1, -d2, -d3]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::element_laws::moved;

    #[test]
    fn hinge_gradient_matches_finite_differences() {
        let x = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.02, 0.001),
            Vec3::new(0.015, 0.01, 0.004),
            Vec3::new(-0.02, 0.012, 0.003),
        ];
        let grad = dihedral_gradient(&x);
        let h = 1e-8;
        for (k, g) in grad.iter().enumerate() {
            for c in 0..3 {
                let (xp, xm) = (moved(x, k, c, h), moved(x, k, c, -h));
                let fd = (dihedral_angle(&xp) - dihedral_angle(&xm)) / (2.0 * h);
                assert!((fd - g[c]).abs() < 1e-6 * g.norm().max(1.0), "corner {k} comp {c}: {fd} vs {}", g[c]);
            }
        }
        let flat = [Vec3::zeros(), Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 0.5, 0.0), Vec3::new(-1.0, 0.5, 0.0)];
        assert!(dihedral_angle(&flat).abs() < 1e-15);
    }
}
