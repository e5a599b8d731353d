//! The self-collision pairs inside the descent: each pair the collision
//! stage found ([`crate::contacts::SelfContact`]) as a penalty energy of
//! the particles it touches, indexed by particle for the local steps.

use crate::contacts::{SelfContact, contact_penalty};
use crate::{Mat3, Vec3};
use cloth_linalg::Buckets;

/// A self-collision pair as an energy of up to four particles: its gap
/// `g(x) = d . sum_k c_k x_k` along the direction `d` found at detection
/// (`c = [1, -w_0, -w_1, -w_2]` for a particle against a point of weights
/// `w` of a triangle or a particle), with the penalty
/// [`contact_penalty`] below the self-collision thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SelfPair {
    pub nodes: [u32; 4],
    pub coefficients: [f64; 4],
    pub direction: Vec3,
    /// Penalty stiffness, N/m.
    pub stiffness_n_m: f64,
}

impl SelfPair {
    /// The pair of a detected self contact, with penalty stiffness `k` (N/m).
    pub(crate) fn of(c: &SelfContact, k: f64) -> Self {
        let [a, b, e] = c.others;
        let [wa, wb, we] = c.weights;
        Self {
            nodes: [c.particle, a, b, e],
            coefficients: [1.0, -wa, -wb, -we],
            direction: c.direction,
            stiffness_n_m: k,
        }
    }

    /// The gap at `x`, m.
    pub(crate) fn gap(&self, x: &[Vec3]) -> f64 {
        let p: Vec3 = (0..4).map(|k| x[self.nodes[k] as usize] * self.coefficients[k]).sum();
        self.direction.dot(&p)
    }

    /// Force on the pair's slot `slot` (N) and its stiffness block (N/m) at `x`.
    pub(crate) fn force_on(&self, slot: usize, x: &[Vec3], thickness: f64) -> (Vec3, Mat3) {
        let (_, push) = contact_penalty(self.gap(x), thickness, self.stiffness_n_m);
        if push == 0.0 {
            return (Vec3::zeros(), Mat3::zeros());
        }
        let c = self.coefficients[slot];
        let d = self.direction;
        (d * (push * c), d * d.transpose() * (self.stiffness_n_m * c * c))
    }
}

/// Per particle, the self pairs it is in (pair index and slot).
#[derive(Debug, Clone, Default)]
pub(crate) struct PairIndex(Buckets<(u32, u8)>);

impl PairIndex {
    /// Rebuilds the index of `pairs` over `n` particles (no allocation
    /// once the buffers have grown).
    pub(crate) fn rebuild(&mut self, n: usize, pairs: &[SelfPair]) {
        self.0.rebuild(n, || {
            pairs.iter().enumerate().flat_map(|(k, p)| {
                (0..4).filter(|&s| p.coefficients[s] != 0.0).map(move |s| (p.nodes[s] as usize, (k as u32, s as u8)))
            })
        });
    }

    /// Particle `i`'s pairs and slots.
    pub(crate) fn of(&self, i: usize) -> &[(u32, u8)] {
        self.0.of(i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::finite_differences::gradient;

    /// A self pair's force on each of its particles is minus its energy's
    /// gradient there, and its block the force's Jacobian.
    #[test]
    fn self_pair_forces_are_the_penalty_gradient() {
        let c = SelfContact {
            particle: 0,
            others: [1, 2, 3],
            weights: [0.2, 0.5, 0.3],
            direction: Vec3::new(0.1, 0.2, 1.0).normalize(),
            distance_m: 0.004,
            repels: true,
        };
        let pair = SelfPair::of(&c, 300.0);
        let thickness = 0.006;
        let x = vec![
            Vec3::new(0.01, 0.0, 0.004),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.02, 0.0, 0.0),
            Vec3::new(0.0, 0.02, 0.0),
        ];
        for slot in 0..4 {
            let energy = |p: Vec3| {
                let mut y = x.clone();
                y[slot] = p;
                contact_penalty(pair.gap(&y), thickness, 300.0).0
            };
            let (f, k) = pair.force_on(slot, &x, thickness);
            assert!((f + gradient(energy, x[slot], 1e-7)).norm() < 1e-6 * f.norm(), "slot {slot}");
            let fd = Mat3::from_fn(|r, col| {
                let d = Vec3::ith(col, 1e-7);
                let (mut yp, mut ym) = (x.clone(), x.clone());
                yp[slot] += d;
                ym[slot] -= d;
                -(pair.force_on(slot, &yp, thickness).0 - pair.force_on(slot, &ym, thickness).0)[r] / 2e-7
            });
            assert!((k - fd).norm() < 1e-6 * k.norm(), "slot {slot}");
        }
        let mut index = PairIndex::default();
        index.rebuild(5, &[pair]);
        assert_eq!(index.of(2), &[(0, 2)]);
        assert!(index.of(4).is_empty());
    }
}
