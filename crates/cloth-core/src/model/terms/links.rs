//! Two-particle links: Choi & Ko's type-1 and type-2 links, Provot's
//! springs, and the seams' stitches ([`crate::forces::eval_link`], laws in
//! [`crate::laws`]). Each link pulls its ends along their chord with its
//! law's force `phi(d)`, and its damper acts on their relative velocity.

use super::{At, ForceTerm, VertexBlock};
use crate::forces::{ForceBuffers, eval_link, gather_links, link_energy, link_energy_at_chord, link_force};
use crate::{ClothModel, Vec3};
use cloth_linalg::ROW_CHUNK;
use rayon::prelude::*;

/// Every link of the model (stretch links, bend links, stitches).
#[derive(Debug, Clone, Copy)]
pub struct Links;

impl ForceTerm for Links {
    fn name(&self) -> &'static str {
        "links"
    }

    fn acts_on(&self, model: &ClothModel) -> bool {
        model.link_count() > 0
    }

    fn energy(&self, at: &At<'_>) -> f64 {
        (0..at.model.link_count()).map(|k| link_energy(at.model, k, at.x, at.stitches_closed)).sum()
    }

    fn dissipation(&self, at: &At<'_>) -> f64 {
        (0..at.model.link_count())
            .map(|k| {
                let (i, j, _) = at.model.link_ends(k);
                let dv = at.v[j] - at.v[i];
                dv.dot(&(eval_link(at.model, k, at.x, at.stitches_closed).damping * dv))
            })
            .sum()
    }

    fn add_forces(&self, at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]) {
        let (model, x, v, closed) = (at.model, at.x, at.v, at.stitches_closed);
        scratch.link.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, fs)| {
            for (k, f) in fs.iter_mut().enumerate() {
                *f = link_force(model, chunk * ROW_CHUNK + k, x, v, closed);
            }
        });
        let link = &scratch.link;
        out.par_chunks_mut(ROW_CHUNK).enumerate().for_each(|(chunk, fs)| {
            for (k, f) in fs.iter_mut().enumerate() {
                *f = gather_links(model, chunk * ROW_CHUNK + k, link, *f);
            }
        });
    }

    fn fused(&self) -> bool {
        true
    }

    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        self.vertex_with_energy(at, i).0
    }

    fn vertex_with_energy(&self, at: &At<'_>, i: usize) -> (VertexBlock, Option<f64>) {
        let (mut block, mut energy) = (VertexBlock::zero(), 0.0);
        for inc in at.model.incidence(i) {
            let e = eval_link(at.model, inc.link as usize, at.x, at.stitches_closed);
            let elastic = if inc.first { e.force } else { -e.force };
            let relative = at.v[inc.other as usize] - at.v[i];
            let damper = e.damping * relative;
            block.force += elastic + damper;
            block.dissipative += damper;
            block.stiffness += e.stiffness;
            block.damping += e.damping;
            energy += e.energy;
        }
        (block, Some(energy))
    }

    fn vertex_energy(&self, at: &At<'_>, i: usize, xi: Vec3) -> Option<f64> {
        let energy = at.model.incidence(i).iter().map(|inc| {
            let chord = (at.x[inc.other as usize] - xi).norm();
            link_energy_at_chord(at.model, inc.link as usize, chord, at.stitches_closed)
        });
        Some(energy.sum())
    }
}
