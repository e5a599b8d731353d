//! Cloth panels given as triangle meshes: read from a Wavefront OBJ file or
//! listed in the scene, with any triangulation (a garment exported from
//! another tool, a pattern piece meshed by a Delaunay triangulator).
//!
//! ## The three models on an irregular mesh
//! - **Provot's springs** lie on the mesh's edges. An edge of rest length
//!   `L` bordering triangles of total area `A_e` gets `k = E A_e / L^2`
//!   (Van Gelder 1998, "Approximate simulation of elastic membranes by
//!   triangulated spring meshes"): exact for equilateral triangles, where
//!   the springs form an isotropic membrane of modulus `E` and Poisson
//!   ratio 1/3, so shear modulus `G = 3E/8` (a spring lattice on triangles
//!   has no other; the grid's two link families set `G` apart). On an
//!   irregular mesh the network relaxes where an affine field would strain
//!   it: softer in tension, stiffer under an affine shear (numbers in
//!   `docs/results/meshes.md`; a least-squares fit of each triangle's three
//!   springs to the membrane was softer still).
//! - **Choi & Ko's membrane** is a triangle each
//!   ([`crate::element_laws::tension_field_response`]): linear and
//!   isotropic (`E`, and `G` as on the grid) while both principal stresses
//!   stay above the buckling stress `-sigma_b`, wrinkling beyond it. That
//!   is their type-1 links' premise, fabric buckles rather than resists
//!   compression, for a triangle. Links on the edges would be a mechanism:
//!   a triangle with a slack edge folds in its plane, so a strip in tension,
//!   whose links across it shorten, stretched 7.4 times too far at `B =
//!   1e-7 N m` with the grid's cap on them, and without a cap (as stiff in
//!   compression as in tension) the network was 7% soft, and a skirt
//!   pressed by a knee crumpled at the mesh's scale. `sigma_b = 12 B / l^2`,
//!   the onset of the arc law for a strip as long as the triangle (`l^2 = 4
//!   A / sqrt(3)`); `buckling_stiffness_n_m`, the grid's ramp, has no part
//!   here. The edges keep links without stiffness for damping (`D A_e /
//!   L^2`) and strain limits, as in Volino's model.
//! - **Type-2 interactions** join the two corners `c`, `d` opposite an
//!   interior edge `ab`. Choi & Ko's arc-path law reads the path `c -> m ->
//!   d` through the point `m = (1 - w) a + w b` where the segment `cd`
//!   crosses `ab` once the pair of triangles is unfolded flat (so the rest
//!   path of the flat fabric is straight, as on the grid), with `k_b =
//!   (9/8) (4/3) B A_p / (L_p 4 a (1 - a))`: `A_p` the area it stands for (its
//!   triangles', a boundary triangle's shared among its interior edges),
//!   `L_p` the unfolded length, `a` the part of it before `m` (unequal
//!   halves read `4 a (1 - a)` of the curvature equal ones do), `4/3` the
//!   path's `PATH_CURVATURE_FACTOR`. `m` lies on the
//!   edge's chord, off the surface when the cloth bends along the edge,
//!   so an interaction reads `kappa_cd - kappa_ab / 3` on a regular mesh,
//!   not the normal curvature `kappa_cd`: over three directions the reads
//!   square to `kappa^2` for a cylinder in any direction (the grid's
//!   lattice sums `cos^4` to 9/8 instead, hence no factor here), and to a
//!   plate's bending energy with Poisson ratio -1/3 for doubly curved
//!   shapes. A strip free to curve across itself then bends with 8/9 of a
//!   cylinder's rigidity; `B` is the strip's (Peirce's), so `k_b` takes
//!   `9/8` of it (`FREE_STRIP_FACTOR` in `build_mesh.rs`) and a cylinder
//!   stores 9/8 of `B kappa^2 / 2`. A pair that is not convex has no crossing and no type-2
//!   interaction (2% of a refined pattern's pairs). Provot's flexion
//!   springs join the same corners, with the share `C_b / (E + C_b)` of
//!   the membrane as on the grid (`k = s E A_p / d^2`), the edges keeping
//!   the rest.
//! - **Volino's elements** are per triangle already: the membrane with its
//!   rest coordinates along the panel's weft axis, the bending triangle
//!   with its edge neighbours. On an irregular mesh his bending triangles
//!   remove the bias of their mid-edge slopes (exact on the grid's
//!   parallelogram pairs), so every uniform curvature stores `B kappa^2 /
//!   2` (`element_laws::curvature_stiffness`).
//!
//! Links along the boundary border one triangle and stand for it alone, as
//! the grid's boundary links stand for half a cell.

