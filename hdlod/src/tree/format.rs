//! The serde types of the `hdlod-tree/2` files, field for field as
//! docs/method.md section 8 fixes them (`schemas/tree-manifest.schema.json` and
//! `schemas/tree-clusters.schema.json` describe the same shapes), and where
//! a geometry file lies ([`Layout`]). These are the on-disk records only;
//! [`super::Tree`] is the validated in-memory form.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The format the builder writes.
pub const FORMAT: &str = "hdlod-tree/2";
/// The previous format, still read: the same files, its geometry flat.
pub const FORMAT_FLAT: &str = "hdlod-tree/1";
pub const MANIFEST_FILE: &str = "manifest.json";
pub const CLUSTERS_FILE: &str = "clusters.json";
/// The object and task tables, optional (their records are in
/// [`super::objects`]).
pub const OBJECTS_FILE: &str = "objects.json";
pub const GEOMETRY_DIR: &str = "geometry";
/// The number of geometry shards of [`Layout::Sharded`]: one per value of
/// a hash's first byte.
pub const SHARDS: usize = 256;
/// The binary serving index of the clusters, optional (`super::index`).
pub const INDEX_FILE: &str = "clusters.bin";
/// The object rows of `objects.json` in binary, optional
/// (`super::object_index`).
pub const OBJECTS_INDEX_FILE: &str = "objects.bin";
/// The skinned objects' skeletons, optional (`super::skins`).
pub const SKINS_FILE: &str = "skins.json";
/// The objects' source digests, optional (`super::sources`).
pub const SOURCES_FILE: &str = "sources.bin";

/// Where a tree's geometry files lie, fixed by its manifest's `format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// `hdlod-tree/1`: `geometry/{hash}.glb`, one directory.
    Flat,
    /// `hdlod-tree/2`: `geometry/{hh}/{hash}.glb`, `hh` the hash's first two
    /// hex digits. A directory of 120,000 entries makes each new file
    /// costly on ext4; 256 of about 500 do not.
    #[default]
    Sharded,
}

impl Layout {
    /// The layout of a manifest's `format`; `None` for a format not read.
    pub fn of_format(format: &str) -> Option<Layout> {
        match format {
            FORMAT => Some(Layout::Sharded),
            FORMAT_FLAT => Some(Layout::Flat),
            _ => None,
        }
    }

    /// The manifest's `format` of this layout.
    pub fn format(self) -> &'static str {
        match self {
            Layout::Flat => FORMAT_FLAT,
            Layout::Sharded => FORMAT,
        }
    }

    /// The geometry file `hash` of the tree in `dir`: the one place its
    /// path is made.
    pub fn geometry_file(self, dir: &Path, hash: &str) -> PathBuf {
        let geometry = dir.join(GEOMETRY_DIR);
        let name = format!("{hash}.glb");
        match self {
            Layout::Flat => geometry.join(name),
            Layout::Sharded => geometry.join(shard_of(hash)).join(name),
        }
    }
}

/// The shard directory name of `hash`: its first two characters (the
/// whole of a shorter name, which no valid hash is).
pub fn shard_of(hash: &str) -> &str {
    hash.get(..2).unwrap_or(hash)
}

/// The names of the [`SHARDS`] shard directories, `00` to `ff`.
pub fn shard_names() -> impl Iterator<Item = String> {
    (0..SHARDS).map(|i| format!("{i:02x}"))
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestRecord {
    pub format: String,
    pub scene: String,
    pub time: TimeRecord,
    pub bounds: BoundsRecord,
    pub up: crate::scene::Up,
    /// The scene's place on Earth, when it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub georeference: Option<crate::scene::Georeference>,
    pub root: u32,
    /// The build configuration, free-form (the builder owns its shape).
    #[serde(default)]
    pub config: serde_json::Value,
    /// Build statistics, free-form.
    #[serde(default)]
    pub stats: serde_json::Value,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TimeRecord {
    pub start: String,
    pub end: String,
    pub seconds: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoundsRecord {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClustersRecord {
    pub clusters: Vec<ClusterRecord>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClusterClass {
    /// The one virtual root: no geometry, all subtrees hang under it.
    Root,
    Static,
    PseudoDynamic,
    Dynamic,
}

impl ClusterClass {
    pub const ALL: [ClusterClass; 4] = [
        ClusterClass::Root,
        ClusterClass::Static,
        ClusterClass::PseudoDynamic,
        ClusterClass::Dynamic,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ClusterClass::Root => "root",
            ClusterClass::Static => "static",
            ClusterClass::PseudoDynamic => "pseudo_dynamic",
            ClusterClass::Dynamic => "dynamic",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterRecord {
    pub id: u32,
    pub parent: Option<u32>,
    pub children: Vec<u32>,
    pub level: u32,
    pub class: ClusterClass,
    /// In the cluster's own frame (dynamic clusters) or the world frame.
    pub bounds: BoundsRecord,
    pub w: f64,
    pub eps: f64,
    pub gamma: f64,
    /// Steps `[t_i, v_i]`: `v(t) = v_i` for the last `t_i <= t`, 0 before `t_0`.
    pub visibility: Vec<(f64, f64)>,
    pub motion: Option<Vec<KeyframeRecord>>,
    /// The cluster whose keyframes this one shares instead of `motion`:
    /// the top of its LOD chain.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_from: Option<u32>,
    pub geometry: Option<String>,
    pub triangles: u64,
    /// The original objects of a leaf (empty above the leaves).
    #[serde(default)]
    pub objects: Vec<String>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KeyframeRecord {
    pub t: f64,
    pub translation: [f32; 3],
    /// Quaternion `[x, y, z, w]`.
    pub rotation: [f32; 4],
    pub scale: [f32; 3],
}
