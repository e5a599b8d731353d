//! Sewing-pattern pieces: a flat polygon in metres, meshed to a target edge
//! length by constrained Delaunay refinement (Ruppert's and Chew's
//! algorithms, as the `spade` crate implements them), then placed in 3D.

use crate::FieldError;
use crate::Vec3;
use serde::{Deserialize, Serialize};
use spade::{AngleLimit, ConstrainedDelaunayTriangulation, Point2, RefinementParameters, Triangulation};

/// One pattern piece as a designer draws it: its outline in the plane
/// (m; curved edges as polylines), meshed with edges of about
/// `edge_length_m`, placed with its x and y axes along `u_axis`, `v_axis`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternPiece {
    /// The outline's corners in order (either way round), m. Outline edge
    /// `k` runs from corner `k` to corner `k + 1` (the last back to the
    /// first).
    pub outline_m: Vec<[f64; 2]>,
    /// Target edge length of the mesh, m: the outline is split into
    /// pieces no longer than it and the inside refined to triangles of
    /// about that size, none with an angle under 25 degrees.
    pub edge_length_m: f64,
    /// Lines inside the piece that the mesh follows (fold lines, darts, a
    /// clamp's edge), each from one point to another, m.
    #[serde(default)]
    pub lines_m: Vec<[[f64; 2]; 2]>,
    /// The 3D direction of the pattern's x axis. Default +x.
    #[serde(default = "x_axis")]
    pub u_axis: [f64; 3],
    /// The 3D direction of the pattern's y axis (made orthogonal to
    /// `u_axis`). Default +y.
    #[serde(default = "y_axis")]
    pub v_axis: [f64; 3],
    /// Wraps the piece around a cylinder of this radius (m) instead of
    /// laying it flat: the cylinder's axis runs along `v_axis` through the
    /// origin, pattern x goes around it (x = 0 towards `u_axis`, turning
    /// towards `v_axis x u_axis`) and y along it, lengths kept. The
    /// pattern's front (counter-clockwise side) faces out. A skirt's or a
    /// sleeve's panels start around the body this way.
    #[serde(default)]
    pub cylinder_radius_m: Option<f64>,
    /// Wraps the piece around a cone instead ([`ConeWrap`]): the gores
    /// of a flared skirt start flared this way. At most one of the two.
    #[serde(default)]
    pub cone: Option<ConeWrap>,
}

/// A cone a pattern piece is wrapped on, lengths kept (a cone unrolls
/// flat). Its axis runs along `v_axis` through the origin, its apex at
/// `apex_m`'s height along it (`v_axis * apex_m[1]`), and it opens towards
/// `v_axis`. A point at distance `rho` from `apex_m`, at angle `psi` from
/// the pattern's +y (positive towards +x), goes `rho sin(beta)` from the
/// axis, `apex_m[1] + rho cos(beta)` along it, and `psi / sin(beta)`
/// around it (0 towards `u_axis`, turning as the cylinder does). So an
/// annular sector about `apex_m` between radii `r_1 / sin(beta)` and
/// `r_2 / sin(beta)` becomes a band of the cone from radius `r_1` to `r_2`,
/// and its angle `alpha` goes `alpha / sin(beta)` round.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConeWrap {
    /// The apex in pattern coordinates, m.
    pub apex_m: [f64; 2],
    /// Angle between the axis and the cone's side, degrees, in (0, 90]
    /// (90: a flat disc across the axis).
    pub half_angle_deg: f64,
}

/// A [`ConeWrap`] checked: its apex (m) and its half angle's sine and cosine.
#[derive(Debug, Clone, Copy)]
struct PlacedCone {
    apex: [f64; 2],
    sin: f64,
    cos: f64,
}

fn x_axis() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}
fn y_axis() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

/// Smallest angle the refinement keeps, degrees (30 can fail to end).
pub(crate) const PATTERN_MIN_ANGLE_DEG: f64 = 25.0;

/// Most triangles a pattern piece may mesh into.
pub(crate) const PATTERN_MAX_TRIANGLES: f64 = 4e6;

