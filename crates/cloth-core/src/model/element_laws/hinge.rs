//! Choi & Ko's bending on meshes: a hinge of two triangles read as the
//! arc-path triple through the middle of its shared edge.

use super::ElementForces;
use super::triple::{bend_triple_energy, bend_triple_into};
use crate::{Mat3, Vec3};

/// Choi & Ko's type-2 interaction across two triangles of a mesh
/// (`crate::cloth_mesh`): corners `[c, a, b, d]`, read as the triple
/// [`super::bend_triple_with`] through the point `m = (1 - w) x_a + w x_b` of the
/// shared edge. Forces and matrix follow by the chain rule (`m`'s force
/// split `(1 - w) : w` between `a` and `b`), so the matrix stays positive
/// semi-definite. `rest` in m, `k_b` in N m^2, `w` in (0, 1).
pub fn bend_hinge_into(
    x: [Vec3; 4],
    w: f64,
    rest: f64,
    k_b: f64,
    hessian: Option<&mut [[Mat3; 4]; 4]>,
) -> ElementForces<4> {
    let middle = x[1] * (1.0 - w) + x[2] * w;
    // Each corner lies in one point of the triple, with a weight: the
    // weight of each corner in each point.
    const POINT: [usize; 4] = [0, 1, 1, 2];
    let weight = [1.0, 1.0 - w, w, 1.0];
    let share = |point: usize, corner: usize| if POINT[corner] == point { weight[corner] } else { 0.0 };
    let mut h3 = [[Mat3::zeros(); 3]; 3];
    let with_matrix = hessian.is_some();
    let r = bend_triple_into([x[0], middle, x[3]], rest, k_b, with_matrix.then_some(&mut h3));
    if let Some(hessian) = hessian {
        // Block (c, e) is that pair of points' block, weighted (added to
        // zero, as a sum over the points would be). Block (e, c) is its
        // transpose to the bit, as the triple's are.
        let block = |c: usize, e: usize| {
            let (s, t) = (POINT[c], POINT[e]);
            Mat3::zeros() + h3[s][t] * (share(s, c) * share(t, e))
        };
        for (c, row) in hessian.iter_mut().enumerate() {
            row[c] = block(c, c);
        }
        for (c, e) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            hessian[c][e] = block(c, e);
            hessian[e][c] = hessian[c][e].transpose();
        }
    }
    let forces = std::array::from_fn(|c| (0..3).map(|s| r.forces[s] * share(s, c)).sum());
    ElementForces { energy: r.energy, forces }
}

