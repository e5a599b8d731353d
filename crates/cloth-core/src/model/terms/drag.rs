//! Viscous drag on every particle (Provot's "viscous damping" `-C_dis v`):
//! `f_i = -c_i v_i`, `c_i = material.drag_n_s_m3` times the particle's area.

use super::{At, ForceTerm, VertexBlock};
use crate::forces::ForceBuffers;
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

    fn fused(&self) -> bool {
        true
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let c = at.model.drag(i);
        let force = -at.v[i] * c;
        VertexBlock { force, stiffness: Mat3::zeros(), damping: Mat3::identity() * c, dissipative: force }
    }
}
