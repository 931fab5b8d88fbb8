//! Local geometry updates: a tree built from an earlier version of a scene
//! in which some objects were edited (new mesh, placement or colour),
//! added or removed is brought up to date by rebuilding only the clusters
//! above them, up to the root, and reusing every other cluster and its
//! geometry file (docs/method.md section 3, "Geometry updates").
//!
//! The tree's groups stay as they were: an edited object's leaf is
//! replaced in place, an added object joins the parent of the nearest leaf
//! of its class (nearest in time first for the pseudo-dynamic class, as
//! the build ranks candidates) or the first cluster above it that its
//! visibility fits in time (else its own lone parents), a moving piece
//! gets its own LOD chain, and a removed object's leaves go with every
//! cluster left without children. An edited object that is not one static
//! or pseudo-dynamic leaf (a moving one) is removed and added again at its
//! index. The scene comes in the old tree's object order, removed objects
//! as tombstones (`super::align`). Each
//! cluster above a changed leaf is *widened* where the objects below it
//! only moved, less than its level's budget allows: it keeps its geometry,
//! and its `eps_c` grows by the farthest move (the triangle inequality).
//! Else it is made again from its children exactly as the build makes it
//! (the union reduced within its level's budget, `eps_c` measured; a lone
//! child's own parent reduced alone), the unchanged children read back
//! from their geometry files. The schedule pass of
//! [`super::update_schedule`] then recomputes `v_c` and `gamma_c` above
//! every change, so the scene's schedule may have moved too.
//!
//! What it does not do, and leaves to a full build: objects whose geometry
//! is the same but whose class changed, trees with baked colour, and
//! changes to more than a quarter of the objects. The levels and their
//! thresholds are the old tree's.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::align::TOMBSTONE;
use super::config::{BuildConfig, thresholds};
use super::context::{Active, Context, bounds_of};
use super::digest::object_sources;
use super::dynamic::dynamic_chains;
use super::instances::{Instance, farthest, shapes_of, single_parents};
use super::leaves::{Piece, leaf_mesh, pieces_by_object, split_at_rest};
use super::level::cluster_class;
use super::outputs::{BuildStats, GeometrySink, Progress, QUANTIZATION_SHARE};
use super::parent::{DIRECT_MAX_TRIANGLES, Single, make_parent};
use super::steps::StepFunction;
use super::update::{Carried, Split, Update, update_schedule_of};
use crate::error::{Error, Result};
use crate::geometry::{ErrorMetric, Mesh};
use crate::io::compact::Decoded;
use crate::scene::{Class, Scene, Visibility};
use crate::tree::sources::Digest;
use crate::tree::{Aabb, Cluster, ClusterClass, ObjectTables, Tree};

/// Edits above this share of the objects are built in full: the groups
/// would no longer be the scene's.
const MAX_TOUCHED_SHARE: f64 = 0.25;

/// Up to this many added leaves of a class join their neighbours' groups;
/// more (a storey modelled anew) are grouped among themselves. Joined one
/// by one, a storey's leaves make the groups they join too large to match
/// a full build's cuts.
const MAX_JOINED: usize = 64;

/// What a geometry update will do, decided before anything is written.
pub struct Plan<'a> {
    scene: Cow<'a, Scene>,
    /// The scene's objects' classes and their leaves' pieces, which the
    /// schedule pass at the end takes over.
    classes: Vec<Class>,
    pieces: Vec<Piece>,
    sources: Vec<Digest>,
    /// The static and pseudo-dynamic leaves are the clusters `0..leaves`;
    /// `kept[c]` is the piece leaf `c` stands for, none if its object was
    /// removed.
    leaves: usize,
    kept: Vec<Option<usize>>,
    /// Old leaves whose object was edited.
    edited: Vec<u32>,
    /// Old leaves of the removed and renewed objects.
    removed: Vec<u32>,
    /// Static and pseudo-dynamic pieces of the added and renewed objects,
    /// and the cluster each joins; none for a piece that fits no group in
    /// time, which gets a chain of lone parents of its own, or one that is
    /// `grouped`.
    added: Vec<(usize, Option<u32>)>,
    /// Per added piece: grouped with the other added pieces of its class,
    /// more than [`MAX_JOINED`] of them.
    grouped: Vec<bool>,
    /// Moving pieces of the added and renewed objects: each gets its LOD
    /// chain under the root.
    chains: Vec<usize>,
    stats: BuildStats,
    pub edited_objects: usize,
    pub added_objects: usize,
    pub removed_objects: usize,
}

/// What a geometry update made.
pub struct Updated {
    pub tree: Tree,
    pub stats: BuildStats,
    /// Clusters made again (leaves included) and geometry files written.
    pub rebuilt: usize,
    /// Clusters above an edit that kept their geometry, their `eps_c`
    /// widened by how far the objects below them moved.
    pub widened: usize,
    /// Clusters dropped: the removed objects' leaves and the clusters left
    /// with no children.
    pub dropped: usize,
    /// Groups dissolved by the schedule pass.
    pub dissolved: usize,
    /// Per cluster of the new tree, the old tree's it was made from: kept,
    /// or made again over the same children (its record may have changed).
    pub origin: Vec<Option<u32>>,
}

