//! Aerodynamic drag and lift on each triangle (effect `aerodynamics`),
//! shared equally by its corners ([`crate::aero_laws::triangle_aero_force`]),
//! with the triangle moving at its corners' mean velocity.

use super::{At, ForceTerm, VertexBlock};
use crate::aero_laws::{triangle_aero_derivative, triangle_aero_force};
use crate::terms::ForceBuffers;
use crate::{ClothModel, Vec3};

/// Drag and lift on triangles (effect `aerodynamics`): an external term,
/// taken as given over a step.
#[derive(Debug, Clone, Copy)]
pub struct Aerodynamics;

/// Triangle `tri`'s unit normal, area (m^2) and relative air velocity
/// `w = u - v_mean` (m/s); `None` for a degenerate triangle or no wind.
fn flow(at: &At<'_>, tri: [u32; 3]) -> Option<(Vec3, f64, Vec3)> {
    let air = at.air_m_s?;
    let [a, b, c] = tri.map(|k| k as usize);
    let (x, v) = (at.x, at.v);
    let cross = (x[b] - x[a]).cross(&(x[c] - x[a]));
    let area = 0.5 * cross.norm();
    if area == 0.0 {
        return None;
    }
    Some((cross / (2.0 * area), area, air - (v[a] + v[b] + v[c]) / 3.0))
}

/// The force on each corner of triangle `tri`, N.
fn corner_force(at: &At<'_>, tri: [u32; 3]) -> Option<Vec3> {
    let wind = at.model.wind()?;
    let (n, area, w) = flow(at, tri)?;
    let (rho, c_d, c_l) = (wind.air_density_kg_m3, wind.drag_coefficient, wind.lift_coefficient);
    // The law in terms of the triangle's velocity: w = wind - v with wind = w, v = 0.
    Some(triangle_aero_force(&n, area, &w, &Vec3::zeros(), rho, c_d, c_l) / 3.0)
}

impl ForceTerm for Aerodynamics {
    fn name(&self) -> &'static str {
        "aerodynamics"
    }

    fn acts_on(&self, model: &ClothModel) -> bool {
        model.effects().aerodynamics && model.wind().is_some()
    }

    fn external(&self) -> bool {
        true
    }

    fn energy(&self, _: &At<'_>) -> f64 {
        0.0
    }

    fn add_forces(&self, at: &At<'_>, _: &mut ForceBuffers, out: &mut [Vec3]) {
        for tri in at.model.triangles() {
            if let Some(f) = corner_force(at, *tri) {
                for k in tri {
                    out[*k as usize] += f;
                }
            }
        }
    }

    /// The force, and `-df_i/dv_i`: each triangle's `dF/dw / 9` (a third of
    /// the force, a third of the mean velocity). The stiffness block is
    /// zero: the normal's turn with position is not linearised, as the
    /// steps take the wind as given over a step.
    fn vertex(&self, at: &At<'_>, i: usize) -> VertexBlock {
        let Some(wind) = at.model.wind() else { return VertexBlock::zero() };
        let (rho, c_d, c_l) = (wind.air_density_kg_m3, wind.drag_coefficient, wind.lift_coefficient);
        let tris = at.model.triangles();
        let mut block = VertexBlock::zero();
        for &t in at.model.particle_triangles(i) {
            let tri = tris[t as usize];
            if let (Some(f), Some((n, area, w))) = (corner_force(at, tri), flow(at, tri)) {
                block.force += f;
                block.damping += triangle_aero_derivative(&n, area, &w, rho, c_d, c_l) / 9.0;
            }
        }
        block
    }
}
