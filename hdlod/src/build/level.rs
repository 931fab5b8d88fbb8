//! One level of the static or the pseudo-dynamic tree: the active
//! clusters grouped along the Hilbert order within the level's thresholds
//! `w(l)` and `gamma(l)` (nearest in time first for the pseudo-dynamic
//! class), each group given a parent, and lone clusters a parent of their
//! own where that pays (docs/method.md section 3).
//!
//! Reference: Semenov et al., "Visualization of large scenes with
//! deterministic dynamics", Programming and Computer Software 46(3), 2020,
//! appendix 2.

use std::sync::Arc;

use glam::Vec3;
use obvhs::aabb::Aabb as BvhBox;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};
use rayon::prelude::*;

use super::config::{Thresholds, thresholds};
use super::context::{Active, Context, Node, add, bounds_of};
use super::hilbert::hilbert_key;
use super::instances::single_parents;
use super::outputs::{LevelStats, Progress, QUANTIZATION_SHARE, Stored};
use super::parent::{Parent, Single, make_parent};
use super::steps::StepFunction;
use crate::Result;
use crate::tree::{Cluster, ClusterClass};

/// Clusters one class level by level; answers the ids of the clusters left
/// at the top and the statistics per level.
#[allow(clippy::too_many_arguments)]
pub(super) fn cluster_class(
    ctx: &Context,
    clusters: &mut Vec<Cluster>,
    kind: ClusterClass,
    mut active: Vec<Active>,
    (scene_lo, scene_hi): (Vec3, Vec3),
    scene_w: f64,
    levels: u32,
    progress: &dyn Progress,
) -> Result<(Vec<u32>, Vec<LevelStats>)> {
    let mut level_stats = Vec::new();
    for level in 1..=levels {
        if active.len() < 2 {
            break;
        }
        let th = thresholds(ctx.config, scene_w, levels, level);
        let groups = group(ctx, &active, &th, (scene_lo, scene_hi), kind);
        let name = format!(
            "{} level {level}/{levels}",
            match kind {
                ClusterClass::Static => "static",
                _ => "pseudo-dynamic",
            }
        );
        progress.phase(&name, groups.len() as u64);
        let clock = std::time::Instant::now();
        let parents: Vec<Result<Parent>> = groups
            .par_iter()
            .map(|g| {
                let made = make_parent(ctx, &active, g, &th);
                progress.advance(1);
                made
            })
            .collect();

        let mut stats = LevelStats {
            level,
            ..LevelStats::default()
        };
        let mut taken = vec![false; active.len()];
        let mut next: Vec<Active> = Vec::with_capacity(active.len());
        let mut made: Vec<Active> = Vec::with_capacity(groups.len());
        for (g, parent) in groups.iter().zip(parents) {
            let Parent {
                mesh,
                eps,
                hash,
                baked,
                originals,
            } = parent?;
            let children: Vec<&Active> = g.iter().map(|&i| &active[i]).collect();
            let (steps, vis, gamma) = temporal(ctx, &children);
            let (lo, hi) = bounds_of(children.iter().copied());
            for c in &children {
                stats.children_triangles += clusters[c.id as usize].triangles;
            }
            stats.clusters += 1;
            stats.triangles += mesh.triangle_count() as u64;
            stats.max_eps = stats.max_eps.max(eps);
            stats.max_gamma = stats.max_gamma.max(gamma);
            let node = Node {
                eps,
                gamma,
                children: children.iter().map(|c| c.id).collect(),
                geometry: Some((hash, mesh.triangle_count() as u64)),
                ..Node::new(kind, level, (lo, hi), &steps)
            };
            let w = node.w;
            let id = add(clusters, node);
            for &i in g {
                taken[i] = true;
            }
            made.push(Active {
                id,
                lo,
                hi,
                w,
                eps,
                steps,
                vis,
                originals,
                mesh: Arc::new(mesh),
                baked: baked.map(Arc::new),
                instance: None,
                parts: Default::default(),
            });
        }
        let grouped = clock.elapsed();
        let alone: Vec<usize> = (0..active.len()).filter(|&i| !taken[i]).collect();
        // Stored on every core: a level may give tens of thousands of lone
        // clusters a parent, each a GLB to encode and write.
        let singles: Vec<Option<(Single, Stored)>> = single_parents(ctx, &active, &alone, &th)
            .into_par_iter()
            .map(|single| match single {
                Some(s) => {
                    let allowance = s.eps * QUANTIZATION_SHARE;
                    let stored = ctx.sink.put(&s.mesh, s.baked.as_ref(), allowance)?;
                    Ok(Some((s, stored)))
                }
                None => Ok(None),
            })
            .collect::<Result<_>>()?;
        tracing::debug!(
            "{name}: {} groups in {:.2} s, {} lone clusters of which {} reduced in {:.2} s",
            groups.len(),
            grouped.as_secs_f64(),
            alone.len(),
            singles.iter().filter(|s| s.is_some()).count(),
            (clock.elapsed() - grouped).as_secs_f64()
        );
        let mut singles = alone.into_iter().zip(singles).peekable();
        for (i, (a, t)) in active.into_iter().zip(taken).enumerate() {
            if t {
                continue;
            }
            let single = singles.next_if(|(j, _)| *j == i).and_then(|(_, s)| s);
            let Some((Single { mesh, eps, baked }, stored)) = single else {
                next.push(a);
                continue;
            };
            // The stored positions lie up to `moved` from the mesh's.
            let eps = eps + stored.moved;
            let child = &clusters[a.id as usize];
            let gamma = child.gamma;
            stats.children_triangles += child.triangles;
            stats.clusters += 1;
            stats.triangles += mesh.triangle_count() as u64;
            stats.max_eps = stats.max_eps.max(eps);
            stats.max_gamma = stats.max_gamma.max(gamma);
            let (lo, hi) = mesh
                .bounds()
                .map_or((a.lo, a.hi), |(lo, hi)| (lo.min(a.lo), hi.max(a.hi)));
            let node = Node {
                eps,
                gamma,
                children: vec![a.id],
                geometry: Some((stored.hash, mesh.triangle_count() as u64)),
                ..Node::new(kind, level, (lo, hi), &a.steps)
            };
            let w = node.w;
            let id = add(clusters, node);
            next.push(Active {
                id,
                lo,
                hi,
                w,
                eps,
                mesh: Arc::new(mesh),
                baked: baked.map(Arc::new),
                instance: None,
                parts: Default::default(),
                ..a
            });
        }
        next.extend(made);
        active = next;
        if stats.clusters > 0 {
            level_stats.push(stats);
        }
    }
    Ok((active.iter().map(|a| a.id).collect(), level_stats))
}

