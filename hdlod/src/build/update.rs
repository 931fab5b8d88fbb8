//! Schedule-only updates: a tree built from an earlier version of a scene
//! whose geometry and placements are unchanged, only its schedule moved,
//! is brought up to date without touching geometry (docs/method.md
//! section 3, "Schedule updates").
//!
//! The clusters keep their groups, geometry, boxes and `eps_c`; the leaves
//! take the new visibility of their objects, and every cluster above a
//! leaf whose visibility changed is recomputed from its children as the
//! build computes it (`v_c` the `w`-weighted mean simplified to K steps,
//! `gamma_c` the largest L1 distance to a leaf visibility below); the
//! others keep theirs. A group that no longer
//! fits its level's temporal threshold `gamma(l)` is dissolved into its
//! parent's group. Where an object changes class (static, pseudo-dynamic,
//! dynamic, absent) the leaves themselves change, and the caller rebuilds
//! in full.

use std::borrow::Cow;

use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::config::{BuildConfig, thresholds};
use super::leaves::{Piece, pieces_by_object, split_at_rest};
use super::outputs::{BuildStats, LevelStats};
use super::scheduled;
use super::steps::StepFunction;
use crate::scene::{Class, Scene};
use crate::tree::{Cluster, ClusterClass, ObjectTables, Tree};

/// What an update made of an old tree.
pub enum Update {
    /// The tree with the new schedule; every geometry file is the old
    /// tree's. `dissolved`: the groups that no longer fit the schedule,
    /// their children handed to their parents.
    Updated {
        tree: Box<Tree>,
        stats: BuildStats,
        dissolved: usize,
        /// Per cluster of the new tree, its id in the tree updated.
        origin: Vec<u32>,
    },
    /// The groups would change: why, for the caller's report.
    Rebuild(String),
}

/// The tree `old` brought to `scene`'s schedule, or why it cannot be.
/// `old` must have been built from a scene with the same
/// [`super::geometry_key`] (the caller compares the key stored in its
/// statistics).
pub fn update_schedule(old: &Tree, scene: &Scene, config: &BuildConfig) -> Update {
    let carried = Carried {
        span: old.time.seconds,
        clusters: None,
    };
    let scene = scheduled(scene, config);
    let split = Split::of(&scene);
    schedule_pass(Cow::Borrowed(old), carried, &scene, split, config, true)
}

/// [`update_schedule`] of a tree made in memory, whose clusters it takes
/// rather than copies (a geometry update's, `super::local`), but for its
/// object tables, which the caller makes beside it: the tree answered has
/// none, and where groups were dissolved the caller renumbers its tables'
/// leaves by `origin`. `scene` is scheduled as `config` says and `split` is
/// of it: the geometry update has made both already.
pub(super) fn update_schedule_of(
    tree: Tree,
    carried: Carried,
    scene: &Scene,
    split: Split,
    config: &BuildConfig,
) -> Update {
    schedule_pass(Cow::Owned(tree), carried, scene, split, config, false)
}

/// A scene's objects' classes and the pieces of its leaves
/// ([`split_at_rest`]).
pub(super) struct Split {
    pub classes: Vec<Class>,
    pub pieces: Vec<Piece>,
}

impl Split {
    pub(super) fn of(scene: &Scene) -> Split {
        let classes: Vec<Class> = scene.objects.iter().map(|o| scene.class_of(o)).collect();
        let pieces = split_at_rest(scene, &classes);
        Split { classes, pieces }
    }
}

/// Which records of the tree a schedule pass is given still hold the
/// `v_c` and `gamma_c` of their children as they were (see
/// `visibility_pass`).
pub(super) struct Carried {
    /// The period they were computed over: with another, none holds.
    pub span: f64,
    /// Per cluster; `None`: all of them.
    pub clusters: Option<Vec<bool>>,
}