/// A meshed pattern piece.
#[derive(Debug, Clone, PartialEq)]
pub struct PatternMesh {
    /// Vertex positions in 3D (the pattern plane placed), m.
    pub positions: Vec<Vec3>,
    /// Triangles, counter-clockwise seen from `u_axis x v_axis`.
    pub triangles: Vec<[u32; 3]>,
    /// The vertices on each outline edge, from its first corner to its last.
    pub outline_edges: Vec<Vec<u32>>,
    /// The placed y axis: the grain when the pattern is drawn with it along y.
    pub v_axis: Vec3,
    /// Each outline edge's length, m.
    pub outline_lengths: Vec<f64>,
}

impl PatternPiece {
    /// A flat piece with outline `outline_m` (m) meshed at `edge_length_m`,
    /// its x and y along +x and +y, no lines inside.
    pub fn new(outline_m: Vec<[f64; 2]>, edge_length_m: f64) -> Self {
        Self {
            outline_m,
            edge_length_m,
            lines_m: Vec::new(),
            u_axis: x_axis(),
            v_axis: y_axis(),
            cylinder_radius_m: None,
            cone: None,
        }
    }

    /// Meshes the piece; errors name the field (`outline_m`,
    /// `edge_length_m`, `lines_m`, `u_axis`, `v_axis`). A panic inside the
    /// triangulator (which reports some degenerate inputs that way) is
    /// caught and refused as an error on `outline_m`.
    pub fn mesh(&self) -> Result<PatternMesh, FieldError> {
        self.mesh_with(&[])
    }

    /// [`PatternPiece::mesh`] with outline edge `k` split into `pieces[k]`
    /// equal pieces where given (a seam sews node to node, so two edges
    /// sewn together need as many), else into pieces no longer than
    /// `edge_length_m`.
    pub fn mesh_with(&self, pieces: &[Option<usize>]) -> Result<PatternMesh, FieldError> {
        cloth_collide::catch_panic(|| self.mesh_unguarded(pieces)).unwrap_or_else(|why| {
            Err(FieldError::new("outline_m", format!("the triangulator failed on this outline ({why})")))
        })
    }

    /// The pieces outline edge `k` is split into by default (`None` for no
    /// such edge, or an outline that cannot be meshed).
    pub fn natural_pieces(&self, k: usize) -> Option<usize> {
        let n = self.outline_m.len();
        let (a, b) = (self.outline_m.get(k)?, self.outline_m.get((k + 1) % n.max(1))?);
        let pieces = pieces_no_longer_than(*a, *b, self.edge_length_m);
        (1.0..PATTERN_MAX_TRIANGLES).contains(&pieces).then_some(pieces as usize)
    }

