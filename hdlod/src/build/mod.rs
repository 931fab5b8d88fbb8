//! The tree builder (docs/method.md section 3; Semenov et al. 2020,
//! appendix 2). Static and pseudo-dynamic objects are clustered bottom-up
//! in Hilbert order, level by level; each dynamic object gets its own
//! cluster under a discrete LOD chain of its shared model; all roots hang
//! under one virtual root.
//!
//! One file per job: `leaves` (objects into leaf clusters, moving objects
//! split where they stand still), `level` (grouping one level), `parent`
//! (a parent's geometry and error), `dynamic` (LOD chains); this file
//! orchestrates them. `context` holds what they share, and the one
//! constructor of a cluster record.

mod align;
mod config;
mod context;
mod digest;
mod dynamic;
mod hilbert;
mod instances;
mod leaves;
mod level;
mod local;
mod outputs;
mod parent;
mod skinned;
mod steps;
mod update;

use std::borrow::Cow;
use std::path::Path;
use std::time::Instant;

use glam::{DVec3, Vec3};

use crate::scene::{Class, Scene, Visibility};
use crate::tree::{
    Aabb, Cluster, ClusterClass, ObjectTables, OldTable, Previous, Tree, TreeWriter,
};
use crate::{Error, Result};
use context::{Context, Node, add};

pub use config::{BuildConfig, Thresholds, level_count, thresholds};
use digest::MeshesKey;
pub use digest::{geometry_key, object_sources};
pub use hilbert::hilbert_key;
pub use outputs::{BuildStats, GeometrySink, LevelStats, Progress, Silent};
pub use steps::StepFunction;
pub use update::{Update, update_schedule};

/// Builds the HDLOD tree of `scene`. Geometry goes to `sink` as it is made.
pub fn build(
    scene: &Scene,
    config: &BuildConfig,
    sink: &dyn GeometrySink,
    progress: &dyn Progress,
) -> Result<(Tree, BuildStats)> {
    config.validate().map_err(|e| match e {
        Error::Argument { at, message } => Error::argument(format!("config.{at}"), message),
        other => other,
    })?;
    let scene = &*scheduled(scene, config);
    if scene.objects.len() > crate::io::glb::MAX_FEATURE_ID as usize {
        return Err(Error::argument(
            "scene.objects",
            format!(
                "{} objects: a tree's feature ids reach {} objects at most",
                scene.objects.len(),
                crate::io::glb::MAX_FEATURE_ID
            ),
        ));
    }
    let span = scene.time.seconds;
    let mut stats = BuildStats {
        geometry_key: geometry_key(scene, config),
        ..BuildStats::default()
    };
    let mut clusters: Vec<Cluster> = Vec::new();
    let mut ctx = Context {
        config,
        span,
        leaf_steps: Vec::new(),
        sink,
        shapes: Vec::new(),
    };

    let classes: Vec<Class> = scene.objects.iter().map(|o| scene.class_of(o)).collect();
    stats.absent_objects = scene
        .objects
        .iter()
        .zip(&classes)
        .filter(|(_, c)| **c == Class::Absent)
        .map(|(o, _)| o.id.clone())
        .collect();

    let pieces = leaves::split_at_rest(scene, &classes);
    let clock = Instant::now();
    let leaves = leaves::leaves(scene, &pieces, &mut ctx, &mut clusters, progress)?;
    stats
        .phases
        .push(("leaves".into(), clock.elapsed().as_secs_f64()));

    // Scene size W and the level count from every clustered object.
    let (lo, hi) = leaves.iter().flatten().fold(
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
        let (top, level_stats) = level::cluster_class(
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
    let (tops, dyn_stats) =
        dynamic::dynamic_chains(scene, &dynamic, &ctx, &mut clusters, progress)?;
    roots.extend(tops);
    stats.dynamic_levels = dyn_stats;
    stats
        .phases
        .push(("dynamic".into(), clock.elapsed().as_secs_f64()));

    let clock = Instant::now();
    let root = virtual_root(&ctx, &mut clusters, roots);
    stats
        .phases
        .push(("root".into(), clock.elapsed().as_secs_f64()));
    let bounds = clusters[root as usize].bounds;
    let objects = ObjectTables::of(scene, &clusters);
    let mut tree = tree_of(scene, bounds, root, clusters);
    tree.config = serde_json::to_value(config).expect("the config serialises");
    tree.stats = serde_json::to_value(&stats).expect("the statistics serialise");
    tree.objects = Some(objects);
    tree.sources = Some(object_sources(scene));
    tree.skins = skinned::skeletons(scene, &tree);
    Ok((tree, stats))
}

/// A tree of `scene`'s name, period, axis and place on Earth over
/// `clusters`, its world box `bounds`.
pub(super) fn tree_of(scene: &Scene, bounds: Aabb, root: u32, clusters: Vec<Cluster>) -> Tree {
    let mut tree = Tree::new(
        scene.name.clone(),
        scene.time,
        bounds,
        scene.up,
        root,
        clusters,
    );
    tree.georeference = scene.georeference;
    tree
}

/// `scene` on the dates `config.schedule` chooses, when it chooses other
/// dates than the scene's own.
pub(super) fn scheduled<'a>(scene: &'a Scene, config: &BuildConfig) -> Cow<'a, Scene> {
    match config.schedule {
        Some(options) if options != scene.schedule_options => {
            let mut owned = scene.clone();
            owned.schedule_options = options;
            owned.apply_schedule();
            Cow::Owned(owned)
        }
        _ => Cow::Borrowed(scene),
    }
}

