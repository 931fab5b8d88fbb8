//! Triangle geometry: the indexed mesh every stage shares, merging,
//! simplification to an error budget, the Hausdorff bound and measures.

pub mod bake;
mod closest;
mod color_bound;
mod distance;
mod ellipsoid;
mod features;
mod hausdorff;
pub mod measure;
mod merge;
mod mesh;
mod parallel;
mod proxy;
mod reduce;
mod simplify;
pub mod skin;
mod union_find;
mod vertex_removal;

pub use closest::{Nearest, TriangleSet, closest_point_on_triangle};
pub use color_bound::{ErrorMetric, bound_within, direct_bound_within, feature_bound_within};
pub use distance::distance;
pub use hausdorff::{Hausdorff, HausdorffOptions, hausdorff, one_sided_bound};
pub use merge::{Part, merge};
pub use mesh::Mesh;
pub use reduce::{Parts, Reduced, reduce_parts};
pub use simplify::{
    Method, Simplified, SimplifyOptions, Strategy, clustering, edge_collapse,
    edge_collapse_in_parts, edge_collapse_placed, simplify,
};
pub use vertex_removal::{FEATURE_ANGLE_DEGREES, vertex_removal, vertex_removal_with_angle};
