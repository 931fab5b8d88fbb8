//! The tree at time `t` as one 3D Tiles 1.1 tile hierarchy (OGC 3D Tiles
//! 1.1, sections "Tiles", "Bounding volumes", "Geometric error",
//! "Refinement" and "Coordinate reference systems"; the cut of
//! `tree::cut`, docs/method.md section 4).
//!
//! Per cluster `c` with `v = v_c(t)`:
//! - `v == 0`: the tile and its subtree are left out (the cut skips them);
//! - content (the cluster's GLB) only where `v >= 0.5`, otherwise a tile
//!   without content: the cut draws nothing there either. A skinned
//!   cluster's content is its mesh posed at `t` (`tiles::content::cluster`),
//!   under `Options::posed_dir`: a URI of its own at each time, since 3D
//!   Tiles clients draw content as it is and would show the bind pose;
//! - the bounding volume is the box the cut tests, `Aabb::transformed` of
//!   the cluster's bounds at `t` for dynamic clusters, written in the tile's
//!   own frame, so that a client that applies the tile transforms gets the
//!   cut's box back exactly;
//! - a dynamic cluster's pose at `t` is its tile's `transform` (relative to
//!   its parent tile, as 3D Tiles composes them);
//! - `geometricError` is `delta_c(t)`, raised where needed so that every
//!   tile's error is strictly above each child's. 3D Tiles expects errors
//!   to shrink downwards and clients rely on it (3DTilesRendererJS never
//!   draws a tile whose error is not below its parent's), but `delta_c(t)`
//!   need not: a child near `v = 0.5` can exceed a parent that is almost
//!   wholly present. Raising the parent (not lowering the child) keeps
//!   every tile's error an upper bound: the client only ever refines more
//!   than the cut, never less.
//! - The root has no geometry and the cut always refines it; its error is
//!   `ROOT_ERROR_FACTOR` times the scene's diagonal (and above every child),
//!   which any client refines unless the whole scene is far below a pixel.

use std::collections::BTreeMap;

use glam::{DMat4, DVec3};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::scene::{Georeference, Up};
use crate::time::format_date;
use crate::tree::format::{CLUSTERS_FILE, MANIFEST_FILE};
use crate::tree::{Aabb, Tree};

/// glTF's y-up to 3D Tiles' z-up: +90 degrees about x, `(x, y, z) -> (x, -z, y)`,
/// the rotation 3D Tiles clients apply to glTF content at load time.
pub const Y_UP_TO_Z_UP: DMat4 = DMat4::from_cols_array(&[
    1.0, 0.0, 0.0, 0.0, //
    0.0, 0.0, 1.0, 0.0, //
    0.0, -1.0, 0.0, 0.0, //
    0.0, 0.0, 0.0, 1.0,
]);

/// The root tile's error in units of the scene's diagonal.
pub const ROOT_ERROR_FACTOR: f64 = 1000.0;

/// The least `Options::max_bytes`: below it a file cannot hold the tileset's
/// own fields and a tile with a few children.
pub const MIN_MAX_BYTES: usize = 4096;

/// A few megabytes: the largest JSON file of a time slice by default.
pub const DEFAULT_MAX_BYTES: usize = 4 << 20;

/// Where a time slice's files point to, relative to the directory of the
/// root `tileset.json`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Options {
    /// The directory of the content GLBs, e.g. `geometry` next to the
    /// tileset on disk, `../geometry` on the server. Relative, no trailing `/`.
    pub content_dir: String,
    /// The directory of the external tilesets (`{id}.json`): one path
    /// segment, no `/`.
    pub subtileset_dir: String,
    /// The largest JSON file, in bytes, before subtrees move to external
    /// tilesets. A file may pass it only when one tile and its direct
    /// children alone do.
    pub max_bytes: usize,
    /// How content files are named in `content_dir`.
    pub content: ContentNames,
    /// The directory of content made for the slice's time alone: a skinned
    /// cluster's mesh posed at `t`, `{cluster}.glb`. Relative, no trailing
    /// `/`; the URI must name the time (`posed` beside the tileset by
    /// default, for a directory that holds one slice).
    pub posed_dir: String,
    /// Whether a georeferenced scene is placed on Earth.
    pub frame: Frame,
}

/// The frame a slice's root maps to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Frame {
    /// ECEF for a georeferenced scene (its root transform places it on
    /// the globe, as CesiumJS and cesium-native expect), else the local
    /// frame.
    #[default]
    Earth,
    /// The scene's own frame turned z-up, origin at its origin: for
    /// engines that work in local coordinates (three.js), where ECEF's
    /// millions of metres would cost `f32` precision.
    Local,
}

