//! The parts of [`ClothModel::build`](super::ClothModel::build) that a
//! mesh panel adds: links, type-2 interactions and Volino's elements with
//! the constants of [`crate::cloth_mesh`]'s module docs.

use super::build_parts::{BendingTriangle, clamped, plane_coordinates, volino_elements};
use super::*;
use crate::FieldError;
use crate::cloth_mesh::{ClothMesh, MeshTopology};
use crate::element_laws::TriangleRest;
use crate::elements::{BendHinge, MembraneElement};
use crate::material::PATH_CURVATURE_FACTOR;

/// The hinges' bending Poisson ratio is -1/3 (`crate::cloth_mesh`): a
/// strip free to curve across itself bends with `1 - nu^2 = 8/9` of the
/// rigidity a cylinder meets. `B` is the strip's (Peirce's cantilever
/// measures it; the grids and Volino's triangles, Poisson ratio 0, meet
/// both), so the hinges take `1 / (1 - nu^2) = 9/8` of it: the cantilever
/// at 1 cm reads 41.42 degrees against the elastica's 41.49 (44.28
/// without), a cylinder stores 1.125-1.17 of `B kappa^2 / 2`.
pub(super) const FREE_STRIP_FACTOR: f64 = 9.0 / 8.0;

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
) -> Result<MeshParts, FieldError> {
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
    let bad = |what: String| FieldError::new("triangles", what);
    let mut stretch = Vec::with_capacity(topology.edges.len());
    for edge in &topology.edges {
        let [a, c] = edge.ends;
        let rest = (p[c as usize] - p[a as usize]).norm();
        let per_length = edge.area / (rest * rest);
        // Choi & Ko's and Volino's membranes are triangles; their links damp and limit.
        let k_s = if spec.kind == ModelKind::Provot { (1.0 - flexion_share) * e * per_length } else { 0.0 };
        let k_d = if spec.effects.damping { d * per_length } else { 0.0 };
        if !(rest > 0.0 && [k_s, k_d].iter().all(|v| v.is_finite())) {
            return Err(bad(format!("edge {a}-{c} has no length or finite constants")));
        }
        stretch.push(StretchLink { i: at(a), j: at(c), rest, k_s, compression: Compression::Linear(k_s), k_d });
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
                    let k_b = FREE_STRIP_FACTOR * PATH_CURVATURE_FACTOR * b * h.area / (h.unfolded * halves);
                    hinges.push(BendHinge { nodes: h.nodes.map(at), w, rest: h.unfolded, k_b });
                }
            }
        }
    }
    let (mut membranes, mut bending_triangles) = (Vec::new(), Vec::new());
    if spec.kind == ModelKind::ChoiKo {
        let nu = e / (2.0 * m.shear_modulus()) - 1.0;
        membranes = tension_field_elements(p, &mesh.triangles, e, nu, b, offset)
            .ok_or_else(|| bad("a triangle has no area".into()))?;
    }
    if spec.kind == ModelKind::Volino {
        let (elements, triangles) = volino_elements(
            p,
            &mesh.triangles,
            m,
            &|k| *mesh.triangle_wefts.get(k).unwrap_or(&mesh.weft),
            index,
            offset,
        )
        .ok_or_else(|| bad("a triangle has no area in the weft's frame".into()))?;
        membranes = elements;
        if bending {
            bending_triangles = triangles;
        }
    }
    Ok(MeshParts { stretch, flexion, hinges, membranes, bending: bending_triangles, topology })
}

/// Choi & Ko's membrane on a mesh: a tension-field triangle
/// ([`TriangleRest::tension_field`]) of modulus `e` (N/m) and Poisson ratio
/// `nu` on each triangle, wrinkling at the onset of their arc law for a
/// strip of the triangle's size `l` and rigidity `b` (N m): `sigma_b = 12
/// b / l^2`, `l^2 = 4 A / sqrt(3)` (the equilateral triangle of its area).
/// None if a triangle is degenerate.
fn tension_field_elements(
    p: &[crate::Vec3],
    triangles: &[[u32; 3]],
    e: f64,
    nu: f64,
    b: f64,
    offset: u32,
) -> Option<Vec<MembraneElement>> {
    triangles
        .iter()
        .map(|t| {
            let x = t.map(|k| p[k as usize]);
            // Isotropic: any axis in the plane will do.
            let uv = plane_coordinates(x, x[2] - x[0])?;
            let area = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
            let sigma_b = 12.0 * b * 3f64.sqrt() / (4.0 * area);
            Some(MembraneElement {
                nodes: t.map(|k| k + offset),
                rest: TriangleRest::tension_field(uv, e, nu, sigma_b)?,
            })
        })
        .collect()
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