/// [`bend_hinge_into`]'s energy alone, J, bit for bit (the triple's
/// energy at the edge's point `m`, [`bend_triple_energy`]).
pub fn bend_hinge_energy(x: [Vec3; 4], w: f64, rest: f64, k_b: f64) -> f64 {
    bend_triple_energy([x[0], x[1] * (1.0 - w) + x[2] * w, x[3]], rest, k_b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::element_laws::moved;

    /// The hinge across two mesh triangles: forces are minus its energy's
    /// gradient, net zero, and a fold across its edge in a flat pair gives
    /// the matrix the finite differences of the forces give (the Gauss-Newton
    /// matrix is exact on a straight path, as for the triple).
    #[test]
    fn bend_hinge_forces_and_matrix_match_finite_differences() {
        let k_b = 3e-7;
        // c, a, b, d: far corners whose segment crosses ab at x = 6.7 mm.
        let flat = [
            Vec3::new(0.004, -0.009, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.02, 0.0, 0.0),
            Vec3::new(0.01, 0.011, 0.0),
        ];
        let (w, rest, _) = crate::cloth_mesh::unfold(flat);
        let w = w.unwrap();
        assert!((w - 0.335).abs() < 1e-12 && (rest - (flat[3] - flat[0]).norm()).abs() < 1e-15, "{w} {rest}");
        let mut bent = flat;
        bent[3].z += 0.003;
        bent[0].z += 0.001;
        let energy = |x: [Vec3; 4]| bend_hinge_into(x, w, rest, k_b, None).energy;
        let r = bend_hinge_into(bent, w, rest, k_b, None);
        let net: Vec3 = r.forces.iter().sum();
        let scale = r.forces.iter().map(|f| f.norm()).fold(0.0, f64::max);
        assert!(scale > 0.0 && net.norm() < 1e-12 * scale, "net {net}");
        let h = 1e-9;
        for k in 0..4 {
            for c in 0..3 {
                let (xp, xm) = (moved(bent, k, c, h), moved(bent, k, c, -h));
                let grad = (energy(xp) - energy(xm)) / (2.0 * h);
                assert!((r.forces[k][c] + grad).abs() < 1e-6 * scale, "force {k},{c}: {} vs {}", r.forces[k][c], -grad);
            }
        }
        assert_eq!(bend_hinge_into(flat, w, rest, k_b, None).energy, 0.0, "flat: no energy");
        // At the flat rest, df/dx = -H for out-of-plane moves.
        let mut m = [[Mat3::zeros(); 4]; 4];
        bend_hinge_into(flat, w, rest, k_b, Some(&mut m));
        let h = 1e-7;
        for k in 0..4 {
            let (xp, xm) = (moved(flat, k, 2, h), moved(flat, k, 2, -h));
            let (fp, fm) = (bend_hinge_into(xp, w, rest, k_b, None), bend_hinge_into(xm, w, rest, k_b, None));
            for a in 0..4 {
                let dfdx = (fp.forces[a].z - fm.forces[a].z) / (2.0 * h);
                let scale = m.iter().flatten().map(|b| b.norm()).fold(0.0, f64::max);
                assert!((dfdx + m[a][k][(2, 2)]).abs() < 1e-5 * scale, "block {a},{k}: {dfdx} vs {}", -m[a][k][(2, 2)]);
            }
        }
    }

    /// The hinge's matrix is the chain rule's sum over the triple's blocks,
    /// `H_ce = sum_st share(s, c) share(t, e) H3_st` summed point by point
    /// from zero, to the bit, flat, bent and folded.
    #[test]
    fn hinge_blocks_are_the_chain_rules_sum_to_the_bit() {
        let (k_b, rest, w) = (3e-7, 0.021, 0.335);
        let share = |point: usize, corner: usize| match (point, corner) {
            (0, 0) | (2, 3) => 1.0,
            (1, 1) => 1.0 - w,
            (1, 2) => w,
            _ => 0.0,
        };
        let bits = |m: &Mat3| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for lift in [0.0, 0.002, 0.009, 0.02] {
            let x = [
                Vec3::new(0.004, -0.009, lift),
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.02, 0.0, 0.0),
                Vec3::new(0.01 - 0.3 * lift, 0.011, 0.5 * lift),
            ];
            let mut m = [[Mat3::zeros(); 4]; 4];
            bend_hinge_into(x, w, rest, k_b, Some(&mut m));
            let middle = x[1] * (1.0 - w) + x[2] * w;
            let mut h3 = [[Mat3::zeros(); 3]; 3];
            bend_triple_into([x[0], middle, x[3]], rest, k_b, Some(&mut h3));
            for (c, row) in m.iter().enumerate() {
                for (e, got) in row.iter().enumerate() {
                    let mut want = Mat3::zeros();
                    for (s, h_row) in h3.iter().enumerate() {
                        for (t, h) in h_row.iter().enumerate() {
                            let weight = share(s, c) * share(t, e);
                            if weight != 0.0 {
                                want += h * weight;
                            }
                        }
                    }
                    assert_eq!(bits(got), bits(&want), "block ({c}, {e}) at lift {lift}");
                }
            }
            assert!(m[0][3].norm() > 0.0, "lift {lift}");
        }
    }

    /// The energy alone is the full evaluation's bit for bit, from a flat
    /// pair of triangles to one folded over its edge.
    #[test]
    fn the_hinge_energy_alone_is_the_full_evaluations_bit_for_bit() {
        let (k_b, rest, w) = (3e-7, 0.021, 0.335);
        let flat = [
            Vec3::new(0.004, -0.009, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.02, 0.0, 0.0),
            Vec3::new(0.01, 0.011, 0.0),
        ];
        let mut bent = 0;
        for k in 0..200 {
            let mut x = flat;
            let lift = 0.0001 * k as f64;
            (x[0].z, x[3].z, x[3].x) = (lift, 0.5 * lift, 0.01 - 0.3 * lift);
            let full = bend_hinge_into(x, w, rest, k_b, None).energy;
            assert_eq!(bend_hinge_energy(x, w, rest, k_b).to_bits(), full.to_bits(), "lift {lift}");
            bent += usize::from(full > 0.0);
        }
        // Measured: every lifted pair bends.
        assert_eq!(bent, 199);
    }
}
