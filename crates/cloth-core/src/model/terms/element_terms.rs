//! Multi-particle elements: Volino's membrane and bending triangles and
//! Choi & Ko's arc-path bending triples ([`crate::elements`], laws in
//! [`crate::element_laws`]).

use super::{At, ForceTerm, TermAssembly, TermScratch, VertexBlock};
use crate::elements::{self, ElementBuffers, ElementEnergies};
use crate::model::assembly::{Row, SystemTerms};
use crate::terms::ForceBuffers;
use crate::{ClothModel, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// Every element of the model.
#[derive(Debug, Clone, Copy)]
pub struct Elements;

impl ForceTerm for Elements {
    fn name(&self) -> &'static str {
        "elements"
    }

    fn acts_on(&self, model: &ClothModel) -> bool {
        !model.elements().is_empty()
    }

    /// Allocates its scratch: for tests and line searches, not the step.
    fn energy(&self, at: &At<'_>) -> f64 {
        let set = at.model.elements();
        elements::energy_only(set, at.x, &mut ElementEnergies::new(set))
    }

    fn add_forces(&self, at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]) {
        let set = at.model.elements();
        elements::evaluate(set, at.x, 0.0, 1.0, None, &mut scratch.elements);
        let bufs = &scratch.elements;
        out.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, fs)| {
            for (k, f) in fs.iter_mut().enumerate() {
                *f += elements::rhs_at(set, bufs, chunk * ROW_CHUNK + k);
            }
        });
    }

    fn coupled_pairs(&self, model: &ClothModel) -> Vec<[usize; 2]> {
        model.elements().pairs().into_iter().map(|(i, j)| [i, j]).collect()
    }

    /// Each element's forces and Hessian blocks, `-df_a/dx_b`; no damping.
    fn jacobian(&self, at: &At<'_>, out: &mut super::Jacobian<'_>) {
        let mut blocks = Vec::new();
        elements::for_each_block(
            at.model.elements(),
            at.x,
            |a, f| out.add_force(a, f),
            |a, b, h| {
                blocks.push((a, b, *h));
            },
        );
        for (a, b, h) in blocks {
            out.add_stiffness(a, b, &h);
        }
    }

    fn assembly(&self) -> Option<&dyn TermAssembly> {
        Some(self)
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let (force, stiffness) = elements::vertex_at(at.model.elements(), at.x, i);
        VertexBlock { force, stiffness, ..VertexBlock::zero() }
    }

    fn vertex_energy(&self, at: &At<'_>, i: usize, xi: Vec3) -> Option<f64> {
        Some(elements::vertex_energy(at.model.elements(), at.x, i, xi))
    }

    fn vertex_with_energy(&self, at: &At<'_>, i: usize) -> (VertexBlock, Option<f64>) {
        let (force, stiffness, energy) = elements::vertex_with_energy(at.model.elements(), at.x, i);
        (VertexBlock { force, stiffness, ..VertexBlock::zero() }, Some(energy))
    }
}

fn buffers(scratch: &TermScratch) -> &ElementBuffers {
    scratch.downcast_ref().expect("the elements' own scratch")
}

/// Each element's right-hand-side terms `c_f f_a - a_k (H w)_a` and blocks
/// `c_x H_ab`, evaluated in parallel; each row sums its elements' corners
/// in a fixed order. The elements carry no damping.
impl TermAssembly for Elements {
    fn scratch(&self, model: &ClothModel) -> TermScratch {
        Box::new(ElementBuffers::new(model.elements()))
    }

    fn evaluate(&self, at: &At<'_>, c: &SystemTerms<'_>, scratch: &mut TermScratch) -> f64 {
        let bufs: &mut ElementBuffers = scratch.downcast_mut().expect("the elements' own scratch");
        elements::evaluate(at.model.elements(), at.x, c.c_x, c.force, c.k_times, bufs);
        elements::energy(at.model.elements(), bufs)
    }

    fn add_rhs(&self, at: &At<'_>, _: &SystemTerms<'_>, scratch: &TermScratch, i: usize, rhs: &mut Vec3) {
        *rhs += elements::rhs_at(at.model.elements(), buffers(scratch), i);
    }

    fn add_row(&self, at: &At<'_>, _: &SystemTerms<'_>, scratch: &TermScratch, i: usize, row: &mut Row<'_>) {
        elements::add_row(at.model.elements(), buffers(scratch), i, |slot, b| row.add(slot, b));
    }

    fn apply(&self, at: &At<'_>, scratch: &TermScratch, i: usize, w: &[Vec3], s: &[f64], acc: &mut Vec3) {
        *acc += elements::apply_at(at.model.elements(), buffers(scratch), i, w, s);
    }

    fn couples(&self) -> bool {
        true
    }
}