/// Whether `old` can be brought to `scene` by a local geometry update, and
/// how; `Err` says why not, for the caller's report. `scene` is in the
/// order of the tree's objects, with `tombstones` where objects were
/// removed (`super::align`); `key`: its [`super::geometry_key`].
pub fn plan<'a>(
    old: &Tree,
    scene: &'a Scene,
    tombstones: &[usize],
    config: &BuildConfig,
    key: String,
) -> std::result::Result<Plan<'a>, String> {
    let Some(before) = &old.sources else {
        return Err("the tree records no digests of its objects' sources (sources.bin)".into());
    };
    if serde_json::to_value(config).ok().as_ref() != Some(&old.config) {
        return Err("the build configuration changed".into());
    }
    if config.bake {
        return Err("a tree with baked colour is rebuilt in full".into());
    }
    if scene.up != old.up {
        return Err("the scene's up axis changed".into());
    }
    let mut stats: BuildStats = serde_json::from_value(old.stats.clone())
        .map_err(|_| "the tree's statistics are not a build's".to_string())?;
    stats.geometry_key = key;
    let scene = super::scheduled(scene, config);
    let mut sources = object_sources(&scene);
    for &k in tombstones {
        sources[k] = TOMBSTONE;
    }
    if sources.len() < before.len() {
        return Err(format!(
            "{} objects were removed and the tree has no object index to keep the others' \
             feature ids by",
            before.len() - sources.len()
        ));
    }
    let touched: Vec<bool> = (0..sources.len())
        .map(|i| before.get(i) != Some(&sources[i]))
        .collect();
    // Removed since: a tombstone now, an object before.
    let removed_object = |k: usize| k < before.len() && touched[k] && sources[k] == TOMBSTONE;
    let removed_objects = (0..before.len()).filter(|&k| removed_object(k)).count();
    let edited_objects = (0..before.len()).filter(|&i| touched[i]).count() - removed_objects;
    let added_objects = sources.len() - before.len();
    let changes = edited_objects + added_objects + removed_objects;
    if changes as f64 > MAX_TOUCHED_SHARE * sources.len().max(1) as f64 {
        return Err(format!(
            "{changes} of {} objects were edited, added or removed: more than a quarter",
            sources.len()
        ));
    }

    // The scene's pieces beside the old tree's leaves: each side is a pass
    // over tens of thousands of objects or leaves, mostly on one core.
    let ((classes, pieces, pieces_of), old_side) = rayon::join(
        || {
            let classes: Vec<Class> = (scene.objects.par_iter())
                .map(|o| scene.class_of(o))
                .collect();
            let pieces = split_at_rest(&scene, &classes);
            let pieces_of = pieces_by_object(&pieces);
            (classes, pieces, pieces_of)
        },
        || old_leaves(old),
    );
    let OldLeaves {
        ids: old_leaves,
        leaves,
        of_object: leaves_of,
    } = old_side?;
    let changed_class = || "an object changed class (static, pseudo-dynamic, dynamic or absent), so the leaves differ";
    let no_leaves: Vec<u32> = Vec::new();
    let old_leaves_of = |k: usize| {
        leaves_of
            .get(scene.objects[k].id.as_str())
            .unwrap_or(&no_leaves)
    };
    // An edited object that is one static or pseudo-dynamic leaf before and
    // after is made again in place. Any other (a moving object, or one
    // split where it stands still) is renewed: its old leaves go as a
    // removed object's, its pieces come as an added object's.
    let renewed: Vec<bool> = (0..sources.len())
        .map(|k| {
            if k >= before.len() || !touched[k] || sources[k] == TOMBSTONE {
                return false;
            }
            let new = pieces_of.get(&k).map_or(&[][..], Vec::as_slice);
            !matches!((&old_leaves_of(k)[..], new), ([leaf], [p])
                if pieces[*p].class != Class::Dynamic
                    && old.class_of(*leaf) == pieces[*p].cluster_class())
        })
        .collect();
    // Each old leaf and its piece, but the removed and renewed objects':
    // an object's leaves are its pieces in order.
    let mut removed = Vec::new();
    // Per old cluster: a table, not a map, for the hundred thousand leaves.
    let mut leaf_pieces: Vec<Option<usize>> = vec![None; old.cluster_count()];
    let mut matched = 0;
    for (k, new) in &pieces_of {
        let old_ones = old_leaves_of(*k);
        if *k >= before.len() || renewed[*k] {
            continue;
        }
        if old_ones.len() != new.len() {
            return Err(changed_class().into());
        }
        for (&leaf, &p) in old_ones.iter().zip(new) {
            if old.class_of(leaf) != pieces[p].cluster_class() {
                return Err(changed_class().into());
            }
            leaf_pieces[leaf as usize] = Some(p);
            matched += 1;
        }
    }
    for k in (0..before.len()).filter(|&k| renewed[k] || removed_object(k)) {
        removed.extend_from_slice(old_leaves_of(k));
    }
    if matched + removed.len() != old_leaves.len() {
        return Err(changed_class().into());
    }
    removed.sort_unstable();
    let mut kept = leaf_pieces;
    kept.truncate(leaves);
    let edited: Vec<u32> = (0..leaves as u32)
        .filter(|&c| kept[c as usize].is_some_and(|p| touched[pieces[p].object]))
        .collect();
    // The pieces of the added and renewed objects: the static and
    // pseudo-dynamic ones join a parent, the moving ones get a chain.
    let fresh = |p: &Piece| p.object >= before.len() || renewed[p.object];
    let (new, new_dynamic): (Vec<usize>, Vec<usize>) = (0..pieces.len())
        .filter(|&i| fresh(&pieces[i]))
        .partition(|&i| pieces[i].class != Class::Dynamic);

    // Each added piece joins the parent of the nearest old leaf of its
    // class.
    let span = scene.time.seconds;
    let time_step = thresholds(config, stats.scene_w, stats.levels, 1)
        .gamma
        .max(1e-9)
        / 4.0;
    // What an added piece is matched with, for none where none is added
    // (a removal), on every core otherwise.
    let joining = if new.is_empty() { 0 } else { leaves };
    let leaf_steps: Vec<Option<StepFunction>> = kept[..joining]
        .par_iter()
        .map(|p| p.map(|p| StepFunction::of_visibility(&pieces[p].visibility, span)))
        .collect();
    let centres: Vec<Vec3> = (0..joining as u32)
        .into_par_iter()
        .map(|c| {
            let b = old.cluster(c).bounds;
            ((b.min + b.max) * 0.5).as_vec3()
        })
        .collect();
    // Many added leaves of a class (a storey modelled anew) are grouped
    // among themselves as the build groups them (`Plan::added_hierarchy`);
    // a few join their neighbours' groups.
    let many = |class: ClusterClass| {
        (new.iter())
            .filter(|&&p| pieces[p].cluster_class() == class)
            .count()
            > MAX_JOINED
    };
    let many = [
        many(ClusterClass::Static),
        many(ClusterClass::PseudoDynamic),
    ];
    let grouped = |p: &Piece| many[usize::from(p.class == Class::PseudoDynamic)];
    let mut added = Vec::with_capacity(new.len());
    for &p in &new {
        let piece = &pieces[p];
        let no_geometry = || {
            format!(
                "added object {} has no geometry",
                scene.objects[piece.object].id
            )
        };
        if grouped(piece) {
            if scene.meshes[scene.objects[piece.object].mesh].triangle_count() == 0 {
                return Err(no_geometry());
            }
            added.push((p, None));
            continue;
        }
        let mesh = leaf_mesh(&scene, piece);
        let Some((lo, hi)) = mesh.bounds() else {
            return Err(no_geometry());
        };
        let centre = (lo + hi) * 0.5;
        let class = piece.cluster_class();
        let steps = StepFunction::of_visibility(&piece.visibility, span);
        let apart = |leaf: usize| {
            if class == ClusterClass::PseudoDynamic && span > 0.0 {
                let theirs = leaf_steps[leaf].as_ref().expect("a kept leaf");
                (steps.l1_distance(theirs, span) / span / time_step).floor() as u32
            } else {
                0
            }
        };
        // The nearest in space of each class of time, the nearest class
        // first.
        let mut near: Vec<(f32, usize)> = (0..leaves)
            .filter(|&l| kept[l].is_some() && old.class_of(l as u32) == class)
            .map(|l| (centres[l].distance_squared(centre), l))
            .collect();
        let take = near.len().min(64);
        if take == 0 {
            return Err(format!(
                "added object {} has no leaf of its class to join",
                scene.objects[piece.object].id
            ));
        }
        near.select_nth_unstable_by(take - 1, |a, b| a.0.total_cmp(&b.0));
        near.truncate(take);
        let &(_, best) = near
            .iter()
            .min_by(|a, b| apart(a.1).cmp(&apart(b.1)).then(a.0.total_cmp(&b.0)))
            .expect("one at least");
        // Its parent, or the first cluster above it whose visibility the
        // piece's is within that level's temporal threshold of: the group
        // it joins would otherwise break it, and the schedule pass
        // dissolve it and the groups above (the others' leaves handed up
        // too), where only the new leaf need go up. A piece that fits none
        // stands alone, as in a build it would group with none.
        let mut at = old.cluster(best as u32).parent;
        let fits = |c: u32| {
            let cluster = old.cluster(c);
            let gamma = thresholds(config, stats.scene_w, stats.levels, cluster.level).gamma;
            span <= 0.0
                || steps.l1_distance(&StepFunction::from_tree(&cluster.visibility), span) / span
                    <= gamma
        };
        while let Some(c) = at.filter(|&c| old.class_of(c) != ClusterClass::Root && !fits(c)) {
            at = old.cluster(c).parent;
        }
        added.push((p, at.filter(|&c| old.class_of(c) != ClusterClass::Root)));
    }
    let grouped = added.iter().map(|&(p, _)| grouped(&pieces[p])).collect();
    Ok(Plan {
        scene,
        classes,
        pieces,
        sources,
        leaves,
        kept,
        edited,
        removed,
        added,
        grouped,
        chains: new_dynamic,
        stats,
        edited_objects,
        added_objects,
        removed_objects,
    })
}