/// Carries out a local geometry update of the tree `old` at `out`
/// (`local.rs`), atomically: the new tree shares the old one's geometry
/// store and adds its new files to it.
/// `(load, planned, table)`: the seconds the old tree took to load, when
/// the plan started, and the old table if it was opened ahead.
fn update_geometry(
    old: &Tree,
    plan: local::Plan<'_>,
    config: &BuildConfig,
    out: &Path,
    (load, planned, table): (f64, Instant, Option<&OldTable>),
    progress: &dyn Progress,
) -> Result<(Tree, BuildStats, How)> {
    let clock = planned;
    let (edited_objects, added_objects, removed_objects) = (
        plan.edited_objects,
        plan.added_objects,
        plan.removed_objects,
    );
    let writer = TreeWriter::create(out)?;
    let old_files: rustc_hash::FxHashSet<[u8; 32]> = old.geometry_hashes().into_iter().collect();
    let shared = writer.share_geometry(old.layout, old_files.iter().copied())?;
    let shared_seconds = clock.elapsed().as_secs_f64();
    let updated = plan.run(old, out, config, &writer, progress)?;
    let mut stats = updated.stats;
    let mut phases = vec![
        ("load tree".to_string(), load),
        ("plan and share".to_string(), shared_seconds),
    ];
    phases.append(&mut stats.phases);
    stats.phases = phases;
    let clock = Instant::now();
    progress.phase("write", 1);
    let kept: Vec<[u8; 32]> = (updated.tree.geometry_hashes().into_iter())
        .filter(|h| old_files.contains(h))
        .collect();
    if !shared {
        // A flat (`hdlod-tree/1`) tree's files are linked one by one.
        for hash in &kept {
            writer.reuse_geometry(out, old.layout, &crate::tree::index::hex(hash))?;
        }
    }
    let geometry_files = kept.len();
    let previous = Previous {
        tree: old,
        dir: out,
        origin: &updated.origin,
        table,
    };
    writer.finish_replacing(&updated.tree, &previous)?;
    stats
        .phases
        .push(("write".into(), clock.elapsed().as_secs_f64()));
    let how = How::GeometryUpdate {
        edited_objects,
        added_objects,
        removed_objects,
        rebuilt: updated.rebuilt,
        widened: updated.widened,
        dropped: updated.dropped,
        geometry_files,
        dissolved: updated.dissolved,
    };
    Ok((updated.tree, stats, how))
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

/// How [`build_or_update_to`] made its tree.
#[derive(Debug, Clone, PartialEq)]
pub enum How {
    /// Built in full. `why`: why the tree that was there was not updated
    /// instead (none when there was no tree or a full build was asked).
    Full { why: Option<String> },
    /// The tree that was there, brought to the scene's new schedule
    /// ([`update_schedule`]): no geometry made, every geometry file kept;
    /// `dissolved` groups no longer fitted it.
    ScheduleUpdate {
        geometry_files: usize,
        dissolved: usize,
    },
    /// The tree that was there, brought to the scene's edited, added or
    /// removed objects (`local.rs`): the clusters above them made again
    /// (`rebuilt`, leaves included) or, where the objects below only moved
    /// a little, kept with their error widened by that (`widened`), the
    /// removed objects' leaves and the clusters left with no children
    /// dropped (`dropped`), every other cluster and geometry file kept
    /// (`geometry_files` of the new tree's were the old tree's).
    GeometryUpdate {
        edited_objects: usize,
        added_objects: usize,
        removed_objects: usize,
        rebuilt: usize,
        widened: usize,
        dropped: usize,
        geometry_files: usize,
        dissolved: usize,
    },
}

/// Like [`build_to`], but when `out` holds a tree built from a scene with
/// the same geometry and configuration ([`geometry_key`]), only the
/// schedule changed, that tree is updated instead of rebuilt; where some
/// objects were edited or added since, only the clusters above them are
/// made again (`local.rs`); unless `full`. Atomic either way: a failure
/// leaves `out` as it was.
pub fn build_or_update_to(
    scene: &Scene,
    config: &BuildConfig,
    out: &Path,
    full: bool,
    progress: &dyn Progress,
) -> Result<(Tree, BuildStats, How)> {
    let manifest = out.join(crate::tree::format::MANIFEST_FILE);
    let why = if full || !manifest.exists() {
        None
    } else {
        let clock = Instant::now();
        progress.phase("load tree", 1);
        let (loaded, beside) = rayon::join(
            || crate::tree::store::load_to_update(out),
            || Beside::of(scene, config, out),
        );
        match loaded {
            Err(e) => Some(format!("the tree there does not load: {e}")),
            Ok(old) => {
                let load = clock.elapsed().as_secs_f64();
                match update_in_place(&old, scene, config, out, (load, beside), progress)? {
                    Ok(done) => return Ok(done),
                    Err(why) => Some(why),
                }
            }
        }
    };
    let (tree, stats) = build_to(scene, config, out, progress)?;
    Ok((tree, stats, How::Full { why }))
}

/// What an update makes of the scene and reads beside the tree while the
/// tree loads.
struct Beside {
    /// The scene's key, which is the key of the scene as aligned to the
    /// tree's objects whenever their order stands, and its meshes' part.
    meshes_key: MeshesKey,
    key: String,
    /// The tree's objects' ids, in their feature order.
    ids: Result<Option<Vec<String>>>,
}

impl Beside {
    fn of(scene: &Scene, config: &BuildConfig, out: &Path) -> Beside {
        let meshes_key = MeshesKey::of(scene, config);
        Beside {
            key: meshes_key.key(scene),
            meshes_key,
            ids: crate::tree::store::object_ids(out),
        }
    }
}

/// The tree `old` at `out` brought to `scene` by a schedule update or a
/// geometry update, or why neither can be done.
fn update_in_place(
    old: &Tree,
    scene: &Scene,
    config: &BuildConfig,
    out: &Path,
    (load, beside): (f64, Beside),
    progress: &dyn Progress,
) -> Result<std::result::Result<(Tree, BuildStats, How), String>> {
    let clock = Instant::now();
    let Beside {
        meshes_key,
        key: scene_key,
        ids,
    } = beside;
    // The scene in the old tree's feature order, when the tree keeps one.
    let aligned = match (ids, &old.sources) {
        (Ok(Some(ids)), Some(sources)) => align::align(scene, &ids, sources),
        _ => Ok(align::Aligned {
            scene: Cow::Borrowed(scene),
            tombstones: Vec::new(),
        }),
    };
    let aligned = match aligned {
        Ok(aligned) => aligned,
        Err(why) => return Ok(Err(format!("the tree cannot be updated in place: {why}"))),
    };
    let scene = &*aligned.scene;
    let key = old.stats.get("geometry_key").and_then(|k| k.as_str());
    let new_key = match aligned.scene {
        Cow::Borrowed(_) => scene_key,
        Cow::Owned(_) => meshes_key.key(scene),
    };
    let same = key == Some(new_key.as_str());
    let key_seconds = clock.elapsed().as_secs_f64();
    // The old table is opened (mapped, its records found) beside the plan
    // or the schedule pass, each of which leaves a core waiting at times,
    // rather than in the write, which keeps both busy.
    let open_table = || OldTable::open(old, out);
    if !same {
        let (planned, table) = rayon::join(
            || local::plan(old, scene, &aligned.tombstones, config, new_key),
            open_table,
        );
        return match planned {
            Err(why) => Ok(Err(format!(
                "the scene's geometry or the build configuration changed since it was built, \
                 and the tree cannot be updated in place: {why}"
            ))),
            Ok(plan) => {
                let previous = (load, clock, table.as_ref());
                update_geometry(old, plan, config, out, previous, progress).map(Ok)
            }
        };
    }
    progress.phase("update", 1);
    let clock = Instant::now();
    let (updated, table) = rayon::join(|| update_schedule(old, scene, config), open_table);
    let (tree, mut stats, dissolved, origin) = match updated {
        Update::Rebuild(why) => return Ok(Err(why)),
        Update::Updated {
            tree,
            stats,
            dissolved,
            origin,
        } => (tree, stats, dissolved, origin),
    };
    stats.phases.push(("load tree".into(), load));
    stats.phases.push(("geometry key".into(), key_seconds));
    stats
        .phases
        .push(("update".into(), clock.elapsed().as_secs_f64()));
    let clock = Instant::now();
    progress.phase("write", 1);
    let writer = TreeWriter::create(out)?;
    let files = tree.geometry_hashes();
    let geometry_files = files.len();
    // A flat (`hdlod-tree/1`) tree's files are linked one by one into the
    // new tree's shards.
    let shared = writer.share_geometry(old.layout, files.iter().copied())?;
    if !shared {
        for hash in &files {
            writer.reuse_geometry(out, old.layout, &crate::tree::index::hex(hash))?;
        }
    }
    stats
        .phases
        .push(("geometry".into(), clock.elapsed().as_secs_f64()));
    let clock = Instant::now();
    let origin: Vec<Option<u32>> = origin.into_iter().map(Some).collect();
    let previous = Previous {
        tree: old,
        dir: out,
        origin: &origin,
        table: table.as_ref(),
    };
    writer.finish_replacing(&tree, &previous)?;
    stats
        .phases
        .push(("write".into(), clock.elapsed().as_secs_f64()));
    let how = How::ScheduleUpdate {
        geometry_files,
        dissolved,
    };
    Ok(Ok((*tree, stats, how)))
}

/// The virtual root over `roots`: no geometry, `w` and `v` aggregated like
/// any cluster's, its box the union of the roots' boxes in the world over
/// the whole span. Answers its id.
fn virtual_root(ctx: &Context, clusters: &mut Vec<Cluster>, roots: Vec<u32>) -> u32 {
    let root_steps: Vec<(f64, StepFunction)> = roots
        .iter()
        .map(|&r| {
            let c = &clusters[r as usize];
            (c.w, StepFunction::from_tree(&c.visibility))
        })
        .collect();
    let parts: Vec<(f64, &StepFunction)> = root_steps.iter().map(|(w, s)| (*w, s)).collect();
    let visibility = StepFunction::weighted_mean(&parts).simplified(ctx.config.max_steps, ctx.span);
    let (bounds, eps) = root_extent(clusters, &roots);
    let level = clusters.iter().map(|c| c.level).max().unwrap_or(0) + 1;
    let node = Node {
        bounds,
        w: bounds.diagonal(),
        eps,
        children: roots,
        ..Node::new(
            ClusterClass::Root,
            level,
            (Vec3::ZERO, Vec3::ZERO),
            &visibility,
        )
    };
    add(clusters, node)
}

/// The virtual root's box, its children's over the whole span, and its
/// error, their largest.
pub(super) fn root_extent(clusters: &[Cluster], roots: &[u32]) -> (Aabb, f64) {
    // On every core: a moving object's box is moved by each of its
    // keyframes, and the root has every moving object's chain below it.
    use rayon::prelude::*;
    let bounds = roots
        .par_iter()
        .map(|&r| world_box(&clusters[r as usize]))
        .reduce_with(|a, b| a.union(&b))
        .unwrap_or(Aabb::new(DVec3::ZERO, DVec3::ZERO));
    let eps = roots
        .iter()
        .map(|&r| clusters[r as usize].eps)
        .fold(0.0, f64::max);
    (bounds, eps)
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