    fn mesh_unguarded(&self, forced: &[Option<usize>]) -> Result<PatternMesh, FieldError> {
        let h = self.edge_length_m;
        if !(h.is_finite() && h > 0.0) {
            return Err(FieldError::new("edge_length_m", format!("must be finite and > 0, got {h}")));
        }
        let corners = &self.outline_m;
        if corners.len() < 3 {
            return Err(FieldError::new("outline_m", format!("needs at least 3 corners, got {}", corners.len())));
        }
        if let Some(k) = corners.iter().position(|c| c.iter().any(|v| !v.is_finite())) {
            return Err(FieldError::new("outline_m", format!("corner {k} is not finite")));
        }
        let (u, v) = self.axes()?;
        let around = v.cross(&u);
        if let Some(r) = self.cylinder_radius_m
            && !(r.is_finite() && r > 0.0)
        {
            return Err(FieldError::new("cylinder_radius_m", format!("must be finite and > 0, got {r}")));
        }
        let cone = self.cone_angles()?;
        let place = |x: f64, y: f64| match (self.cylinder_radius_m, cone) {
            (Some(r), _) => (u * (x / r).cos() + around * (x / r).sin()) * r + v * y,
            (None, Some(PlacedCone { apex: [ax, ay], sin, cos })) => {
                let (dx, dy) = (x - ax, y - ay);
                let (rho, turn) = (dx.hypot(dy), dx.atan2(dy) / sin);
                (u * turn.cos() + around * turn.sin()) * (rho * sin) + v * (ay + rho * cos)
            }
            (None, None) => u * x + v * y,
        };
        let n = corners.len();
        let signed_area: f64 = (0..n)
            .map(|k| corners[k][0] * corners[(k + 1) % n][1] - corners[(k + 1) % n][0] * corners[k][1])
            .sum::<f64>()
            / 2.0;
        let expected = signed_area.abs() / (3f64.sqrt() / 4.0 * h * h);
        if !expected.is_finite() || expected >= PATTERN_MAX_TRIANGLES {
            return Err(FieldError::new(
                "edge_length_m",
                format!("{h} m makes about {expected:.0} triangles; at most 4e6"),
            ));
        }
        if signed_area.abs() == 0.0 {
            return Err(FieldError::new("outline_m", "the outline encloses no area"));
        }
        let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
        let insert = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>, p: [f64; 2]| {
            cdt.insert(Point2::new(p[0], p[1]))
                .map_err(|e| FieldError::new("outline_m", format!("corner at {p:?}: {e:?}")))
        };
        // Corners first, so that a repeated corner is seen before the edges split.
        let mut corner_handles = Vec::with_capacity(n);
        for (k, &c) in corners.iter().enumerate() {
            let handle = insert(&mut cdt, c)?;
            if corner_handles.contains(&handle) {
                return Err(FieldError::new("outline_m", format!("corner {k} {c:?} repeats an earlier corner")));
            }
            corner_handles.push(handle);
        }
        // A segment from `a` to `b` split into `pieces`, or into pieces no longer than `h`.
        let split = |cdt: &mut ConstrainedDelaunayTriangulation<Point2<f64>>,
                     a: [f64; 2],
                     b: [f64; 2],
                     pieces: Option<usize>| {
            let pieces = pieces.unwrap_or(pieces_no_longer_than(a, b, h) as usize);
            (1..pieces)
                .map(|s| {
                    let t = s as f64 / pieces as f64;
                    insert(cdt, [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
                })
                .collect::<Result<Vec<_>, _>>()
        };
        // A line that ends on the outline ends at a vertex of it: the end
        // is moved onto the edge, which is split there.
        let extent = corners.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
        let mut lines = self.lines_m.clone();
        let mut breaks: Vec<Vec<f64>> = vec![Vec::new(); n];
        for (k, line) in lines.iter_mut().enumerate() {
            if line.iter().flatten().any(|c| !c.is_finite()) || line[0] == line[1] {
                return Err(FieldError::new("lines_m", format!("line {k} must join two different finite points")));
            }
            for end in line.iter_mut() {
                for (e, b) in breaks.iter_mut().enumerate() {
                    let (t, on, off) = nearest_on_segment(*end, corners[e], corners[(e + 1) % n]);
                    if (0.0..=1.0).contains(&t) && off <= 1e-9 * extent {
                        *end = on;
                        b.push(t);
                        break;
                    }
                }
            }
        }
        let mut edge_handles = Vec::with_capacity(n);
        for (k, b) in breaks.iter_mut().enumerate() {
            let (p, q) = (corners[k], corners[(k + 1) % n]);
            b.extend([0.0, 1.0]);
            b.sort_by(f64::total_cmp);
            b.dedup();
            let at = |t: f64| [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])];
            let pieces = forced.get(k).copied().flatten();
            if pieces.is_some() && b.len() > 2 {
                return Err(FieldError::new(
                    "lines_m",
                    format!("a line ends on outline edge {k}, which a seam splits evenly"),
                ));
            }
            if pieces.is_some_and(|p| p == 0 || p as f64 >= PATTERN_MAX_TRIANGLES) {
                return Err(FieldError::new(
                    "outline_m",
                    format!("outline edge {k} cannot be split into {pieces:?} pieces"),
                ));
            }
            let mut handles = vec![corner_handles[k]];
            for w in b.windows(2) {
                handles.extend(split(&mut cdt, at(w[0]), at(w[1]), pieces)?);
                handles.push(if w[1] == 1.0 { corner_handles[(k + 1) % n] } else { insert(&mut cdt, at(w[1]))? });
            }
            edge_handles.push(handles);
        }
        // A line starts and ends inside or on the outline, and does not
        // leave it between (crossing the outline is caught as a constraint
        // conflict; leaving through a corner by its midpoint).
        let on_or_inside = |p: [f64; 2]| {
            inside_polygon(corners, p)
                || (0..n).any(|e| nearest_on_segment(p, corners[e], corners[(e + 1) % n]).2 <= 1e-9 * extent)
        };
        for (k, &[a, b]) in lines.iter().enumerate() {
            let middle = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
            if !(on_or_inside(a) && on_or_inside(b) && on_or_inside(middle)) {
                return Err(FieldError::new("lines_m", format!("line {k} reaches outside the outline")));
            }
        }
        let mut line_handles = Vec::with_capacity(lines.len());
        for &[a, b] in &lines {
            let mut handles = vec![insert(&mut cdt, a)?];
            handles.extend(split(&mut cdt, a, b, None)?);
            handles.push(insert(&mut cdt, b)?);
            line_handles.push(handles);
        }
        // Each run of vertices becomes constraint edges; a run that meets
        // another (or itself) is refused with `why(k)`.
        let mut constrain = |runs: &[Vec<_>], field: &'static str, why: &dyn Fn(usize) -> String| {
            for (k, handles) in runs.iter().enumerate() {
                for pair in handles.windows(2) {
                    if pair[0] == pair[1] || cdt.try_add_constraint(pair[0], pair[1]).is_empty() {
                        return Err(FieldError::new(field, why(k)));
                    }
                }
            }
            Ok(())
        };
        constrain(&edge_handles, "outline_m", &|k| format!("outline edge {k} crosses or touches another edge"))?;
        constrain(&line_handles, "lines_m", &|k| format!("line {k} crosses the outline or another line"))?;
        let expected_vertices = (expected as usize).max(16);
        // The whole hull is refined: spade's own test of what is outside
        // counts crossings of every constraint, and an inside line flips it.
        let params = RefinementParameters::<f64>::new()
            .keep_constraint_edges()
            .with_angle_limit(AngleLimit::from_deg(PATTERN_MIN_ANGLE_DEG))
            .with_max_allowed_area(3f64.sqrt() / 4.0 * h * h * 1.3)
            // Without a floor, a slanted outline edge that may not be split
            // drew circumcentres ever closer to it: three vertices within
            // 1e-5 m, 1e-9 kg each, and the skirt blew up on its 5th step.
            .with_min_required_area(3f64.sqrt() / 4.0 * h * h * 0.05)
            .with_max_additional_vertices(8 * expected_vertices);
        let result = cdt.refine(params);
        if !result.refinement_complete {
            return Err(FieldError::new("outline_m", "the refinement did not finish: a corner may be too sharp"));
        }
        let mut index = vec![u32::MAX; cdt.num_vertices()];
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        // Slivers between outline points in a line (split pieces of one
        // straight edge, off by rounding) lie outside with their centres on
        // the outline: they have no area and are dropped.
        for face in cdt.inner_faces().filter(|f| {
            let c = f.center();
            f.area() > 1e-9 * h * h && inside_polygon(corners, [c.x, c.y])
        }) {
            let t = face.vertices().map(|vertex| {
                let slot = &mut index[vertex.fix().index()];
                if *slot == u32::MAX {
                    let p = vertex.position();
                    *slot = positions.len() as u32;
                    positions.push(place(p.x, p.y));
                }
                *slot
            });
            triangles.push(t);
        }
        // A cone of a vanishing half angle turns a point round without bound.
        if let Some(p) = positions.iter().find(|p| !p.iter().all(|c| c.is_finite())) {
            let field = if self.cone.is_some() { "cone" } else { "outline_m" };
            return Err(FieldError::new(field, format!("the piece places a point at {p:?}, not a finite position")));
        }
        let outline_edges = edge_handles.iter().map(|hs| hs.iter().map(|h| index[h.index()]).collect()).collect();
        if line_handles.iter().flatten().any(|h| index[h.index()] == u32::MAX) {
            return Err(FieldError::new("lines_m", "a line reaches outside the outline"));
        }
        let outline_lengths = (0..n)
            .map(|k| (corners[(k + 1) % n][0] - corners[k][0]).hypot(corners[(k + 1) % n][1] - corners[k][1]))
            .collect();
        Ok(PatternMesh { positions, triangles, outline_edges, v_axis: v, outline_lengths })
    }

    /// The cone's apex and the sine and cosine of its half angle, checked.
    fn cone_angles(&self) -> Result<Option<PlacedCone>, FieldError> {
        let Some(cone) = self.cone else { return Ok(None) };
        if self.cylinder_radius_m.is_some() {
            return Err(FieldError::new("cone", "a piece wraps on a cylinder or a cone, not both"));
        }
        let beta = cone.half_angle_deg;
        if !(beta > 0.0 && beta <= 90.0) {
            return Err(FieldError::new("cone", format!("half_angle_deg must be in (0, 90], got {beta}")));
        }
        if cone.apex_m.iter().any(|c| !c.is_finite()) {
            return Err(FieldError::new("cone", format!("apex_m must be finite, got {:?}", cone.apex_m)));
        }
        let (sin, cos) = beta.to_radians().sin_cos();
        Ok(Some(PlacedCone { apex: cone.apex_m, sin, cos }))
    }

    /// The placed x and y axes, orthonormal.
    fn axes(&self) -> Result<(Vec3, Vec3), FieldError> {
        let u = Vec3::from(self.u_axis)
            .try_normalize(1e-12)
            .filter(|u| u.iter().all(|c| c.is_finite()))
            .ok_or(FieldError::new("u_axis", format!("must be a finite non-zero direction, got {:?}", self.u_axis)))?;
        let v = Vec3::from(self.v_axis);
        let v = (v - u * u.dot(&v)).try_normalize(1e-9 * v.norm()).filter(|v| v.iter().all(|c| c.is_finite())).ok_or(
            FieldError::new("v_axis", format!("must be finite, non-zero and not along u_axis, got {:?}", self.v_axis)),
        )?;
        Ok((u, v))
    }
}