/// What the update made, for the assembly: the edited leaves by old id, the
/// added leaves, the added leaves each old cluster gains, the clusters
/// made again by old id, and the new moving objects' chains (ids within
/// `chains`) with their tops.
struct Remade {
    edited: HashMap<u32, Made>,
    added: Vec<Made>,
    joined: HashMap<u32, Vec<usize>>,
    made: HashMap<u32, Made>,
    widened: HashMap<u32, Widened>,
    chains: Vec<Cluster>,
    /// The grouped added leaves' hierarchy and its tops (`added_hierarchy`).
    hierarchy: Vec<Cluster>,
    hierarchy_tops: Vec<u32>,
    tops: Vec<u32>,
    /// The added leaves that fit no group, each with its lone parents.
    alone: Vec<LoneChain>,
}

/// An added leaf (its place in the plan) and its lone parents by level.
type LoneChain = (usize, Vec<(u32, Made)>);

/// A cluster's geometry while the update runs.
#[derive(Clone)]
struct Made {
    mesh: Arc<Mesh>,
    eps: f64,
    lo: Vec3,
    hi: Vec3,
    hash: String,
    originals: Option<Vec<Arc<Mesh>>>,
    /// A new leaf's shape, when other new leaves share it.
    instance: Option<Instance>,
}

/// A cluster above an edit that keeps its geometry: its error widened by
/// how far the objects below it moved, its box grown to theirs.
struct Widened {
    eps: f64,
    lo: Vec3,
    hi: Vec3,
}

/// A child of a cluster being made again, by its id in the old tree, or
/// an added leaf by its place in the plan.
#[derive(Clone, Copy)]
enum Child {
    Old(u32),
    Added(usize),
}

