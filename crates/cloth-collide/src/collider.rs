//! Solid shapes for cloth to collide with, and the narrow phase: the
//! signed distance, closest surface point and outward normal of a point,
//! computed by parry (f64).

use crate::Vec3;
use crate::obj::{ObjError, parse_obj};
use nalgebra::UnitQuaternion;
use parry3d_f64::math::{Pose, Rotation, Vector};
use parry3d_f64::shape::{SharedShape, TriMeshFlags};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A solid's shape in its own frame (scene name in brackets). Lengths in m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// A sphere (`ball`) centred on the origin.
    Ball {
        /// Radius, m.
        radius_m: f64,
    },
    /// A box (`cuboid`) centred on the origin.
    Cuboid {
        /// Half the edge lengths along x, y, z, m.
        half_extents_m: [f64; 3],
    },
    /// A capsule (`capsule`) around the local z axis.
    Capsule {
        /// Half the length of the axis segment (without the caps), m.
        half_length_m: f64,
        /// Radius, m.
        radius_m: f64,
    },
    /// A cylinder (`cylinder`) around the local z axis, centred on the origin.
    Cylinder {
        /// Half the height, m.
        half_length_m: f64,
        /// Radius, m.
        radius_m: f64,
    },
    /// The convex hull (`convex-hull`) of points.
    ConvexHull {
        /// At least four points not in one plane, m.
        points_m: Vec<[f64; 3]>,
    },
    /// A closed, consistently oriented triangle mesh (`mesh`) from an OBJ
    /// file, resolved relative to the scene file's directory.
    Mesh {
        /// Path of the OBJ file.
        obj: PathBuf,
        /// Factor from the file's units to metres (default 1).
        #[serde(default = "unit_scale")]
        scale: f64,
    },
    /// The half-space (`half-space`) below the plane through the origin
    /// with outward normal `normal` (the ground).
    HalfSpace {
        /// Outward normal (normalised internally).
        normal: [f64; 3],
    },
}

fn unit_scale() -> f64 {
    1.0
}

/// Why a shape cannot be built. `field` is relative to the shape table.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeError {
    /// A number is out of range.
    #[error("{field}: {message}")]
    Invalid {
        /// The offending field.
        field: &'static str,
        /// Why.
        message: String,
    },
    /// The mesh file cannot be read or parsed.
    #[error("obj: {}: {message}", path.display())]
    Mesh {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

/// Where a solid is: its frame's origin and orientation in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyPose {
    /// Origin of the solid's frame, m.
    pub position: Vec3,
    /// Orientation of the solid's frame.
    pub rotation: UnitQuaternion<f64>,
}

/// The closest point of a solid's surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Closest surface point, m.
    pub point: Vec3,
    /// Unit outward normal there.
    pub normal: Vec3,
    /// Signed distance of the query point, m: negative inside the solid.
    pub distance_m: f64,
}

/// A built solid shape, ready for queries.
#[derive(Debug, Clone)]
pub struct SolidShape {
    shape: SharedShape,
    /// Pose of parry's shape in the solid's frame (parry's cylinders run along y; ours along z).
    local: Pose,
    /// See [`SolidShape::distance_is_lipschitz`]; asked once, at construction.
    lipschitz: bool,
}

fn to_parry(v: Vec3) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

fn from_parry(v: Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

fn positive(field: &'static str, value: f64) -> Result<f64, ShapeError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ShapeError::Invalid { field, message: format!("must be finite and > 0, got {value}") })
    }
}

fn finite3(field: &'static str, v: &[f64; 3]) -> Result<Vec3, ShapeError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(Vec3::from(*v))
    } else {
        Err(ShapeError::Invalid { field, message: format!("must be finite, got {v:?}") })
    }
}

