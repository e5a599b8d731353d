//! The quasi-Newton step's initial Hessian `H0 = M/h^2 + C/h + L` (Liu,
//! Bouaziz & Kavan 2017, §4): mass, a damping graph Laplacian `C` and a
//! stiffness graph Laplacian `L`, one `n x n` scalar matrix for all three
//! coordinates, factored once per step size and set of prescribed
//! particles.
//!
//! Each pair of particles a term couples gets the weight its Jacobian
//! block has along its stiffest direction, `w_ij = max(0, -lambda_min(K_ij))`
//! with `K_ij = -df_i/dx_j` (a spring of stiffness `k` at its rest length
//! gives `k`), evaluated once with the rest shape stretched by
//! [`PROBE_STRETCH`] so that tension-only links read their tension branch;
//! the dampers' `-df_i/dv_j` give `C` the same way, and drag adds to its
//! diagonal. A prescribed particle's row and column become the identity
//! (its direction is zero); its links stay on its free neighbours'
//! diagonals.
//!
//! Each step also adds the contacts' stiffness to the diagonal, the same
//! in every direction ([`InitialHessian::prepare`]'s `contact`): without
//! it the first directions of a step drove particles deep into their
//! solids' penalty, and a cloth on an incline slid 15 times Coulomb's creep
//! after 200 iterations a step.

use crate::terms::{At, JacobianBlocks, acting};
use crate::{ClothModel, Mat3, StepError, Vec3};
use cloth_linalg::{CholeskyError, ScalarCholesky};

/// How far the rest shape is stretched (about its centroid) where the
/// weights are read: enough to put every link on its tension branch.
pub(crate) const PROBE_STRETCH: f64 = 1e-3;

/// One coupled pair's weights and its slot in the factor.
#[derive(Debug, Clone, Copy)]
struct Edge {
    i: usize,
    j: usize,
    slot: usize,
    /// Stiffness weight, N/m.
    stiffness_n_m: f64,
    /// Damping weight, N s/m.
    damping_n_s_m: f64,
}

/// The factored initial Hessian and what it was factored for.
#[derive(Debug)]
pub(crate) struct InitialHessian {
    factor: ScalarCholesky,
    edges: Vec<Edge>,
    diagonal: Vec<usize>,
    /// Whether the factor is current, and the step (s), prescribed
    /// particles and contact stiffness (N/m) it was made for.
    valid: bool,
    factored_h: f64,
    factored_fixed: Vec<bool>,
    factored_contact: Vec<f64>,
}

/// The weight of a coupling block along its most negative direction:
/// `max(0, -lambda_min((B + B^T) / 2))`.
fn coupling_weight(block: &Mat3) -> f64 {
    let sym = (block + block.transpose()) * 0.5;
    (-sym.symmetric_eigenvalues().min()).max(0.0)
}

impl InitialHessian {
    /// The pattern and weights of `model` (`stitches_closed` as for the
    /// state), unfactored.
    pub(crate) fn new(model: &ClothModel, stitches_closed: &[bool]) -> Result<Self, CholeskyError> {
        let n = model.particle_count();
        let rest = model.rest_positions();
        let centroid = rest.iter().sum::<Vec3>() / n.max(1) as f64;
        let probe: Vec<Vec3> = rest.iter().map(|x| centroid + (x - centroid) * (1.0 + PROBE_STRETCH)).collect();
        let still = vec![Vec3::zeros(); n];
        let at = At::new(model, &probe, &still, stitches_closed);
        let mut weights: std::collections::BTreeMap<(usize, usize), (f64, f64)> = Default::default();
        for term in acting(model).filter(|t| !t.external()) {
            let pairs = term.coupled_pairs(model);
            if pairs.is_empty() {
                continue;
            }
            let blocks = JacobianBlocks::of(term, &at);
            for [a, b] in pairs.into_iter().filter(|[a, b]| a != b) {
                let (i, j) = (a.min(b), a.max(b));
                let w = weights.entry((i, j)).or_default();
                w.0 += coupling_weight(&blocks.stiffness(i, j));
                w.1 += coupling_weight(&blocks.damping(i, j));
            }
        }
        let factor = ScalarCholesky::new(n, weights.keys().copied())?;
        let slot = |i: usize, j: usize| factor.slot(i, j).expect("the factor's pattern holds every coupled pair");
        let edges = weights
            .iter()
            .map(|(&(i, j), &(stiffness_n_m, damping_n_s_m))| Edge {
                i,
                j,
                slot: slot(i, j),
                stiffness_n_m,
                damping_n_s_m,
            })
            .collect();
        let diagonal = (0..n).map(|i| slot(i, i)).collect();
        Ok(Self {
            factor,
            edges,
            diagonal,
            valid: false,
            factored_h: 0.0,
            factored_fixed: vec![false; n],
            factored_contact: vec![0.0; n],
        })
    }

    /// Factors `H0` for step `h` (s) with the particles `fixed` prescribed
    /// and `contact[i]` (N/m) added to particle `i`'s diagonal, unless the
    /// current factor is already for them; whether it factored.
    pub(crate) fn prepare(
        &mut self,
        model: &ClothModel,
        h: f64,
        fixed: &[bool],
        contact: &[f64],
    ) -> Result<bool, CholeskyError> {
        if self.valid
            && self.factored_h == h
            && self.factored_fixed[..] == *fixed
            && self.factored_contact[..] == *contact
        {
            return Ok(false);
        }
        self.valid = false;
        let masses = model.masses();
        let values = self.factor.values_mut();
        values.iter_mut().for_each(|v| *v = 0.0);
        for (i, &s) in self.diagonal.iter().enumerate() {
            values[s] = if fixed[i] { 1.0 } else { masses[i] / (h * h) + model.drag(i) / h + contact[i] };
        }
        for e in &self.edges {
            let w = e.stiffness_n_m + e.damping_n_s_m / h;
            for (k, other) in [(e.i, e.j), (e.j, e.i)] {
                if !fixed[k] && !fixed[other] {
                    values[e.slot] = -w;
                }
                if !fixed[k] {
                    values[self.diagonal[k]] += w;
                }
            }
        }
        self.factor.factor()?;
        self.factored_h = h;
        self.factored_fixed.copy_from_slice(fixed);
        self.factored_contact.copy_from_slice(contact);
        self.valid = true;
        Ok(true)
    }

    /// `H0^-1 r` in place (zero in the prescribed rows when `r` is).
    pub(crate) fn solve(&mut self, r: &mut [Vec3]) {
        self.factor.solve_vec3(r);
    }

    /// The matrix's entry `(i, j)` as factored (tests).
    #[cfg(test)]
    pub(crate) fn entry(&self, i: usize, j: usize) -> f64 {
        self.factor.slot(i, j).map_or(0.0, |s| self.factor.values()[s])
    }
}

/// A failed factor as a step's error.
pub(crate) fn factor_error(step: u64, time_s: f64, source: CholeskyError) -> StepError {
    StepError::Factor { step, time_s, source }
}