impl Plan<'_> {
    /// Carries the plan out: the new leaves and the clusters above them
    /// made and stored in `sink`, the unchanged geometry read from the old
    /// tree's files in `old_dir`.
    pub fn run(
        self,
        old: &Tree,
        old_dir: &Path,
        config: &BuildConfig,
        sink: &dyn GeometrySink,
        progress: &dyn Progress,
    ) -> Result<Updated> {
        let clock = std::time::Instant::now();
        let mut phases: Vec<(String, f64)> = Vec::new();
        let mut lap = |name: &str| {
            phases.push((name.to_string(), clock.elapsed().as_secs_f64()));
        };
        let scene = &self.scene;
        let span = scene.time.seconds;
        // The new leaves' repeated shapes: their own parents share one
        // reduction per shape, as in a full build (`instances`).
        let new_pieces: Vec<usize> = (self.edited.iter())
            .map(|&c| self.kept_piece(c))
            .chain(self.added.iter().map(|&(p, _)| p))
            .collect();
        let placements: Vec<(usize, glam::Mat4, [f32; 4])> = new_pieces
            .iter()
            .map(|&p| {
                let o = &scene.objects[self.pieces[p].object];
                (o.mesh, self.pieces[p].transform, o.color)
            })
            .collect();
        let (shapes, instances) = shapes_of(&scene.meshes, &placements);
        let instance_of: HashMap<usize, Instance> = new_pieces
            .iter()
            .zip(instances)
            .filter_map(|(&p, i)| Some((p, i?)))
            .collect();
        let ctx = Context {
            config,
            span,
            leaf_steps: Vec::new(),
            sink,
            shapes,
        };
        let added_count = self.added.len();
        progress.phase("leaves", (self.edited.len() + added_count) as u64);
        let leaf = |p: usize| -> Result<Made> {
            let mesh = leaf_mesh(scene, &self.pieces[p]);
            let hash = sink.put(&mesh, None, 0.0)?.hash;
            let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
            let mesh = Arc::new(mesh);
            progress.advance(1);
            Ok(Made {
                originals: (mesh.triangle_count() <= DIRECT_MAX_TRIANGLES)
                    .then(|| vec![mesh.clone()]),
                mesh,
                eps: 0.0,
                lo,
                hi,
                hash,
                instance: instance_of.get(&p).copied(),
            })
        };
        let edited: HashMap<u32, Made> = self
            .edited
            .par_iter()
            .map(|&c| Ok((c, leaf(self.kept_piece(c))?)))
            .collect::<Result<_>>()?;
        let added: Vec<Made> = self
            .added
            .par_iter()
            .map(|&(p, _)| leaf(p))
            .collect::<Result<_>>()?;
        // How far each edited leaf's object moved, at most (`moved_by`). A
        // removed leaf moved infinitely far.
        let within = Within {
            metric: config.error_metric,
            tolerance: (config.hausdorff_fraction
                * thresholds(config, self.stats.scene_w, self.stats.levels, 1).eps)
                as f32,
            budget: thresholds(
                config,
                self.stats.scene_w,
                self.stats.levels,
                self.stats.levels,
            )
            .eps as f32,
        };
        let mut moved: HashMap<u32, f64> = self
            .edited
            .par_iter()
            .map(|&c| {
                let before = placed(stored_file(old, old_dir, c)?.0);
                let after = as_stored(&edited[&c].mesh);
                Ok((c, moved_by(&before, &after, &within)))
            })
            .collect::<Result<_>>()?;
        moved.extend(self.removed.iter().map(|&c| (c, f64::INFINITY)));
        // The added and renewed moving objects' LOD chains, as the build
        // makes them.
        let moving: Vec<(usize, Visibility)> = (self.chains.iter())
            .map(|&p| (self.pieces[p].object, self.pieces[p].visibility.clone()))
            .collect();
        progress.phase("dynamic", moving.len() as u64);
        let mut chains = Vec::new();
        let (tops, _) = dynamic_chains(scene, &moving, &ctx, &mut chains, progress)?;
        lap("leaves");

        let grouped = &self.grouped;
        let (hierarchy, hierarchy_tops) =
            self.added_hierarchy(&ctx, old, &added, grouped, progress)?;
        // The clusters above a changed leaf, up to the root's children.
        let mut joined: HashMap<u32, Vec<usize>> = HashMap::new();
        for (a, &(_, parent)) in self.added.iter().enumerate() {
            if let Some(parent) = parent {
                joined.entry(parent).or_default().push(a);
            }
        }
        let alone = self.lone_chains(&ctx, &added, grouped, progress)?;
        // (level, id) of each, so that the levels come out in order.
        let mut dirty: Vec<(u32, u32)> = Vec::new();
        let mut seen = vec![false; old.cluster_count()];
        let starts = (self.edited.iter().chain(&self.removed))
            .filter_map(|&c| old.cluster(c).parent)
            .chain(joined.keys().copied());
        for start in starts {
            let mut at = Some(start);
            while let Some(c) = at {
                let cluster = old.cluster(c);
                if seen[c as usize] || cluster.class == ClusterClass::Root {
                    break;
                }
                seen[c as usize] = true;
                dirty.push((cluster.level, c));
                at = cluster.parent;
            }
        }
        dirty.sort_unstable();

        // Level by level, each on every core: a cluster's children are at
        // lower levels. A cluster left with no children goes too.
        let mut made: HashMap<u32, Made> = HashMap::new();
        let mut widened: HashMap<u32, Widened> = HashMap::new();
        let mut gone = vec![false; old.cluster_count()];
        for &c in &self.removed {
            gone[c as usize] = true;
        }
        for of_level in dirty.chunk_by(|a, b| a.0 == b.0) {
            let level = of_level[0].0;
            progress.phase(&format!("rebuild level {level}"), of_level.len() as u64);
            let th = thresholds(config, self.stats.scene_w, self.stats.levels, level);
            // A cluster over the same objects, some of them moved at most
            // `far`, keeps its geometry where its error widened by `far`
            // still fits its level: the triangle inequality carries the
            // bound from the objects as they were to the objects now.
            let mut to_make = Vec::new();
            for &(_, c) in of_level {
                let far = if joined.contains_key(&c) {
                    f64::INFINITY
                } else {
                    (old.children_of(c).iter())
                        .map(|k| moved.get(k).copied().unwrap_or(0.0))
                        .fold(0.0, f64::max)
                };
                moved.insert(c, far);
                let child = |k: u32| match edited.get(&k).or_else(|| made.get(&k)) {
                    Some(m) => (m.eps, m.lo, m.hi),
                    None => match widened.get(&k) {
                        Some(w) => (w.eps, w.lo, w.hi),
                        None => {
                            let k = old.cluster(k);
                            (k.eps, k.bounds.min.as_vec3(), k.bounds.max.as_vec3())
                        }
                    },
                };
                let was = old.cluster(c);
                let (mut eps, mut lo, mut hi) = (
                    was.eps + far,
                    was.bounds.min.as_vec3(),
                    was.bounds.max.as_vec3(),
                );
                for &k in old.children_of(c) {
                    let (e, l, h) = child(k);
                    (eps, lo, hi) = (eps.max(e), lo.min(l), hi.max(h));
                }
                if eps <= th.eps {
                    widened.insert(c, Widened { eps, lo, hi });
                } else {
                    to_make.push(c);
                }
            }
            let children: Vec<(u32, Vec<Active>)> = to_make
                .par_iter()
                .map(|&c| {
                    let children: Vec<Child> = old
                        .children_of(c)
                        .iter()
                        .filter(|&&k| !gone[k as usize])
                        .map(|&k| Child::Old(k))
                        .chain(
                            joined
                                .get(&c)
                                .into_iter()
                                .flatten()
                                .map(|&a| Child::Added(a)),
                        )
                        .collect();
                    // The originals below the unchanged children are read
                    // only where the cluster can use them: all of its
                    // children's together within the direct bound's reach.
                    let originals = |m: &Made| -> Option<usize> {
                        Some(
                            m.originals
                                .as_ref()?
                                .iter()
                                .map(|o| o.triangle_count())
                                .sum(),
                        )
                    };
                    let mut below: HashMap<u32, Vec<u32>> = HashMap::new();
                    let wanted = (children.iter())
                        .map(|&child| match child {
                            Child::Added(a) => originals(&added[a]),
                            Child::Old(k) => match edited.get(&k).or_else(|| made.get(&k)) {
                                Some(m) => originals(m),
                                None => {
                                    let (leaves, triangles) = self.leaves_below(old, k)?;
                                    below.insert(k, leaves);
                                    Some(triangles)
                                }
                            },
                        })
                        .try_fold(0, |total, t| Some(total + t?))
                        .is_some_and(|total| total <= DIRECT_MAX_TRIANGLES);
                    let active: Vec<Active> = children
                        .iter()
                        .map(|&child| {
                            let m = match child {
                                Child::Added(a) => added[a].clone(),
                                Child::Old(k) => match edited.get(&k).or_else(|| made.get(&k)) {
                                    Some(m) => m.clone(),
                                    None => {
                                        let leaves = below.remove(&k).filter(|_| wanted);
                                        let mut m = self.stored(old, old_dir, k, leaves)?;
                                        if let Some(w) = widened.get(&k) {
                                            (m.eps, m.lo, m.hi) = (w.eps, w.lo, w.hi);
                                        }
                                        m
                                    }
                                },
                            };
                            Ok(active_of(m))
                        })
                        .collect::<Result<_>>()?;
                    Ok((c, active))
                })
                .collect::<Result<_>>()?;
            let (empty, children): (Vec<_>, Vec<_>) =
                children.into_iter().partition(|(_, a)| a.is_empty());
            for (c, _) in empty {
                gone[c as usize] = true;
            }
            let (lone, groups): (Vec<_>, Vec<_>) =
                children.into_iter().partition(|(_, a)| a.len() == 1);
            let this: Vec<(u32, Made)> = groups
                .into_par_iter()
                .map(|(c, active)| {
                    let out = remade(&ctx, &active, &th)?;
                    progress.advance(1);
                    Ok((c, out))
                })
                .collect::<Result<_>>()?;
            made.extend(this);
            let this = lone_remade(&ctx, lone, &th, progress)?;
            made.extend(this);
            tracing::debug!(
                "level {level}: {} clusters made again, {} widened, {:.2} s in",
                to_make.len(),
                of_level.len() - to_make.len(),
                clock.elapsed().as_secs_f64()
            );
        }
        let rebuilt = edited.len()
            + added.len()
            + made.len()
            + chains.len()
            + hierarchy.len()
            + alone.iter().map(|(_, c)| c.len()).sum::<usize>();
        lap("rebuild");
        let remade = Remade {
            edited,
            added,
            joined,
            made,
            widened,
            chains,
            hierarchy,
            hierarchy_tops,
            tops,
            alone,
        };
        let mut updated = self.assemble(old, config, remade, &gone, rebuilt)?;
        lap("schedule");
        // Each phase's own seconds, from the laps.
        let mut last = 0.0;
        for (name, at) in phases {
            updated.stats.phases.push((name, at - last));
            last = at;
        }
        Ok(updated)
    }

    /// The hierarchy of the `grouped` added leaves (`added`, by their place
    /// in the plan), each class clustered level by level as the build
    /// clusters it (`level::cluster_class`), with the old tree's levels and
    /// thresholds. Answers its clusters above the leaves and the ids of its
    /// tops, in one numbering: below `self.added.len()` an added leaf,
    /// from there the clusters answered, in order.
    fn added_hierarchy(
        &self,
        ctx: &Context,
        old: &Tree,
        added: &[Made],
        grouped: &[bool],
        progress: &dyn Progress,
    ) -> Result<(Vec<Cluster>, Vec<u32>)> {
        let span = self.scene.time.seconds;
        let first = self.added.len();
        // The leaves' places are taken by their records, so that the
        // clusters made get the ids after them.
        let mut clusters: Vec<Cluster> = (self.added.iter())
            .map(|&(p, _)| piece_record(&self.pieces[p], 0, Vec::new(), span))
            .collect();
        let mut tops = Vec::new();
        let mut leaf_steps: Vec<StepFunction> = Vec::new();
        let mut vis_ids: FxHashMap<Vec<(u64, u64)>, u32> = FxHashMap::default();
        let mut of_class: [Vec<Active>; 2] = [Vec::new(), Vec::new()];
        for (a, m) in added.iter().enumerate().filter(|&(a, _)| grouped[a]) {
            let piece = &self.pieces[self.added[a].0];
            let steps = StepFunction::of_visibility(&piece.visibility, span);
            let key: Vec<(u64, u64)> = (steps.points().iter())
                .map(|&(t, v)| (t.to_bits(), v.to_bits()))
                .collect();
            let vis = *vis_ids.entry(key).or_insert_with(|| {
                leaf_steps.push(steps.clone());
                leaf_steps.len() as u32 - 1
            });
            let mut active = active_of(m.clone());
            (active.id, active.steps, active.vis) = (a as u32, steps, vec![vis]);
            of_class[usize::from(piece.class == Class::PseudoDynamic)].push(active);
        }
        let ctx = Context {
            leaf_steps,
            shapes: ctx.shapes.clone(),
            ..*ctx
        };
        let bounds = (old.bounds.min.as_vec3(), old.bounds.max.as_vec3());
        for (kind, active) in [ClusterClass::Static, ClusterClass::PseudoDynamic]
            .into_iter()
            .zip(of_class)
        {
            if active.is_empty() {
                continue;
            }
            let (top, _) = cluster_class(
                &ctx,
                &mut clusters,
                kind,
                active,
                bounds,
                self.stats.scene_w,
                self.stats.levels,
                progress,
            )?;
            tops.extend(top);
        }
        Ok((clusters.split_off(first), tops))
    }

    /// The lone parents of the added leaves that joined no group, level by
    /// level as the build gives a cluster that groups with none: its own
    /// parent reduced alone where that pays, else the cluster carried up
    /// as it is.
    fn lone_chains(
        &self,
        ctx: &Context,
        added: &[Made],
        grouped: &[bool],
        progress: &dyn Progress,
    ) -> Result<Vec<LoneChain>> {
        let mut chains: Vec<LoneChain> = (self.added.iter().enumerate())
            .filter(|&(a, (_, parent))| parent.is_none() && !grouped[a])
            .map(|(a, _)| (a, Vec::new()))
            .collect();
        if chains.is_empty() {
            return Ok(chains);
        }
        let mut tops: Vec<Made> = chains.iter().map(|&(a, _)| added[a].clone()).collect();
        for level in 1..=self.stats.levels {
            progress.phase(&format!("lone level {level}"), tops.len() as u64);
            let th = thresholds(ctx.config, self.stats.scene_w, self.stats.levels, level);
            let children: Vec<Active> = tops.iter().cloned().map(active_of).collect();
            let all: Vec<usize> = (0..children.len()).collect();
            let singles = single_parents(ctx, &children, &all, &th);
            for (k, single) in singles.into_iter().enumerate() {
                if let Some(single) = single {
                    let m = single_made(ctx, &children[k], single)?;
                    chains[k].1.push((level, m.clone()));
                    tops[k] = m;
                }
                progress.advance(1);
            }
        }
        Ok(chains)
    }

    /// The piece old clustered leaf `c` stands for, its object not removed.
    fn kept_piece(&self, c: u32) -> usize {
        self.kept[c as usize].expect("a leaf of an object still in the scene")
    }

    /// The unchanged cluster `id` of `old`: its geometry read back from its
    /// file, its error as stored, and the original objects of `leaves`
    /// ([`Plan::leaves_below`] it) where the direct bound will use them.
    fn stored(
        &self,
        old: &Tree,
        old_dir: &Path,
        id: u32,
        leaves: Option<Vec<u32>>,
    ) -> Result<Made> {
        let c = old.cluster(id);
        let (decoded, hash) = stored_file(old, old_dir, id)?;
        let mesh = placed(decoded.drawn());
        Ok(Made {
            mesh: Arc::new(mesh),
            eps: c.eps,
            lo: c.bounds.min.as_vec3(),
            hi: c.bounds.max.as_vec3(),
            hash,
            originals: leaves.map(|leaves| self.originals_of(leaves)),
            instance: None,
        })
    }

    /// The original objects of old `leaves`, as the scene now places them.
    fn originals_of(&self, leaves: Vec<u32>) -> Vec<Arc<Mesh>> {
        (leaves.into_iter())
            .map(|c| Arc::new(leaf_mesh(&self.scene, &self.pieces[self.kept_piece(c)])))
            .collect()
    }

    /// The static and pseudo-dynamic leaves below old cluster `id` and
    /// their triangles, when they are all of its leaves and have at most
    /// [`DIRECT_MAX_TRIANGLES`] triangles.
    fn leaves_below(&self, old: &Tree, id: u32) -> Option<(Vec<u32>, usize)> {
        let mut leaves = Vec::new();
        let mut stack = vec![id];
        let mut triangles = 0;
        while let Some(c) = stack.pop() {
            let children = old.children_of(c);
            if children.is_empty() {
                triangles += old.triangles_of(c) as usize;
                if triangles > DIRECT_MAX_TRIANGLES || c as usize >= self.leaves {
                    return None;
                }
                leaves.push(c);
            } else {
                stack.extend_from_slice(children);
            }
        }
        Some((leaves, triangles))
    }

    /// The new tree: the old clusters in their order but the `gone` ones,
    /// with the added leaves after the old ones, the changed clusters'
    /// geometry replaced, then the schedule pass over all of it.
    fn assemble(
        self,
        old: &Tree,
        config: &BuildConfig,
        remade: Remade,
        gone: &[bool],
        rebuilt: usize,
    ) -> Result<Updated> {
        let Remade {
            edited,
            added,
            joined,
            made,
            widened,
            chains,
            hierarchy,
            hierarchy_tops,
            tops,
            alone,
        } = remade;
        let n = old.cluster_count();
        // New ids: the old leaves that stay, the added leaves, the other
        // old clusters, the new chains, the root.
        let mut new_ids = vec![None; n];
        let mut next = 0u32;
        let mut number = |range: std::ops::Range<usize>, next: &mut u32| {
            for c in range.filter(|&c| !gone[c] && c != old.root as usize) {
                new_ids[c] = Some(*next);
                *next += 1;
            }
        };
        number(0..self.leaves, &mut next);
        let first_added = next;
        next += added.len() as u32;
        number(self.leaves..n, &mut next);
        let first_chain = next;
        let lone_parents: usize = alone.iter().map(|(_, c)| c.len()).sum();
        let first_grouped = first_chain + chains.len() as u32;
        new_ids[old.root as usize] = Some(first_grouped + (hierarchy.len() + lone_parents) as u32);
        let new_id = |c: u32| new_ids[c as usize];
        let scene = &self.scene;
        let span = scene.time.seconds;
        // Room for every cluster, the root last: growing a vector of
        // 180,000 records to push it copied them all.
        let total = first_grouped as usize + hierarchy.len() + lone_parents + 1;
        let mut clusters: Vec<Cluster> = Vec::with_capacity(total);
        let mut origin: Vec<Option<u32>> = Vec::with_capacity(total);
        let replace = |c: &mut Cluster, m: &Made| {
            c.bounds = Aabb::from_f32(m.lo, m.hi);
            c.w = f64::from((m.hi - m.lo).length());
            c.eps = m.eps;
            c.triangles = m.mesh.triangle_count() as u64;
            c.geometry = Some(m.hash.clone());
        };
        // The old clusters that stay, decoded from a mapped tree's index,
        // their children renumbered and their remade geometry put in, on
        // every core and straight into place: one by one, that was most of
        // the assembly. The root takes its new children below.
        let kept = |id: u32| {
            let mut c = old.cluster(id).into_owned();
            c.children = c.children.iter().filter_map(|&k| new_id(k)).collect();
            if let Some(a) = joined.get(&id) {
                c.children.extend(a.iter().map(|&a| first_added + a as u32));
            }
            if let Some(m) = edited.get(&id).or_else(|| made.get(&id)) {
                replace(&mut c, m);
            } else if let Some(w) = widened.get(&id) {
                c.bounds = Aabb::from_f32(w.lo, w.hi);
                c.w = f64::from((w.hi - w.lo).length());
                c.eps = w.eps;
            }
            c
        };
        let stay = |range: std::ops::Range<usize>| -> Vec<u32> {
            (range.start as u32..range.end as u32)
                .filter(|&c| c != old.root && new_id(c).is_some())
                .collect()
        };
        // In pieces of at most `PIECE`: decoding costs more for some
        // clusters than others, and in rayon's few large pieces one core
        // was left decoding alone for a third of the time.
        const PIECE: usize = 1024;
        let leaves = stay(0..self.leaves);
        clusters.par_extend(leaves.par_iter().with_max_len(PIECE).map(|&id| kept(id)));
        origin.extend(leaves.iter().map(|&id| Some(id)));
        for ((p, _), m) in self.added.iter().zip(&added) {
            let piece = &self.pieces[*p];
            let mut c = piece_record(piece, 0, Vec::new(), span);
            c.objects = vec![scene.objects[piece.object].id.clone()];
            replace(&mut c, m);
            clusters.push(c);
            origin.push(None);
        }
        let others = stay(self.leaves..n);
        clusters.par_extend(others.par_iter().with_max_len(PIECE).map(|&id| kept(id)));
        origin.extend(others.iter().map(|&id| Some(id)));
        clusters.extend(chains.iter().cloned().map(|mut c| {
            c.children.iter_mut().for_each(|k| *k += first_chain);
            c
        }));
        // The grouped added leaves' hierarchy: its leaves are the added ones.
        let leaves_added = self.added.len() as u32;
        let grouped_id = |k: u32| match k.checked_sub(leaves_added) {
            Some(k) => first_grouped + k,
            None => first_added + k,
        };
        clusters.extend(hierarchy.into_iter().map(|mut c| {
            c.children.iter_mut().for_each(|k| *k = grouped_id(*k));
            c
        }));
        origin.resize(clusters.len(), None);
        let mut alone_tops = Vec::new();
        for (a, parents) in &alone {
            let (p, _) = self.added[*a];
            let piece = &self.pieces[p];
            let mut below = first_added + *a as u32;
            for (level, m) in parents {
                let mut c = piece_record(piece, *level, vec![below], span);
                replace(&mut c, m);
                below = clusters.len() as u32;
                clusters.push(c);
                origin.push(None);
            }
            alone_tops.push(below);
        }
        let mut root = kept(old.root);
        root.children.extend(tops.iter().map(|&t| first_chain + t));
        root.children
            .extend(hierarchy_tops.iter().map(|&t| grouped_id(t)));
        root.children.extend(alone_tops);
        clusters.push(root);
        origin.push(Some(old.root));
        debug_assert_eq!(clusters.len(), total, "every cluster was counted");
        // The object tables are made on one core while the other numbers
        // the clusters and makes the schedule pass: the kept clusters'
        // objects read from the old tree, the new ones' from their records.
        let fresh = |c: &Cluster| (!c.objects.is_empty()).then(|| c.objects.clone());
        let added_range = first_added as usize..first_added as usize + added.len();
        let new_named: Vec<(u32, Vec<String>)> = (added_range.chain(first_chain as usize..total))
            .filter_map(|i| Some((i as u32, fresh(&clusters[i])?)))
            .collect();
        let kept_named = (0..n as u32)
            .filter(|&c| old.object_count_of(c) > 0)
            .filter_map(|c| Some((new_id(c)?, old.objects_of(c))));
        let named = kept_named
            .chain((new_named.iter()).map(|(i, o)| (*i, o.iter().map(String::as_str).collect())));
        // As `virtual_root` makes it, from its children's new boxes and
        // errors; on every core, before one of them makes the tables.
        let root = new_id(old.root).expect("the root stays");
        let (bounds, eps) = super::root_extent(&clusters, &clusters[root as usize].children);
        let stats = self.stats;
        let sources = self.sources;
        let split = Split {
            classes: self.classes,
            pieces: self.pieces,
        };
        let (objects, (skins, update)) = rayon::join(
            || ObjectTables::of_leaves(scene, named),
            || {
                for (i, c) in clusters.iter_mut().enumerate() {
                    c.id = i as u32;
                    c.parent = None;
                }
                set_parents(&mut clusters);
                {
                    let r = &mut clusters[root as usize];
                    r.bounds = bounds;
                    r.w = bounds.diagonal();
                    r.eps = eps;
                }
                // The clusters kept as they were hold the visibility of
                // their children: the schedule pass recomputes the others
                // and those above a change.
                let carried = Carried {
                    span: old.time.seconds,
                    clusters: Some(
                        origin
                            .par_iter()
                            .map(|o| {
                                o.is_some_and(|o| {
                                    !(edited.contains_key(&o)
                                        || made.contains_key(&o)
                                        || widened.contains_key(&o)
                                        || joined.contains_key(&o))
                                })
                            })
                            .collect(),
                    ),
                };
                let mut tree = super::tree_of(scene, bounds, root, clusters);
                tree.config = old.config.clone();
                tree.stats = serde_json::to_value(&stats).expect("the statistics serialise");
                tree.sources = Some(sources);
                // The skeletons are the dynamic leaves' objects', which the
                // pass keeps (it renumbers, and dissolves no leaf): made
                // beside it.
                let dynamic = super::skinned::dynamic_leaf_objects(&tree);
                rayon::join(
                    || super::skinned::skeletons_of(scene, &dynamic),
                    || update_schedule_of(tree, carried, scene, split, config),
                )
            },
        );
        match update {
            Update::Updated {
                mut tree,
                stats,
                dissolved,
                origin: passed,
            } => {
                // A dissolved group may come before a leaf, whose id then
                // changed; no leaf is dissolved.
                let objects = if dissolved == 0 {
                    objects
                } else {
                    let mut new_id = vec![u32::MAX; origin.len()];
                    for (i, &c) in passed.iter().enumerate() {
                        new_id[c as usize] = i as u32;
                    }
                    objects.renumbered(|c| new_id[c as usize])
                };
                tree.objects = Some(objects);
                tree.skins = skins;
                Ok(Updated {
                    tree: *tree,
                    stats,
                    rebuilt,
                    widened: widened.len(),
                    dropped: gone.iter().filter(|&&g| g).count(),
                    dissolved,
                    origin: passed.iter().map(|&c| origin[c as usize]).collect(),
                })
            }
            Update::Rebuild(why) => Err(Error::argument("scene", why)),
        }
    }
}

