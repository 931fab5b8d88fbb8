//! Mesh file formats: glTF/GLB in ([`gltf`]) and out ([`glb`]), OBJ in and
//! out ([`obj`]), PLY in ([`ply`]), a mesh's colour texture ([`texture`]);
//! [`read_mesh`] picks the reader by the file's extension;
//! [`gltf::read_skinned_mesh`] reads a tree's skinned cluster GLB.

pub mod compact;
pub mod glb;
pub mod gltf;
pub mod obj;
pub mod ply;
pub mod texture;

use std::path::Path;

use crate::error::{Error, Result};
use crate::geometry::Mesh;

/// One mesh from an `.obj`, `.ply`, `.glb` or `.gltf` file (a glTF file's
/// meshes all placed into one), checked by [`Mesh::validate`]: the
/// simplifiers and the Hausdorff bound assume a valid mesh.
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let mesh = match extension.as_str() {
        "obj" => obj::read_mesh(path)?,
        "ply" => ply::read_mesh(path)?,
        "glb" | "gltf" => gltf::read_mesh(path)?,
        other => {
            return Err(Error::file(
                path,
                format!("unknown mesh format {other:?} (expected .obj, .ply, .glb or .gltf)"),
            ));
        }
    };
    mesh.validate()
        .map_err(|m| Error::file(path, m.to_string()))?;
    Ok(mesh)
}

/// [`read_mesh`] and the mesh's colour texture, where a `.glb` or `.gltf`
/// of one mesh node has one ([`gltf::read_textured_mesh`]; the tree's
/// cluster GLBs with baked colour): its coordinates are checked against
/// the mesh, the image is passed on as it is.
pub fn read_textured_mesh(path: &Path) -> Result<(Mesh, Option<texture::Texture>)> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if !matches!(extension.as_str(), "glb" | "gltf") {
        return Ok((read_mesh(path)?, None));
    }
    let (mesh, texture) = gltf::read_textured_mesh(path)?;
    mesh.validate()
        .map_err(|m| Error::file(path, m.to_string()))?;
    Ok((mesh, texture))
}
