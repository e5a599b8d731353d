//! The parts of [`ClothModel::build`](super::ClothModel::build): pins,
//! clamped bending near pins, and the bending and membrane elements of
//! Volino's model and of Choi & Ko's arc-path law.

use super::*;
use crate::element_laws::{EdgeSupport, TriangleRest, curvature_stiffness, dihedral_angle, edge_hinge};
use crate::elements::{BendTriple, CurvatureElement, MembraneElement};
use crate::material::Compressive;
use crate::{Edge, Material, Pin, Vec3, laws::BucklingLaw};

/// How a lattice model's links resist compression before they buckle
/// (`crate::material` docs, "Three lattices"): the arc-path law's type-1
/// links with the ramp `c_b = (C_b / E) k_s`; Provot's linear springs
/// (his flexion springs share the axis links' stiffness); the arc-chord
/// law's type-2 ramps only (`(2/3) C_b` per area along
/// each axis, `C_b / 3` on each diagonal family).
pub(super) fn compressive_response(spec: &ModelSpec, path: bool) -> Compressive {
    let (c_b, e) = (spec.material.buckling_stiffness_n_m, spec.material.tensile_stiffness_n_m);
    let bending = spec.effects.bending;
    match spec.kind {
        ModelKind::ChoiKo if path => Compressive { ratio: c_b / e, ..Compressive::default() },
        ModelKind::ChoiKo if bending => Compressive { ratio: 0.0, axis: 2.0 / 3.0 * c_b, diagonal: c_b / 3.0 },
        ModelKind::Provot => Compressive { ratio: 1.0, ..Compressive::default() },
        ModelKind::ChoiKo | ModelKind::Volino => Compressive::default(),
    }
}

pub(super) fn build_pins(
    spec: &ModelSpec,
    panels: &[PanelRange],
    meshes: &[MeshRange],
    rest: &[Vec3],
) -> Result<(Vec<Pin>, Vec<bool>), ModelError> {
    let mut pins = Vec::new();
    let mut pinned = vec![false; rest.len()];
    for (k, ps) in spec.pins.iter().enumerate() {
        let err = |field: &str, message: String| ModelError::Pin { pin: k, field: field.into(), message };
        ps.motion.validate().map_err(|e| err("motion", e.message))?;
        if let Some(m) = ps.mesh {
            let mesh =
                meshes.get(m).ok_or_else(|| err("mesh", format!("no mesh {m} (the scene has {})", meshes.len())))?;
            if ps.panel != 0 || !ps.nodes.is_empty() || ps.edge.is_some() {
                return Err(err("mesh", "pins a mesh's `vertices`: `panel`, `nodes` and `edge` are a grid's".into()));
            }
            let mut vertices = ps.vertices.clone();
            for &e in &ps.outline_edges {
                let edge = mesh.outline_edges.get(e).ok_or_else(|| {
                    let n = mesh.outline_edges.len();
                    err(
                        "outline_edges",
                        format!("no outline edge {e} (mesh {m} has {n}: only pattern pieces have them)"),
                    )
                })?;
                // Neighbouring edges share their corner: pinned once.
                for v in edge.iter().map(|&v| v as usize) {
                    if !vertices.contains(&v) {
                        vertices.push(v);
                    }
                }
            }
            if vertices.is_empty() {
                return Err(err("vertices", "pins nothing: list the mesh's vertices or outline edges".into()));
            }
            for &v in &vertices {
                if v >= mesh.len {
                    return Err(err("vertices", format!("vertex {v} is outside the mesh's {}", mesh.len)));
                }
                let particle = mesh.offset + v;
                if pinned[particle] {
                    return Err(err("vertices", format!("vertex {v} is pinned twice")));
                }
                pinned[particle] = true;
                pins.push(Pin { particle, anchor: rest[particle], motion: ps.motion.clone(), spec: k });
            }
            continue;
        }
        if !ps.vertices.is_empty() || !ps.outline_edges.is_empty() {
            let field = if ps.vertices.is_empty() { "outline_edges" } else { "vertices" };
            return Err(err(field, "are a mesh's: give `mesh` too".into()));
        }
        let panel = *panels
            .get(ps.panel)
            .ok_or_else(|| err("panel", format!("no panel {} (the scene has {})", ps.panel, panels.len())))?;
        let mut nodes = ps.nodes.clone();
        if let Some(edge) = ps.edge {
            let (nx, ny) = (panel.nx, panel.ny);
            match edge {
                Edge::IMin => nodes.extend((0..ny).map(|j| [0, j])),
                Edge::IMax => nodes.extend((0..ny).map(|j| [nx - 1, j])),
                Edge::JMin => nodes.extend((0..nx).map(|i| [i, 0])),
                Edge::JMax => nodes.extend((0..nx).map(|i| [i, ny - 1])),
            }
        }
        if nodes.is_empty() {
            return Err(err("nodes", "pins nothing: give `nodes` or `edge`".into()));
        }
        for [i, j] in nodes {
            if i >= panel.nx || j >= panel.ny {
                return Err(err("nodes", format!("node [{i}, {j}] is outside the {} x {} grid", panel.nx, panel.ny)));
            }
            let particle = panel.offset + j * panel.nx + i;
            if pinned[particle] {
                return Err(err("nodes", format!("node [{i}, {j}] is pinned twice")));
            }
            pinned[particle] = true;
            pins.push(Pin { particle, anchor: rest[particle], motion: ps.motion.clone(), spec: k });
        }
    }
    Ok((pins, pinned))
}

