//! Bottom-up clustering of the static and the pseudo-dynamic objects, and
//! the assembly of the whole tree under its virtual root.
//!
//! Reference: Semenov et al., "Visualization of large scenes with
//! deterministic dynamics", Programming and Computer Software 46(3), 2020,
//! appendix 2; the thresholds and errors are those of DESIGN.md.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use glam::{DVec3, Mat4, Vec3};
use obvhs::aabb::Aabb as BvhBox;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};
use rayon::prelude::*;

use super::config::{BuildConfig, Thresholds, level_count, thresholds};
use super::dynamic::dynamic_chains;
use super::hilbert::hilbert_key;
use super::steps::Steps;
use super::{BuildStats, GeometrySink, LevelStats, Progress};
use crate::geometry::{self, Mesh, Part, SimplifyOptions, Strategy};
use crate::scene::{Class, Scene, Visibility, VisibilityType};
use crate::tree::{Aabb, Cluster, ClusterClass, Tree, TreeWriter};
use crate::{Error, Result};

/// A cluster while its level is being built: what the next level needs.
struct Active {
    id: u32,
    lo: Vec3,
    hi: Vec3,
    w: f64,
    eps: f64,
    steps: Steps,
    /// Ids of the distinct leaf visibility functions below (sorted): the
    /// temporal error is a maximum over these, and objects of one task
    /// share one, so this stays short.
    vis: Vec<u32>,
    /// Dropped once the cluster has a parent: memory stays bounded by one
    /// level's geometry (and the originals below kept for `direct_eps`).
    mesh: Arc<Mesh>,
    /// The original objects' geometry below, while it has at most
    /// `DIRECT_MAX_TRIANGLES` triangles: see `direct_eps`.
    originals: Option<Vec<Arc<Mesh>>>,
}

pub(super) struct Context<'a> {
    pub config: &'a BuildConfig,
    pub span: f64,
    /// Distinct 0/1 visibility functions of the leaves.
    pub leaf_steps: Vec<Steps>,
    pub sink: &'a dyn GeometrySink,
}

