//! A minimal Wavefront OBJ reader: vertices (`v`), texture coordinates
//! (`vt`) and polygonal faces (`f`, fan-triangulated). Everything else
//! (normals, groups, materials) is skipped: a collider needs only the
//! surface, a cloth the surface and the grain its texture map gives.

use crate::Vec3;

/// A triangle mesh read from a file (OBJ, or glTF: [`crate::read_gltf`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SurfaceMesh {
    /// Vertex positions, in the file's units.
    pub vertices: Vec<Vec3>,
    /// Triangles as vertex indices (0-based), counter-clockwise as in the file.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates `(u, v)`.
    pub uvs: Vec<[f64; 2]>,
    /// Each triangle's corners' indices into `uvs`, `None` for a triangle
    /// whose face gave none (one vertex can have several, across a seam of
    /// the texture map).
    pub triangle_uvs: Vec<Option<[u32; 3]>>,
}

/// Why OBJ text could not be read: the 1-based line and the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct ObjError {
    /// 1-based line number (0 when the error is about the whole file).
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// Parses OBJ text. Face indices may be negative (relative to the end) and
/// may carry `/vt/vn` suffixes; faces with more than three corners are
/// split into a fan. A mesh without faces is an error (see
/// [`parse_obj_points`]).
pub fn parse_obj(text: &str) -> Result<SurfaceMesh, ObjError> {
    let mesh = parse_obj_points(text)?;
    if mesh.triangles.is_empty() {
        return Err(ObjError { line: 0, message: "no faces".into() });
    }
    Ok(mesh)
}

/// Parses OBJ text as [`parse_obj`] does, but accepts vertices alone (a
/// point cloud, as `cloth regress` keeps a final frame).
pub fn parse_obj_points(text: &str) -> Result<SurfaceMesh, ObjError> {
    let mut mesh = SurfaceMesh::default();
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let err = |message: String| ObjError { line, message };
        let mut words = raw.split('#').next().unwrap_or("").split_whitespace();
        match words.next() {
            Some("v") => {
                let c = numbers::<3>(&mut words, "vertex needs three coordinates", "coordinate").map_err(err)?;
                mesh.vertices.push(Vec3::from(c));
            }
            Some("vt") => {
                mesh.uvs.push(
                    numbers::<2>(&mut words, "texture coordinate needs u and v", "texture coordinate").map_err(err)?,
                );
            }
            Some("f") => {
                let (n, n_uv) = (mesh.vertices.len(), mesh.uvs.len());
                // A 1-based (or negative, from the end) index among `count` read so far.
                let index = |w: &str, text: &str, count: usize, what: &str| {
                    let i: i64 = text.parse().map_err(|_| err(format!("bad face index {w:?}")))?;
                    let index = if i > 0 { i - 1 } else { count as i64 + i };
                    if i == 0 || index < 0 || index >= count as i64 {
                        return Err(err(format!("face index {i} outside the {count} {what} read so far")));
                    }
                    Ok(index as u32)
                };
                let corners = words
                    .map(|w| {
                        let mut parts = w.split('/');
                        let vertex = index(w, parts.next().unwrap_or(""), n, "vertices")?;
                        let uv = match parts.next() {
                            Some(t) if !t.is_empty() => Some(index(w, t, n_uv, "texture coordinates")?),
                            _ => None,
                        };
                        Ok((vertex, uv))
                    })
                    .collect::<Result<Vec<(u32, Option<u32>)>, ObjError>>()?;
                if corners.len() < 3 {
                    return Err(err(format!("face has {} corners, needs at least 3", corners.len())));
                }
                let uv_at = |k: usize| corners[k].1;
                for w in 1..corners.len() - 1 {
                    mesh.triangles.push([corners[0].0, corners[w].0, corners[w + 1].0]);
                    let uv = [uv_at(0), uv_at(w), uv_at(w + 1)];
                    mesh.triangle_uvs.push(match uv {
                        [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                        _ => None,
                    });
                }
            }
            _ => {}
        }
    }
    Ok(mesh)
}

/// The next `N` finite numbers of a line; `missing` when there are fewer,
/// and a bad or non-finite `what` named with the word.
fn numbers<'a, const N: usize>(
    words: &mut impl Iterator<Item = &'a str>,
    missing: &str,
    what: &str,
) -> Result<[f64; N], String> {
    let mut c = [0.0; N];
    for slot in &mut c {
        let w = words.next().ok_or_else(|| missing.to_string())?;
        *slot = w.parse::<f64>().map_err(|_| format!("bad {what} {w:?}"))?;
        if !slot.is_finite() {
            return Err(format!("non-finite {what} {w:?}"));
        }
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_vertices_and_fans_polygons() {
        let text = "# a unit square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n";
        let mesh = parse_obj(text).unwrap();
        assert_eq!(mesh.vertices.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        let relative = parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n").unwrap();
        assert_eq!(relative.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn texture_coordinates_follow_the_faces() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\n\
                    f 1/1 2/2 3/3 4/4\nf 1 3 4\nf 1/-4/1 2/-3/1 3/-2/1\n";
        let mesh = parse_obj(text).unwrap();
        assert_eq!(mesh.uvs.len(), 4);
        assert_eq!(mesh.triangle_uvs, vec![Some([0, 1, 2]), Some([0, 2, 3]), None, Some([0, 1, 2])]);
        assert_eq!(parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n").unwrap_err().line, 5);
        assert_eq!(parse_obj("vt 0 inf\n").unwrap_err().line, 1);
    }

    #[test]
    fn errors_name_the_line() {
        assert_eq!(parse_obj("v 0 0 0\nv 1 0\n").unwrap_err().line, 2);
        assert_eq!(parse_obj("v 0 0 0\nf 1 2 3\n").unwrap_err().line, 2);
        assert_eq!(parse_obj("v 0 0 nan\n").unwrap_err().line, 1);
        assert_eq!(parse_obj("v 0 0 0\n").unwrap_err().line, 0);
    }

    #[test]
    fn points_alone_are_a_point_cloud() {
        let points = parse_obj_points("# a frame\nv 0.1 -2 3e-17\nv 1 0 0\n").unwrap();
        assert_eq!(points.vertices, vec![Vec3::new(0.1, -2.0, 3e-17), Vec3::new(1.0, 0.0, 0.0)]);
        assert!(points.triangles.is_empty());
        assert_eq!(parse_obj_points("v 0 0\n").unwrap_err().line, 1);
    }
}
