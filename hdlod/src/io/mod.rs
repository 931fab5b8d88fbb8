//! Mesh file formats: glTF/GLB in ([`gltf`]) and out ([`glb`]).

pub mod glb;
pub mod gltf;
