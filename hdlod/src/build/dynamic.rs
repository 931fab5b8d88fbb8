//! Dynamic objects: one cluster per object, its geometry in its own frame
//! and shared by content hash among identical instances, and above it a
//! discrete LOD chain of its model: coarser versions, each with its
//! measured Hausdorff error to the original and the object's own
//! visibility and motion. A dynamic cluster is one object, named by the
//! tree (its chain's leaf), so its shared GLB carries no feature ids (a
//! copy per instance to carry them measured 321 MB on the paper scene,
//! against 634 MB for the rest of its geometry).

use std::collections::HashMap;

use glam::{Mat4, Vec3};
use rayon::prelude::*;

use super::context::{Context, Node, add};
use super::outputs::{LevelStats, Progress, QUANTIZATION_SHARE};
use super::parent::{bake_colour, reduce_within};
use super::skinned;
use super::steps::StepFunction;
use crate::Result;
use crate::geometry::bake::Source;
use crate::geometry::{self, Mesh, Part};
use crate::scene::{Scene, Visibility};
use crate::tree::{Cluster, ClusterClass};

/// One version of a model: its stored geometry and what the tree records.
#[derive(Clone)]
pub(super) struct Version {
    pub hash: String,
    pub triangles: u64,
    pub eps: f64,
    pub bounds: (Vec3, Vec3),
}

/// Builds the chain of one model (finest first): the original, then one
/// version per configured budget (a share of the model's size), each the
/// model reduced within that budget (`parent::reduce_within`: boxes per
/// member of a lattice crane, meshoptimizer on solid parts) and kept only
/// when it has at most `min_reduction` of the triangles of the version
/// below. The cut takes a coarser version once its error is small enough
/// on screen, so the chain is made by error, not by triangle count.
fn chain(ctx: &Context, mesh: &Mesh) -> Result<Vec<Version>> {
    let bounds = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let mut out = vec![Version {
        hash: ctx.sink.put(mesh, None, 0.0)?.hash,
        triangles: mesh.triangle_count() as u64,
        eps: 0.0,
        bounds,
    }];
    let size = f64::from((bounds.1 - bounds.0).length());
    for &share in &ctx.config.dynamic_budgets {
        let previous = out.last().expect("chain starts with the original");
        let budget = share * size;
        if budget <= previous.eps {
            continue;
        }
        let tolerance = (budget * ctx.config.hausdorff_fraction) as f32;
        // Measured against the original model directly: a tighter bound
        // than a recursive sum, and still a bound. Kept monotone.
        let Some((reduced, h)) =
            reduce_within(mesh, budget as f32, tolerance, ctx.config.error_metric)
        else {
            continue;
        };
        if reduced.triangle_count() as f64 > previous.triangles as f64 * ctx.config.min_reduction {
            continue;
        }
        let eps = f64::from(h).max(previous.eps);
        // Baked from the model itself, as the bound is measured.
        let model = Source { mesh, baked: None };
        let baked = bake_colour(ctx, &reduced, eps, &[model], None);
        // Contains the finer versions' boxes, as a parent's box must.
        let (lo, hi) = reduced.bounds().unwrap_or(bounds);
        let stored = ctx
            .sink
            .put(&reduced, baked.as_ref(), eps * QUANTIZATION_SHARE)?;
        out.push(Version {
            hash: stored.hash,
            triangles: reduced.triangle_count() as u64,
            eps: eps + stored.moved,
            bounds: (lo.min(previous.bounds.0), hi.max(previous.bounds.1)),
        });
    }
    Ok(out)
}

/// A chain's model: a scene mesh, a colour (its bits) and, for a skinned
/// object, the object's index.
type Model = (usize, [u32; 4], Option<usize>);

/// Adds the clusters of the dynamic objects; answers the tops of their
/// chains and per-level statistics.
pub(super) fn dynamic_chains(
    scene: &Scene,
    objects: &[(usize, Visibility)],
    ctx: &Context,
    clusters: &mut Vec<Cluster>,
    progress: &dyn Progress,
) -> Result<(Vec<u32>, Vec<LevelStats>)> {
    // A model is a scene mesh with a colour: instances that share both
    // share every version of the chain. A skinned object is a model of
    // its own: its joints pose it.
    let key = |i: usize| {
        let o = &scene.objects[i];
        (
            o.mesh,
            o.color.map(f32::to_bits),
            skinned::is_skinned(o).then_some(i),
        )
    };
    let visibility_of: HashMap<usize, &Visibility> = objects.iter().map(|(i, v)| (*i, v)).collect();
    let mut models: Vec<Model> = objects.iter().map(|&(i, _)| key(i)).collect();
    models.sort_unstable();
    models.dedup();
    let chains: Vec<Result<Vec<Version>>> = models
        .par_iter()
        .map(|&(mesh, color, skinned)| {
            let color = color.map(f32::from_bits);
            if let Some(i) = skinned {
                let o = &scene.objects[i];
                let skin = o.skin.as_ref().expect("a skinned model has a skin");
                let times = skinned::pose_times(skin, visibility_of[&i], scene.time.seconds);
                // Its vertices one for one with the skin's, which a merge
                // (welding equal vertices) would not keep.
                let mut coloured = scene.meshes[mesh].clone();
                if coloured.colors.is_empty() {
                    coloured.colors = vec![color; coloured.positions.len()];
                }
                coloured.features.clear();
                return skinned::chain(ctx, &o.id, &coloured, skin, &times);
            }
            let coloured = geometry::merge(
                &[Part {
                    mesh: &scene.meshes[mesh],
                    transform: Mat4::IDENTITY,
                    color,
                    feature: None,
                }],
                0.0,
            );
            chain(ctx, &coloured)
        })
        .collect();
    let mut by_model: HashMap<Model, Vec<Version>> = HashMap::new();
    for (m, c) in models.into_iter().zip(chains) {
        by_model.insert(m, c?);
    }

    let mut stats: Vec<LevelStats> = Vec::new();
    let mut tops = Vec::with_capacity(objects.len());
    for (i, visibility) in objects {
        let i = *i;
        let o = &scene.objects[i];
        let versions = &by_model[&key(i)];
        let visibility = StepFunction::of_visibility(visibility, ctx.span);
        let mut below: Option<u32> = None;
        for (level, v) in versions.iter().enumerate() {
            let node = Node {
                eps: v.eps,
                children: below.into_iter().collect(),
                motion: if skinned::is_skinned(o) {
                    Some(skinned::world_frame())
                } else {
                    o.motion.clone()
                },
                geometry: Some((v.hash.clone(), v.triangles)),
                objects: if level == 0 {
                    vec![o.id.clone()]
                } else {
                    Vec::new()
                },
                ..Node::new(ClusterClass::Dynamic, level as u32, v.bounds, &visibility)
            };
            let id = add(clusters, node);
            if level > 0 {
                if stats.len() < level {
                    stats.push(LevelStats {
                        level: level as u32,
                        ..LevelStats::default()
                    });
                }
                let s = &mut stats[level - 1];
                s.clusters += 1;
                s.triangles += v.triangles;
                s.children_triangles += versions[level - 1].triangles;
                s.max_eps = s.max_eps.max(v.eps);
            }
            below = Some(id);
        }
        tops.extend(below);
        progress.advance(1);
    }
    Ok((tops, stats))
}
