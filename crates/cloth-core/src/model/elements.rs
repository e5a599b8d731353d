//! Multi-particle elements (Volino's membrane triangles and bending hinges)
//! and the drivers that fold them into forces and the system matrix.
//!
//! Each element adds `f_a` to its corners and `H_ab` (a PSD approximation of
//! `d^2 E / dx_a dx_b`, so `K_ab = -H_ab`) to the blocks between them:
//! `A_ab += c_x H_ab`, `b_a += c_f f_a - a_k (H w)_a`. Elements are
//! evaluated in parallel into per-element buffers; each particle then adds
//! its elements in a fixed order, as for links.

use crate::element_laws::{ElementResponse, TriangleRest, hinge_bending_with, membrane_triangle_with};
use crate::{Mat3, Vec3};
use cloth_linalg::{BlockPattern, ROW_CHUNK};
use rayon::prelude::*;

/// A membrane triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneElement {
    /// Corners.
    pub nodes: [u32; 3],
    /// Rest shape and stiffness.
    pub rest: TriangleRest,
}

/// A bending hinge: corners 0-1 are the shared edge, 2 and 3 the opposite
/// corners of triangles `(0, 1, 2)` and `(1, 0, 3)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HingeElement {
    /// Corners.
    pub nodes: [u32; 4],
    /// Rest dihedral angle, rad.
    pub rest_angle: f64,
    /// Stiffness `k` of `E = k (theta - theta_0)^2 / 2`, N m.
    pub k: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Corner {
    hinge: bool,
    elem: u32,
    corner: u8,
}

/// All elements of a model, with per-particle incidence and, once the
/// pattern is known, the matrix slot of every corner pair.
#[derive(Debug, Clone, Default)]
pub struct ElementSet {
    /// Membrane triangles.
    pub membranes: Vec<MembraneElement>,
    /// Bending hinges.
    pub hinges: Vec<HingeElement>,
    inc_ptr: Vec<usize>,
    inc: Vec<Corner>,
    membrane_slots: Vec<[[u32; 3]; 3]>,
    hinge_slots: Vec<[[u32; 4]; 4]>,
}

impl ElementSet {
    /// Whether there is no element (the link models).
    pub fn is_empty(&self) -> bool {
        self.membranes.is_empty() && self.hinges.is_empty()
    }

    /// Every coupled pair of particles, for the sparsity pattern.
    pub fn pairs(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        let mut add = |nodes: &[u32]| {
            for (a, &p) in nodes.iter().enumerate() {
                for &q in &nodes[a + 1..] {
                    out.push((p as usize, q as usize));
                }
            }
        };
        self.membranes.iter().for_each(|m| add(&m.nodes));
        self.hinges.iter().for_each(|h| add(&h.nodes));
        out
    }

    /// Builds incidence and slot tables for `n` particles and `pattern`.
    pub fn index(&mut self, n: usize, pattern: &BlockPattern) {
        let mut per: Vec<Vec<Corner>> = vec![Vec::new(); n];
        for (e, m) in self.membranes.iter().enumerate() {
            for (a, &p) in m.nodes.iter().enumerate() {
                per[p as usize].push(Corner { hinge: false, elem: e as u32, corner: a as u8 });
            }
        }
        for (e, h) in self.hinges.iter().enumerate() {
            for (a, &p) in h.nodes.iter().enumerate() {
                per[p as usize].push(Corner { hinge: true, elem: e as u32, corner: a as u8 });
            }
        }
        self.inc_ptr = std::iter::once(0)
            .chain(per.iter().scan(0, |acc, v| {
                *acc += v.len();
                Some(*acc)
            }))
            .collect();
        self.inc = per.into_iter().flatten().collect();
        let slot = |p: u32, q: u32| {
            (pattern.slot(p as usize, q as usize).expect("element pair in the pattern")
                - pattern.row_range(p as usize).start) as u32
        };
        self.membrane_slots = self
            .membranes
            .iter()
            .map(|m| std::array::from_fn(|a| std::array::from_fn(|b| slot(m.nodes[a], m.nodes[b]))))
            .collect();
        self.hinge_slots = self
            .hinges
            .iter()
            .map(|h| std::array::from_fn(|a| std::array::from_fn(|b| slot(h.nodes[a], h.nodes[b]))))
            .collect();
    }

    fn corners(&self, i: usize) -> &[Corner] {
        &self.inc[self.inc_ptr[i]..self.inc_ptr[i + 1]]
    }
}

/// One element's energy and right-hand-side terms.
#[derive(Debug, Clone, Copy)]
struct ElementRhs<const K: usize> {
    energy: f64,
    rhs: [Vec3; K],
}

impl<const K: usize> Default for ElementRhs<K> {
    fn default() -> Self {
        Self { energy: 0.0, rhs: [Vec3::zeros(); K] }
    }
}

/// Per-element scratch, sized once per model. Blocks live apart from the
/// right-hand sides so that a forces-only evaluation writes no blocks.
#[derive(Debug, Clone, Default)]
pub struct ElementBuffers {
    membranes: Vec<ElementRhs<3>>,
    membrane_blocks: Vec<[[Mat3; 3]; 3]>,
    hinges: Vec<ElementRhs<4>>,
    hinge_blocks: Vec<[[Mat3; 4]; 4]>,
}

