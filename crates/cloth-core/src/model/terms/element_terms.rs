//! Multi-particle elements: Volino's membrane and bending triangles and
//! Choi & Ko's arc-path bending triples ([`crate::elements`], laws in
//! [`crate::element_laws`]).

use super::{At, ForceTerm, VertexBlock};
use crate::elements::{self, ElementBuffers};
use crate::forces::ForceBuffers;
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
        let mut bufs = ElementBuffers::forces_only(set);
        elements::evaluate(set, at.x, 0.0, 1.0, None, &mut bufs);
        elements::energy(&bufs)
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

    fn fused(&self) -> bool {
        true
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