/// Builds the HDLOD tree of `scene`. Geometry goes to `sink` as it is made.
pub fn build(
    scene: &Scene,
    config: &BuildConfig,
    sink: &dyn GeometrySink,
    progress: &dyn Progress,
) -> Result<(Tree, BuildStats)> {
    config
        .validate()
        .map_err(|(field, message)| Error::argument(format!("config.{field}"), message))?;
    let mut scene_owned;
    let scene = match config.schedule {
        Some(options) if options != scene.schedule_options => {
            scene_owned = scene.clone();
            scene_owned.schedule_options = options;
            scene_owned.apply_schedule();
            &scene_owned
        }
        _ => scene,
    };
    let span = scene.time.seconds;
    let mut stats = BuildStats::default();
    let mut clusters: Vec<Cluster> = Vec::new();
    let mut ctx = Context {
        config,
        span,
        leaf_steps: Vec::new(),
        sink,
    };

    let classes: Vec<Class> = scene.objects.iter().map(|o| scene.class_of(o)).collect();
    stats.absent_objects = scene
        .objects
        .iter()
        .zip(&classes)
        .filter(|(_, c)| **c == Class::Absent)
        .map(|(o, _)| o.id.clone())
        .collect();

    let pieces = split_at_rest(scene, &classes);

    // Leaves of the static and pseudo-dynamic trees: each object's mesh
    // moved into the world frame, coloured.
    let clock = Instant::now();
    let mut leaves: [Vec<Active>; 2] = [Vec::new(), Vec::new()];
    let members: Vec<(&Piece, usize)> = pieces
        .iter()
        .filter_map(|p| match p.class {
            Class::Static => Some((p, 0)),
            Class::PseudoDynamic => Some((p, 1)),
            _ => None,
        })
        .collect();
    progress.phase("leaves", members.len() as u64);
    let leaf_meshes: Vec<Result<(Mesh, String)>> = members
        .par_iter()
        .map(|&(p, _)| {
            let o = &scene.objects[p.object];
            let mesh = geometry::merge(
                &[Part {
                    mesh: &scene.meshes[o.mesh],
                    transform: p.transform,
                    color: o.color,
                }],
                0.0,
            );
            let hash = sink.put(&mesh)?;
            progress.advance(1);
            Ok((mesh, hash))
        })
        .collect();
    // Objects of one task share one visibility: the temporal error is a
    // maximum over the distinct ones.
    let mut vis_ids: HashMap<Vec<(u64, u64)>, u32> = HashMap::new();
    for (&(p, tree), made) in members.iter().zip(leaf_meshes) {
        let (mesh, hash) = made?;
        let o = &scene.objects[p.object];
        let steps = Steps::of_visibility(&p.visibility, span);
        let key: Vec<(u64, u64)> = steps
            .points()
            .iter()
            .map(|&(t, v)| (t.to_bits(), v.to_bits()))
            .collect();
        let vis = *vis_ids.entry(key).or_insert_with(|| {
            ctx.leaf_steps.push(steps.clone());
            ctx.leaf_steps.len() as u32 - 1
        });
        let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let w = f64::from((hi - lo).length());
        let id = clusters.len() as u32;
        clusters.push(Cluster {
            id,
            parent: None,
            children: Vec::new(),
            level: 0,
            class: if tree == 0 {
                ClusterClass::Static
            } else {
                ClusterClass::PseudoDynamic
            },
            bounds: Aabb::from_f32(lo, hi),
            w,
            eps: 0.0,
            gamma: 0.0,
            visibility: steps.to_tree(),
            motion: None,
            geometry: Some(hash),
            triangles: mesh.triangle_count() as u64,
            objects: vec![o.id.clone()],
        });
        let mesh = Arc::new(mesh);
        leaves[tree].push(Active {
            id,
            lo,
            hi,
            w,
            eps: 0.0,
            steps,
            vis: vec![vis],
            originals: (mesh.triangle_count() <= DIRECT_MAX_TRIANGLES).then(|| vec![mesh.clone()]),
            mesh,
        });
    }
    stats
        .phases
        .push(("leaves".into(), clock.elapsed().as_secs_f64()));

    // Scene size W and the level count from every clustered object.
    let all = leaves.iter().flatten();
    let (lo, hi) = all.fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), a| (lo.min(a.lo), hi.max(a.hi)),
    );
    let scene_w = if lo.x.is_finite() {
        f64::from((hi - lo).length())
    } else {
        0.0
    };
    let mut sizes: Vec<f64> = leaves.iter().flatten().map(|a| a.w).collect();
    sizes.sort_by(f64::total_cmp);
    let median = sizes.get(sizes.len() / 2).copied().unwrap_or(0.0);
    let levels = level_count(config, scene_w, median);
    stats.levels = levels;
    stats.scene_w = scene_w;

    let [static_leaves, pd_leaves] = leaves;
    let mut roots: Vec<u32> = Vec::new();
    for (kind, active) in [
        (ClusterClass::Static, static_leaves),
        (ClusterClass::PseudoDynamic, pd_leaves),
    ] {
        let clock = Instant::now();
        let (top, level_stats) = cluster_class(
            &ctx,
            &mut clusters,
            kind,
            active,
            (lo, hi),
            scene_w,
            levels,
            progress,
        )?;
        roots.extend(top);
        let name = match kind {
            ClusterClass::Static => {
                stats.static_levels = level_stats;
                "static"
            }
            _ => {
                stats.pseudo_dynamic_levels = level_stats;
                "pseudo_dynamic"
            }
        };
        stats
            .phases
            .push((name.into(), clock.elapsed().as_secs_f64()));
    }

    let clock = Instant::now();
    let dynamic: Vec<(usize, Visibility)> = pieces
        .iter()
        .filter(|p| p.class == Class::Dynamic)
        .map(|p| (p.object, p.visibility.clone()))
        .collect();
    progress.phase("dynamic", dynamic.len() as u64);
    let (tops, dyn_stats) = dynamic_chains(scene, &dynamic, &ctx, &mut clusters, progress)?;
    roots.extend(tops);
    stats.dynamic_levels = dyn_stats;
    stats
        .phases
        .push(("dynamic".into(), clock.elapsed().as_secs_f64()));

    // The virtual root: no geometry, w and v aggregated like any cluster.
    let root = clusters.len() as u32;
    let root_steps: Vec<(f64, Steps)> = roots
        .iter()
        .map(|&r| {
            let c = &clusters[r as usize];
            (c.w, Steps::from_tree(&c.visibility))
        })
        .collect();
    let parts: Vec<(f64, &Steps)> = root_steps.iter().map(|(w, s)| (*w, s)).collect();
    let visibility = Steps::weighted_mean(&parts).simplified(config.max_steps, span);
    let bounds = roots
        .iter()
        .map(|&r| world_box(&clusters[r as usize]))
        .reduce(|a, b| a.union(&b))
        .unwrap_or(Aabb::new(DVec3::ZERO, DVec3::ZERO));
    let eps = roots
        .iter()
        .map(|&r| clusters[r as usize].eps)
        .fold(0.0, f64::max);
    for &r in &roots {
        clusters[r as usize].parent = Some(root);
    }
    clusters.push(Cluster {
        id: root,
        parent: None,
        children: roots,
        level: clusters.iter().map(|c| c.level).max().unwrap_or(0) + 1,
        class: ClusterClass::Root,
        bounds,
        w: bounds.diagonal(),
        eps,
        gamma: 0.0,
        visibility: visibility.to_tree(),
        motion: None,
        geometry: None,
        triangles: 0,
        objects: Vec::new(),
    });
    stats
        .phases
        .push(("root".into(), clock.elapsed().as_secs_f64()));
    let tree = Tree {
        scene: scene.name.clone(),
        time: scene.time,
        bounds: clusters[root as usize].bounds,
        up: scene.up,
        root,
        config: serde_json::to_value(config).expect("the config serialises"),
        stats: serde_json::to_value(&stats).expect("the statistics serialise"),
        clusters,
        presence: Default::default(),
        nodes: Default::default(),
    };
    Ok((tree, stats))
}