use crate::FieldError;
use crate::Vec3;
pub(crate) use crate::model::pattern::PatternPiece;
use cloth_collide::GltfError;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A cloth panel given as a triangle mesh (`[[meshes]]` in a scene): an
/// OBJ file, vertices and triangles listed in place, or a sewing-pattern
/// piece meshed here ([`PatternPiece`]). The rest shape is the mesh as
/// given, scaled and moved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshPanel {
    /// Wavefront OBJ file with the rest shape (relative to the scene's
    /// directory). Faces of more than three corners are split into fans.
    #[serde(default)]
    pub obj: Option<PathBuf>,
    /// glTF 2.0 file (`.glb` or `.gltf`, relative to the scene's
    /// directory) with the rest shape: its mesh `gltf_mesh` (or its only
    /// one), placed by its node and turned from glTF's y-up to z-up;
    /// vertices split by the exporter at one place are welded
    /// ([`cloth_collide::read_gltf`]).
    #[serde(default)]
    pub gltf: Option<PathBuf>,
    /// The mesh to read from `gltf`, by name.
    #[serde(default)]
    pub gltf_mesh: Option<String>,
    /// Take the grain from the texture map (OBJ `vt`, glTF `TEXCOORD_0`):
    /// on each triangle the weft runs along the map's v and the warp across
    /// it, as a pattern tool lays the pieces out. Only Volino's orthotropic
    /// membrane has a grain; the lattices and Choi & Ko's membrane are
    /// isotropic. Not with `weft_axis`.
    #[serde(default)]
    pub grain_from_uv: bool,
    /// Rest positions listed in place (instead of `obj`), in the mesh's
    /// units (see `scale`).
    #[serde(default)]
    pub vertices: Vec<[f64; 3]>,
    /// Triangles listed in place: 0-based vertex indices, counter-clockwise
    /// seen from the cloth's front.
    #[serde(default)]
    pub triangles: Vec<[u32; 3]>,
    /// A pattern piece to mesh (instead of `obj` or listed triangles).
    #[serde(default)]
    pub pattern: Option<PatternPiece>,
    /// Metres per mesh unit (an OBJ in centimetres: 0.01). Default 1.
    #[serde(default = "unit_scale")]
    pub scale: f64,
    /// Translation applied after scaling, m.
    #[serde(default)]
    pub offset_m: [f64; 3],
    /// The weft direction in the rest shape (projected on each triangle;
    /// the warp runs across it): the axes of Volino's orthotropic
    /// membrane. Default: a pattern's placed y axis, else +y.
    #[serde(default)]
    pub weft_axis: Option<[f64; 3]>,
}

fn unit_scale() -> f64 {
    1.0
}

/// Each triangle's weft: the direction in which the texture map's v grows
/// (`dx/dv` of the map from the triangle's texture coordinates to its
/// rest positions), unit. Errors name `grain_from_uv` and the triangle.
fn uv_wefts(mesh: &ClothMesh, uvs: &[[f64; 2]], corners: &[Option<[u32; 3]>]) -> Result<Vec<Vec3>, FieldError> {
    let err = |k: usize, what: &str| FieldError::new("grain_from_uv", format!("triangle {k} {what}"));
    mesh.triangles
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let c = corners.get(k).copied().flatten().ok_or_else(|| err(k, "has no texture coordinates"))?;
            let [t0, t1, t2] = c.map(|i| nalgebra::Vector2::from(uvs[i as usize]));
            let [x0, x1, x2] = t.map(|i| mesh.positions[i as usize]);
            let (du1, du2) = (t1 - t0, t2 - t0);
            let det = du1.x * du2.y - du2.x * du1.y;
            if det.abs() <= 1e-12 * du1.norm_squared().max(du2.norm_squared()) || !det.is_finite() {
                return Err(err(k, "is degenerate in the texture map"));
            }
            // [x1 - x0, x2 - x0] = [dx/du, dx/dv] [du1, du2]: dx/dv from the inverse's second row.
            let dv = ((x1 - x0) * -du2.x + (x2 - x0) * du1.x) / det;
            dv.try_normalize(1e-300).ok_or_else(|| err(k, "maps v to no direction"))
        })
        .collect()
}