/// The pass over `scene`, scheduled as the build's configuration says;
/// with the tree's object tables where `tables`.
fn schedule_pass(
    old: Cow<Tree>,
    carried: Carried,
    scene: &Scene,
    Split { classes, pieces }: Split,
    config: &BuildConfig,
    tables: bool,
) -> Update {
    let span = scene.time.seconds;
    let Some(leaf_pieces) = match_leaves(&old, scene, &pieces) else {
        return Update::Rebuild(
            "an object changed class (static, pseudo-dynamic, dynamic or absent), \
             or a moving object's rests before or after its motion changed, \
             so the leaves differ"
                .into(),
        );
    };
    let Ok(mut stats) = serde_json::from_value::<BuildStats>(old.stats.clone()) else {
        return Update::Rebuild("the tree's statistics are not a build's".into());
    };
    let (levels, scene_w) = (stats.levels, stats.scene_w);
    let n = old.cluster_count();
    let carried = match carried.clusters {
        _ if carried.span != span => vec![false; n],
        Some(clusters) => clusters,
        None => vec![true; n],
    };
    let (bounds, old_config, sources) = (old.bounds, old.config.clone(), old.sources.clone());
    // The skinned objects' joints are no part of the schedule.
    let skins = old.skins.clone();
    let mut records: Vec<Cluster> = match old {
        // Decoded on every core: one by one, that was a third of the pass.
        Cow::Borrowed(t) => (0..n as u32)
            .into_par_iter()
            .map(|c| t.cluster(c).into_owned())
            .collect(),
        Cow::Owned(mut t) => std::mem::take(t.clusters_mut()),
    };
    // The object tables need the leaves' objects and ids alone: made on
    // one core while the other recomputes the visibility, the objects put
    // back after.
    let leaf_objects: Vec<(u32, Vec<String>)> = if tables {
        (records.iter_mut())
            .filter(|c| !c.objects.is_empty())
            .map(|c| (c.id, std::mem::take(&mut c.objects)))
            .collect()
    } else {
        Vec::new()
    };
    let (objects, visibility) = rayon::join(
        || {
            let named = leaf_objects
                .iter()
                .map(|(c, o)| (*c, o.iter().map(String::as_str)));
            tables.then(|| ObjectTables::of_leaves(scene, named))
        },
        || {
            visibility_pass(
                records,
                &carried,
                &leaf_pieces,
                &pieces,
                config,
                (span, scene_w, levels),
            )
        },
    );
    let (mut clusters, dissolved) = visibility;
    for (c, o) in leaf_objects {
        clusters[c as usize].objects = o;
    }
    let gone = dissolved.iter().filter(|d| d.is_some()).count();
    let origin = (0..n as u32)
        .filter(|&c| dissolved[c as usize].is_none())
        .collect();
    let new_ids = kept_ids(&dissolved);
    // Nothing dissolved: the ids and parents stand, and moving 180,000
    // records to the places they are in was a tenth of the pass.
    let clusters = if gone == 0 {
        clusters
    } else {
        renumbered(clusters, &new_ids)
    };
    let root = clusters
        .iter()
        .position(|c| c.class == ClusterClass::Root)
        .expect("a built tree has its virtual root") as u32;
    // A dissolved group may come before a leaf, whose id then changed; no
    // leaf is dissolved.
    let objects = match objects {
        Some(objects) if gone > 0 => Some(objects.renumbered(|c| new_ids[c as usize])),
        objects => objects,
    };
    level_stats(&clusters, &mut stats);
    // A removed object's tombstone (`super::align`) is no object of the
    // scene's.
    let tombstone = |k: usize| {
        sources
            .as_ref()
            .is_some_and(|s| s.get(k) == Some(&super::align::TOMBSTONE))
    };
    stats.absent_objects = scene
        .objects
        .iter()
        .zip(&classes)
        .enumerate()
        .filter(|&(k, (_, c))| *c == Class::Absent && !tombstone(k))
        .map(|(_, (o, _))| o.id.clone())
        .collect();
    stats.phases.clear();
    let mut tree = super::tree_of(scene, bounds, root, clusters);
    tree.config = old_config;
    tree.stats = serde_json::to_value(&stats).expect("the statistics serialise");
    tree.objects = objects;
    tree.sources = sources;
    tree.skins = skins;
    Update::Updated {
        tree: Box::new(tree),
        stats,
        dissolved: gone,
        origin,
    }
}