/// Mesh panels with a lattice model: Choi & Ko's arc-chord law needs the
/// grid's middle particles and family areas, and a spring lattice on
/// triangles has the shear modulus `3E/8` only ([`crate::cloth_mesh`]), so
/// a different one given is refused rather than ignored.
pub(super) fn check_lattice_on_meshes(spec: &ModelSpec, path: bool) -> Result<(), ModelError> {
    if spec.kind == ModelKind::ChoiKo && !path {
        return Err(ModelError::MeshBendingLaw);
    }
    let m = &spec.material;
    let (e, g) = (m.tensile_stiffness_n_m, m.shear_modulus());
    if spec.kind == ModelKind::ChoiKo && g <= e / 4.0 {
        let message = format!("{g} N/m: an isotropic membrane of E = {e} N/m needs G > E/4 (Poisson ratio under 1)");
        return Err(ModelError::Material { field: "shear_modulus_n_m".into(), message });
    }
    let lattice = crate::material::triangle_lattice_shear_modulus(m.tensile_stiffness_n_m);
    if let Some(g) = m.shear_modulus_n_m
        && spec.kind == ModelKind::Provot
        && (g - lattice).abs() > 1e-3 * lattice
    {
        let message = format!(
            "{g} N/m: {}'s springs on a triangle mesh have G = 3E/8 = {lattice} N/m; the volino model takes any",
            spec.kind.name()
        );
        return Err(ModelError::Material { field: "shear_modulus_n_m".into(), message });
    }
    Ok(())
}

/// Whether a type-2 interaction across `(i, m, j)` spans a clamped edge: its
/// middle particle and one end pinned, the other end free. It then stands
/// for half the bending of a free one (the pinned half of its span cannot
/// bend), so its constants double (see [`crate::material`]).
pub(super) fn spans_clamp(pinned: &[bool], [i, m, j]: [u32; 3]) -> bool {
    let [i, m, j] = [i, m, j].map(|q| pinned[q as usize]);
    clamped(m, [i, j])
}

/// The clamp rule of [`spans_clamp`] on pinned flags: the middle pinned
/// and exactly one end.
pub(super) fn clamped(middle: bool, [i, j]: [bool; 2]) -> bool {
    middle && i != j
}

/// Doubles the constants of the paper's type-2 links that [`spans_clamp`].
pub(super) fn clamp_bend_links(bend: &mut [BendLink], middle: &[Option<u32>], pinned: &[bool]) {
    for (link, middle) in bend.iter_mut().zip(middle) {
        let (Some(m), BendLaw::Buckling(law)) = (middle, &mut link.law) else { continue };
        if spans_clamp(pinned, [link.i, *m, link.j]) {
            *law = BucklingLaw::new(law.rest, 2.0 * law.k_b, 2.0 * law.c_b);
        }
    }
}

/// Doubles the rigidity of the type-2 triples that [`spans_clamp`].
pub(super) fn clamp_triples(triples: &mut [BendTriple], pinned: &[bool]) {
    for t in triples.iter_mut().filter(|t| spans_clamp(pinned, t.nodes)) {
        t.k_b *= 2.0;
    }
}

/// A bending triangle before the pins are known: its corners and the
/// corner across each edge (None on a free edge), as global indices.
#[derive(Debug, Clone, Copy)]
pub(super) struct BendingTriangle {
    panel: usize,
    corners: [u32; 3],
    across: [Option<u32>; 3],
}