impl SolidShape {
    /// Checks `spec` and builds the shape; mesh paths are resolved against `base_dir`.
    pub fn build(spec: &ShapeSpec, base_dir: &Path) -> Result<Self, ShapeError> {
        let identity = Pose::IDENTITY;
        let (shape, local) = match spec {
            ShapeSpec::Ball { radius_m } => (SharedShape::ball(positive("radius_m", *radius_m)?), identity),
            ShapeSpec::Cuboid { half_extents_m } => {
                for (axis, h) in half_extents_m.iter().enumerate() {
                    positive(["half_extents_m[0]", "half_extents_m[1]", "half_extents_m[2]"][axis], *h)?;
                }
                let [x, y, z] = *half_extents_m;
                (SharedShape::cuboid(x, y, z), identity)
            }
            ShapeSpec::Capsule { half_length_m, radius_m } => {
                let h = positive("half_length_m", *half_length_m)?;
                (SharedShape::capsule_z(h, positive("radius_m", *radius_m)?), identity)
            }
            ShapeSpec::Cylinder { half_length_m, radius_m } => {
                let h = positive("half_length_m", *half_length_m)?;
                let y_to_z = Pose::from_rotation(Rotation::from_rotation_x(std::f64::consts::FRAC_PI_2));
                (SharedShape::cylinder(h, positive("radius_m", *radius_m)?), y_to_z)
            }
            ShapeSpec::ConvexHull { points_m } => {
                let points =
                    points_m.iter().map(|p| finite3("points_m", p).map(to_parry)).collect::<Result<Vec<_>, _>>()?;
                let hull = spans_volume(points_m).then(|| SharedShape::convex_hull(&points)).flatten();
                let hull = hull.ok_or_else(|| ShapeError::Invalid {
                    field: "points_m",
                    message: "needs at least four points not all in one plane".into(),
                })?;
                (hull, identity)
            }
            ShapeSpec::Mesh { obj, scale } => {
                let scale = positive("scale", *scale)?;
                (load_mesh(&base_dir.join(obj), Vec3::repeat(scale))?, identity)
            }
            ShapeSpec::HalfSpace { normal } => {
                let n = finite3("normal", normal)?;
                if n.norm() < 1e-12 {
                    return Err(ShapeError::Invalid { field: "normal", message: "must be non-zero".into() });
                }
                (SharedShape::halfspace(to_parry(n.normalize())), identity)
            }
        };
        Ok(Self::new(shape, local))
    }

    fn new(shape: SharedShape, local: Pose) -> Self {
        let lipschitz = shape.is_convex();
        Self { shape, local, lipschitz }
    }

    /// A closed, consistently oriented triangle mesh from the OBJ file at
    /// `path`, its vertices scaled per axis by `scale` (each finite and > 0).
    pub fn obj_mesh(path: &Path, scale: Vec3) -> Result<Self, ShapeError> {
        for k in 0..3 {
            positive(["scale[0]", "scale[1]", "scale[2]"][k], scale[k])?;
        }
        Ok(Self::new(load_mesh(path, scale)?, Pose::IDENTITY))
    }

    /// Wraps a shape built elsewhere (a rapier collider's), placed at
    /// `local` in the solid's frame. Not checked: parry's constructors
    /// already refused degenerate shapes.
    pub fn from_parry(shape: SharedShape, local: Pose) -> Self {
        Self::new(shape, local)
    }

    /// parry's shape and its pose in the solid's frame (to give a
    /// rigid-body engine the same solid).
    pub fn parts(&self) -> (&SharedShape, Pose) {
        (&self.shape, self.local)
    }

    fn pose(&self, body: &BodyPose) -> Pose {
        let q = body.rotation.quaternion();
        let rotation = Rotation::from_xyzw(q.i, q.j, q.k, q.w);
        Pose::from_parts(to_parry(body.position), rotation) * self.local
    }

    /// Triangles of a mesh solid (0 for the primitive shapes): what Choi &
    /// Ko's Table 1 counts as "triangles of solid".
    pub fn triangle_count(&self) -> usize {
        self.shape.as_trimesh().map_or(0, |mesh| mesh.indices().len())
    }