/// Old cluster `id`'s file as stored (its mesh in the node's frame) and
/// its hash.
fn stored_file(old: &Tree, old_dir: &Path, id: u32) -> Result<(Decoded, String)> {
    let hash = (old.cluster(id).geometry.clone())
        .ok_or_else(|| Error::argument("tree", format!("cluster {id} has no geometry")))?;
    let path = old.geometry_file(old_dir, &hash);
    let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    let decoded = crate::io::compact::decode(&bytes)
        .map_err(|message| Error::invalid(&path, "glb", message))?;
    Ok((decoded, hash))
}

/// A decoded file's mesh where the scene has it: moved by its node's
/// translation.
fn placed(decoded: Decoded) -> Mesh {
    let mut mesh = decoded.mesh;
    for p in &mut mesh.positions {
        *p += decoded.translation;
    }
    mesh
}

/// A leaf's `mesh` as its file stores it and [`stored_file`] reads it
/// back: its vertices welded and numbered as in the file, so that
/// [`displacement`] pairs them with those of the leaf's old file.
fn as_stored(mesh: &Mesh) -> Mesh {
    let (glb, _) = crate::io::glb::compact_mesh_to_glb(mesh, None, 0.0);
    placed(crate::io::compact::decode(&glb).expect("a GLB just written reads back"))
}