/// A mesh panel's rest shape, read and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct ClothMesh {
    /// Rest positions, m.
    pub positions: Vec<Vec3>,
    /// Triangles, consistently wound.
    pub triangles: Vec<[u32; 3]>,
    /// Weft direction (unit).
    pub weft: Vec3,
    /// Each triangle's weft direction (unit, in its plane) when the grain
    /// comes from the texture map; empty otherwise (`weft` for all).
    pub triangle_wefts: Vec<Vec3>,
    /// A pattern piece's vertices along each outline edge (none for other meshes).
    pub outline_edges: Vec<Vec<u32>>,
    /// Each outline edge's length, m.
    pub outline_lengths: Vec<f64>,
}

impl MeshPanel {
    /// A panel from vertices (m) and triangles listed in place.
    pub fn from_triangles(vertices: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Self {
        Self { vertices, triangles, ..Self::from_pattern_piece(None) }
    }

    /// A panel meshed from a pattern piece ([`PatternPiece::mesh`]).
    pub fn from_pattern(piece: PatternPiece) -> Self {
        Self::from_pattern_piece(Some(piece))
    }

    fn from_pattern_piece(pattern: Option<PatternPiece>) -> Self {
        Self {
            obj: None,
            gltf: None,
            gltf_mesh: None,
            grain_from_uv: false,
            vertices: Vec::new(),
            triangles: Vec::new(),
            pattern,
            scale: 1.0,
            offset_m: [0.0; 3],
            weft_axis: None,
        }
    }

    /// Reads the mesh (an OBJ path relative to `base_dir`), scales and
    /// moves it, and checks it ([`ClothMesh::check`]).
    pub fn resolve(&self, base_dir: &Path) -> Result<ClothMesh, FieldError> {
        self.resolve_with(base_dir, &[])
    }

    /// [`MeshPanel::resolve`] with a pattern's outline edges split into
    /// `pieces` where given ([`PatternPiece::mesh_with`]).
    pub fn resolve_with(&self, base_dir: &Path, pieces: &[Option<usize>]) -> Result<ClothMesh, FieldError> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(FieldError::new("scale", format!("must be finite and > 0, got {}", self.scale)));
        }
        if self.offset_m.iter().any(|c| !c.is_finite()) {
            return Err(FieldError::new("offset_m", format!("must be finite, got {:?}", self.offset_m)));
        }
        let sources = [
            self.obj.is_some(),
            self.gltf.is_some(),
            !self.vertices.is_empty() || !self.triangles.is_empty(),
            self.pattern.is_some(),
        ];
        if sources.iter().filter(|&&s| s).count() != 1 {
            return Err(FieldError::new("obj", "give one of `obj`, `gltf`, `vertices` with `triangles`, or `pattern`"));
        }
        if self.gltf_mesh.is_some() && self.gltf.is_none() {
            return Err(FieldError::new("gltf_mesh", "names a mesh of a `gltf` file, and none is given"));
        }
        if self.grain_from_uv && self.weft_axis.is_some() {
            return Err(FieldError::new(
                "grain_from_uv",
                "give the grain by `weft_axis` or by the texture map, not both",
            ));
        }
        if self.grain_from_uv && self.obj.is_none() && self.gltf.is_none() {
            return Err(FieldError::new("grain_from_uv", "needs a texture map: an `obj` or `gltf` file"));
        }
        let (mut outline_edges, mut outline_lengths) = (Vec::new(), Vec::new());
        let mut weft = Vec3::y();
        let mut file_uvs = None;
        let (vertices, triangles) = match (&self.obj, &self.pattern) {
            (_, Some(piece)) => {
                let m = piece.mesh_with(pieces).map_err(|e| {
                    let field = match e.path.as_str() {
                        "outline_m" => "pattern.outline_m",
                        "edge_length_m" => "pattern.edge_length_m",
                        "lines_m" => "pattern.lines_m",
                        "u_axis" => "pattern.u_axis",
                        "v_axis" => "pattern.v_axis",
                        "cylinder_radius_m" => "pattern.cylinder_radius_m",
                        "cone" => "pattern.cone",
                        _ => "pattern",
                    };
                    FieldError::new(field, e.message)
                })?;
                outline_edges = m.outline_edges;
                outline_lengths = m.outline_lengths.iter().map(|l| l * self.scale).collect();
                weft = m.v_axis;
                (m.positions, m.triangles)
            }
            (Some(path), None) => {
                let full = base_dir.join(path);
                let text = std::fs::read_to_string(&full)
                    .map_err(|e| FieldError::new("obj", format!("cannot read {}: {e}", full.display())))?;
                let mesh = cloth_collide::parse_obj(&text)
                    .map_err(|e| FieldError::new("obj", format!("{}: {e}", full.display())))?;
                file_uvs = Some((mesh.uvs, mesh.triangle_uvs));
                (mesh.vertices, mesh.triangles)
            }
            (None, None) => match &self.gltf {
                Some(path) => {
                    let mesh = cloth_collide::read_gltf(&base_dir.join(path), self.gltf_mesh.as_deref()).map_err(
                        |e| match e {
                            GltfError::MeshChoice(why) => FieldError::new("gltf_mesh", why),
                            GltfError::File(why) => FieldError::new("gltf", why),
                        },
                    )?;
                    file_uvs = Some((mesh.uvs, mesh.triangle_uvs));
                    (mesh.vertices, mesh.triangles)
                }
                None => (self.vertices.iter().map(|&v| Vec3::from(v)).collect(), self.triangles.clone()),
            },
        };
        if let Some(w) = self.weft_axis {
            weft = Vec3::from(w)
                .try_normalize(1e-12)
                .filter(|w| w.iter().all(|c| c.is_finite()))
                .ok_or(FieldError::new("weft_axis", format!("must be a finite non-zero direction, got {w:?}")))?;
        }
        let offset = Vec3::from(self.offset_m);
        let positions: Vec<Vec3> = vertices.iter().map(|v| v * self.scale + offset).collect();
        let mut mesh =
            ClothMesh { positions, triangles, weft, triangle_wefts: Vec::new(), outline_edges, outline_lengths };
        mesh.check()?;
        if let (true, Some((uvs, corners))) = (self.grain_from_uv, file_uvs) {
            mesh.triangle_wefts = uv_wefts(&mesh, &uvs, &corners)?;
        }
        Ok(mesh)
    }
}

