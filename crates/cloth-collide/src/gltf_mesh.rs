//! One mesh of a glTF 2.0 file (`.glb`, or `.gltf` with its buffers in
//! `.bin` files or embedded), as a [`SurfaceMesh`] in this project's z-up
//! frame: what a garment exported from Blender or a pattern tool becomes.
//!
//! - Every triangle primitive of the mesh is read (positions, indices and
//!   `TEXCOORD_0`); other primitive modes are refused.
//! - Vertices at the same position are welded into one: exporters split a
//!   vertex wherever its texture coordinates or normals differ, which for
//!   a cloth would cut the surface along every seam of its texture map.
//!   Each triangle keeps its corners' own texture coordinates. Welded
//!   vertices are numbered in the file's order (primitives in turn), each
//!   place by its first vertex there.
//! - The mesh is placed by the world transform of the first node that
//!   shows it (scenes searched in order, depth first), then turned from
//!   glTF's y-up to z-up: `(x, y, z) -> (x, -z, y)`.

use crate::{SurfaceMesh, Vec3};
use base64::Engine;
use nalgebra::Matrix4;
use std::collections::HashMap;
use std::path::Path;

/// Why a glTF mesh cannot be read. The text names the file and the part
/// of it at fault (mesh names, primitive numbers).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GltfError {
    /// The file cannot be read, is not glTF 2.0, or its mesh is not a
    /// triangle mesh this reader takes.
    #[error("{0}")]
    File(String),
    /// The mesh asked for is not in the file, or none was named and the
    /// file has several: a matter of the mesh's name, not of the file.
    #[error("{0}")]
    MeshChoice(String),
}

/// Reads the mesh named `name` (or the file's only mesh when `None`) from
/// the glTF file at `path`.
pub fn read_gltf(path: &Path, name: Option<&str>) -> Result<SurfaceMesh, GltfError> {
    let bytes = std::fs::read(path).map_err(|e| GltfError::File(format!("cannot read {}: {e}", path.display())))?;
    parse_gltf(&bytes, path, name)
}

/// [`read_gltf`] on the file's bytes; `path` names it in errors and
/// locates the `.bin` files beside it. The `gltf` crate's validation
/// indexes some arrays before checking them (a primitive's `POSITION`
/// naming an accessor that does not exist panics in gltf-json 1.4.1), so
/// a panic while reading is caught and refused as a malformed file.
pub fn parse_gltf(bytes: &[u8], path: &Path, name: Option<&str>) -> Result<SurfaceMesh, GltfError> {
    crate::catch_panic(|| parse_unguarded(bytes, path, name)).unwrap_or_else(|why| {
        Err(GltfError::File(format!("{}: malformed glTF (the reader failed: {why})", path.display())))
    })
}

fn parse_unguarded(bytes: &[u8], path: &Path, name: Option<&str>) -> Result<SurfaceMesh, GltfError> {
    let file_error = |what: String| GltfError::File(format!("{}: {what}", path.display()));
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| file_error(format!("not glTF 2.0: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let buffers = gltf
        .buffers()
        .map(|b| buffer_data(&gltf, &b, dir).map_err(|e| file_error(format!("buffer {}: {e}", b.index()))))
        .collect::<Result<Vec<Vec<u8>>, GltfError>>()?;
    let names: Vec<String> =
        gltf.meshes().map(|m| m.name().map_or_else(|| format!("#{}", m.index()), str::to_owned)).collect();
    let mesh = match name {
        Some(wanted) => gltf.meshes().find(|m| m.name() == Some(wanted)).ok_or_else(|| {
            let message = format!("{}: no mesh named {wanted:?}; the file has {}", path.display(), names.join(", "));
            GltfError::MeshChoice(message)
        })?,
        None => {
            let mut meshes = gltf.meshes();
            match (meshes.next(), meshes.next()) {
                (Some(only), None) => only,
                (None, _) => return Err(file_error("no mesh".into())),
                (Some(_), Some(_)) => {
                    let message =
                        format!("{}: {} meshes ({}); name one", path.display(), names.len(), names.join(", "));
                    return Err(GltfError::MeshChoice(message));
                }
            }
        }
    };
    let transform = world_transform(&gltf, mesh.index()).map_err(file_error)?;
    let mut out = SurfaceMesh::default();
    let mut welded: HashMap<[u32; 3], u32> = HashMap::new();
    for primitive in mesh.primitives() {
        let err =
            |what: String| file_error(format!("mesh {}: primitive {}: {what}", names[mesh.index()], primitive.index()));
        if primitive.mode() != gltf::mesh::Mode::Triangles {
            return Err(err(format!("mode {:?}; only triangles are read", primitive.mode())));
        }
        let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let positions: Vec<[f32; 3]> =
            reader.read_positions().ok_or_else(|| err("no POSITION attribute".into()))?.collect();
        let uvs: Option<Vec<[f32; 2]>> = reader.read_tex_coords(0).map(|t| t.into_f32().collect());
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        if !indices.len().is_multiple_of(3) {
            return Err(err(format!("{} indices, not a whole number of triangles", indices.len())));
        }
        let uv_base = out.uvs.len() as u32;
        if let Some(uvs) = &uvs {
            out.uvs.extend(uvs.iter().map(|t| [f64::from(t[0]), f64::from(t[1])]));
        }
        // Welded in the file's order: vertex k becomes the first vertex at its place.
        let mut index_of = Vec::with_capacity(positions.len());
        for (k, p) in positions.iter().enumerate() {
            if p.iter().any(|c| !c.is_finite()) {
                return Err(err(format!("vertex {k} is not finite: {p:?}")));
            }
            index_of.push(*welded.entry(p.map(f32::to_bits)).or_insert_with(|| {
                let local = nalgebra::Vector4::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]), 1.0);
                let world = transform * local;
                out.vertices.push(Vec3::new(world.x, -world.z, world.y));
                out.vertices.len() as u32 - 1
            }));
        }
        let vertex = |k: u32| -> Result<u32, GltfError> {
            index_of
                .get(k as usize)
                .copied()
                .ok_or_else(|| err(format!("index {k} outside its {} vertices", positions.len())))
        };
        for corners in indices.chunks_exact(3) {
            let t = [vertex(corners[0])?, vertex(corners[1])?, vertex(corners[2])?];
            out.triangles.push(t);
            out.triangle_uvs.push(uvs.as_ref().map(|_| corners_uv(corners, uv_base)));
        }
    }
    if out.triangles.is_empty() {
        return Err(file_error(format!("mesh {} has no triangles", names[mesh.index()])));
    }
    Ok(out)
}

