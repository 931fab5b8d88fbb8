//! Mesh file formats: glTF/GLB in ([`gltf`]) and out ([`glb`]), OBJ in and
//! out ([`obj`]), PLY in ([`ply`]).

pub mod glb;
pub mod gltf;
pub mod obj;
pub mod ply;
