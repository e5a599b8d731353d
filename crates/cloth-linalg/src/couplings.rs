//! Stiffness couplings outside a matrix's pattern: terms that tie a few
//! nodes along one direction, as a contact between a particle and a
//! triangle does, changing from one solve to the next.

use crate::Vec3;

/// One coupling: the stiffness `k g g^T ⊗ u u^T` over up to four nodes,
/// `g` the node weights (`g . x` is the coupled gap along `u`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling {
    /// The nodes; a node with weight 0 takes no part.
    pub nodes: [u32; 4],
    /// Each node's weight `g_i` in the gap (dimensionless).
    pub weights: [f64; 4],
    /// Unit direction `u` of the gap.
    pub direction: Vec3,
    /// Stiffness `k` (the matrix's units).
    pub stiffness: f64,
}

/// Couplings a solve adds to its matrix `A`: the operator becomes `A + E`,
/// `E` the couplings' blocks off the diagonal. The diagonal blocks
/// `k g_i^2 u u^T` belong in `A` itself (where the preconditioner sees
/// them), so `A` keeps its fixed pattern and the operator is the exact
/// `A + sum k g g^T ⊗ u u^T`.
///
/// Applied in the order the couplings were pushed, on one thread: the
/// result does not depend on the thread count. A term costs a few dozen
/// flops, far below a matrix row's, for the hundreds a cloth's contacts
/// give.
#[derive(Debug, Clone, Default)]
pub struct Couplings {
    terms: Vec<Coupling>,
}

impl Couplings {
    /// Removes every term (keeps the allocation).
    pub fn clear(&mut self) {
        self.terms.clear();
    }

    /// Adds a term.
    pub fn push(&mut self, c: Coupling) {
        self.terms.push(c);
    }

    /// Whether there is no term.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// The terms, in the order they were pushed.
    pub fn terms(&self) -> &[Coupling] {
        &self.terms
    }

    /// `p . (E q)`, without a buffer.
    pub fn bilinear(&self, p: &[Vec3], q: &[Vec3]) -> f64 {
        let mut sum = 0.0;
        for c in &self.terms {
            let (mut gp, mut gq, mut own) = (0.0, 0.0, 0.0);
            for j in 0..4 {
                let g = c.weights[j];
                if g != 0.0 {
                    let k = c.nodes[j] as usize;
                    let (a, b) = (g * c.direction.dot(&p[k]), g * c.direction.dot(&q[k]));
                    (gp, gq, own) = (gp + a, gq + b, own + a * b);
                }
            }
            sum += c.stiffness * (gp * gq - own);
        }
        sum
    }

    /// `out += factor E p`; returns `p . (factor E p)`.
    pub fn add_off_diagonal(&self, p: &[Vec3], factor: f64, out: &mut [Vec3]) -> f64 {
        let mut dot = 0.0;
        for c in &self.terms {
            let k = factor * c.stiffness;
            // Each node's share of the gap, g_j u.p_j (0 for a node outside).
            let mut share = [0.0; 4];
            for j in 0..4 {
                if c.weights[j] != 0.0 {
                    share[j] = c.weights[j] * c.direction.dot(&p[c.nodes[j] as usize]);
                }
            }
            let gap: f64 = share.iter().sum();
            let own_sq: f64 = share.iter().map(|a| a * a).sum();
            // (E p)_i = k g_i u (sum_{j != i} g_j u.p_j).
            for j in 0..4 {
                let g = c.weights[j];
                if g != 0.0 {
                    out[c.nodes[j] as usize] += c.direction * (k * g * (gap - share[j]));
                }
            }
            dot += k * (gap * gap - own_sq);
        }
        dot
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The product and its dot against the dense `k g g^T ⊗ u u^T` with
    /// its diagonal blocks removed, for a particle over a triangle.
    #[test]
    fn off_diagonal_product_matches_the_dense_blocks() {
        let u = Vec3::new(0.3, -0.4, 0.5).normalize();
        let c = Coupling { nodes: [4, 0, 2, 3], weights: [1.0, -0.2, -0.5, -0.3], direction: u, stiffness: 7.0 };
        let mut e = Couplings::default();
        e.push(c);
        let p: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f64 - 1.5, 0.7 * i as f64, 2.0 - 0.3 * i as f64)).collect();
        let mut out = vec![Vec3::zeros(); 5];
        let dot = e.add_off_diagonal(&p, 2.0, &mut out);
        let mut expect = vec![Vec3::zeros(); 5];
        for (a, &ga) in c.nodes.iter().zip(&c.weights) {
            for (b, &gb) in c.nodes.iter().zip(&c.weights) {
                if a != b {
                    expect[*a as usize] += u * u.transpose() * p[*b as usize] * (2.0 * 7.0 * ga * gb);
                }
            }
        }
        let expect_dot: f64 = p.iter().zip(&expect).map(|(p, e)| p.dot(e)).sum();
        for (o, x) in out.iter().zip(&expect) {
            assert!((o - x).norm() < 1e-13, "{o} against {x}");
        }
        assert!((dot - expect_dot).abs() < 1e-12, "{dot} against {expect_dot}");
        let q: Vec<Vec3> = (0..5).map(|i| Vec3::new(0.2 * i as f64, 1.0 - 0.1 * i as f64, 0.5)).collect();
        let q_e_p: f64 = q.iter().zip(&expect).map(|(q, e)| q.dot(e)).sum::<f64>() / 2.0;
        assert!((e.bilinear(&q, &p) - q_e_p).abs() < 1e-12, "{} against {q_e_p}", e.bilinear(&q, &p));
        assert_eq!(out[1], Vec3::zeros(), "a node outside the term");
    }
}