/// The visibility, `v_c` and `gamma_c`, of every cluster of `records`
/// (children before parents) recomputed from the leaves' `pieces`; the
/// groups that no longer fit their level, dissolved (`Some` of the children
/// handed to the parent).
///
/// Where `carried[c]`, the record's own `v_c` and `gamma_c` are what this
/// pass made of its children as they were (the same children with the same
/// `w`): it keeps them while nothing below it changed, and only its leaves'
/// distinct visibilities are gathered. Recomputing every cluster was most
/// of an update that changes a few.
fn visibility_pass(
    records: Vec<Cluster>,
    carried: &[bool],
    leaf_pieces: &[u32],
    pieces: &[Piece],
    config: &BuildConfig,
    (span, scene_w, levels): (f64, f64, u32),
) -> (Vec<Cluster>, Vec<Option<Vec<u32>>>) {
    let n = records.len();
    // Distinct leaf visibilities, as the build numbers them, and per
    // cluster the ones below it. A group whose recomputed `gamma_c` breaks
    // its level's threshold is dissolved: its children join its parent's
    // group. Every cluster keeps the same objects below it, so its geometry
    // and `eps_c` stay a bound, and the parent's `gamma_c` is measured over
    // its new children against its own, higher, threshold.
    let mut leaf_steps: Vec<StepFunction> = Vec::new();
    let mut vis_ids: FxHashMap<Vec<(u64, u64)>, u32> = FxHashMap::default();
    // A kept cluster's steps are read back from its record only when a
    // parent is recomputed.
    let mut steps: Vec<Option<StepFunction>> = Vec::with_capacity(n);
    let mut below: Vec<Vec<u32>> = Vec::with_capacity(n);
    // Whether a cluster's `v_c`, `gamma_c` or `w` may differ from what its
    // parent's record was made of.
    let mut changed: Vec<bool> = Vec::with_capacity(n);
    let mut clusters: Vec<Cluster> = Vec::with_capacity(n);
    let mut dissolved: Vec<Option<Vec<u32>>> = vec![None; n];
    for mut c in records {
        let regrouped = c.children.iter().any(|&k| dissolved[k as usize].is_some());
        if regrouped {
            c.children = c
                .children
                .iter()
                .flat_map(|&k| dissolved[k as usize].clone().unwrap_or_else(|| vec![k]))
                .collect();
        }
        let carried = carried[c.id as usize];
        let stale = !carried || regrouped || c.children.iter().any(|&k| changed[k as usize]);
        let (s, vis, gamma) = if c.class == ClusterClass::Root {
            // As `virtual_root` aggregates: from the roots' stored steps.
            let stored: Vec<(f64, StepFunction)> = c
                .children
                .iter()
                .map(|&r| {
                    let r = &clusters[r as usize];
                    (r.w, StepFunction::from_tree(&r.visibility))
                })
                .collect();
            let parts: Vec<(f64, &StepFunction)> = stored.iter().map(|(w, s)| (*w, s)).collect();
            let s = StepFunction::weighted_mean(&parts).simplified(config.max_steps, span);
            (Some(s), Vec::new(), 0.0)
        } else if let Some(&piece) = leaf_pieces.get(c.id as usize).filter(|&&p| p != NO_PIECE) {
            let s = StepFunction::of_visibility(&pieces[piece as usize].visibility, span);
            let key: Vec<(u64, u64)> = s
                .points()
                .iter()
                .map(|&(t, v)| (t.to_bits(), v.to_bits()))
                .collect();
            let next = leaf_steps.len() as u32;
            let vis = *vis_ids.entry(key).or_insert(next);
            if vis == next {
                leaf_steps.push(s.clone());
            }
            (Some(s), vec![vis], 0.0)
        } else if c.children.len() == 1 {
            // A lone cluster's own parent, or a coarser version in a
            // dynamic model's chain: the child's visibility and error.
            let child = c.children[0] as usize;
            let s = stale.then(|| steps_of(&mut steps, &clusters, child).clone());
            (s, below[child].clone(), clusters[child].gamma)
        } else {
            let mut vis: Vec<u32> = c
                .children
                .iter()
                .flat_map(|&k| below[k as usize].iter().copied())
                .collect();
            vis.sort_unstable();
            vis.dedup();
            let (s, gamma) = if stale {
                for &k in &c.children {
                    steps_of(&mut steps, &clusters, k as usize);
                }
                let parts: Vec<(f64, &StepFunction)> = c
                    .children
                    .iter()
                    .map(|&k| {
                        let s = steps[k as usize].as_ref().expect("read back above");
                        (clusters[k as usize].w.max(1e-9), s)
                    })
                    .collect();
                let s = StepFunction::weighted_mean(&parts).simplified(config.max_steps, span);
                let gamma = if span > 0.0 {
                    vis.iter()
                        .map(|&v| s.l1_distance(&leaf_steps[v as usize], span) / span)
                        .fold(0.0, f64::max)
                } else {
                    0.0
                };
                (Some(s), gamma)
            } else {
                (None, c.gamma)
            };
            if gamma > thresholds(config, scene_w, levels, c.level).gamma {
                dissolved[c.id as usize] = Some(c.children.clone());
            }
            (s, vis, gamma)
        };
        let mut differs = !carried;
        if let Some(s) = &s {
            let visibility = s.to_tree();
            differs |= visibility != c.visibility || gamma != c.gamma;
            c.visibility = visibility;
            c.gamma = gamma;
        }
        steps.push(s);
        below.push(vis);
        changed.push(differs);
        clusters.push(c);
    }
    (clusters, dissolved)
}

/// The steps of cluster `k`, read back from its record where the pass kept
/// it.
fn steps_of<'a>(
    steps: &'a mut [Option<StepFunction>],
    clusters: &[Cluster],
    k: usize,
) -> &'a StepFunction {
    steps[k].get_or_insert_with(|| StepFunction::from_tree(&clusters[k].visibility))
}

