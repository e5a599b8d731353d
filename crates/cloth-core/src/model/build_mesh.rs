//! The parts of [`ClothModel::build`](super::ClothModel::build) that a
//! mesh panel adds: links, type-2 interactions and Volino's elements with
//! the constants of [`crate::cloth_mesh`]'s module docs.

use super::build_parts::{BendingTriangle, clamped, volino_elements};
use super::*;
use crate::cloth_mesh::{ClothMesh, MeshError, MeshTopology};
use crate::elements::{BendHinge, MembraneElement};
use crate::material::{Compressive, PATH_CURVATURE_FACTOR};

/// The shear modulus of a spring lattice on triangles: `3E/8` (Poisson
/// ratio 1/3), N/m for `E` in N/m.
pub fn triangle_lattice_shear_modulus(e: f64) -> f64 {
    3.0 / 8.0 * e
}

/// What one mesh panel adds to the model (global particle indices).
pub(super) struct MeshParts {
    pub stretch: Vec<StretchLink>,
    pub flexion: Vec<BendLink>,
    pub hinges: Vec<BendHinge>,
    pub membranes: Vec<MembraneElement>,
    pub bending: Vec<BendingTriangle>,
    pub topology: MeshTopology,
}

/// The models' parts on `mesh`, its particles from `offset`; `index`
/// names it among all panels (grids first) in bending-triangle errors.
pub(super) fn mesh_parts(
    spec: &ModelSpec,
    mesh: &ClothMesh,
    index: usize,
    offset: u32,
    compressive: Compressive,
) -> Result<MeshParts, MeshError> {
    let m = &spec.material;
    let (e, b, d) = (m.tensile_stiffness_n_m, m.flexural_rigidity_n_m, m.damping_n_s_m);
    let bending = spec.effects.bending;
    let flexion_share = if spec.kind == ModelKind::Provot && bending {
        m.buckling_stiffness_n_m / (e + m.buckling_stiffness_n_m)
    } else {
        0.0
    };
    let topology = mesh.topology();
    let p = &mesh.positions;
    let at = |k: u32| k + offset;
    let bad = |what: String| ("triangles", what);
    let mut stretch = Vec::with_capacity(topology.edges.len());
    for edge in &topology.edges {
        let [a, c] = edge.ends;
        let rest = (p[c as usize] - p[a as usize]).norm();
        let per_length = edge.area / (rest * rest);
        let k_s = if spec.kind == ModelKind::Volino { 0.0 } else { (1.0 - flexion_share) * e * per_length };
        let k_d = if spec.effects.damping { d * per_length } else { 0.0 };
        if !(rest > 0.0 && [k_s, k_d].iter().all(|v| v.is_finite())) {
            return Err(bad(format!("edge {a}-{c} has no length or finite constants")));
        }
        let compression = match spec.kind {
            // Linear: capped at its strip's buckling load, a triangle with one
            // slack edge folds in its plane (module docs of `cloth_mesh`).
            ModelKind::ChoiKo => Compression::Linear(compressive.ratio * k_s),
            ModelKind::Provot => Compression::Linear(k_s),
            ModelKind::Volino => Compression::Linear(0.0),
        };
        stretch.push(StretchLink { i: at(a), j: at(c), rest, k_s, compression, k_d });
    }
    let (mut flexion, mut hinges) = (Vec::new(), Vec::new());
    if bending && spec.kind != ModelKind::Volino {
        for h in &topology.hinges {
            let [c, _, _, q] = h.nodes;
            match spec.kind {
                ModelKind::Provot => {
                    let rest = (p[q as usize] - p[c as usize]).norm();
                    let k = flexion_share * e * h.area / (rest * rest);
                    flexion.push(BendLink { i: at(c), j: at(q), law: BendLaw::Flexion { rest, k } });
                }
                _ => {
                    let Some(w) = h.crossing else { continue };
                    // Halves a L and (1 - a) L read 1 - r = kappa^2 a (1 - a) L^2 / 2,
                    // 4 a (1 - a) times what equal halves read.
                    // (At most 4 times: a middle within 7% of an end reads too little to scale up.)
                    let halves = (4.0 * h.first_half * (1.0 - h.first_half)).max(0.25);
                    let k_b = PATH_CURVATURE_FACTOR * b * h.area / (h.unfolded * halves);
                    hinges.push(BendHinge { nodes: h.nodes.map(at), w, rest: h.unfolded, k_b });
                }
            }
        }
    }
    let (mut membranes, mut bending_triangles) = (Vec::new(), Vec::new());
    if spec.kind == ModelKind::Volino {
        let (elements, triangles) = volino_elements(p, &mesh.triangles, m, mesh.weft, index, offset)
            .ok_or_else(|| bad("a triangle has no area in the weft's frame".into()))?;
        membranes = elements;
        if bending {
            bending_triangles = triangles;
        }
    }
    Ok(MeshParts { stretch, flexion, hinges, membranes, bending: bending_triangles, topology })
}

/// Clamped type-2 interactions across a mesh edge: the edge pinned and one
/// far corner too stand for half a free one's bending, as on the grid
/// ([`spans_clamp`]), so their rigidity doubles.
pub(super) fn clamp_hinges(hinges: &mut [BendHinge], pinned: &[bool]) {
    for h in hinges.iter_mut() {
        let [c, a, b, d] = h.nodes.map(|q| pinned[q as usize]);
        if clamped(a && b, [c, d]) {
            h.k_b *= 2.0;
        }
    }
}