impl ElementBuffers {
    /// Buffers for `set`.
    pub fn new(set: &ElementSet) -> Self {
        Self {
            membranes: vec![ElementRhs::default(); set.membranes.len()],
            membrane_blocks: vec![[[Mat3::zeros(); 3]; 3]; set.membranes.len()],
            hinges: vec![ElementRhs::default(); set.hinges.len()],
            hinge_blocks: vec![[[Mat3::zeros(); 4]; 4]; set.hinges.len()],
        }
    }
}

/// Folds a law's response into right-hand-side terms.
fn fold<const K: usize>(
    r: &ElementResponse<K>,
    nodes: &[u32; K],
    force: f64,
    k_times: Option<(f64, &[Vec3])>,
) -> ElementRhs<K> {
    let rhs = std::array::from_fn(|a| {
        let mut v = r.forces[a] * force;
        if let Some((coef, w)) = k_times {
            for b in 0..K {
                v -= r.hessian[a][b] * w[nodes[b] as usize] * coef;
            }
        }
        v
    });
    ElementRhs { energy: r.energy, rhs }
}

/// Evaluates every element at `x`: right-hand-side terms
/// `force f_a - a_k (H w)_a` and blocks `c_x H_ab` (no Hessian work and no
/// block writes when `c_x = 0` and there is no `k_times`, as for explicit
/// integrators).
pub fn evaluate(
    set: &ElementSet,
    x: &[Vec3],
    c_x: f64,
    force: f64,
    k_times: Option<(f64, &[Vec3])>,
    bufs: &mut ElementBuffers,
) {
    let hessian = c_x != 0.0 || k_times.is_some();
    let scale = |h: &Mat3| h * c_x;
    if hessian {
        bufs.membranes
            .par_iter_mut()
            .zip(bufs.membrane_blocks.par_iter_mut())
            .zip(set.membranes.par_iter())
            .with_min_len(ROW_CHUNK)
            .for_each(|((out, blocks), m)| {
                let r = membrane_triangle_with(m.nodes.map(|p| x[p as usize]), &m.rest, true);
                *out = fold(&r, &m.nodes, force, k_times);
                *blocks = r.hessian.map(|row| row.map(|h| scale(&h)));
            });
        bufs.hinges
            .par_iter_mut()
            .zip(bufs.hinge_blocks.par_iter_mut())
            .zip(set.hinges.par_iter())
            .with_min_len(ROW_CHUNK)
            .for_each(|((out, blocks), h)| {
                let r = hinge_bending_with(h.nodes.map(|p| x[p as usize]), h.rest_angle, h.k, true);
                *out = fold(&r, &h.nodes, force, k_times);
                *blocks = r.hessian.map(|row| row.map(|b| scale(&b)));
            });
    } else {
        bufs.membranes.par_iter_mut().zip(set.membranes.par_iter()).with_min_len(ROW_CHUNK).for_each(|(out, m)| {
            *out = fold(&membrane_triangle_with(m.nodes.map(|p| x[p as usize]), &m.rest, false), &m.nodes, force, None);
        });
        bufs.hinges.par_iter_mut().zip(set.hinges.par_iter()).with_min_len(ROW_CHUNK).for_each(|(out, h)| {
            let r = hinge_bending_with(h.nodes.map(|p| x[p as usize]), h.rest_angle, h.k, false);
            *out = fold(&r, &h.nodes, force, None);
        });
    }
}

/// Sum of the element right-hand-side terms at particle `i`.
pub fn rhs_at(set: &ElementSet, bufs: &ElementBuffers, i: usize) -> Vec3 {
    let mut acc = Vec3::zeros();
    for c in set.corners(i) {
        acc += if c.hinge {
            bufs.hinges[c.elem as usize].rhs[c.corner as usize]
        } else {
            bufs.membranes[c.elem as usize].rhs[c.corner as usize]
        };
    }
    acc
}

/// Adds the element blocks of row `i` into `row` (the row's stored blocks).
pub fn add_row(set: &ElementSet, bufs: &ElementBuffers, i: usize, row: &mut [Mat3]) {
    for c in set.corners(i) {
        let (e, a) = (c.elem as usize, c.corner as usize);
        if c.hinge {
            for (b, s) in set.hinge_slots[e][a].iter().enumerate() {
                row[*s as usize] += bufs.hinge_blocks[e][a][b];
            }
        } else {
            for (b, s) in set.membrane_slots[e][a].iter().enumerate() {
                row[*s as usize] += bufs.membrane_blocks[e][a][b];
            }
        }
    }
}

/// `sum_b blocks_ab w_b s_b` over the elements of particle `i` (with
/// `s = m^-1/2` for the mass-scaled operator).
pub fn apply_at(set: &ElementSet, bufs: &ElementBuffers, i: usize, w: &[Vec3], s: &[f64]) -> Vec3 {
    let mut acc = Vec3::zeros();
    for c in set.corners(i) {
        let (e, a) = (c.elem as usize, c.corner as usize);
        if c.hinge {
            for (b, &p) in set.hinges[e].nodes.iter().enumerate() {
                acc += bufs.hinge_blocks[e][a][b] * (w[p as usize] * s[p as usize]);
            }
        } else {
            for (b, &p) in set.membranes[e].nodes.iter().enumerate() {
                acc += bufs.membrane_blocks[e][a][b] * (w[p as usize] * s[p as usize]);
            }
        }
    }
    acc
}

/// Total element energy of the last [`evaluate`], J.
pub fn energy(bufs: &ElementBuffers) -> f64 {
    bufs.membranes.iter().map(|m| m.energy).sum::<f64>() + bufs.hinges.iter().map(|h| h.energy).sum::<f64>()
}
