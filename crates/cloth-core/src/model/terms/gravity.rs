//! Uniform gravity: `f_i = m_i g`, energy `-sum_i m_i g . x_i`.

use super::{At, ForceTerm, TermAssembly, TermScratch, VertexBlock};
use crate::model::assembly::{Row, SystemTerms};
use crate::terms::ForceBuffers;
use crate::{ClothModel, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// Gravity (`simulation.gravity_m_s2`, effect `gravity`).
#[derive(Debug, Clone, Copy)]
pub struct Gravity;

impl ForceTerm for Gravity {
    fn name(&self) -> &'static str {
        "gravity"
    }

    fn acts_on(&self, model: &ClothModel) -> bool {
        model.effects().gravity.is_some()
    }

    fn energy(&self, at: &At<'_>) -> f64 {
        let g = at.model.effects().gravity.unwrap_or_else(Vec3::zeros);
        -at.model.masses().iter().zip(at.x).map(|(m, x)| m * g.dot(x)).sum::<f64>()
    }

    fn add_forces(&self, at: &At<'_>, _: &mut ForceBuffers, out: &mut [Vec3]) {
        let Some(g) = at.model.effects().gravity else { return };
        let masses = at.model.masses();
        out.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, fs)| {
            for (k, f) in fs.iter_mut().enumerate() {
                *f += g * masses[chunk * ROW_CHUNK + k];
            }
        });
    }

    fn assembly(&self) -> Option<&dyn TermAssembly> {
        Some(self)
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let g = at.model.effects().gravity.unwrap_or_else(Vec3::zeros);
        VertexBlock { force: g * at.model.masses()[i], ..VertexBlock::zero() }
    }

    fn vertex_energy(&self, at: &At<'_>, i: usize, xi: Vec3) -> Option<f64> {
        let g = at.model.effects().gravity.unwrap_or_else(Vec3::zeros);
        Some(-at.model.masses()[i] * g.dot(&xi))
    }
}

/// Gravity adds `c_f m_i g` to each row's right-hand side; it has no
/// Jacobian.
impl TermAssembly for Gravity {
    fn scratch(&self, _: &ClothModel) -> TermScratch {
        Box::new(())
    }

    fn evaluate(&self, _: &At<'_>, _: &SystemTerms<'_>, _: &mut TermScratch) -> f64 {
        0.0
    }

    fn add_rhs(&self, at: &At<'_>, c: &SystemTerms<'_>, _: &TermScratch, i: usize, rhs: &mut Vec3) {
        if let Some(g) = at.model.effects().gravity {
            *rhs += g * (at.model.masses()[i] * c.force);
        }
    }

    fn add_row(&self, _: &At<'_>, _: &SystemTerms<'_>, _: &TermScratch, _: usize, _: &mut Row<'_>) {}
}
