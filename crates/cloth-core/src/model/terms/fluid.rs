//! Provot's (1995) viscous fluid force (effect `wind`): on each particle,
//! `F = C_v A_i [n_i . (u - v_i)] n_i`, with `n_i` the particle's
//! area-weighted normal and `A_i` a third of its triangles' area
//! ([`crate::aero_laws::provot_fluid_force`]).

use super::{At, ForceTerm, VertexBlock};
use crate::aero_laws::provot_fluid_force;
use crate::terms::ForceBuffers;
use crate::{ClothModel, Mat3, Vec3};

/// Provot's fluid force (effect `wind`): an external term, taken as given
/// over a step.
#[derive(Debug, Clone, Copy)]
pub struct Fluid;

/// Twice the area-weighted normal of a triangle (`|cross| = 2 area`).
fn cross(x: &[Vec3], [a, b, c]: [u32; 3]) -> Vec3 {
    let [a, b, c] = [a, b, c].map(|k| k as usize);
    (x[b] - x[a]).cross(&(x[c] - x[a]))
}

/// The force on a particle whose triangles' crosses sum to `normal` (the
/// area-weighted normal, six times the particle's area long), and `C_v A n n^T`.
fn particle_force(at: &At<'_>, i: usize, normal: Vec3) -> Option<(Vec3, Mat3)> {
    let (wind, air) = (at.model.wind()?, at.air_m_s?);
    let len = normal.norm();
    if len == 0.0 {
        return None;
    }
    // A particle's area: a third of its triangles' areas.
    let (n, area) = (normal / len, len / 6.0);
    let c = wind.fluid_coefficient_n_s_m3;
    Some((provot_fluid_force(&n, area, c, &air, &at.v[i]), n * n.transpose() * (c * area)))
}

impl ForceTerm for Fluid {
    fn name(&self) -> &'static str {
        "wind"
    }

    fn acts_on(&self, model: &ClothModel) -> bool {
        model.effects().wind && model.wind().is_some()
    }

    fn external(&self) -> bool {
        true
    }

    fn energy(&self, _: &At<'_>) -> f64 {
        0.0
    }

    fn add_forces(&self, at: &At<'_>, scratch: &mut ForceBuffers, out: &mut [Vec3]) {
        let normals = &mut scratch.normals;
        normals.clear();
        normals.resize(at.x.len(), Vec3::zeros());
        for tri in at.model.triangles() {
            let cross = cross(at.x, *tri);
            if cross.norm() == 0.0 {
                continue;
            }
            for k in tri {
                normals[*k as usize] += cross;
            }
        }
        for (i, n) in normals.iter().enumerate() {
            if let Some((f, _)) = particle_force(at, i, *n) {
                out[i] += f;
            }
        }
    }

    /// The force, and `-df_i/dv_i = C_v A_i n_i n_i^T`. The stiffness block
    /// is zero: the normal's turn with position is not linearised, as the
    /// steps take the wind as given over a step.
    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let tris = at.model.triangles();
        let normal = at.model.particle_triangles(i).iter().map(|&t| cross(at.x, tris[t as usize])).sum();
        match particle_force(at, i, normal) {
            Some((force, damping)) => {
                VertexBlock { force, stiffness: Mat3::zeros(), damping, dissipative: Vec3::zeros() }
            }
            None => VertexBlock::zero(),
        }
    }
}