/// The pieces no longer than `h` that the segment from `a` to `b` splits
/// into (at least one), as a float for range checks.
fn pieces_no_longer_than(a: [f64; 2], b: [f64; 2], h: f64) -> f64 {
    ((b[0] - a[0]).hypot(b[1] - a[1]) / h).ceil().max(1.0)
}

/// The point of the segment `a`-`b` nearest `p`: its parameter along the
/// line (not clamped; 0 at `a`, 1 at `b`), the point at that parameter
/// clamped to the segment, and `p`'s distance to it, m.
fn nearest_on_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> (f64, [f64; 2], f64) {
    let d = [b[0] - a[0], b[1] - a[1]];
    let t = ((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1]);
    let s = t.clamp(0.0, 1.0);
    let on = [a[0] + s * d[0], a[1] + s * d[1]];
    (t, on, (p[0] - on[0]).hypot(p[1] - on[1]))
}

/// Whether `p` is inside the polygon `corners` (crossing count of a ray
/// along +x; a face's centre is never on the outline).
fn inside_polygon(corners: &[[f64; 2]], p: [f64; 2]) -> bool {
    let n = corners.len();
    let mut inside = false;
    for k in 0..n {
        let (a, b) = (corners[k], corners[(k + 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if x > p[0] {
                inside = !inside;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rectangle(w: f64, l: f64, h: f64) -> PatternPiece {
        PatternPiece {
            outline_m: vec![[0.0, 0.0], [w, 0.0], [w, l], [0.0, l]],
            edge_length_m: h,
            lines_m: Vec::new(),
            u_axis: x_axis(),
            v_axis: y_axis(),
            cylinder_radius_m: None,
            cone: None,
        }
    }

    #[test]
    fn a_rectangle_meshes_to_its_area_with_edges_near_the_target() {
        let m = rectangle(0.3, 0.2, 0.02).mesh().unwrap();
        let p = &m.positions;
        let area: f64 = m
            .triangles
            .iter()
            .map(|t| 0.5 * (p[t[1] as usize] - p[t[0] as usize]).cross(&(p[t[2] as usize] - p[t[0] as usize])).z)
            .sum();
        assert!((area - 0.06).abs() < 1e-12, "area {area}: every triangle counter-clockwise, none missing");
        let mut lengths: Vec<f64> = m
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| (p[t[k] as usize] - p[t[(k + 1) % 3] as usize]).norm()))
            .collect();
        lengths.sort_by(f64::total_cmp);
        let median = lengths[lengths.len() / 2];
        println!("{} vertices, {} triangles, median edge {median}", p.len(), m.triangles.len());
        assert!(median > 0.017 && median <= 0.02, "median edge {median} m");
        // The outline's vertices lie on its edges, in order.
        assert_eq!(m.outline_edges.len(), 4);
        assert_eq!(m.outline_edges[0].len(), 16);
        for (k, w) in m.outline_edges[0].windows(2).enumerate() {
            let (a, b) = (p[w[0] as usize], p[w[1] as usize]);
            assert!(a.y.abs() < 1e-15 && b.x > a.x, "edge 0, piece {k}: {a} -> {b}");
        }
        assert_eq!(m.outline_edges[0].last(), m.outline_edges[1].first());
    }

    #[test]
    fn bad_outlines_name_the_field() {
        let mut r = rectangle(0.3, 0.2, 0.02);
        r.outline_m[2] = [0.3, 0.0];
        assert_eq!(r.mesh().unwrap_err().path, "outline_m", "a repeated corner");
        let mut bow = rectangle(0.3, 0.2, 0.02);
        bow.outline_m.swap(2, 3);
        assert_eq!(bow.mesh().unwrap_err().path, "outline_m", "a bow tie crosses itself");
        assert_eq!(rectangle(0.3, 0.2, 0.0).mesh().unwrap_err().path, "edge_length_m");
        assert_eq!(rectangle(0.3, 0.2, 1e-6).mesh().unwrap_err().path, "edge_length_m", "too many triangles");
        let mut flat = rectangle(0.3, 0.2, 0.02);
        flat.v_axis = [2.0, 0.0, 0.0];
        assert_eq!(flat.mesh().unwrap_err().path, "v_axis");
        let mut outside = rectangle(0.3, 0.2, 0.02);
        outside.lines_m = vec![[[0.1, 0.1], [0.5, 0.1]]];
        assert_eq!(outside.mesh().unwrap_err().path, "lines_m");
    }

    /// Every triangle of `m`, a piece wrapped round the z axis, faces away
    /// from the axis, and every edge is at most as long as in `flat` and
    /// shorter by at most `shortening(its flat length)` (+1e-15 m).
    fn assert_faces_out_and_keeps_lengths(m: &PatternMesh, flat: &PatternMesh, shortening: impl Fn(f64) -> f64) {
        for t in &m.triangles {
            let (a, b, c) = (m.positions[t[0] as usize], m.positions[t[1] as usize], m.positions[t[2] as usize]);
            let normal = (b - a).cross(&(c - a));
            let radial = Vec3::new(a.x + b.x + c.x, a.y + b.y + c.y, 0.0);
            assert!(normal.dot(&radial) > 0.0, "triangle {t:?} faces in");
            for (k, &q) in t.iter().enumerate() {
                let o = t[(k + 1) % 3];
                let wrapped = (m.positions[q as usize] - m.positions[o as usize]).norm();
                let plane = (flat.positions[q as usize] - flat.positions[o as usize]).norm();
                assert!(
                    wrapped <= plane + 1e-15 && plane - wrapped <= shortening(plane) + 1e-15,
                    "{wrapped} vs {plane}"
                );
            }
        }
    }

    /// A half-round annular sector about its apex (radii 0.4 and 0.7 m)
    /// wrapped on a cone of half angle 30 degrees: every vertex lies on the
    /// cone, the inner arc at 0.2 m from the axis goes half way round (its
    /// ends at +-y), every edge keeps its length to a chord's shortening
    /// (about `L^3 / (24 R^2)`, `R` the cone's smallest radius of curvature),
    /// and the front faces out.
    #[test]
    fn a_sector_wrapped_on_a_cone_lies_on_it_and_keeps_its_lengths() {
        let beta = 30f64.to_radians();
        let alpha = std::f64::consts::PI * beta.sin();
        let apex = [0.0, -0.4];
        let arc = |rho: f64, k: usize| {
            let psi = -alpha / 2.0 + alpha * k as f64 / 8.0;
            [apex[0] + rho * psi.sin(), apex[1] + rho * psi.cos()]
        };
        let outline = (0..=8).map(|k| arc(0.4, k)).chain((0..=8).rev().map(|k| arc(0.7, k))).collect();
        let mut piece = PatternPiece::new(outline, 0.03);
        piece.v_axis = [0.0, 0.0, -1.0];
        let flat = piece.mesh().unwrap();
        piece.cone = Some(ConeWrap { apex_m: apex, half_angle_deg: 30.0 });
        let m = piece.mesh().unwrap();
        // The apex sits at z = 0.4 (v_axis * -0.4); the cone opens down.
        for p in &m.positions {
            let radius = p.x.hypot(p.y);
            assert!((radius - (0.4 - p.z) * beta.tan()).abs() < 1e-12, "{p}");
            // The arcs are polylines of 8 and 12 chords: the inner one's dip in.
            assert!((0.2 * (alpha / 16.0).cos() - 1e-12..=0.35 + 1e-12).contains(&radius), "{p}");
        }
        let first = Vec3::new(0.0, 0.2, 0.4 - 0.4 * beta.cos());
        let last = Vec3::new(0.0, -0.2, first.z);
        for end in [first, last] {
            assert!(m.positions.iter().any(|p| (p - end).norm() < 1e-12), "no vertex at {end}");
        }
        // At the inner chords' dip; the bound is the leading term, 10% kept for the next.
        let smallest_radius_of_curvature = 0.2 * (alpha / 16.0).cos() / beta.cos();
        let shortening = |plane: f64| 1.1 * plane.powi(3) / (24.0 * smallest_radius_of_curvature.powi(2));
        assert_faces_out_and_keeps_lengths(&m, &flat, shortening);
        let mut both = piece.clone();
        both.cylinder_radius_m = Some(0.2);
        assert_eq!(both.mesh().unwrap_err().path, "cone");
        let mut steep = piece.clone();
        steep.cone = Some(ConeWrap { apex_m: apex, half_angle_deg: 95.0 });
        assert!(steep.mesh().unwrap_err().message.contains("half_angle_deg"));
        // A denormal half angle: its sine is so small that the turn overflows.
        let mut thin = piece.clone();
        thin.cone = Some(ConeWrap { apex_m: apex, half_angle_deg: 1e-320 });
        assert_eq!(thin.mesh().unwrap_err().path, "cone");
    }

    /// Wrapped around a cylinder, every edge keeps its length (chords of
    /// arcs: within `L^3 / (24 R^2)`), every vertex sits on the cylinder,
    /// and the front faces out.
    #[test]
    fn a_piece_wrapped_on_a_cylinder_keeps_its_lengths_and_faces_out() {
        let mut r = rectangle(0.6, 0.3, 0.03);
        r.v_axis = [0.0, 0.0, -1.0];
        let flat = r.mesh().unwrap();
        r.cylinder_radius_m = Some(0.2);
        let m = r.mesh().unwrap();
        for p in &m.positions {
            assert!(((p.x * p.x + p.y * p.y).sqrt() - 0.2).abs() < 1e-12, "{p}");
        }
        assert_faces_out_and_keeps_lengths(&m, &flat, |plane| plane.powi(3) / (24.0 * 0.04));
        r.cylinder_radius_m = Some(-1.0);
        assert_eq!(r.mesh().unwrap_err().path, "cylinder_radius_m");
    }

    #[test]
    fn the_mesh_follows_an_inside_line() {
        let mut r = rectangle(0.3, 0.2, 0.02);
        r.lines_m = vec![[[0.1, 0.0], [0.1, 0.2]]];
        let m = r.mesh().unwrap();
        // No triangle straddles x = 0.1.
        for t in &m.triangles {
            let x = t.map(|v| m.positions[v as usize].x - 0.1);
            assert!(x.iter().all(|&x| x <= 1e-12) || x.iter().all(|&x| x >= -1e-12), "{x:?}");
        }
    }
}
