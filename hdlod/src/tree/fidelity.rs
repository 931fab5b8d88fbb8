//! Feature fidelity: how far the triangles a cluster gives an object (its
//! feature id) lie from that object's own geometry, beside the cluster's
//! stored error `eps_c`. A viewer that picks or hides an object inside a
//! coarse cluster acts on those triangles, so they should stand for that
//! object and no other: within `eps_c` of it, as the whole cluster is
//! within `eps_c` of all its objects. A dynamic cluster's GLB has no
//! feature ids: it is all one object, its chain's.

use std::collections::HashMap;
use std::path::Path;

use glam::Mat4;

use super::Tree;
use crate::error::{Error, Result};
use crate::geometry::{Mesh, Part, TriangleSet, merge, one_sided_bound};
use crate::io::gltf::read_mesh;
use crate::scene::Scene;
use crate::tree::ClusterClass;

/// One object's triangles in one cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureDistance {
    pub cluster: u32,
    /// The object's index in the scene.
    pub feature: u32,
    pub triangles: usize,
    /// A bound (within `tolerance`) of the farthest any of those triangles
    /// lies from the object's own geometry.
    pub distance: f64,
    /// The cluster's `eps_c`.
    pub eps: f64,
}

/// The distances of every feature in `clusters` of the tree written at
/// `dir`, built from `scene`. Dynamic clusters are in their object's frame
/// and are measured there; the others against the object wherever it
/// stands still (its transform, or its motion's first and last pose).
pub fn feature_distances(
    dir: &Path,
    tree: &Tree,
    scene: &Scene,
    clusters: &[u32],
    tolerance: f32,
) -> Result<Vec<FeatureDistance>> {
    let mut references: HashMap<(u32, bool), TriangleSet> = HashMap::new();
    let mut out = Vec::new();
    for &id in clusters {
        let cluster = tree.get_cluster(id).ok_or_else(|| {
            Error::argument("clusters", format!("cluster {id} is not in the tree"))
        })?;
        let Some(hash) = &cluster.geometry else {
            continue;
        };
        let file = tree.geometry_file(dir, hash);
        let mut mesh = read_mesh(&file)?;
        let own_frame = cluster.class == ClusterClass::Dynamic;
        if mesh.features.is_empty() {
            // A dynamic cluster is one object, which the tree names.
            let object = tree
                .dynamic_object_id(id)
                .and_then(|object| scene.objects.iter().position(|o| o.id == object))
                .ok_or_else(|| {
                    Error::invalid(
                        &file,
                        "_FEATURE_ID_0",
                        "the cluster's geometry has no feature ids",
                    )
                })?;
            mesh.features = vec![object as u32; mesh.positions.len()];
        }
        for (feature, part) in by_feature(&mesh) {
            let object = scene.objects.get(feature as usize).ok_or_else(|| {
                Error::invalid(
                    &file,
                    "_FEATURE_ID_0",
                    format!(
                        "feature {feature} is not an object of the scene ({} objects)",
                        scene.objects.len()
                    ),
                )
            })?;
            let reference = references.entry((feature, own_frame)).or_insert_with(|| {
                let poses: Vec<Mat4> = if own_frame {
                    vec![Mat4::IDENTITY]
                } else {
                    match &object.motion {
                        Some(m) => {
                            let keys = m.keyframes();
                            vec![keys[0].matrix(), keys[keys.len() - 1].matrix()]
                        }
                        None => vec![object.transform],
                    }
                };
                let parts: Vec<Part> = poses
                    .iter()
                    .map(|&transform| Part {
                        mesh: &scene.meshes[object.mesh],
                        transform,
                        color: object.color,
                        feature: None,
                    })
                    .collect();
                TriangleSet::new(merge(&parts, 0.0).triangles())
            });
            out.push(FeatureDistance {
                cluster: id,
                feature,
                triangles: part.triangle_count(),
                distance: f64::from(one_sided_bound(&part, reference, tolerance)),
                eps: cluster.eps,
            });
        }
    }
    Ok(out)
}

/// The triangles of each feature of `mesh`, by feature.
fn by_feature(mesh: &Mesh) -> Vec<(u32, Mesh)> {
    let mut parts: HashMap<u32, Mesh> = HashMap::new();
    for t in mesh.indices.chunks_exact(3) {
        let part = parts.entry(mesh.features[t[0] as usize]).or_default();
        for &i in t {
            part.indices.push(part.positions.len() as u32);
            part.positions.push(mesh.positions[i as usize]);
        }
    }
    let mut parts: Vec<(u32, Mesh)> = parts.into_iter().collect();
    parts.sort_unstable_by_key(|(f, _)| *f);
    parts
}