/// How an edited leaf's move is measured: the build's metric, and the
/// tolerance and the largest distance worth measuring (the top level's
/// budget).
struct Within {
    metric: ErrorMetric,
    tolerance: f32,
    budget: f32,
}

/// A bound of the Hausdorff distance between an edited leaf's geometry
/// `before` and `after`, its colours the same; infinite where they are not,
/// where the bound is over `within.budget`, or under the appearance
/// metric, whose colour regions a move that is not rigid may grow (the
/// clusters above are then made again). The same triangles over moved
/// vertices are bounded by the farthest vertex's move; others are
/// measured.
fn moved_by(before: &Mesh, after: &Mesh, within: &Within) -> f64 {
    let colours = |m: &Mesh| -> Vec<[u8; 4]> {
        m.colors
            .iter()
            .map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
            .collect()
    };
    let (was, now) = (colours(before), colours(after));
    let distinct = |c: &[[u8; 4]]| -> Vec<[u8; 4]> {
        let mut d = c.to_vec();
        d.sort_unstable();
        d.dedup();
        d
    };
    if within.metric != ErrorMetric::Geometry || distinct(&was) != distinct(&now) {
        return f64::INFINITY;
    }
    match displacement(before, after) {
        Some(far) if was == now => far,
        _ => crate::geometry::bound_within(
            before,
            after,
            within.tolerance,
            within.budget,
            within.metric,
        )
        .map_or(f64::INFINITY, f64::from),
    }
}

