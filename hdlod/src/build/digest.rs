//! The digests an update decides by: the scene's geometry key (the build
//! configuration, the meshes, the objects in order) and each object's
//! source digest (`tree::sources`); and a mesh's content digest, which
//! also tells the build's repeated shapes apart (`instances`).
//!
//! Both are blake3 over a byte stream that trees already written fix: each
//! value in order, little-endian. The stream is fed in bulk (a mesh's
//! positions as one slice, the objects' bytes made on every core and then
//! hashed in order); blake3 hashes the bytes, not the calls, so the
//! digests are those of one value at a time.

use rayon::prelude::*;

use super::config::BuildConfig;
use crate::geometry::Mesh;
use crate::scene::{Motion, Object, Scene};
use crate::tree::sources::Digest;

/// A digest of everything in `scene` and `config` that the tree's groups
/// and geometry depend on, except the schedule: meshes, objects in order
/// (ids, meshes, placements, colours, motions) and the build
/// configuration. Two scenes with the same key differ at most in their
/// tasks, their objects' visibility and properties.
pub fn geometry_key(scene: &Scene, config: &BuildConfig) -> String {
    MeshesKey::of(scene, config).key(scene)
}

/// The [`geometry_key`] hashed up to the scene's objects: its configuration
/// and meshes. The scene as aligned to a tree's objects has the same
/// meshes, and its key then costs the objects alone.
#[derive(Clone)]
pub(super) struct MeshesKey(blake3::Hasher);

impl MeshesKey {
    pub(super) fn of(scene: &Scene, config: &BuildConfig) -> MeshesKey {
        let mut hash = blake3::Hasher::new();
        let config = serde_json::to_string(config).expect("the config serialises");
        hash.feed(config.as_bytes());
        hash.feed(&(scene.meshes.len() as u64).to_le_bytes());
        for mesh in &scene.meshes {
            hash_mesh(&mut hash, mesh);
        }
        MeshesKey(hash)
    }

    /// The key of `scene`, whose meshes are those this was made of.
    pub(super) fn key(&self, scene: &Scene) -> String {
        let mut hash = self.0.clone();
        hash.feed(&(scene.objects.len() as u64).to_le_bytes());
        let runs: Vec<Vec<u8>> = (scene.objects.par_chunks(256))
            .map(|run| {
                let mut bytes = Vec::new();
                run.iter().for_each(|o| hash_object(&mut bytes, o));
                bytes
            })
            .collect();
        for bytes in &runs {
            hash.feed(bytes);
        }
        hash.feed(&[scene.up as u8]);
        hash.finalize().to_hex().to_string()
    }
}

/// Per object of `scene`, in order, a digest of what its leaves are made
/// of: its id, its mesh's content, its placement, colour and motion
/// (`tree::sources`). A geometry update compares them with the tree's.
pub fn object_sources(scene: &Scene) -> Vec<Digest> {
    let meshes: Vec<blake3::Hash> = scene.meshes.par_iter().map(mesh_digest).collect();
    scene
        .objects
        .par_iter()
        .map_init(Vec::new, |bytes, o| {
            bytes.clear();
            bytes.extend_from_slice(meshes[o.mesh].as_bytes());
            hash_object(bytes, o);
            let mut digest = [0u8; 16];
            digest.copy_from_slice(&blake3::hash(bytes).as_bytes()[..16]);
            digest
        })
        .collect()
}

/// A digest of `mesh`'s content, every array with its length: meshes
/// with the same digest are the same.
pub(super) fn mesh_digest(mesh: &Mesh) -> blake3::Hash {
    let mut hash = blake3::Hasher::new();
    hash_mesh(&mut hash, mesh);
    hash.finalize()
}

/// Where a digest's bytes go: a hasher, or bytes hashed later.
trait Feed {
    fn feed(&mut self, bytes: &[u8]);

    /// A float's bytes are those of its bits as a word.
    fn floats(&mut self, values: &[f32]) {
        self.words(bytemuck::cast_slice(values));
    }

    fn words(&mut self, values: &[u32]) {
        if cfg!(target_endian = "little") {
            self.feed(bytemuck::cast_slice(values));
        } else {
            values.iter().for_each(|v| self.feed(&v.to_le_bytes()));
        }
    }
}

impl Feed for blake3::Hasher {
    fn feed(&mut self, bytes: &[u8]) {
        // blake3's own threshold for hashing on every core paying off.
        if bytes.len() >= 128 * 1024 {
            self.update_rayon(bytes);
        } else {
            self.update(bytes);
        }
    }
}

impl Feed for Vec<u8> {
    fn feed(&mut self, bytes: &[u8]) {
        self.extend_from_slice(bytes);
    }
}

fn hash_mesh(hash: &mut impl Feed, mesh: &Mesh) {
    for (name, len) in [
        ("positions", mesh.positions.len()),
        ("normals", mesh.normals.len()),
        ("colors", mesh.colors.len()),
        ("features", mesh.features.len()),
        ("indices", mesh.indices.len()),
    ] {
        hash.feed(name.as_bytes());
        hash.feed(&(len as u64).to_le_bytes());
    }
    hash.floats(bytemuck::cast_slice(&mesh.positions));
    hash.floats(bytemuck::cast_slice(&mesh.normals));
    hash.floats(bytemuck::cast_slice(&mesh.colors));
    hash.words(&mesh.features);
    hash.words(&mesh.indices);
}

fn hash_object(hash: &mut impl Feed, o: &Object) {
    hash.feed(&(o.id.len() as u64).to_le_bytes());
    hash.feed(o.id.as_bytes());
    hash.feed(&(o.mesh as u64).to_le_bytes());
    hash.floats(&o.transform.to_cols_array());
    hash.floats(&o.color);
    fn keys(hash: &mut impl Feed, m: &Option<Motion>) {
        match m {
            None => hash.feed(&[0]),
            Some(m) => {
                hash.feed(&(m.keyframes().len() as u64).to_le_bytes());
                for k in m.keyframes() {
                    hash.feed(&k.t.to_le_bytes());
                    hash.floats(&k.matrix().to_cols_array());
                }
            }
        }
    }
    keys(hash, &o.motion);
    // Only a skinned object's digest grows: the others' stay those of
    // trees built before skins were kept.
    if let Some(skin) = &o.skin {
        hash.feed(b"skin");
        for (j, w) in skin.vertices.joints.iter().zip(&skin.vertices.weights) {
            hash.feed(bytemuck::cast_slice(j));
            hash.floats(w);
        }
        for (inverse, joint) in skin.inverse_bind.iter().zip(&skin.joints) {
            hash.floats(&inverse.to_cols_array());
            hash.floats(&joint.transform.to_cols_array());
            keys(hash, &joint.motion);
        }
    }
}
