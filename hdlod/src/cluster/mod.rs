//! The tree builder (DESIGN.md section 3, the paper's appendix 2): static and
//! pseudo-dynamic objects are clustered bottom-up in Hilbert order level by
//! level; each dynamic object gets its own cluster under a discrete LOD chain
//! of its shared model; all roots hang under one virtual root.

mod build;
mod config;
mod dynamic;
mod hilbert;
mod steps;

use glam::Vec3;

use crate::Result;
use crate::geometry::Mesh;
use crate::scene::Motion;

pub use build::build;
pub use config::{BuildConfig, Thresholds, level_count, thresholds};
pub use hilbert::hilbert_key;
pub use steps::Steps;

/// Where the builder puts cluster geometry; answers the content hash under
/// which the mesh is stored. Called from several threads.
pub trait GeometrySink: Sync {
    fn put(&self, mesh: &Mesh) -> Result<String>;
}

/// Progress of a long build: a phase with a known amount of work, then
/// steps of it. The library prints nothing itself.
pub trait Progress: Sync {
    fn phase(&self, name: &str, total: u64);
    fn advance(&self, n: u64);
}

/// A progress report that goes nowhere.
pub struct Silent;

impl Progress for Silent {
    fn phase(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
}

/// The kind of a cluster in the tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Root,
    Static,
    PseudoDynamic,
    Dynamic,
}

/// One cluster `(g_c, v_c, p_c, b_c, w_c, eps_c, gamma_c)` as built. Its id
/// is its index in [`Built::clusters`].
#[derive(Debug, Clone)]
pub struct Cluster {
    pub parent: Option<u32>,
    pub children: Vec<u32>,
    pub level: u32,
    pub kind: Kind,
    /// Box in the cluster's own frame (world frame unless dynamic).
    pub bounds: (Vec3, Vec3),
    pub w: f64,
    pub eps: f64,
    pub gamma: f64,
    pub visibility: Steps,
    pub motion: Option<Motion>,
    pub geometry: Option<String>,
    pub triangles: u64,
    /// Ids of the scene objects of a leaf.
    pub objects: Vec<String>,
}

/// Per level of one class: clusters made and their triangles, and the
/// triangles of their children (to show the reduction).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LevelStats {
    pub level: u32,
    pub clusters: u64,
    pub triangles: u64,
    pub children_triangles: u64,
    pub max_eps: f64,
    pub max_gamma: f64,
}

#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct BuildStats {
    pub levels: u32,
    pub scene_w: f64,
    /// Objects never visible, left out of the tree.
    pub absent_objects: Vec<String>,
    pub static_levels: Vec<LevelStats>,
    pub pseudo_dynamic_levels: Vec<LevelStats>,
    pub dynamic_levels: Vec<LevelStats>,
    /// Seconds per phase, in the order run.
    pub phases: Vec<(String, f64)>,
}

#[derive(Debug, Clone)]
pub struct Built {
    pub clusters: Vec<Cluster>,
    pub root: u32,
    pub stats: BuildStats,
}
