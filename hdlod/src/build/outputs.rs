//! Where a build's results go besides the tree: its geometry (a sink that
//! stores each mesh and names it by content), its progress, and its
//! statistics. The library prints nothing itself; the caller decides.

use crate::Result;
use crate::geometry::Mesh;
use crate::geometry::bake::Baked;
use crate::io::glb::{Encoding, encoded_mesh_to_glb};
use crate::io::texture::textured;
use crate::tree::TreeWriter;

/// Where the builder puts cluster geometry, with its baked colour if it
/// has one; answers the content hash under which it is stored. Called
/// from several threads.
pub trait GeometrySink: Sync {
    fn put(&self, mesh: &Mesh, baked: Option<&Baked>) -> Result<String>;
}

impl GeometrySink for TreeWriter {
    fn put(&self, mesh: &Mesh, baked: Option<&Baked>) -> Result<String> {
        let glb = match baked {
            Some(b) => {
                let (drawn, texture) = textured(mesh, b);
                encoded_mesh_to_glb(&drawn, Some(&texture), Encoding::Compact)
            }
            None => encoded_mesh_to_glb(mesh, None, Encoding::Compact),
        };
        self.put_geometry(&glb)
    }
}

/// Progress of a long build: a phase with a known amount of work, then
/// steps of it.
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

/// Per level of one class: clusters made and their triangles, and the
/// triangles of their children (to show the reduction).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LevelStats {
    pub level: u32,
    pub clusters: u64,
    pub triangles: u64,
    pub children_triangles: u64,
    pub max_eps: f64,
    pub max_gamma: f64,
}

#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct BuildStats {
    /// The scene's [`super::geometry_key`]: a later build of a scene with
    /// the same key may update this tree instead of rebuilding it. Empty
    /// in trees written before it was recorded.
    #[serde(default)]
    pub geometry_key: String,
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
