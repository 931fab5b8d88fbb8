//! Mesh file formats: glTF/GLB in and out, OBJ and PLY in.
pub mod obj;
pub mod ply;