/// A bound of the Hausdorff distance between `before` and `after` when they
/// are the same triangles over the same vertices, each vertex perhaps
/// moved: a point of a triangle is the same weights of its corners in
/// both, so it moved at most as far as the farthest corner. `None` when
/// the triangles differ (a corner turned within its triangle still
/// counts as the same).
fn displacement(before: &Mesh, after: &Mesh) -> Option<f64> {
    if before.positions.len() != after.positions.len()
        || before.indices.len() != after.indices.len()
    {
        return None;
    }
    let same = |a: &[u32], b: &[u32]| a == b || a == [b[1], b[2], b[0]] || a == [b[2], b[0], b[1]];
    if !(before.indices.chunks_exact(3))
        .zip(after.indices.chunks_exact(3))
        .all(|(a, b)| same(a, b))
    {
        return None;
    }
    Some(farthest(&after.positions, &before.positions, Vec3::ZERO))
}

/// Each cluster's `parent` set from its parent's children list.
fn set_parents(clusters: &mut [Cluster]) {
    // Gathered into a small table first, then set on every core: set one
    // by one, each write missed the cache on records of 180,000 clusters.
    let mut parents: Vec<Option<u32>> = vec![None; clusters.len()];
    for (i, c) in clusters.iter().enumerate() {
        for &k in &c.children {
            parents[k as usize] = Some(i as u32);
        }
    }
    (clusters.par_iter_mut().zip(parents)).for_each(|(c, p)| {
        if p.is_some() {
            c.parent = p;
        }
    });
}