/// Builds the tree of `scene` into the directory `out`, atomically: a
/// failed build leaves what was there before.
pub fn build_to(
    scene: &Scene,
    config: &BuildConfig,
    out: &Path,
    progress: &dyn Progress,
) -> Result<(Tree, BuildStats)> {
    let writer = TreeWriter::create(out)?;
    let (tree, stats) = build(scene, config, &writer, progress)?;
    progress.phase("write", 1);
    writer.finish(&tree)?;
    progress.advance(1);
    Ok((tree, stats))
}

/// A part of an object's life that becomes one leaf.
struct Piece {
    object: usize,
    class: Class,
    transform: Mat4,
    visibility: Visibility,
}

/// Splits each moving object where it stands still. Before its first and
/// after its last keyframe its pose is held, so those parts of its
/// visibility are a pseudo-dynamic (or static) object at that pose, which
/// clusters with its neighbours; only the part in between stays dynamic.
/// A steel beam hoisted into place is then a moving object during its lift
/// and part of the structure afterwards. The cut draws the same geometry at
/// every time either way.
fn split_at_rest(scene: &Scene, classes: &[Class]) -> Vec<Piece> {
    let span = scene.time.seconds;
    let mut pieces = Vec::with_capacity(scene.objects.len());
    for (i, (o, &class)) in scene.objects.iter().zip(classes).enumerate() {
        let motion = match (class, &o.motion) {
            (Class::Absent, _) => continue,
            (Class::Dynamic, Some(m)) => m,
            _ => {
                // A motion that never moves is a fixed pose.
                pieces.push(Piece {
                    object: i,
                    class,
                    transform: o.pose(0.0),
                    visibility: o.visibility.clone(),
                });
                continue;
            }
        };
        let keys = motion.keyframes();
        let (first, last) = (keys[0], keys[keys.len() - 1]);
        let parts = [
            (f64::NEG_INFINITY, first.t, Some(first.matrix())),
            (first.t, last.t, None),
            (last.t, f64::INFINITY, Some(last.matrix())),
        ];
        for (from, to, rest) in parts {
            let visibility = o.visibility.clipped_to(from, to);
            if visibility.present_seconds(span) <= 0.0 {
                continue;
            }
            let class = match rest {
                None => Class::Dynamic,
                Some(_) if visibility.kind(span) == VisibilityType::Static => Class::Static,
                Some(_) => Class::PseudoDynamic,
            };
            pieces.push(Piece {
                object: i,
                class,
                transform: rest.unwrap_or(o.transform),
                visibility,
            });
        }
    }
    pieces
}

