//! Mesh file formats: glTF/GLB in and out, OBJ and PLY in.