/// The leaves of an old tree.
struct OldLeaves<'a> {
    /// In order of id.
    ids: Vec<u32>,
    /// How many of them come first, as a build's static and pseudo-dynamic
    /// leaves do.
    leaves: usize,
    /// Each object's leaves.
    of_object: FxHashMap<&'a str, Vec<u32>>,
}

fn old_leaves(old: &Tree) -> std::result::Result<OldLeaves<'_>, String> {
    // The build's order: the static and pseudo-dynamic leaves first.
    let old_leaves: Vec<u32> = (0..old.cluster_count() as u32)
        .into_par_iter()
        .filter(|&c| old.children_of(c).is_empty() && old.class_of(c) != ClusterClass::Root)
        .collect();
    let leaves = old_leaves
        .iter()
        .take_while(|&&c| old.class_of(c) != ClusterClass::Dynamic)
        .count();
    if old_leaves[..leaves]
        .iter()
        .enumerate()
        .any(|(i, &c)| c as usize != i)
    {
        return Err("the tree's leaves are not in the build's order".into());
    }
    let mut leaves_of: FxHashMap<&str, Vec<u32>> =
        FxHashMap::with_capacity_and_hasher(old_leaves.len(), Default::default());
    for &leaf in &old_leaves {
        match old.sole_object(leaf) {
            Some(object) => leaves_of.entry(object).or_default().push(leaf),
            None => return Err(format!("leaf cluster {leaf} does not name one object")),
        }
    }
    Ok(OldLeaves {
        ids: old_leaves,
        leaves,
        of_object: leaves_of,
    })
}

/// The record of a cluster of `piece`'s class at `level` over `children`
/// (its leaf, or one of its lone parents): its geometry, box and errors
/// set by the caller, its visibility the piece's until the schedule pass.
fn piece_record(piece: &Piece, level: u32, children: Vec<u32>, span: f64) -> Cluster {
    Cluster {
        id: 0,
        parent: None,
        children,
        level,
        class: piece.cluster_class(),
        bounds: Aabb::from_f32(Vec3::ZERO, Vec3::ZERO),
        w: 0.0,
        eps: 0.0,
        gamma: 0.0,
        visibility: StepFunction::of_visibility(&piece.visibility, span).to_tree(),
        motion: None,
        geometry: None,
        triangles: 0,
        objects: Vec::new(),
    }
}

/// `child`'s own parent, reduced alone to `single` as the build stores it.
fn single_made(ctx: &Context, child: &Active, single: Single) -> Result<Made> {
    let Single { mesh, eps, .. } = single;
    let stored = ctx.sink.put(&mesh, None, eps * QUANTIZATION_SHARE)?;
    let (lo, hi) = bounds_of(std::slice::from_ref(child));
    let (lo, hi) = mesh
        .bounds()
        .map_or((lo, hi), |(l, h)| (l.min(lo), h.max(hi)));
    Ok(Made {
        mesh: Arc::new(mesh),
        eps: eps + stored.moved,
        lo,
        hi,
        hash: stored.hash,
        originals: child.originals.clone(),
        instance: None,
    })
}

fn active_of(m: Made) -> Active {
    Active {
        id: 0,
        lo: m.lo,
        hi: m.hi,
        w: f64::from((m.hi - m.lo).length()),
        eps: m.eps,
        steps: StepFunction::constant(1.0),
        vis: Vec::new(),
        mesh: m.mesh,
        baked: None,
        originals: m.originals,
        instance: m.instance,
        parts: Default::default(),
    }
}

/// A group made again from its children as the build makes it: their
/// union reduced within the level's budget.
fn remade(ctx: &Context, children: &[Active], th: &super::config::Thresholds) -> Result<Made> {
    let (lo, hi) = bounds_of(children);
    let group: Vec<usize> = (0..children.len()).collect();
    let parent = make_parent(ctx, children, &group, th)?;
    Ok(Made {
        mesh: Arc::new(parent.mesh),
        eps: parent.eps,
        lo,
        hi,
        hash: parent.hash,
        originals: parent.originals,
        instance: None,
    })
}

/// Lone children's own parents made again as the build makes them: each
/// reduced alone, new leaves of one shape sharing one reduction; where
/// that no longer pays, the child's geometry as it is.
fn lone_remade(
    ctx: &Context,
    lone: Vec<(u32, Vec<Active>)>,
    th: &super::config::Thresholds,
    progress: &dyn Progress,
) -> Result<Vec<(u32, Made)>> {
    let (ids, children): (Vec<u32>, Vec<Active>) = lone
        .into_iter()
        .map(|(c, mut a)| (c, a.pop().expect("one child")))
        .unzip();
    let all: Vec<usize> = (0..children.len()).collect();
    let singles = single_parents(ctx, &children, &all, th);
    ids.into_par_iter()
        .zip(children.par_iter())
        .zip(singles)
        .map(|((c, child), single)| {
            let out = match single {
                Some(single) => single_made(ctx, child, single)?,
                None => remade(ctx, std::slice::from_ref(child), th)?,
            };
            progress.advance(1);
            Ok((c, out))
        })
        .collect()
}