/// The texture-coordinate indices of a triangle's corners.
fn corners_uv(corners: &[u32], base: u32) -> [u32; 3] {
    [corners[0] + base, corners[1] + base, corners[2] + base]
}

/// A buffer's bytes: the `.glb`'s binary chunk, an embedded `data:` URI
/// (base64), or a file beside the glTF.
fn buffer_data(gltf: &gltf::Gltf, buffer: &gltf::Buffer<'_>, dir: &Path) -> Result<Vec<u8>, String> {
    let data = match buffer.source() {
        gltf::buffer::Source::Bin => gltf.blob.clone().ok_or("refers to a binary chunk the file does not have")?,
        gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
            let (_, encoded) = uri.split_once(";base64,").ok_or("a data URI that is not base64")?;
            base64::engine::general_purpose::STANDARD.decode(encoded).map_err(|e| format!("bad base64: {e}"))?
        }
        gltf::buffer::Source::Uri(uri) => {
            let file = dir.join(uri);
            std::fs::read(&file).map_err(|e| format!("cannot read {}: {e}", file.display()))?
        }
    };
    if data.len() < buffer.length() {
        return Err(format!("{} bytes, the file declares {}", data.len(), buffer.length()));
    }
    Ok(data)
}

/// The world transform of the first node showing mesh `mesh` (identity if
/// no scene shows it). glTF's nodes form trees: a node reached twice (its
/// own ancestor, or the child of two parents) is refused, where following
/// it would recurse for ever or take exponential time.
fn world_transform(gltf: &gltf::Gltf, mesh: usize) -> Result<Matrix4<f64>, String> {
    fn search(
        node: gltf::Node<'_>,
        parent: Matrix4<f64>,
        mesh: usize,
        seen: &mut [bool],
    ) -> Result<Option<Matrix4<f64>>, String> {
        let k = node.index();
        if std::mem::replace(&mut seen[k], true) {
            return Err(format!("node {k} is reached twice: glTF nodes form trees (no cycles, one parent each)"));
        }
        let local = node.transform().matrix();
        let world = parent * Matrix4::from_fn(|r, c| f64::from(local[c][r]));
        if node.mesh().is_some_and(|m| m.index() == mesh) {
            return Ok(Some(world));
        }
        for child in node.children() {
            if let Some(found) = search(child, world, mesh, seen)? {
                return Ok(Some(found));
            }
        }
        Ok(None)
    }
    for scene in gltf.scenes() {
        let mut seen = vec![false; gltf.nodes().len()];
        for root in scene.nodes() {
            if let Some(found) = search(root, Matrix4::identity(), mesh, &mut seen)? {
                return Ok(found);
            }
        }
    }
    Ok(Matrix4::identity())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square of two triangles whose shared edge's vertices are
    /// split (as an exporter splits them at a seam of the texture map),
    /// under a node moved by `translation`, with its buffer embedded.
    fn square_gltf(extra_mesh: bool, mode: u32, translation: [f32; 3]) -> String {
        let positions: [[f32; 3]; 6] =
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, -1.0], [0.0, 0.0, 0.0], [1.0, 0.0, -1.0], [0.0, 0.0, -1.0]];
        let uvs: [[f32; 2]; 6] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [5.0, 5.0], [6.0, 6.0], [5.0, 6.0]];
        let mut bytes: Vec<u8> = positions.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        bytes.extend(uvs.iter().flatten().flat_map(|c| c.to_le_bytes()));
        let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
        let other = if extra_mesh { r#",{"name":"other","primitives":[{"attributes":{"POSITION":0}}]}"# } else { "" };
        format!(
            r#"{{"asset":{{"version":"2.0"}},
            "scenes":[{{"nodes":[0]}}],
            "nodes":[{{"children":[1],"translation":[{},{},{}]}},{{"mesh":0}}],
            "meshes":[{{"name":"skirt","primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"mode":{mode}}}]}}{other}],
            "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{data}"}}],
            "bufferViews":[{{"buffer":0,"byteLength":72}},{{"buffer":0,"byteOffset":72,"byteLength":48}}],
            "accessors":[
              {{"bufferView":0,"componentType":5126,"count":6,"type":"VEC3","min":[0,0,-1],"max":[1,0,0]}},
              {{"bufferView":1,"componentType":5126,"count":6,"type":"VEC2"}}]}}"#,
            translation[0],
            translation[1],
            translation[2],
            bytes.len()
        )
    }

    fn read(text: &str, name: Option<&str>) -> Result<SurfaceMesh, GltfError> {
        let dir = std::env::temp_dir().join(format!("cloth-gltf-{}-{:p}", std::process::id(), text));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("square.gltf");
        std::fs::write(&path, text).unwrap();
        let mesh = read_gltf(&path, name);
        std::fs::remove_dir_all(&dir).unwrap();
        mesh
    }

    #[test]
    fn a_split_square_is_welded_placed_and_turned_z_up() {
        let mesh = read(&square_gltf(false, 4, [0.0, 2.0, 0.0]), None).unwrap();
        // Six exported vertices, four places.
        assert_eq!(mesh.vertices.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        // glTF's -z (into the screen) is this frame's +y; its +y (the node's 2 m) is +z.
        assert_eq!(mesh.vertices[2], Vec3::new(1.0, 1.0, 2.0));
        assert_eq!(mesh.vertices[3], Vec3::new(0.0, 1.0, 2.0));
        // Each triangle keeps its own corners' texture coordinates.
        assert_eq!(mesh.triangle_uvs, vec![Some([0, 1, 2]), Some([3, 4, 5])]);
        assert_eq!(mesh.uvs[4], [6.0, 6.0]);
    }

    #[test]
    fn wrong_meshes_and_modes_are_named() {
        let two = read(&square_gltf(true, 4, [0.0; 3]), None).unwrap_err();
        assert!(matches!(two, GltfError::MeshChoice(_)), "{two}");
        let two = two.to_string();
        assert!(two.contains("2 meshes (skirt, other); name one"), "{two}");
        assert_eq!(read(&square_gltf(true, 4, [0.0; 3]), Some("skirt")).unwrap().triangles.len(), 2);
        let unknown = read(&square_gltf(true, 4, [0.0; 3]), Some("dress")).unwrap_err();
        assert!(matches!(unknown, GltfError::MeshChoice(_)), "{unknown}");
        let unknown = unknown.to_string();
        assert!(unknown.contains("no mesh named \"dress\"; the file has skirt, other"), "{unknown}");
        let lines = read(&square_gltf(false, 1, [0.0; 3]), None).unwrap_err().to_string();
        assert!(lines.contains("mesh skirt: primitive 0: mode Lines"), "{lines}");
        let dangling = read(&square_gltf(false, 4, [0.0; 3]).replace("\"POSITION\":0", "\"POSITION\":7"), None);
        assert!(dangling.unwrap_err().to_string().contains("malformed glTF"));
        let garbage = read("{\"asset\":", None).unwrap_err().to_string();
        assert!(garbage.contains("not glTF 2.0"), "{garbage}");
        // Found by libFuzzer: a node among its own children recursed until
        // the stack overflowed, which aborts the host; two parents of one
        // node are refused too (chains of them take exponential time).
        let square = square_gltf(false, 4, [0.0; 3]);
        let cycle = read(&square.replace("\"children\":[1]", "\"children\":[0,1]"), None).unwrap_err().to_string();
        assert!(cycle.contains("node 0 is reached twice"), "{cycle}");
        let shared =
            square.replace("\"children\":[1]", "\"children\":[2,2,1]").replace("{\"mesh\":0}]", "{\"mesh\":0},{}]");
        let shared = read(&shared, None).unwrap_err().to_string();
        assert!(shared.contains("node 2 is reached twice"), "{shared}");
    }
}