/// Sets the static and pseudo-dynamic levels' figures in `stats` from
/// `clusters`, in one pass over them.
fn level_stats(clusters: &[Cluster], stats: &mut BuildStats) {
    let mut of: FxHashMap<(ClusterClass, u32), LevelStats> = FxHashMap::default();
    for c in clusters {
        if !matches!(c.class, ClusterClass::Static | ClusterClass::PseudoDynamic) {
            continue;
        }
        let l = of.entry((c.class, c.level)).or_default();
        l.clusters += 1;
        l.triangles += c.triangles;
        l.children_triangles += c
            .children
            .iter()
            .map(|&k| clusters[k as usize].triangles)
            .sum::<u64>();
        l.max_gamma = l.max_gamma.max(c.gamma);
        // The same as built for a schedule update; a geometry update
        // (`local.rs`) made some clusters again.
        l.max_eps = l.max_eps.max(c.eps);
    }
    for (levels, class) in [
        (&mut stats.static_levels, ClusterClass::Static),
        (
            &mut stats.pseudo_dynamic_levels,
            ClusterClass::PseudoDynamic,
        ),
    ] {
        for level in levels {
            let figures = of.remove(&(class, level.level)).unwrap_or_default();
            *level = LevelStats {
                level: level.level,
                ..figures
            };
        }
    }
}

/// Per cluster of `old`, the piece of `scene` it stands for if it is a
/// leaf ([`NO_PIECE`] if not), when the pieces are those the tree was built
/// from: each object's leaves are its pieces, of the same classes, the
/// static and pseudo-dynamic ones first. Matched by the objects' ids, as a
/// geometry update may place an object's leaves after others'
/// (`super::local`).
fn match_leaves(old: &Tree, scene: &Scene, pieces: &[Piece]) -> Option<Vec<u32>> {
    // Each object's pieces, and how many of them its leaves took so far.
    let by_object = pieces_by_object(pieces);
    let mut pieces_of: FxHashMap<&str, (Vec<usize>, usize)> =
        FxHashMap::with_capacity_and_hasher(by_object.len(), Default::default());
    pieces_of.extend(
        (by_object.into_iter())
            .map(|(k, of_object)| (scene.objects[k].id.as_str(), (of_object, 0))),
    );
    // Per cluster: a table, not a map, for the hundred thousand leaves.
    let mut out = vec![NO_PIECE; old.cluster_count()];
    let leaves = (0..old.cluster_count() as u32)
        .filter(|&c| old.children_of(c).is_empty() && old.class_of(c) != ClusterClass::Root);
    for leaf in leaves {
        let id = old.sole_object(leaf)?;
        let (of_object, next) = pieces_of.get_mut(id)?;
        let &i = of_object.get(*next)?;
        *next += 1;
        if old.class_of(leaf) != pieces[i].cluster_class() {
            return None;
        }
        out[leaf as usize] = i as u32;
    }
    pieces_of
        .values()
        .all(|(of_object, next)| *next == of_object.len())
        .then_some(out)
}

/// In [`match_leaves`]' table, a cluster that is no leaf.
const NO_PIECE: u32 = u32::MAX;

/// Per cluster, its id once the `dissolved` are dropped (`u32::MAX` for
/// those).
fn kept_ids(dissolved: &[Option<Vec<u32>>]) -> Vec<u32> {
    let mut id = vec![u32::MAX; dissolved.len()];
    let mut next = 0;
    for (old, d) in dissolved.iter().enumerate() {
        if d.is_none() {
            id[old] = next;
            next += 1;
        }
    }
    id
}

/// The `clusters` but the dissolved ones (`u32::MAX` in `id`), each
/// numbered by its place's `id`, in the same order (children before
/// parents, the root last), parents set from the children lists.
fn renumbered(mut clusters: Vec<Cluster>, id: &[u32]) -> Vec<Cluster> {
    // The records before the first dissolved one keep their places, their
    // ids and their children's (numbered lower): only the rest moves and is
    // renumbered, and the children of the rest are given their parents
    // again. Moving and renumbering all 180,000 was most of the pass's end.
    let first = (id.iter())
        .position(|&new| new == u32::MAX)
        .unwrap_or(id.len());
    let mut at = 0;
    clusters.retain_mut(|c| {
        let new = id[at];
        at += 1;
        if new != u32::MAX && at > first {
            c.id = new;
            for k in &mut c.children {
                *k = id[*k as usize];
            }
        }
        new != u32::MAX
    });
    // Every cluster but the root is a child, of a cluster after it: a
    // parent in the rest is set here, one before it stands.
    for i in first..clusters.len() {
        let children = std::mem::take(&mut clusters[i].children);
        for &k in &children {
            clusters[k as usize].parent = Some(i as u32);
        }
        clusters[i].children = children;
    }
    clusters
}