    /// A triangle mesh of the surface with the solid at `body`, for
    /// drawing: world vertices (m) and triangles, wound outward. Round
    /// shapes are tessellated (24 around); a half-space is a 10 m square of
    /// its plane centred at the frame origin.
    pub fn surface_mesh(&self, body: &BodyPose) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let s = &self.shape;
        let (vertices, triangles) = if let Some(b) = s.as_ball() {
            b.to_trimesh(24, 12)
        } else if let Some(c) = s.as_cuboid() {
            c.to_trimesh()
        } else if let Some(c) = s.as_capsule() {
            c.to_trimesh(24, 6)
        } else if let Some(c) = s.as_cylinder() {
            c.to_trimesh(24)
        } else if let Some(c) = s.as_convex_polyhedron() {
            c.to_trimesh()
        } else if let Some(m) = s.as_trimesh() {
            (m.vertices().to_vec(), m.indices().to_vec())
        } else if let Some(h) = s.as_halfspace() {
            let n = from_parry(h.normal);
            let u = n.cross(&if n.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() }).normalize() * 5.0;
            let v = n.cross(&u);
            // Wound so that (b - a) x (c - a) = 4 |u|^2 n: outward.
            let pose = self.pose(body);
            let corners = [-u - v, u - v, u + v, -u + v].map(|c| from_parry(pose.transform_point(to_parry(c))));
            return (corners.to_vec(), vec![[0, 1, 2], [0, 2, 3]]);
        } else {
            (Vec::new(), Vec::new())
        };
        let pose = self.pose(body);
        let vertices: Vec<Vec3> = vertices.into_iter().map(|p| from_parry(pose.transform_point(p))).collect();
        // parry's tessellations do not all wind the same way: turn each
        // face whose normal points into the solid.
        let triangles = triangles
            .into_iter()
            .map(|t| {
                let [a, b, c] = t.map(|k| vertices[k as usize]);
                let normal = (b - a).cross(&(c - a));
                let inward = normal.dot(&self.closest(body, (a + b + c) / 3.0).normal) < 0.0;
                if inward { [t[0], t[2], t[1]] } else { t }
            })
            .collect();
        (vertices, triangles)
    }

    /// The world bounding box `(min, max)` at `body`, m (infinite for a half-space).
    pub fn aabb(&self, body: &BodyPose) -> (Vec3, Vec3) {
        let b = self.shape.compute_aabb(&self.pose(body));
        (from_parry(b.mins), from_parry(b.maxs))
    }

    /// Whether [`SolidShape::closest`]'s signed distance changes by no more
    /// than the distance its point moves (is 1-Lipschitz), so a distance
    /// measured once bounds it nearby: true of convex solids (ball,
    /// cuboid, capsule, cylinder, convex hull, half-space: parry's
    /// `is_convex`), not taken for granted of the rest: an OBJ mesh's
    /// inside test (pseudo-normals) may flip the sign away from an open or
    /// self-crossing surface, and a compound's is its parts'.
    pub fn distance_is_lipschitz(&self) -> bool {
        self.lipschitz
    }

    /// Where a point moving in a straight line from `a` to `b` (m, the
    /// solid at `body`) first enters the solid: the share of the way there
    /// (0 to 1) and the outward normal at the entry. `None` when the
    /// segment misses it or `a` is already inside (share 0 from a
    /// surface point is a hit). Continuous collision detection for a
    /// particle whose step would carry it through the solid.
    pub fn first_entry(&self, body: &BodyPose, a: Vec3, b: Vec3) -> Option<(f64, Vec3)> {
        let ray = parry3d_f64::query::Ray::new(to_parry(a), to_parry(b - a));
        let hit = self.shape.cast_ray_and_get_normal(&self.pose(body), &ray, 1.0, true)?;
        // Solid cast: a start inside hits at once, with no entry face.
        if hit.time_of_impact <= 0.0 && self.closest(body, a).distance_m < 0.0 {
            return None;
        }
        Some((hit.time_of_impact, from_parry(hit.normal)))
    }

    /// The closest surface point to `p` (m) and the signed distance of `p`,
    /// with the solid at `body`.
    pub fn closest(&self, body: &BodyPose, p: Vec3) -> SurfacePoint {
        let pose = self.pose(body);
        let query = to_parry(p);
        let (proj, feature) = self.shape.project_point_and_get_feature(&pose, query);
        if !proj.point.is_finite() {
            // A query at a ball's centre (parry divides by its distance
            // from it): every surface point is closest; take the one along
            // the shape frame's +Z, at the depth the distance query gives.
            let distance = self.shape.distance_to_point(&pose, query, false);
            let normal = pose.rotation * Vector::Z;
            let point = query - normal * distance;
            return SurfacePoint { point: from_parry(point), normal: from_parry(normal), distance_m: distance };
        }
        let diff = query - proj.point;
        let len = diff.length();
        let sign = if proj.is_inside { -1.0 } else { 1.0 };
        let normal = if len > 1e-12 {
            diff * (sign / len)
        } else {
            // On the surface: ask the feature, else point away from the centre.
            let local = pose.inverse_transform_point(proj.point);
            match self.shape.feature_normal_at_point(0, feature, local) {
                Some(n) => pose.rotation * n,
                None => (query - pose.translation).try_normalize().unwrap_or(Vector::Z),
            }
        };
        SurfacePoint { point: from_parry(proj.point), normal: from_parry(normal), distance_m: sign * len }
    }
}

