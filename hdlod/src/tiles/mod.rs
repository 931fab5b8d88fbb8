//! Time slices of the HDLOD tree as 3D Tiles 1.1 tilesets (OGC 3D Tiles 1.1,
//! <https://docs.ogc.org/cs/22-025r4/22-025r4.html>; docs/method.md section 4).
//!
//! The cut's rule `delta_c(t) / distance < r` is the screen-space-error rule
//! of 3D Tiles, so the tree at a time `t` is a tileset with
//! `refine: REPLACE` and `geometricError = delta_c(t)`: [`tileset`] builds it
//! as plain data (serde structs), [`time_slice`] splits it into external
//! tilesets so that no JSON file passes [`Options::max_bytes`]. There is no
//! HTTP here: the server and `hdlod export-tiles` write these structs.
//!
//! Frames. glTF content is y-up and 3D Tiles is z-up; a 3D Tiles client
//! turns glTF content by `Y_UP_TO_Z_UP` (+90 degrees about x) when it loads
//! it. Every box and transform inside the tileset is therefore written in
//! the scene's frame turned the same way, and the root's `transform` maps
//! that to the z-up world: the identity for a y-up scene (the usual case:
//! the tileset's z is the scene's y), `Y_UP_TO_Z_UP^-1` for a scene that is
//! already z-up (whose GLB content holds z-up coordinates).

pub mod content;
mod split;
pub mod tileset;

pub use tileset::{
    Asset, BoundingVolume, Content, ContentNames, DEFAULT_MAX_BYTES, Frame, MIN_MAX_BYTES, Options,
    ROOT_ERROR_FACTOR, Refine, Tile, TileExtras, Tileset, TimeSlice, Y_UP_TO_Z_UP, root_transform,
    tileset, time_slice,
};
