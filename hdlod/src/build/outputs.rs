//! Where a build's results go besides the tree: its geometry (a sink that
//! stores each mesh and names it by content), its progress, and its
//! statistics. The library prints nothing itself; the caller decides.

use crate::Result;
use crate::geometry::Mesh;
use crate::geometry::bake::Baked;
use crate::io::glb::{compact_mesh_to_glb, skinned_mesh_to_glb};
use crate::io::texture::textured;
use crate::scene::ObjectSkin;
use crate::tree::TreeWriter;

/// The share of a cluster's `eps` its stored positions may move by when
/// they are quantized (`io::compact`): small enough that the cut hardly
/// changes, large enough that most coarse clusters take 16-bit positions.
/// The move is measured and added to `eps`, which stays a bound.
pub const QUANTIZATION_SHARE: f64 = 1.0 / 32.0;

/// A cluster's geometry as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct Stored {
    /// The content hash it is stored under.
    pub hash: String,
    /// How far a stored position lies from the mesh's at most, 0 when
    /// they are exact: what the cluster's `eps` adds.
    pub moved: f64,
}

/// Where the builder puts cluster geometry, with its baked colour if it
/// has one, its positions allowed to move by up to `allowance`. Called
/// from several threads.
pub trait GeometrySink: Sync {
    fn put(&self, mesh: &Mesh, baked: Option<&Baked>, allowance: f64) -> Result<Stored>;
    /// Stores a skinned `mesh` in its bind pose with its joints and
    /// weights and `skin`'s joints (`skin.vertices` one per vertex of
    /// `mesh`), its positions exact; answers its hash. `name` names the
    /// joints' animation.
    fn put_skinned(&self, mesh: &Mesh, skin: &ObjectSkin, name: &str) -> Result<String>;
}

impl GeometrySink for TreeWriter {
    fn put(&self, mesh: &Mesh, baked: Option<&Baked>, allowance: f64) -> Result<Stored> {
        let (glb, moved) = match baked {
            Some(b) => {
                let (drawn, texture) = textured(mesh, b);
                compact_mesh_to_glb(&drawn, Some(&texture), allowance as f32)
            }
            None => compact_mesh_to_glb(mesh, None, allowance as f32),
        };
        Ok(Stored {
            hash: self.put_geometry(&glb)?,
            moved: f64::from(moved),
        })
    }

    fn put_skinned(&self, mesh: &Mesh, skin: &ObjectSkin, name: &str) -> Result<String> {
        self.put_geometry(&skinned_mesh_to_glb(mesh, skin, name))
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
