//! Triangle mesh writers: OBJ, binary PLY, GLB.

use std::path::Path;

use crate::{IoError, Result};

/// A mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (text).
    Obj,
    /// Binary little-endian PLY.
    Ply,
    /// glTF 2.0 binary.
    Glb,
}

impl MeshFormat {
    /// From a file extension (`obj`, `ply`, `glb`).
    pub fn from_extension(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            "glb" => Some(MeshFormat::Glb),
            _ => None,
        }
    }
}

/// Writes a mesh, format from the extension.
pub fn write_mesh(
    path: &Path,
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    normals: Option<&[[f32; 3]]>,
) -> Result<()> {
    let f = MeshFormat::from_extension(path).ok_or_else(|| {
        IoError::UnknownFormat(format!(
            "{}: mesh extension must be .obj, .ply or .glb",
            path.display()
        ))
    })?;
    write_mesh_as(path, f, positions, triangles, normals)
}

/// Writes a mesh in format `f`.
pub fn write_mesh_as(
    path: &Path,
    _f: MeshFormat,
    _positions: &[[f32; 3]],
    _triangles: &[[u32; 3]],
    _normals: Option<&[[f32; 3]]>,
) -> Result<()> {
    Err(IoError::UnknownFormat(format!(
        "{}: not yet implemented",
        path.display()
    )))
}