/// The fractional visibility of a would-be parent (simplified to K steps),
/// its distinct leaf visibilities, and its temporal error
/// `gamma = max_s (1/T) integral |v_c - v_s|`.
fn temporal(ctx: &Context, children: &[&Active]) -> (StepFunction, Vec<u32>, f64) {
    let parts: Vec<(f64, &StepFunction)> =
        children.iter().map(|c| (c.w.max(1e-9), &c.steps)).collect();
    let steps = StepFunction::weighted_mean(&parts).simplified(ctx.config.max_steps, ctx.span);
    let mut vis: Vec<u32> = children
        .iter()
        .flat_map(|c| c.vis.iter().copied())
        .collect();
    vis.sort_unstable();
    vis.dedup();
    let gamma = if ctx.span > 0.0 {
        vis.iter()
            .map(|&v| steps.l1_distance(&ctx.leaf_steps[v as usize], ctx.span) / ctx.span)
            .fold(0.0, f64::max)
    } else {
        0.0
    };
    (steps, vis, gamma)
}

/// Candidates are ranked by their temporal distance to the representative
/// in this many classes of `gamma(l)`, then by spatial distance.
const TIME_CLASSES: f64 = 4.0;

/// Picks the groups of one level: representatives in Hilbert order of
/// their centres, neighbours from a BVH over the active boxes, nearest in
/// time then in space first, while the merged box fits `w(l)` and the
/// temporal error fits `gamma(l)`.
fn group(
    ctx: &Context,
    active: &[Active],
    th: &Thresholds,
    (scene_lo, scene_hi): (Vec3, Vec3),
    kind: ClusterClass,
) -> Vec<Vec<usize>> {
    let aabbs: Vec<BvhBox> = active
        .iter()
        .map(|a| BvhBox::new(a.lo.into(), a.hi.into()))
        .collect();
    let bvh = PlocBuilder::new().build(
        PlocSearchDistance::Minimum,
        &aabbs,
        (0..active.len() as u32).collect(),
        SortPrecision::U64,
        1,
    );
    let mut order: Vec<(u64, usize)> = active
        .iter()
        .enumerate()
        .map(|(i, a)| (hilbert_key((a.lo + a.hi) * 0.5, scene_lo, scene_hi), i))
        .collect();
    order.sort_unstable();

    let w_max = th.w as f32;
    let diag = |lo: Vec3, hi: Vec3| (hi - lo).length();
    let mut taken = vec![false; active.len()];
    let mut groups = Vec::new();
    let mut candidates: Vec<(u32, f32, usize)> = Vec::new();
    let time_step = th.gamma.max(1e-9) / TIME_CLASSES;
    for &(_, i) in &order {
        if taken[i] {
            continue;
        }
        let rep = &active[i];
        if diag(rep.lo, rep.hi) > w_max {
            continue;
        }
        let centre = (rep.lo + rep.hi) * 0.5;
        let query = BvhBox::new((rep.lo - w_max).into(), (rep.hi + w_max).into());
        candidates.clear();
        bvh.aabb_traverse(query, |bvh, node| {
            let node = &bvh.nodes[node as usize];
            let first = node.first_index as usize;
            for &j in &bvh.primitive_indices[first..first + node.prim_count as usize] {
                let j = j as usize;
                let c = &active[j];
                if j != i && !taken[j] && diag(rep.lo.min(c.lo), rep.hi.max(c.hi)) <= w_max {
                    // Alike in time first: a parent whose children appear
                    // together is wholly present or absent at most times,
                    // and then the cut can draw it (`delta_c = eps_c`).
                    let apart = if kind == ClusterClass::PseudoDynamic && ctx.span > 0.0 {
                        (rep.steps.l1_distance(&c.steps, ctx.span) / ctx.span / time_step).floor()
                            as u32
                    } else {
                        0
                    };
                    candidates.push((apart, centre.distance_squared((c.lo + c.hi) * 0.5), j));
                }
            }
            true
        });
        candidates
            .sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut members = vec![i];
        let (mut lo, mut hi) = (rep.lo, rep.hi);
        for &(_, _, j) in candidates.iter() {
            if members.len() >= ctx.config.max_children {
                break;
            }
            let c = &active[j];
            let (nlo, nhi) = (lo.min(c.lo), hi.max(c.hi));
            if diag(nlo, nhi) > w_max {
                continue;
            }
            if kind == ClusterClass::PseudoDynamic {
                let mut trial: Vec<&Active> = members.iter().map(|&m| &active[m]).collect();
                trial.push(c);
                if temporal(ctx, &trial).2 > th.gamma {
                    continue;
                }
            }
            members.push(j);
            lo = nlo;
            hi = nhi;
        }
        if members.len() > 1 {
            for &m in &members {
                taken[m] = true;
            }
            groups.push(members);
        }
    }
    groups
}
