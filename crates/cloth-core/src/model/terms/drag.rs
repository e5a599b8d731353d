//! Viscous drag on every particle (Provot's "viscous damping" `-C_dis v`):
//! `f_i = -c_i v_i`, `c_i = material.drag_n_s_m3` times the particle's area.

use super::{At, ForceTerm, TermAssembly, TermScratch, VertexBlock};
use crate::model::assembly::{Row, SystemTerms};
use crate::terms::ForceBuffers;
use crate::{ClothModel, Mat3, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// Drag (effect `drag`).
#[derive(Debug, Clone, Copy)]
pub struct Drag;

impl ForceTerm for Drag {
    fn name(&self) -> &'static str {
        "drag"
    }

    fn acts_on(&self, model: &ClothModel) -> bool {
        model.has_drag()
    }

    fn energy(&self, _: &At<'_>) -> f64 {
        0.0
    }

    fn dissipation(&self, at: &At<'_>) -> f64 {
        at.v.iter().enumerate().map(|(i, v)| at.model.drag(i) * v.norm_squared()).sum()
    }

    fn add_forces(&self, at: &At<'_>, _: &mut ForceBuffers, out: &mut [Vec3]) {
        out.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, fs)| {
            for (k, f) in fs.iter_mut().enumerate() {
                let i = chunk * ROW_CHUNK + k;
                *f -= at.v[i] * at.model.drag(i);
            }
        });
    }

    fn assembly(&self) -> Option<&dyn TermAssembly> {
        Some(self)
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let c = at.model.drag(i);
        let force = -at.v[i] * c;
        VertexBlock { force, stiffness: Mat3::zeros(), damping: Mat3::identity() * c, dissipative: force }
    }
}

/// Drag is a diagonal damping `D_ii = -c_i I`: it adds `c_v c_i I` to each
/// diagonal block and `-a_d c_i w_i` to the right-hand side.
impl TermAssembly for Drag {
    fn scratch(&self, _: &ClothModel) -> TermScratch {
        Box::new(())
    }

    fn evaluate(&self, _: &At<'_>, _: &SystemTerms<'_>, _: &mut TermScratch) -> f64 {
        0.0
    }

    fn add_rhs(&self, at: &At<'_>, c: &SystemTerms<'_>, _: &TermScratch, i: usize, rhs: &mut Vec3) {
        if let Some((a, w)) = c.d_times {
            *rhs -= w[i] * (a * at.model.drag(i));
        }
    }

    fn add_row(&self, at: &At<'_>, c: &SystemTerms<'_>, _: &TermScratch, i: usize, row: &mut Row<'_>) {
        row.add_diag(&(Mat3::identity() * (c.c_v * at.model.drag(i))));
    }
}
