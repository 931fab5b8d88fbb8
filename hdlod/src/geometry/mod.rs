//! Triangle geometry: the indexed mesh every stage shares, and (in their own
//! files) merging, simplification and the Hausdorff bound.

mod mesh;

pub use mesh::Mesh;