/// An edge of a mesh: its ends (the smaller index first) and the area of
/// the one or two triangles it borders, m^2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshEdge {
    /// The two vertices.
    pub ends: [u32; 2],
    /// Area of the triangles on either side, m^2.
    pub area: f64,
}

/// Two triangles sharing the edge `ab`, seen from their far corners `c`
/// (in the triangle where the edge runs from `a` to `b`) and `d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshHinge {
    /// `[c, a, b, d]`.
    pub nodes: [u32; 4],
    /// Where `cd` crosses `ab` in the unfolded pair, as the weight of `b`
    /// (`None` when the pair is not convex).
    pub crossing: Option<f64>,
    /// Length of `cd` in the unfolded pair, m.
    pub unfolded: f64,
    /// The part of that length from `c` to the crossing (0 to 1).
    pub first_half: f64,
    /// The area the interaction stands for, m^2: each of its two
    /// triangles' area times 3 over the triangle's interior edges (inside,
    /// the pair's area), so that a triangle on a free boundary (two
    /// interior edges, or one) stands for as much bending as inside.
    pub area: f64,
}

/// A mesh's parts for the models: area shares, edges, hinges.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshTopology {
    /// Each vertex's share of the area (a third of each of its triangles), m^2.
    pub area_share: Vec<f64>,
    /// Every edge once, in order of first appearance.
    pub edges: Vec<MeshEdge>,
    /// Every interior edge's pair of triangles.
    pub hinges: Vec<MeshHinge>,
}

fn triangle_area(x: [Vec3; 3]) -> f64 {
    0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm()
}

