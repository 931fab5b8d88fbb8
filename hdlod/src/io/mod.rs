//! Mesh file formats: glTF/GLB in ([`gltf`]) and out ([`glb`]), OBJ and PLY
//! in ([`obj`], [`ply`]).

pub mod glb;
pub mod gltf;
pub mod obj;
pub mod ply;