/// Volino's bending elements, once the pins are known: a triangle whose
/// corners are all pinned bends nowhere and has none; an edge it shares
/// with a free triangle is a clamp there (the mid-edge slope is the
/// clamp's: [`EdgeSupport::Clamped`]). Without that the clamp line of
/// Peirce's cantilever is as compliant as a cell's width of free cloth.
/// Err(panel) if a triangle of that panel is degenerate.
pub(super) fn curvature_elements(
    triangles: &[BendingTriangle],
    rest: &[Vec3],
    pinned: &[bool],
    b: f64,
) -> Result<Vec<CurvatureElement>, usize> {
    let is_pinned = |q: u32| pinned[q as usize];
    let mut out = Vec::with_capacity(triangles.len());
    for t in triangles.iter().filter(|t| !t.corners.iter().all(|&q| is_pinned(q))) {
        let c = t.corners;
        let support: [EdgeSupport; 3] = std::array::from_fn(|k| match t.across[k] {
            None => EdgeSupport::Free,
            Some(o) if is_pinned(o) && is_pinned(c[(k + 1) % 3]) && is_pinned(c[(k + 2) % 3]) => EdgeSupport::Clamped,
            Some(_) => EdgeSupport::Shared,
        });
        let across = std::array::from_fn(|k| rest[t.across[k].unwrap_or(c[k]) as usize]);
        let stiffness = curvature_stiffness(c.map(|q| rest[q as usize]), support, across, b).ok_or(t.panel)?;
        if stiffness == crate::Mat3::zeros() {
            continue;
        }
        // A free edge's neighbour slot repeats the opposite corner (never evaluated).
        let nodes =
            [c[0], c[1], c[2], t.across[0].unwrap_or(c[0]), t.across[1].unwrap_or(c[1]), t.across[2].unwrap_or(c[2])];
        let x = nodes.map(|q| rest[q as usize]);
        let rest_angles = std::array::from_fn(|k| match t.across[k] {
            Some(_) => dihedral_angle(&edge_hinge(k).map(|a| x[a])),
            None => 0.0,
        });
        out.push(CurvatureElement { nodes, rest_angles, stiffness });
    }
    Ok(out)
}

/// A triangle's corners `x` in its own plane, from its first corner, with
/// the second coordinate along `v_axis` projected on the plane: the rest
/// (u, v) coordinates of a membrane whose weft is `v_axis`. None if the
/// triangle is degenerate or `v_axis` is normal to it.
pub(super) fn plane_coordinates(x: [Vec3; 3], v_axis: Vec3) -> Option<[nalgebra::Vector2<f64>; 3]> {
    let normal = (x[1] - x[0]).cross(&(x[2] - x[0]));
    let e2 = (v_axis - normal * (normal.dot(&v_axis) / normal.norm_squared())).try_normalize(1e-12)?;
    let e1 = e2.cross(&normal).try_normalize(1e-12)?;
    Some(x.map(|q| nalgebra::Vector2::new((q - x[0]).dot(&e1), (q - x[0]).dot(&e2))))
}

/// Volino's elements for one panel's triangles over rest positions `p`
/// (local indices shifted by `offset`):
/// a membrane per triangle, with rest (u, v) coordinates in the triangle's
/// plane along triangle `k`'s weft axis `weft(k)` (so warp and weft keep
/// their directions on curved rest shapes), and each triangle with its
/// neighbours for bending ([`curvature_elements`]).
/// None if a triangle is degenerate.
pub(super) fn volino_elements(
    p: &[Vec3],
    mesh_triangles: &[[u32; 3]],
    material: &Material,
    weft: &dyn Fn(usize) -> Vec3,
    panel: usize,
    offset: u32,
) -> Option<(Vec<MembraneElement>, Vec<BendingTriangle>)> {
    let c = material.membrane_stiffness();
    let mut membranes = Vec::with_capacity(mesh_triangles.len());
    for (k, t) in mesh_triangles.iter().enumerate() {
        let uv = plane_coordinates(t.map(|k| p[k as usize]), weft(k))?;
        membranes.push(MembraneElement { nodes: t.map(|k| k + offset), rest: TriangleRest::new(uv, c)? });
    }
    // Each interior edge appears as (a, b) in one triangle and (b, a) in its neighbour.
    let opposite: std::collections::HashMap<(u32, u32), u32> =
        mesh_triangles.iter().flat_map(|t| (0..3).map(move |k| ((t[k], t[(k + 1) % 3]), t[(k + 2) % 3]))).collect();
    let bending = mesh_triangles
        .iter()
        .map(|t| BendingTriangle {
            panel,
            corners: t.map(|q| q + offset),
            // Edge k runs from corner k+1 to corner k+2; the neighbour has it reversed.
            across: std::array::from_fn(|k| opposite.get(&(t[(k + 2) % 3], t[(k + 1) % 3])).map(|o| o + offset)),
        })
        .collect();
    Some((membranes, bending))
}