/// Whether the points contain a tetrahedron of non-negligible volume.
fn spans_volume(points: &[[f64; 3]]) -> bool {
    let p: Vec<Vec3> = points.iter().map(|c| Vec3::from(*c)).collect();
    let Some(&p0) = p.first() else { return false };
    let farthest = |score: &dyn Fn(&Vec3) -> f64| p.iter().copied().max_by(|a, b| score(a).total_cmp(&score(b)));
    let Some(p1) = farthest(&|q| (q - p0).norm()) else { return false };
    let extent = (p1 - p0).norm();
    let axis = (p1 - p0) / extent.max(f64::MIN_POSITIVE);
    let off_line = |q: &Vec3| (q - p0 - axis * axis.dot(&(q - p0))).norm();
    let Some(p2) = farthest(&off_line) else { return false };
    let normal = axis.cross(&(p2 - p0)).normalize();
    let off_plane = |q: &Vec3| normal.dot(&(q - p0)).abs();
    let Some(p3) = farthest(&off_plane) else { return false };
    let tiny = 1e-9 * extent;
    extent > 0.0 && off_line(&p2) > tiny && off_plane(&p3) > tiny
}

fn load_mesh(path: &Path, scale: Vec3) -> Result<SharedShape, ShapeError> {
    let fail = |message: String| ShapeError::Mesh { path: path.to_path_buf(), message };
    let text = std::fs::read_to_string(path).map_err(|e| fail(e.to_string()))?;
    let mesh = parse_obj(&text).map_err(|e: ObjError| fail(e.to_string()))?;
    let vertices = mesh.vertices.iter().map(|v| to_parry(v.component_mul(&scale))).collect();
    // ORIENTED: pseudo-normals tell inside from outside, so points that
    // crossed the surface are pushed back out, not through.
    let flags = TriMeshFlags::ORIENTED | TriMeshFlags::MERGE_DUPLICATE_VERTICES;
    SharedShape::trimesh_with_flags(vertices, mesh.triangles, flags).map_err(|e| fail(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(position: Vec3) -> BodyPose {
        BodyPose { position, rotation: UnitQuaternion::identity() }
    }

    fn sd(spec: &ShapeSpec, body: &BodyPose, p: Vec3) -> SurfacePoint {
        SolidShape::build(spec, Path::new(".")).unwrap().closest(body, p)
    }

    /// A path through a posed, turned 2 mm slab enters by the face it
    /// meets, at the share of the way where that face is; a path that
    /// stops short, runs beside it, or starts inside has no entry.
    #[test]
    fn a_path_through_a_thin_solid_enters_by_its_near_face() {
        let turn = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7);
        let body = BodyPose { position: Vec3::new(0.1, 0.2, 0.3), rotation: turn };
        let slab = SolidShape::build(&ShapeSpec::Cuboid { half_extents_m: [0.5, 0.5, 0.001] }, Path::new(".")).unwrap();
        let above = body.position + Vec3::new(0.0, 0.0, 0.011);
        let (share, normal) = slab.first_entry(&body, above, above - Vec3::new(0.0, 0.0, 0.04)).unwrap();
        assert!((share - 0.25).abs() < 1e-12 && (normal - Vec3::z()).norm() < 1e-12, "{share} {normal}");
        assert!(slab.first_entry(&body, above, above - Vec3::new(0.0, 0.0, 0.009)).is_none(), "stops short");
        assert!(slab.first_entry(&body, above, above + Vec3::new(0.3, 0.0, 0.0)).is_none(), "runs beside");
        let inside = body.position;
        assert!(slab.first_entry(&body, inside, inside - Vec3::new(0.0, 0.0, 0.04)).is_none(), "starts inside");
    }

    #[test]
    fn surface_meshes_lie_on_the_surface() {
        let body = BodyPose {
            position: Vec3::new(0.3, -0.2, 1.0),
            rotation: UnitQuaternion::from_euler_angles(0.3, -0.4, 0.9),
        };
        let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes");
        for spec in [
            ShapeSpec::Ball { radius_m: 0.5 },
            ShapeSpec::Cuboid { half_extents_m: [0.1, 0.2, 0.3] },
            ShapeSpec::Capsule { half_length_m: 0.4, radius_m: 0.1 },
            ShapeSpec::Cylinder { half_length_m: 0.4, radius_m: 0.1 },
            ShapeSpec::Mesh { obj: "pillow.obj".into(), scale: 1.0 },
            ShapeSpec::HalfSpace { normal: [0.0, 1.0, 1.0] },
        ] {
            let shape = SolidShape::build(&spec, &fixtures).unwrap();
            let (vertices, triangles) = shape.surface_mesh(&body);
            assert!(!triangles.is_empty(), "{spec:?}");
            // Every vertex on the surface (tessellated round shapes: their
            // vertices are on it exactly too).
            let off = vertices.iter().map(|p| shape.closest(&body, *p).distance_m.abs()).fold(0.0, f64::max);
            assert!(off < 1e-9, "{spec:?}: {off}");
            // Outward winding: each face's normal along the surface's
            // outward normal nearest its centre (degenerate faces aside).
            let mut inward = 0;
            for t in &triangles {
                let [a, b, c] = t.map(|k| vertices[k as usize]);
                let normal = (b - a).cross(&(c - a));
                if normal.norm() > 1e-12 {
                    let outward = match spec {
                        ShapeSpec::HalfSpace { .. } => body.rotation * Vec3::new(0.0, 1.0, 1.0).normalize(),
                        _ => shape.closest(&body, (a + b + c) / 3.0).normal,
                    };
                    inward += usize::from(normal.normalize().dot(&outward) <= 0.0);
                }
            }
            assert_eq!(inward, 0, "{spec:?}: {inward} of {} faces wind inward", triangles.len());
        }
    }

    /// A point at a ball's very centre is inside by the radius, with a
    /// unit normal and a surface point on the ball (parry's projection of
    /// it divides by zero: it went through as NaN, and the point counted
    /// as outside).
    #[test]
    fn the_centre_of_a_ball_is_inside_by_its_radius() {
        let body = at(Vec3::new(0.2, -0.1, 0.4));
        let c = sd(&ShapeSpec::Ball { radius_m: 0.08 }, &body, body.position);
        assert_eq!(c.distance_m, -0.08);
        assert!((c.normal.norm() - 1.0).abs() < 1e-15 && ((c.point - body.position).norm() - 0.08).abs() < 1e-15);
        // A hair off the centre: the same depth, the normal along the offset.
        let near = sd(&ShapeSpec::Ball { radius_m: 0.08 }, &body, body.position + Vec3::new(1e-9, 0.0, 0.0));
        assert!((near.distance_m + 0.08).abs() < 2e-9 && near.normal.x > 0.999, "{near:?}");
    }

    #[test]
    fn meshes_count_their_triangles_and_primitives_none() {
        // The pillow fixture lists 64 triangles (its poles) and 448 quads,
        // each split in two: 960.
        let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes");
        let pillow = ShapeSpec::Mesh { obj: "pillow.obj".into(), scale: 1.0 };
        assert_eq!(SolidShape::build(&pillow, &fixtures).unwrap().triangle_count(), 960);
        let ball = ShapeSpec::Ball { radius_m: 0.5 };
        assert_eq!(SolidShape::build(&ball, &fixtures).unwrap().triangle_count(), 0);
    }

    #[test]
    fn signed_distances_match_closed_forms() {
        let ball = ShapeSpec::Ball { radius_m: 0.5 };
        let c = Vec3::new(1.0, 2.0, 3.0);
        let out = sd(&ball, &at(c), c + Vec3::new(0.0, 0.0, 0.8));
        assert!((out.distance_m - 0.3).abs() < 1e-12 && (out.normal - Vec3::z()).norm() < 1e-12);
        let inside = sd(&ball, &at(c), c + Vec3::new(0.2, 0.0, 0.0));
        assert!((inside.distance_m + 0.3).abs() < 1e-12 && (inside.normal - Vec3::x()).norm() < 1e-12);

        // Cylinder along z (the local axis), whatever parry's convention.
        let cyl = ShapeSpec::Cylinder { half_length_m: 1.0, radius_m: 0.5 };
        let side = sd(&cyl, &at(Vec3::zeros()), Vec3::new(0.0, 0.9, 0.7));
        assert!((side.distance_m - 0.4).abs() < 1e-9 && (side.normal - Vec3::y()).norm() < 1e-9);
        let top = sd(&cyl, &at(Vec3::zeros()), Vec3::new(0.1, 0.1, 1.25));
        assert!((top.distance_m - 0.25).abs() < 1e-9 && (top.normal - Vec3::z()).norm() < 1e-9);

        // A half-space tilted by 30 degrees, rotated body frame.
        let ground = ShapeSpec::HalfSpace { normal: [0.0, 0.0, 1.0] };
        let tilt = BodyPose {
            position: Vec3::zeros(),
            rotation: UnitQuaternion::from_axis_angle(&Vec3::x_axis(), 30f64.to_radians()),
        };
        let p = Vec3::new(0.3, 0.0, -0.2);
        let expect_n = tilt.rotation * Vec3::z();
        let g = sd(&ground, &tilt, p);
        assert!((g.distance_m - p.dot(&expect_n)).abs() < 1e-12 && (g.normal - expect_n).norm() < 1e-12);

        let boxed = ShapeSpec::Cuboid { half_extents_m: [1.0, 0.5, 0.25] };
        let b = sd(&boxed, &at(Vec3::zeros()), Vec3::new(0.2, 0.1, 0.2));
        assert!((b.distance_m + 0.05).abs() < 1e-12 && (b.normal - Vec3::z()).norm() < 1e-12);
    }

    #[test]
    fn capsule_hull_and_mesh_agree_with_geometry() {
        let cap = ShapeSpec::Capsule { half_length_m: 0.5, radius_m: 0.1 };
        let end = sd(&cap, &at(Vec3::zeros()), Vec3::new(0.0, 0.0, 0.8));
        assert!((end.distance_m - 0.2).abs() < 1e-12);
        // The unit cube as a hull and as an OBJ mesh (written to a temp file).
        let corners: Vec<[f64; 3]> =
            (0..8).map(|k| [(k & 1) as f64 - 0.5, ((k >> 1) & 1) as f64 - 0.5, ((k >> 2) & 1) as f64 - 0.5]).collect();
        let hull = ShapeSpec::ConvexHull { points_m: corners.clone() };
        let h = sd(&hull, &at(Vec3::zeros()), Vec3::new(0.1, 0.0, 0.9));
        assert!((h.distance_m - 0.4).abs() < 1e-9 && (h.normal - Vec3::z()).norm() < 1e-9);
        let dir = std::env::temp_dir().join(format!("cloth-collide-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut obj = String::new();
        for c in &corners {
            obj += &format!("v {} {} {}\n", c[0], c[1], c[2]);
        }
        // Outward-facing (counter-clockwise seen from outside) quads of the cube.
        obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
        std::fs::write(dir.join("cube.obj"), obj).unwrap();
        let mesh = ShapeSpec::Mesh { obj: "cube.obj".into(), scale: 2.0 };
        let shape = SolidShape::build(&mesh, &dir).unwrap();
        let out = shape.closest(&at(Vec3::zeros()), Vec3::new(0.1, 0.0, 1.3));
        assert!((out.distance_m - 0.3).abs() < 1e-9 && (out.normal - Vec3::z()).norm() < 1e-9, "{out:?}");
        let inside = shape.closest(&at(Vec3::zeros()), Vec3::new(0.1, 0.0, 0.8));
        assert!((inside.distance_m + 0.2).abs() < 1e-9 && (inside.normal - Vec3::z()).norm() < 1e-9, "{inside:?}");
        let missing = SolidShape::build(&ShapeSpec::Mesh { obj: "nope.obj".into(), scale: 1.0 }, &dir);
        assert!(matches!(missing, Err(ShapeError::Mesh { .. })));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn bad_numbers_name_the_field() {
        let e = SolidShape::build(&ShapeSpec::Ball { radius_m: -1.0 }, Path::new(".")).unwrap_err();
        assert!(e.to_string().starts_with("radius_m"), "{e}");
        let flat =
            ShapeSpec::ConvexHull { points_m: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]] };
        assert!(SolidShape::build(&flat, Path::new(".")).unwrap_err().to_string().starts_with("points_m"));
        let nan = ShapeSpec::HalfSpace { normal: [0.0, f64::NAN, 1.0] };
        assert!(SolidShape::build(&nan, Path::new(".")).unwrap_err().to_string().starts_with("normal"));
    }
}
