//! Hierarchical dynamic level of detail (HDLOD) for 4D construction scenes.
//!
//! Data flows one way through the modules:
//! [`scene`] (model, schedule, `hdlod-scene/1` files) -> [`geometry`] (merge,
//! simplify, Hausdorff) -> [`build`] (the tree builder) -> [`tree`] (the
//! `hdlod-tree/2` format and the cut) -> [`tiles`] (time slices as 3D Tiles).
//! [`io`] reads and writes mesh files and `import` (cargo feature `ifc`, on
//! by default) turns BIM models and schedules into scenes. Generated test scenes, the sample tree and the
//! paper's benchmark set-up live in the `hdlod-fixtures` crate, which this
//! one never depends on. See `docs/ARCHITECTURE.md` for the map.

pub mod build;
pub mod debris;
pub mod error;
pub mod geometry;
#[cfg(feature = "ifc")]
pub mod import;
pub mod input;
pub mod io;
pub mod scene;
pub mod tiles;
pub mod time;
pub mod tree;

pub use error::{Error, Result};
