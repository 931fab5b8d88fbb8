//! Triangle geometry: the indexed mesh every stage shares, merging,
//! simplification to an error budget, the Hausdorff bound and measures.

mod closest;
mod hausdorff;
pub mod measure;
mod merge;
mod mesh;
mod proxy;
mod reduce;
mod simplify;

pub use closest::{Nearest, TriangleSet, closest_point_on_triangle};
pub use hausdorff::{Hausdorff, HausdorffOptions, hausdorff, one_sided_bound};
pub use merge::{Part, merge};
pub use mesh::Mesh;
pub use reduce::{Reduced, reduce_parts};
pub use simplify::{Simplified, SimplifyOptions, Strategy, clustering, edge_collapse, simplify};