/// The box of a cluster in the world over the whole span: a dynamic
/// cluster's own box moved by every keyframe.
fn world_box(c: &Cluster) -> Aabb {
    let Some(motion) = &c.motion else {
        return c.bounds;
    };
    motion
        .keyframes()
        .iter()
        .map(|k| c.bounds.transformed(&k.matrix().as_dmat4()))
        .reduce(|a, b| a.union(&b))
        .unwrap_or(c.bounds)
}

/// Clusters one class level by level; answers the ids of the clusters left
/// at the top and the statistics per level.
#[allow(clippy::too_many_arguments)]
fn cluster_class(
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
                originals,
            } = parent?;
            let children: Vec<&Active> = g.iter().map(|&i| &active[i]).collect();
            let (steps, vis, gamma) = temporal(ctx, &children);
            let lo = children
                .iter()
                .fold(Vec3::splat(f32::INFINITY), |a, c| a.min(c.lo));
            let hi = children
                .iter()
                .fold(Vec3::splat(f32::NEG_INFINITY), |a, c| a.max(c.hi));
            let w = f64::from((hi - lo).length());
            let id = clusters.len() as u32;
            for c in &children {
                clusters[c.id as usize].parent = Some(id);
                stats.children_triangles += clusters[c.id as usize].triangles;
            }
            stats.clusters += 1;
            stats.triangles += mesh.triangle_count() as u64;
            stats.max_eps = stats.max_eps.max(eps);
            stats.max_gamma = stats.max_gamma.max(gamma);
            clusters.push(Cluster {
                id,
                parent: None,
                children: children.iter().map(|c| c.id).collect(),
                level,
                class: kind,
                bounds: Aabb::from_f32(lo, hi),
                w,
                eps,
                gamma,
                visibility: steps.to_tree(),
                motion: None,
                geometry: Some(hash),
                triangles: mesh.triangle_count() as u64,
                objects: Vec::new(),
            });
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
            });
        }
        let alone: Vec<usize> = (0..active.len()).filter(|&i| !taken[i]).collect();
        let singles: Vec<Option<(Mesh, f64)>> = alone
            .par_iter()
            .map(|&i| single_parent(ctx, &active[i], &th))
            .collect();
        let mut singles = alone.into_iter().zip(singles).peekable();
        for (i, (a, t)) in active.into_iter().zip(taken).enumerate() {
            if t {
                continue;
            }
            let single = singles.next_if(|(j, _)| *j == i).and_then(|(_, s)| s);
            let Some((mesh, eps)) = single else {
                next.push(a);
                continue;
            };
            let id = clusters.len() as u32;
            let child = &mut clusters[a.id as usize];
            child.parent = Some(id);
            let gamma = child.gamma;
            stats.children_triangles += child.triangles;
            stats.clusters += 1;
            stats.triangles += mesh.triangle_count() as u64;
            stats.max_eps = stats.max_eps.max(eps);
            stats.max_gamma = stats.max_gamma.max(gamma);
            let (lo, hi) = mesh
                .bounds()
                .map_or((a.lo, a.hi), |(lo, hi)| (lo.min(a.lo), hi.max(a.hi)));
            let w = f64::from((hi - lo).length());
            clusters.push(Cluster {
                id,
                parent: None,
                children: vec![a.id],
                level,
                class: kind,
                bounds: Aabb::from_f32(lo, hi),
                w,
                eps,
                gamma,
                visibility: a.steps.to_tree(),
                motion: None,
                geometry: Some(ctx.sink.put(&mesh)?),
                triangles: mesh.triangle_count() as u64,
                objects: Vec::new(),
            });
            next.push(Active {
                id,
                lo,
                hi,
                w,
                eps,
                mesh: Arc::new(mesh),
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
fn temporal(ctx: &Context, children: &[&Active]) -> (Steps, Vec<u32>, f64) {
    let parts: Vec<(f64, &Steps)> = children.iter().map(|c| (c.w.max(1e-9), &c.steps)).collect();
    let steps = Steps::weighted_mean(&parts).simplified(ctx.config.max_steps, ctx.span);
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

/// A parent made by `make_parent`: its geometry, `eps_c`, geometry hash and
/// the originals below it (if kept).
struct Parent {
    mesh: Mesh,
    eps: f64,
    hash: String,
    originals: Option<Vec<Arc<Mesh>>>,
}

/// Merges the children's geometry, simplifies it within the level's budget
/// and measures the spatial error: `eps_c = D_H(g_c, union g_c') + max
/// eps_c'`, with `D_H` a computed upper bound (see `reduce_within`). When
/// nothing removes triangles, the parent is the union (`D_H = 0`).
fn make_parent(
    ctx: &Context,
    active: &[Active],
    group: &[usize],
    th: &Thresholds,
) -> Result<Parent> {
    let children: Vec<&Active> = group.iter().map(|&i| &active[i]).collect();
    let child_eps = children.iter().map(|c| c.eps).fold(0.0, f64::max);
    let parts: Vec<Part> = children
        .iter()
        .map(|c| Part {
            mesh: &c.mesh,
            transform: Mat4::IDENTITY,
            color: [1.0; 4],
        })
        .collect();
    let union = geometry::merge(&parts, 0.0);
    let budget = (th.eps - child_eps) as f32;
    let tolerance = (ctx.config.hausdorff_fraction * th.eps) as f32;
    let (mesh, h) = reduce_within(&union, budget, tolerance).unwrap_or((union, 0.0));
    let originals = originals_of(&children);
    let eps = stored_eps(&mesh, h, child_eps, originals.as_deref(), tolerance);
    let hash = ctx.sink.put(&mesh)?;
    Ok(Parent {
        mesh,
        eps,
        hash,
        originals,
    })
}

/// Clusters whose original objects have at most this many triangles in all
/// get `direct_eps`: the measure costs what a parent's own does, and on the
/// paper scene this covers the static surroundings and the lower levels.
const DIRECT_MAX_TRIANGLES: usize = 20_000;

/// The originals below `children`, if all of them kept theirs and there
/// are few enough.
fn originals_of(children: &[&Active]) -> Option<Vec<Arc<Mesh>>> {
    let mut out = Vec::new();
    let mut triangles = 0;
    for c in children {
        for m in c.originals.as_ref()? {
            triangles += m.triangle_count();
            out.push(m.clone());
        }
    }
    (triangles <= DIRECT_MAX_TRIANGLES).then_some(out)
}

/// The `eps_c` stored for geometry `mesh` made within the measured bound
/// `h` of children whose largest error is `child_eps`. The recursive
/// `h + child_eps` of DESIGN.md section 2 bounds `D_H(g_c, union of the
/// original objects of c)` through the triangle inequality, adding each
/// level's bound to the one below; where the `originals` were kept, that
/// distance is also measured directly, often half the sum, and the
/// smaller of the two is stored (both are bounds), never below a child's,
/// so errors still grow upwards. A smaller `eps_c` lets the cut stop
/// higher in the tree.
fn stored_eps(
    mesh: &Mesh,
    h: f32,
    child_eps: f64,
    originals: Option<&[Arc<Mesh>]>,
    tolerance: f32,
) -> f64 {
    let recursive = f64::from(h) + child_eps;
    originals.map_or(recursive, |o| {
        direct_eps(mesh, o, tolerance, recursive)
            .map_or(recursive, |direct| direct.min(recursive))
            .max(child_eps)
    })
}

/// A bound of `D_H(mesh, union of originals)`, measured, if it is at most
/// `budget`.
fn direct_eps(mesh: &Mesh, originals: &[Arc<Mesh>], tolerance: f32, budget: f64) -> Option<f64> {
    let parts: Vec<Part> = originals
        .iter()
        .map(|m| Part {
            mesh: m,
            transform: Mat4::IDENTITY,
            color: [1.0; 4],
        })
        .collect();
    let union = geometry::merge(&parts, 0.0);
    geometry::bound_within(mesh, &union, tolerance, budget as f32).map(f64::from)
}

/// The paper's loop moves a cluster with no neighbours up unchanged; an
/// element longer than `w(l)` then stays a leaf until a level whose error
/// may be more than one pixel where the cut reaches it, so the cut draws
/// the leaf. Instead it gets a parent of its own: its geometry reduced
/// within `eps(l)`, when that keeps at most `min_reduction` of its
/// triangles. Answers the parent's geometry and error.
fn single_parent(ctx: &Context, child: &Active, th: &Thresholds) -> Option<(Mesh, f64)> {
    let triangles = child.mesh.triangle_count();
    if (triangles as f64) * ctx.config.min_reduction < QUAD_TRIANGLES {
        return None;
    }
    let budget = (th.eps - child.eps) as f32;
    let tolerance = (ctx.config.hausdorff_fraction * th.eps) as f32;
    let (mesh, h) = reduce_within(&child.mesh, budget, tolerance)?;
    if mesh.triangle_count() as f64 > triangles as f64 * ctx.config.min_reduction {
        return None;
    }
    let eps = stored_eps(&mesh, h, child.eps, child.originals.as_deref(), tolerance);
    Some((mesh, eps))
}

/// The fewest triangles a part is reduced to (a quad): a cluster with fewer
/// left after the reduction gains nothing from a parent of its own.
const QUAD_TRIANGLES: f64 = 2.0;

/// `mesh` reduced within `budget` (scene units) and the measured bound of
/// its Hausdorff distance to `mesh`, if some candidate removes triangles.
/// The candidates: part by part (`geometry::reduce_parts`: per-part boxes
/// or simplifications and a greedy cover) at half and all of the budget,
/// the latter also followed by meshoptimizer on what is left of the
/// budget, and, where those keep more than half, meshoptimizer on the
/// whole. The cut draws a cluster once its error is small enough on
/// screen, so a smaller error is worth some triangles: of the candidates
/// within `EPS_PREFERENCE` times the fewest triangles, the one with the
/// least error wins.
pub(super) fn reduce_within(mesh: &Mesh, budget: f32, tolerance: f32) -> Option<(Mesh, f32)> {
    if budget <= 0.0 {
        return None;
    }
    let mut candidates: Vec<(Mesh, f32)> = Vec::new();
    for share in [0.5, 1.0] {
        let r = geometry::reduce_parts(mesh, budget * share, tolerance * share);
        if share == 1.0
            && let Some((m, h)) = simplified_within(&r.mesh, budget - r.bound, tolerance)
        {
            candidates.push((m, h + r.bound));
        }
        candidates.push((r.mesh, r.bound));
    }
    // Worth its cost only where the parts gave little.
    if candidates
        .iter()
        .all(|(m, _)| m.triangle_count() * 2 > mesh.triangle_count())
    {
        candidates.extend(simplified_within(mesh, budget, tolerance));
    }
    let fewest = candidates
        .iter()
        .map(|(m, _)| m.triangle_count())
        .min()
        .unwrap_or(usize::MAX);
    candidates
        .into_iter()
        .filter(|(m, h)| {
            *h <= budget
                && m.triangle_count() < mesh.triangle_count()
                && m.triangle_count() as f64 <= EPS_PREFERENCE * fewest as f64
        })
        .min_by(|a, b| {
            a.1.total_cmp(&b.1)
                .then(a.0.triangle_count().cmp(&b.0.triangle_count()))
        })
}

/// How many times the fewest triangles a candidate parent may keep and
/// still win by a smaller error.
const EPS_PREFERENCE: f64 = 1.5;

/// meshoptimizer's simplification of `mesh` within `budget` and its
/// measured Hausdorff bound, if it removed triangles and the bound fits.
fn simplified_within(mesh: &Mesh, budget: f32, tolerance: f32) -> Option<(Mesh, f32)> {
    if budget <= 0.0 {
        return None;
    }
    let s = geometry::simplify(
        mesh,
        &SimplifyOptions {
            max_error: budget,
            target_triangles: None,
            prune: true,
        },
    );
    if s.strategy == Strategy::Unchanged || s.triangles >= mesh.triangle_count() {
        return None;
    }
    geometry::bound_within(&s.mesh, mesh, tolerance, budget).map(|h| (s.mesh, h))
}