/// How a slice names its content files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ContentNames {
    /// `{hash}.glb`: the cluster's own geometry, the same at every time.
    #[default]
    Geometry,
    /// `{cluster}.glb`: content made for the slice, with its elements'
    /// state at the slice's time (`tiles::content`).
    Cluster,
}

impl Options {
    pub fn new(content_dir: impl Into<String>, subtileset_dir: impl Into<String>) -> Self {
        Options {
            content_dir: content_dir.into(),
            subtileset_dir: subtileset_dir.into(),
            max_bytes: DEFAULT_MAX_BYTES,
            content: ContentNames::Geometry,
            posed_dir: "posed".into(),
            frame: Frame::Earth,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Tileset {
    pub asset: Asset,
    pub geometric_error: f64,
    pub root: Tile,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extras: Option<serde_json::Value>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Asset {
    /// Always `"1.1"`.
    pub version: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generator: Option<String>,
    /// The slice's date (ISO 8601): tilesets of different dates differ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tileset_version: Option<String>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Refine {
    #[serde(rename = "REPLACE")]
    Replace,
    #[serde(rename = "ADD")]
    Add,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Tile {
    pub bounding_volume: BoundingVolume,
    pub geometric_error: f64,
    /// Set on the root of each file; the other tiles inherit it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine: Option<Refine>,
    /// Column-major 4x4, relative to the parent tile; absent for the identity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transform: Option<[f64; 16]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub content: Option<Content>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub children: Vec<Tile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extras: Option<TileExtras>,
}

/// A 3D Tiles `box`: the centre, then the x, y and z half-axes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoundingVolume {
    #[serde(rename = "box")]
    pub obb: [f64; 12],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Content {
    pub uri: String,
}

/// What the tile is in the tree.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TileExtras {
    pub cluster: u32,
    /// `v_c(t)`.
    pub visibility: f32,
}

/// A time slice split into files: the root `tileset.json` and the external
/// tilesets, each at `{subtileset_dir}/{cluster id}.json`.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeSlice {
    /// Seconds since the scene's start.
    pub time: f64,
    pub root: Tileset,
    pub external: BTreeMap<u32, Tileset>,
}

/// The root tile's `transform` (see the module documentation of `tiles`):
/// the identity for a y-up scene, the inverse of [`Y_UP_TO_Z_UP`] for a
/// z-up one; then, for a scene placed on Earth, its east-north-up frame to
/// ECEF (none for map coordinates without a CRS). A CRS that cannot be
/// projected is an error naming the manifest's field.
pub fn root_transform(up: Up, georeference: Option<&Georeference>) -> Result<DMat4> {
    let local = match up {
        Up::Y => DMat4::IDENTITY,
        Up::Z => Y_UP_TO_Z_UP.inverse(),
    };
    let Some(g) = georeference else {
        return Ok(local);
    };
    let to_ecef = g
        .to_ecef()
        .map_err(|m| Error::invalid(MANIFEST_FILE, "georeference", m))?;
    Ok(to_ecef.map_or(local, |m| m * local))
}

/// `x` raised by a hair: the least error strictly above a child's that
/// survives printing as JSON and reading back as a double.
fn above(x: f64) -> f64 {
    x + (x * 1e-9).max(1e-9)
}

/// The box of `world` seen from a frame whose map from the world is `local`.
fn local_box(world: &Aabb, local: &DMat4) -> BoundingVolume {
    let centre = local.transform_point3((world.min + world.max) / 2.0);
    let half = (world.max - world.min) / 2.0;
    let axis = |k: usize| {
        let mut v = DVec3::ZERO;
        v[k] = half[k];
        local.transform_vector3(v)
    };
    let (x, y, z) = (axis(0), axis(1), axis(2));
    BoundingVolume {
        obb: [
            centre.x, centre.y, centre.z, x.x, x.y, x.z, y.x, y.y, y.z, z.x, z.y, z.z,
        ],
    }
}

struct Slice<'a> {
    tree: &'a Tree,
    t: f64,
    content_dir: &'a str,
    names: ContentNames,
    posed_dir: &'a str,
}

impl Slice<'_> {
    /// The tile of cluster `id` under a parent whose world pose is `parent`,
    /// or `None` when the cluster is absent at `t`.
    fn tile(&self, id: u32, parent: &DMat4) -> Result<Option<Tile>> {
        let c = self.tree.cluster(id);
        let v = c.visibility.at(self.t);
        if v <= 0.0 {
            return Ok(None);
        }
        // The same single-precision pose as the cut, so the boxes agree.
        let (pose, world) = match &c.motion {
            Some(m) => {
                let pose = m.at(self.t).as_dmat4();
                (pose, c.bounds.transformed(&pose))
            }
            None => (DMat4::IDENTITY, c.bounds),
        };
        if pose.determinant().abs() < 1e-12 {
            return Err(Error::invalid(
                CLUSTERS_FILE,
                format!("clusters[{id}].motion"),
                format!("the pose at t = {} s cannot be inverted", self.t),
            ));
        }
        let r = Y_UP_TO_Z_UP;
        let relative = r * parent.inverse() * pose * r.inverse();
        let transform =
            (!relative.abs_diff_eq(DMat4::IDENTITY, 1e-12)).then(|| relative.to_cols_array());
        let mut children = Vec::new();
        for &ch in &c.children {
            if let Some(tile) = self.tile(ch, &pose)? {
                children.push(tile);
            }
        }
        let delta = c.delta(v);
        let error = children
            .iter()
            .map(|ch| above(ch.geometric_error))
            .fold(delta, f64::max);
        let content = match &c.geometry {
            Some(hash) if v >= 0.5 => Some(Content {
                uri: if self.tree.skeleton_of(id).is_some() {
                    format!("{}/{id}.glb", self.posed_dir)
                } else {
                    match self.names {
                        ContentNames::Geometry => format!("{}/{hash}.glb", self.content_dir),
                        ContentNames::Cluster => format!("{}/{id}.glb", self.content_dir),
                    }
                },
            }),
            _ => None,
        };
        Ok(Some(Tile {
            bounding_volume: local_box(&world, &(r * pose.inverse())),
            geometric_error: error,
            refine: None,
            transform,
            content,
            children,
            extras: Some(TileExtras {
                cluster: id,
                visibility: v,
            }),
        }))
    }
}

/// The whole tree at `t` (seconds since the scene's start) as one tileset,
/// content URIs under `options.content_dir` (relative to the tileset's
/// directory); `max_bytes` and `subtileset_dir` are [`time_slice`]'s.
pub fn tileset(tree: &Tree, t: f64, options: &Options) -> Result<Tileset> {
    if !t.is_finite() {
        return Err(Error::argument(
            "time",
            "must be a finite number of seconds",
        ));
    }
    let slice = Slice {
        tree,
        t,
        content_dir: options.content_dir.trim_end_matches('/'),
        names: options.content,
        posed_dir: options.posed_dir.trim_end_matches('/'),
    };
    let root = tree.root();
    let v = root.visibility.at(t);
    let mut tile = match slice.tile(tree.root, &DMat4::IDENTITY)? {
        Some(tile) => tile,
        // Nothing is present at `t`: a tileset still needs its root.
        None => Tile {
            bounding_volume: local_box(&root.bounds, &Y_UP_TO_Z_UP),
            geometric_error: 0.0,
            refine: None,
            transform: None,
            content: None,
            children: Vec::new(),
            extras: Some(TileExtras {
                cluster: tree.root,
                visibility: v,
            }),
        },
    };
    if !tile.children.is_empty() {
        tile.geometric_error = tile
            .geometric_error
            .max(ROOT_ERROR_FACTOR * tree.bounds.diagonal());
    }
    let georeference = match options.frame {
        Frame::Earth => tree.georeference.as_ref(),
        Frame::Local => None,
    };
    let root = root_transform(tree.up, georeference)?;
    tile.transform = (root != DMat4::IDENTITY).then(|| root.to_cols_array());
    tile.refine = Some(Refine::Replace);
    Ok(Tileset {
        asset: asset(),
        geometric_error: tile.geometric_error,
        root: tile,
        extras: Some(serde_json::json!({
            "scene": tree.scene,
            "time": t,
            "date": format_date(tree.time.date_at(t)),
            "up": tree.up,
        })),
    })
}

/// No `tilesetVersion`: CesiumJS appends it to every content URL, which
/// would give a GLB shared by every date another URL on each.
pub(super) fn asset() -> Asset {
    Asset {
        version: "1.1".into(),
        generator: Some(format!("hdlod {}", env!("CARGO_PKG_VERSION"))),
        tileset_version: None,
    }
}

/// The tree at `t` as a root tileset and external tilesets (see [`Options`]).
pub fn time_slice(tree: &Tree, t: f64, options: &Options) -> Result<TimeSlice> {
    let dir = options.subtileset_dir.as_str();
    if dir.is_empty() || dir == "." || dir == ".." || dir.contains(['/', '\\']) {
        return Err(Error::argument(
            "subtileset_dir",
            "must be one relative path segment",
        ));
    }
    if options.max_bytes < MIN_MAX_BYTES {
        return Err(Error::argument(
            "max_bytes",
            format!("must be at least {MIN_MAX_BYTES} (room for a tile and its children's stubs)"),
        ));
    }
    let mut root = tileset(tree, t, options)?;
    let external = super::split::split(&mut root, options, &asset());
    Ok(TimeSlice {
        time: t,
        root,
        external,
    })
}
