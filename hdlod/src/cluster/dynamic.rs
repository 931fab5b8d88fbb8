//! Dynamic objects: one cluster per object, its geometry in its own frame
//! and shared by content hash among identical instances, and above it a
//! discrete LOD chain of its model: coarser versions, each with its
//! measured Hausdorff error to the original and the object's own
//! visibility and motion.

use std::collections::HashMap;

use glam::{Mat4, Vec3};
use rayon::prelude::*;

use super::build::Context;
use super::steps::Steps;
use super::{LevelStats, Progress};
use crate::Result;
use crate::geometry::{self, HausdorffOptions, Mesh, Part, SimplifyOptions};
use crate::scene::{Scene, Visibility};
use crate::tree::{Aabb, Cluster, ClusterClass};

/// The largest error of a coarser version, as a share of the model's size.
const MAX_LOD_ERROR: f64 = 0.25;

/// One version of a model: its stored geometry and what the tree records.
#[derive(Clone)]
struct Version {
    hash: String,
    triangles: u64,
    eps: f64,
    bounds: (Vec3, Vec3),
}

/// Builds the chain of one model (finest first): the original, then each
/// configured ratio, stopping when a step no longer reduces enough.
fn chain(ctx: &Context, mesh: &Mesh) -> Result<Vec<Version>> {
    let bounds = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let mut out = vec![Version {
        hash: ctx.sink.put(mesh)?,
        triangles: mesh.triangle_count() as u64,
        eps: 0.0,
        bounds,
    }];
    let size = (bounds.1 - bounds.0).length();
    let original = mesh.triangle_count();
    for &ratio in &ctx.config.dynamic_lods {
        let previous = out.last().expect("chain starts with the original");
        let target = (original as f64 * ratio).round() as usize;
        if target == 0 || target as f64 > previous.triangles as f64 * ctx.config.min_reduction {
            continue;
        }
        let s = geometry::simplify(
            mesh,
            &SimplifyOptions {
                max_error: size,
                target_triangles: Some(target),
                prune: true,
            },
        );
        if s.triangles == 0
            || s.triangles as f64 > previous.triangles as f64 * ctx.config.min_reduction
        {
            break;
        }
        // Measured against the original model directly: a tighter bound
        // than the recursive sum, and still a bound. Kept monotone.
        let h = geometry::hausdorff(
            &s.mesh,
            mesh,
            &HausdorffOptions {
                tolerance: (f64::from(size) * ctx.config.k_eps * ctx.config.hausdorff_fraction)
                    as f32,
                seed: 0,
            },
        );
        let eps = f64::from(h.bound).max(previous.eps);
        // A version off by a large part of the model is no level of detail
        // of it: the chain ends there.
        if eps > MAX_LOD_ERROR * f64::from(size) {
            break;
        }
        // Contains the finer versions' boxes, as a parent's box must.
        let (lo, hi) = s.mesh.bounds().unwrap_or(bounds);
        out.push(Version {
            hash: ctx.sink.put(&s.mesh)?,
            triangles: s.triangles as u64,
            eps,
            bounds: (lo.min(previous.bounds.0), hi.max(previous.bounds.1)),
        });
    }
    Ok(out)
}

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
    // share every version of the chain.
    let key = |i: usize| {
        let o = &scene.objects[i];
        (o.mesh, o.color.map(f32::to_bits))
    };
    let mut models: Vec<(usize, [u32; 4])> = objects.iter().map(|&(i, _)| key(i)).collect();
    models.sort_unstable();
    models.dedup();
    let chains: Vec<Result<Vec<Version>>> = models
        .par_iter()
        .map(|&(mesh, color)| {
            let coloured = geometry::merge(
                &[Part {
                    mesh: &scene.meshes[mesh],
                    transform: Mat4::IDENTITY,
                    color: color.map(f32::from_bits),
                }],
                0.0,
            );
            chain(ctx, &coloured)
        })
        .collect();
    let mut by_model: HashMap<(usize, [u32; 4]), Vec<Version>> = HashMap::new();
    for (m, c) in models.into_iter().zip(chains) {
        by_model.insert(m, c?);
    }

    let mut stats: Vec<LevelStats> = Vec::new();
    let mut tops = Vec::with_capacity(objects.len());
    for (i, visibility) in objects {
        let i = *i;
        let o = &scene.objects[i];
        let versions = &by_model[&key(i)];
        let visibility = Steps::of_visibility(visibility, ctx.span).to_tree();
        let mut below: Option<u32> = None;
        for (level, v) in versions.iter().enumerate() {
            let id = clusters.len() as u32;
            if let Some(child) = below {
                clusters[child as usize].parent = Some(id);
            }
            let motion = o.motion.clone();
            let w = f64::from((v.bounds.1 - v.bounds.0).length());
            clusters.push(Cluster {
                id,
                parent: None,
                children: below.into_iter().collect(),
                level: level as u32,
                class: ClusterClass::Dynamic,
                bounds: Aabb::from_f32(v.bounds.0, v.bounds.1),
                w,
                eps: v.eps,
                gamma: 0.0,
                visibility: visibility.clone(),
                motion,
                geometry: Some(v.hash.clone()),
                triangles: v.triangles,
                objects: if level == 0 {
                    vec![o.id.clone()]
                } else {
                    Vec::new()
                },
            });
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