impl ClothMesh {
    /// Checks that the mesh is a consistently wound manifold surface of
    /// finite, non-degenerate triangles using every vertex; names the
    /// field (`vertices` or `triangles`) of the first fault.
    pub fn check(&self) -> Result<(), FieldError> {
        let n = self.positions.len();
        if self.triangles.is_empty() {
            return Err(FieldError::new("triangles", "the mesh has no triangles"));
        }
        if n > u32::MAX as usize / 2 {
            return Err(FieldError::new("vertices", format!("{n} vertices is too many")));
        }
        if let Some(k) = self.positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(FieldError::new("vertices", format!("vertex {k} is not finite")));
        }
        let mut used = vec![false; n];
        let longest = self.positions.iter().map(|p| p.norm()).fold(0.0, f64::max).max(1e-300);
        for (k, t) in self.triangles.iter().enumerate() {
            if let Some(&v) = t.iter().find(|&&v| v as usize >= n) {
                return Err(FieldError::new("triangles", format!("triangle {k} names vertex {v}; the mesh has {n}")));
            }
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(FieldError::new("triangles", format!("triangle {k} repeats a vertex: {t:?}")));
            }
            let area = triangle_area(t.map(|v| self.positions[v as usize]));
            if area <= 1e-14 * longest * longest {
                return Err(FieldError::new("triangles", format!("triangle {k} {t:?} has no area")));
            }
            t.iter().for_each(|&v| used[v as usize] = true);
        }
        if let Some(v) = used.iter().position(|u| !u) {
            return Err(FieldError::new(
                "vertices",
                format!("vertex {v} belongs to no triangle (it would have no mass)"),
            ));
        }
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for (k, t) in self.triangles.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                if let Some(other) = directed.insert((a, b), k) {
                    return Err(FieldError::new(
                        "triangles",
                        format!(
                            "triangles {other} and {k} both run along edge {a} -> {b}: they are wound \
                             opposite ways, or the edge has more than two triangles"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Area shares, edges and hinges ([`MeshTopology`]), in a fixed order.
    pub fn topology(&self) -> MeshTopology {
        let p = &self.positions;
        let mut area_share = vec![0.0; p.len()];
        let mut edge_of: HashMap<[u32; 2], usize> = HashMap::new();
        let mut edges: Vec<MeshEdge> = Vec::new();
        // The corner opposite each directed edge.
        let mut opposite: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &self.triangles {
            let area = triangle_area(t.map(|v| p[v as usize]));
            t.iter().for_each(|&v| area_share[v as usize] += area / 3.0);
            for e in 0..3 {
                let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                opposite.insert((a, b), c);
                let key = [a.min(b), a.max(b)];
                let k = *edge_of.entry(key).or_insert_with(|| {
                    edges.push(MeshEdge { ends: key, area: 0.0 });
                    edges.len() - 1
                });
                edges[k].area += area;
            }
        }
        // Each triangle's area, three times over its interior edges.
        let interior = |a: u32, b: u32| opposite.contains_key(&(a, b)) && opposite.contains_key(&(b, a));
        let per_interior_edge = |t: [u32; 3]| {
            let n = (0..3).filter(|&e| interior(t[e], t[(e + 1) % 3])).count();
            3.0 * triangle_area(t.map(|v| p[v as usize])) / n.max(1) as f64
        };
        let hinges = edges
            .iter()
            .filter_map(|e| {
                let [a, b] = e.ends;
                let (&c, &d) = (opposite.get(&(a, b))?, opposite.get(&(b, a))?);
                let [xa, xb, xc, xd] = [a, b, c, d].map(|v| p[v as usize]);
                let (crossing, unfolded, first_half) = unfold([xc, xa, xb, xd]);
                let area = per_interior_edge([a, b, c]) + per_interior_edge([b, a, d]);
                Some(MeshHinge { nodes: [c, a, b, d], crossing, unfolded, first_half, area })
            })
            .collect();
        MeshTopology { area_share, edges, hinges }
    }
}

/// The pair of triangles `(c, a, b)` and `(a, b, d)` unfolded flat about
/// `ab`: where `cd` crosses `ab` as the weight of `b` (`None` unless it
/// crosses strictly inside), the length of `cd` (m), and the part of it
/// from `c` to the crossing.
pub(crate) fn unfold([c, a, b, d]: [Vec3; 4]) -> (Option<f64>, f64, f64) {
    let ab = b - a;
    let len = ab.norm();
    let along = ab / len;
    // Each far corner as (distance along ab from a, distance off the line).
    let flat = |q: Vec3| {
        let x = (q - a).dot(&along);
        (x, (q - a - along * x).norm())
    };
    let ((xc, yc), (xd, yd)) = (flat(c), flat(d));
    // c above the line, d below it.
    let unfolded = ((xd - xc).powi(2) + (yc + yd).powi(2)).sqrt();
    let t = yc / (yc + yd);
    let w = (xc + t * (xd - xc)) / len;
    ((w > 0.0 && w < 1.0 && w.is_finite()).then_some(w), unfolded, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> MeshPanel {
        MeshPanel::from_triangles(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn a_square_has_five_edges_one_hinge_and_its_area() {
        let mesh = square().resolve(Path::new(".")).unwrap();
        let t = mesh.topology();
        assert_eq!(t.edges.len(), 5);
        assert!((t.area_share.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        let diagonal = t.edges.iter().find(|e| e.ends == [0, 2]).unwrap();
        assert!((diagonal.area - 1.0).abs() < 1e-15);
        assert_eq!(t.hinges.len(), 1);
        let h = t.hinges[0];
        assert_eq!(h.nodes, [3, 0, 2, 1]);
        assert!((h.crossing.unwrap() - 0.5).abs() < 1e-15);
        assert!((h.unfolded - 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn a_folded_pair_unfolds_to_its_flat_length() {
        // The square folded by 90 degrees about its diagonal: the same pair flat.
        let (w, len, half) = unfold([
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::zeros(),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.5, 0.5, -0.5f64.sqrt()),
        ]);
        assert!((w.unwrap() - 0.5).abs() < 1e-15 && (len - 2f64.sqrt()).abs() < 1e-15, "{w:?} {len}");
        assert!((half - 0.5).abs() < 1e-15);
        // A pair that is not convex: no crossing.
        let (w, _, _) =
            unfold([Vec3::new(2.0, 0.5, 0.0), Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, -0.5, 0.0)]);
        assert_eq!(w, None);
    }

    #[test]
    fn bad_meshes_name_the_fault() {
        let base = Path::new(".");
        let with = |f: &dyn Fn(&mut MeshPanel)| {
            let mut m = square();
            f(&mut m);
            m.resolve(base).unwrap_err()
        };
        assert_eq!(with(&|m| m.triangles[1] = [0, 3, 2]).path, "triangles", "wound the other way");
        assert_eq!(with(&|m| m.triangles[1] = [0, 2, 4]).path, "triangles");
        assert_eq!(with(&|m| m.triangles[1] = [0, 2, 2]).path, "triangles");
        assert_eq!(with(&|m| m.vertices.push([5.0, 5.0, 5.0])).path, "vertices");
        assert_eq!(with(&|m| m.vertices[3] = [0.5, 0.5, 0.0]).path, "triangles", "no area");
        assert_eq!(with(&|m| m.vertices[3][2] = f64::NAN).path, "vertices");
        assert_eq!(with(&|m| m.scale = 0.0).path, "scale");
        assert_eq!(with(&|m| m.weft_axis = Some([0.0; 3])).path, "weft_axis");
        assert_eq!(with(&|m| m.obj = Some("nowhere.obj".into())).path, "obj");
        let mut missing = square();
        (missing.vertices, missing.triangles) = (Vec::new(), Vec::new());
        missing.obj = Some("nowhere.obj".into());
        let crate::FieldError { path: field, message } = missing.resolve(base).unwrap_err();
        assert!(field == "obj" && message.contains("nowhere.obj"), "{message}");
        // A pattern's own fields, each under `pattern.`.
        let square = || crate::PatternPiece::new(vec![[0.0, 0.0], [0.1, 0.0], [0.1, 0.1], [0.0, 0.1]], 0.02);
        let mut outside = square();
        outside.lines_m = vec![[[0.05, 0.05], [0.5, 0.05]]];
        let mut flat = square();
        flat.cylinder_radius_m = Some(0.0);
        let mut along = square();
        along.v_axis = [1.0, 0.0, 0.0];
        let mut cone = square();
        cone.cone = Some(crate::ConeWrap { apex_m: [0.05, -0.5], half_angle_deg: 0.0 });
        for (piece, field) in [
            (outside, "pattern.lines_m"),
            (flat, "pattern.cylinder_radius_m"),
            (along, "pattern.v_axis"),
            (cone, "pattern.cone"),
        ] {
            assert_eq!(MeshPanel::from_pattern(piece).resolve(base).unwrap_err().path, field);
        }
    }
}
