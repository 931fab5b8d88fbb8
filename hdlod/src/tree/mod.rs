//! The HDLOD tree: the `hdlod-tree/2` format on disk ([`format`], [`store`]),
//! the cut ([`camera`], [`cut`]) and, apart from what the cut reads, the
//! object and task tables ([`objects`]). [`Tree`] is the validated in-memory
//! form the builder produces and the cut reads: clusters in a `Vec` indexed
//! by id, visibility as sorted steps. The tests that need a whole tree (the
//! store, the cut, its presence index and baseline) run on the sample tree
//! of `hdlod-fixtures`, in `fixtures/tests/`.

pub mod baseline;
pub mod camera;
pub mod cut;
pub mod fidelity;
pub mod format;
pub mod index;
pub mod migrate;
mod nodes;
pub mod object_index;
pub mod objects;
mod objects_json;
pub mod presence;
mod sections;
pub mod skins;
pub mod sources;
pub mod store;
mod table;

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3, Mat4, Quat, Vec3};
use serde::Serialize;

use crate::error::{Error, Result};
use crate::scene::{Georeference, Keyframe, Motion, Up};
use crate::time::{TimeSpan, format_date, parse_date};

pub use baseline::Baseline;
pub use camera::{CameraSpec, View, Viewport};
pub use cut::{Cut, CutItem, CutStats, JointRange, cut};
pub use format::{ClusterClass, Layout};
pub use objects::ObjectTables;
pub use skins::{Skeleton, Skins};
pub use store::{TreeWriter, load};
pub use table::{OldTable, Previous};

/// An axis-aligned box. Plain old data: the cut's node records hold one.
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub fn new(min: DVec3, max: DVec3) -> Self {
        Aabb { min, max }
    }

    /// The box of single-precision bounds such as `Mesh::bounds` gives.
    pub fn from_f32(min: Vec3, max: Vec3) -> Self {
        Aabb::new(min.as_dvec3(), max.as_dvec3())
    }

    pub fn diagonal(&self) -> f64 {
        (self.max - self.min).length()
    }

    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb::new(self.min.min(other.min), self.max.max(other.max))
    }

    pub fn contains(&self, other: &Aabb, tolerance: f64) -> bool {
        (other.min - self.min).min_element() >= -tolerance
            && (self.max - other.max).min_element() >= -tolerance
    }

    /// The box moved by `m`: the bounds of its 8 moved corners.
    pub fn transformed(&self, m: &DMat4) -> Aabb {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for i in 0..8 {
            let corner = DVec3::new(
                if i & 1 == 0 { self.min.x } else { self.max.x },
                if i & 2 == 0 { self.min.y } else { self.max.y },
                if i & 4 == 0 { self.min.z } else { self.max.z },
            );
            let p = m.transform_point3(corner);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        Aabb::new(lo, hi)
    }
}

/// A fractional visibility `v_c(t)` as a step function: `v(t) = v_i` for the
/// last step with `t_i <= t`, 0 before the first step. Times strictly
/// increase and every value is in `[0, 1]`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Steps {
    steps: Vec<(f64, f32)>,
}

impl Steps {
    pub fn new(steps: Vec<(f64, f32)>) -> Result<Self> {
        for (i, &(t, v)) in steps.iter().enumerate() {
            if !t.is_finite() || !v.is_finite() {
                return Err(Error::value(format!("step {i} has a non-finite value")));
            }
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::value(format!(
                    "step {i}: value {v} is outside [0, 1]"
                )));
            }
            if i > 0 && steps[i - 1].0 >= t {
                return Err(Error::value(format!(
                    "step {i}: time {t} does not follow the one before"
                )));
            }
        }
        Ok(Steps { steps })
    }

    /// Visible at `value` from t = 0 on (a static cluster).
    pub fn constant(value: f32) -> Self {
        Steps {
            steps: vec![(0.0, value)],
        }
    }

    /// Steps known to be valid (read from a checked index).
    pub(crate) fn from_checked(steps: Vec<(f64, f32)>) -> Self {
        Steps { steps }
    }

    pub fn steps(&self) -> &[(f64, f32)] {
        &self.steps
    }

    pub fn at(&self, t: f64) -> f32 {
        step_at(&self.steps, t)
    }
}

/// The value of sorted steps `(t_i, v_i)` at `t`: 0 before the first.
pub(crate) fn step_at(steps: &[(f64, f32)], t: f64) -> f32 {
    let i = steps.partition_point(|s| s.0 <= t);
    if i == 0 { 0.0 } else { steps[i - 1].1 }
}

/// `delta_c(t) = eps_c + 2 w_c min(v, 1 - v)` (docs/method.md section 2).
pub(crate) fn delta(eps: f64, w: f64, v: f32) -> f64 {
    let v = f64::from(v);
    eps + 2.0 * w * v.min(1.0 - v)
}

/// One cluster `c = (g_c, v_c, p_c, b_c, w_c, eps_c, gamma_c)` of docs/method.md
/// section 2. `id` equals its index in [`Tree::clusters`].
#[derive(Debug, Clone, PartialEq)]
pub struct Cluster {
    pub id: u32,
    pub parent: Option<u32>,
    pub children: Vec<u32>,
    pub level: u32,
    pub class: ClusterClass,
    /// In the cluster's own frame for dynamic clusters, the world's otherwise.
    pub bounds: Aabb,
    pub w: f64,
    pub eps: f64,
    pub gamma: f64,
    pub visibility: Steps,
    /// Present exactly on dynamic clusters.
    pub motion: Option<Motion>,
    /// Blake3 hex of the GLB bytes; `None` only on the root.
    pub geometry: Option<String>,
    pub triangles: u64,
    /// The original objects of a leaf.
    pub objects: Vec<String>,
}

impl Cluster {
    pub fn is_leaf(&self) -> bool {
        self.children.is_empty()
    }

    /// True when `self` and `other` are the same record but for their ids
    /// (`id`, `parent`, `children`): every float compared by its bits, so
    /// that `0.0` and `-0.0`, which print differently, are not taken for
    /// one another. What lets an update copy a record's JSON (`table.rs`).
    pub(crate) fn same_content(&self, other: &Cluster) -> bool {
        let floats = |c: &Cluster| {
            let (lo, hi) = (c.bounds.min, c.bounds.max);
            [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z, c.w, c.eps, c.gamma].map(f64::to_bits)
        };
        fn steps(c: &Cluster) -> impl Iterator<Item = (u64, u32)> + '_ {
            c.visibility.steps().iter().map(|&s| step_bits(s))
        }
        fn keys(c: &Cluster) -> impl Iterator<Item = (u64, [u32; 10])> + '_ {
            (c.motion.iter())
                .flat_map(|m| m.keyframes())
                .map(keyframe_bits)
        }
        self.level == other.level
            && self.class == other.class
            && self.triangles == other.triangles
            && self.geometry == other.geometry
            && self.objects == other.objects
            && self.motion.is_some() == other.motion.is_some()
            && floats(self) == floats(other)
            && steps(self).eq(steps(other))
            && keys(self).eq(keys(other))
    }

    /// `delta_c(t) = eps_c + 2 w_c min(v, 1 - v)` (docs/method.md section 2).
    pub fn delta(&self, v: f32) -> f64 {
        delta(self.eps, self.w, v)
    }
}

/// How a cluster's record compares with another's ([`Tree::compare`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Match {
    /// The same, ids and all.
    Same,
    /// The same but the ids: `id`, `parent`, `children`, `motion_from`.
    SameButIds,
    Differs,
}

/// A visibility step's bits, for [`Cluster::same_content`].
pub(crate) fn step_bits((t, v): (f64, f32)) -> (u64, u32) {
    (t.to_bits(), v.to_bits())
}

/// A keyframe's bits, for [`Cluster::same_content`].
pub(crate) fn keyframe_bits(k: &Keyframe) -> (u64, [u32; 10]) {
    let (t, r, s) = (k.translation, k.rotation, k.scale);
    (
        k.t.to_bits(),
        [t.x, t.y, t.z, r.x, r.y, r.z, r.w, s.x, s.y, s.z].map(f32::to_bits),
    )
}

/// The whole tree as loaded or built.
#[derive(Debug, Clone, PartialEq)]
pub struct Tree {
    pub scene: String,
    pub time: TimeSpan,
    /// The scene's world bounds over the whole period.
    pub bounds: Aabb,
    pub up: Up,
    /// The scene's place on Earth, if it has one.
    pub georeference: Option<Georeference>,
    pub root: u32,
    pub config: serde_json::Value,
    pub stats: serde_json::Value,
    /// Where the geometry files of the tree as loaded lie (a built tree is
    /// written [`Layout::Sharded`]).
    pub layout: Layout,
    /// Read through [`Tree::cluster`] and [`Tree::clusters`].
    clusters: Clusters,
    /// The object and task tables (`objects.json`), when the tree has them.
    /// The cut never reads them.
    pub objects: Option<ObjectTables>,
    /// Per scene object, a digest of what its leaves are made of
    /// (`sources.bin`), when the tree has them: what a geometry update
    /// compares.
    pub sources: Option<Vec<sources::Digest>>,
    /// The skeletons of the skinned objects (`skins.json`), when the tree
    /// has any: what poses their chains' clusters at a time.
    pub skins: Option<Skins>,
    /// The root's children by time, made on the first cut (the clusters
    /// must not change after it).
    pub(crate) presence: Derived<presence::Presence>,
    /// The cut's compact copy of the clusters of a tree not mapped from
    /// its index, or mapped from an index older than version 3 (whose node
    /// records lack the triangle counts), made on the first cut.
    pub(crate) nodes: Derived<nodes::Nodes>,
    summary: Derived<TreeSummary>,
    baseline: Derived<Baseline>,
    /// Each cluster's [`Tree::motion_source`] (`u32::MAX` for none), made
    /// once for the writer's three readers of it (the cluster table, the
    /// index's keyframe ranges, the cut's nodes).
    motion_sources: Derived<Vec<u32>>,
    /// Each cluster's skeleton in `skins` (`u32::MAX` for none), made on
    /// first use.
    skin_sources: Derived<Vec<u32>>,
}

/// The clusters of a tree: built (or read from `clusters.json`) as
/// records, or mapped from the serving index (`clusters.bin`) and decoded
/// on demand.
// One per tree, read on every cut: the mapped index's section table
// inline (no box to follow) is worth the bytes the built form leaves unused.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
enum Clusters {
    Built(Vec<Cluster>),
    Mapped(index::Index),
}

impl PartialEq for Clusters {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Clusters::Built(a), Clusters::Built(b)) => a == b,
            _ => {
                self.len() == other.len()
                    && (0..self.len() as u32).all(|id| self.get(id) == other.get(id))
            }
        }
    }
}

impl Clusters {
    fn len(&self) -> usize {
        match self {
            Clusters::Built(v) => v.len(),
            Clusters::Mapped(index) => index.len(),
        }
    }

    fn get(&self, id: u32) -> Option<Cow<'_, Cluster>> {
        match self {
            Clusters::Built(v) => v.get(id as usize).map(Cow::Borrowed),
            Clusters::Mapped(index) => {
                ((id as usize) < index.len()).then(|| Cow::Owned(index.cluster(id)))
            }
        }
    }
}

/// Data derived from a tree's clusters on first use: not part of what the
/// tree is, so any two compare equal.
#[derive(Debug, Clone)]
pub(crate) struct Derived<T>(std::sync::OnceLock<T>);

impl<T> Default for Derived<T> {
    fn default() -> Self {
        Derived(std::sync::OnceLock::new())
    }
}

impl<T> PartialEq for Derived<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Tree {
    /// A tree of `clusters` under `root`, with empty `config` and `stats`
    /// for the maker to fill in. It is validated when written
    /// ([`TreeWriter::finish`]) or loaded; what the cut derives from the
    /// clusters is made on first use.
    pub fn new(
        scene: String,
        time: TimeSpan,
        bounds: Aabb,
        up: Up,
        root: u32,
        clusters: Vec<Cluster>,
    ) -> Tree {
        Tree {
            scene,
            time,
            bounds,
            up,
            georeference: None,
            root,
            config: serde_json::json!({}),
            stats: serde_json::json!({}),
            layout: Layout::default(),
            clusters: Clusters::Built(clusters),
            objects: None,
            sources: None,
            skins: None,
            presence: Derived::default(),
            nodes: Derived::default(),
            summary: Derived::default(),
            baseline: Derived::default(),
            motion_sources: Derived::default(),
            skin_sources: Derived::default(),
        }
    }

    /// The geometry file `hash` of this tree, loaded from `dir`.
    pub fn geometry_file(&self, dir: &Path, hash: &str) -> PathBuf {
        self.layout.geometry_file(dir, hash)
    }

    /// The tree mapped from its index, with the manifest's fields of
    /// `like` (read from the JSON manifest).
    pub(crate) fn mapped(like: Tree, index: index::Index) -> Tree {
        Tree {
            clusters: Clusters::Mapped(index),
            ..like
        }
    }

    pub fn cluster_count(&self) -> usize {
        self.clusters.len()
    }

    /// Cluster `id`, borrowed from a built tree or decoded from the index.
    /// Panics when there is none, as indexing does.
    pub fn cluster(&self, id: u32) -> Cow<'_, Cluster> {
        self.get_cluster(id)
            .unwrap_or_else(|| panic!("no cluster {id} in a tree of {}", self.cluster_count()))
    }

    pub fn get_cluster(&self, id: u32) -> Option<Cow<'_, Cluster>> {
        self.clusters.get(id)
    }

    /// How cluster `id`'s record compares with that of `c`, a cluster of a
    /// tree that replaces this one whose record names `motion_from`: read
    /// in place from a mapped tree's index rather than decoded.
    pub(crate) fn compare(&self, id: u32, c: &Cluster, motion_from: Option<u32>) -> Match {
        let (content, ids) = match &self.clusters {
            Clusters::Built(v) => {
                let old = &v[id as usize];
                (
                    old.same_content(c),
                    old.parent == c.parent && old.children == c.children,
                )
            }
            Clusters::Mapped(index) => (
                index.same_content(id, c),
                index.parent(id) == c.parent && index.children(id) == c.children.as_slice(),
            ),
        };
        let own_from = match &self.clusters {
            Clusters::Built(_) => self.motion_source(id),
            Clusters::Mapped(index) => index.motion_source(id),
        }
        .filter(|&s| s != id);
        match (content, ids && c.id == id && own_from == motion_from) {
            (false, _) => Match::Differs,
            (true, true) => Match::Same,
            (true, false) => Match::SameButIds,
        }
    }

    /// Every cluster in id order.
    pub fn clusters(&self) -> impl ExactSizeIterator<Item = Cow<'_, Cluster>> + '_ {
        (0..self.cluster_count() as u32).map(|id| self.cluster(id))
    }

    /// The clusters as records to edit (decoded first from the index of a
    /// mapped tree); what was derived from them is made again on use.
    pub fn clusters_mut(&mut self) -> &mut Vec<Cluster> {
        if let Clusters::Mapped(_) = self.clusters {
            self.clusters = Clusters::Built(self.clusters().map(Cow::into_owned).collect());
        }
        self.presence = Derived::default();
        self.nodes = Derived::default();
        self.summary = Derived::default();
        self.baseline = Derived::default();
        self.motion_sources = Derived::default();
        self.skin_sources = Derived::default();
        match &mut self.clusters {
            Clusters::Built(v) => v,
            Clusters::Mapped(_) => unreachable!("decoded above"),
        }
    }

    /// The index the clusters are mapped from, if they are.
    pub fn index(&self) -> Option<&index::Index> {
        match &self.clusters {
            Clusters::Mapped(index) => Some(index),
            Clusters::Built(_) => None,
        }
    }

    /// Cluster `id`'s class, without decoding it.
    pub fn class_of(&self, id: u32) -> ClusterClass {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].class,
            Clusters::Mapped(index) => index.class(id),
        }
    }

    pub fn level_of(&self, id: u32) -> u32 {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].level,
            Clusters::Mapped(index) => index.level(id),
        }
    }

    pub fn triangles_of(&self, id: u32) -> u64 {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].triangles,
            Clusters::Mapped(index) => index.triangles(id),
        }
    }

    pub fn children_of(&self, id: u32) -> &[u32] {
        match &self.clusters {
            Clusters::Built(v) => &v[id as usize].children,
            Clusters::Mapped(index) => index.children(id),
        }
    }

    /// The blake3 hex of cluster `id`'s GLB; `None` on the root.
    pub fn geometry_of(&self, id: u32) -> Option<Cow<'_, str>> {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].geometry.as_deref().map(Cow::Borrowed),
            Clusters::Mapped(index) => index.geometry(id).map(Cow::Owned),
        }
    }

    /// Appends [`Self::geometry_of`] to `out` without making a string of it
    /// (a cut answer writes thousands); nothing on the root.
    pub fn push_geometry_of(&self, id: u32, out: &mut Vec<u8>) {
        match &self.clusters {
            Clusters::Built(v) => {
                if let Some(hash) = &v[id as usize].geometry {
                    out.extend_from_slice(hash.as_bytes());
                }
            }
            Clusters::Mapped(index) => {
                if let Some(hash) = index.geometry_hash(id) {
                    index::push_hex(hash, out);
                }
            }
        }
    }

    /// The distinct geometry hashes of the clusters, as bytes: read from a
    /// mapped tree's index as they are stored.
    pub fn geometry_hashes(&self) -> Vec<[u8; 32]> {
        match &self.clusters {
            // On every core: an update asks it of 180,000 clusters.
            Clusters::Built(v) => {
                use rayon::prelude::*;
                let mut hashes: Vec<[u8; 32]> = (v.par_iter())
                    .filter_map(|c| c.geometry.as_deref().and_then(index::hash_bytes))
                    .collect();
                hashes.par_sort_unstable();
                hashes.dedup();
                hashes
            }
            Clusters::Mapped(index) => index.hashes().to_vec(),
        }
    }

    /// Whether some cluster's geometry is the GLB of hash `hash` (hex).
    /// A scan of the clusters or the index's distinct hashes: for the rare
    /// request whose file is missing, not for every one.
    pub fn names_geometry(&self, hash: &str) -> bool {
        let Some(bytes) = index::hash_bytes(hash) else {
            return false;
        };
        match &self.clusters {
            Clusters::Built(v) => v.iter().any(|c| c.geometry.as_deref() == Some(hash)),
            Clusters::Mapped(index) => index.hashes().contains(&bytes),
        }
    }

    /// The first object a leaf names.
    fn first_object(&self, id: u32) -> Option<&str> {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].objects.first().map(String::as_str),
            Clusters::Mapped(index) => index.objects(id).next(),
        }
    }

    /// The objects cluster `id` names, without decoding it.
    pub fn objects_of(&self, id: u32) -> Vec<&str> {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].objects.iter().map(String::as_str).collect(),
            Clusters::Mapped(index) => index.objects(id).collect(),
        }
    }

    /// The one object cluster `id` names, if it names one (as a leaf
    /// does), without decoding it.
    pub(crate) fn sole_object(&self, id: u32) -> Option<&str> {
        match &self.clusters {
            Clusters::Built(v) => match &v[id as usize].objects[..] {
                [object] => Some(object),
                _ => None,
            },
            Clusters::Mapped(index) => {
                let mut objects = index.objects(id);
                objects.next().filter(|_| objects.next().is_none())
            }
        }
    }

    /// The number of objects cluster `id` names, without decoding it.
    pub(crate) fn object_count_of(&self, id: u32) -> usize {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].objects.len(),
            Clusters::Mapped(index) => index.object_count(id),
        }
    }

    /// Whether cluster `id` names object `object`, without decoding it.
    pub(crate) fn names_object(&self, id: u32, object: &str) -> bool {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize].objects.iter().any(|o| o == object),
            Clusters::Mapped(index) => index.objects(id).any(|o| o == object),
        }
    }

    /// What the summary and the baseline read of cluster `id`, without
    /// decoding it.
    pub(crate) fn facts(&self, id: u32) -> Facts<'_> {
        match &self.clusters {
            Clusters::Built(v) => {
                let c = &v[id as usize];
                Facts {
                    class: c.class,
                    level: c.level,
                    triangles: c.triangles,
                    eps: c.eps,
                    gamma: c.gamma,
                    leaf: c.is_leaf(),
                    geometry: c.geometry.is_some(),
                    objects: c.objects.len(),
                    steps: StepsOf::Built(c.visibility.steps().iter()),
                }
            }
            Clusters::Mapped(index) => Facts {
                class: index.class(id),
                level: index.level(id),
                triangles: index.triangles(id),
                eps: index.eps(id),
                gamma: index.gamma(id),
                leaf: index.children(id).is_empty(),
                geometry: index.has_geometry(id),
                objects: index.object_count(id),
                steps: StepsOf::Mapped(index.visibility(id).iter()),
            },
        }
    }

    /// The pose at `t` of dynamic cluster `id`.
    pub(crate) fn pose_at(&self, id: u32, t: f64) -> Mat4 {
        match &self.clusters {
            Clusters::Built(v) => v[id as usize]
                .motion
                .as_ref()
                .expect("a motion source has a motion")
                .at(t),
            Clusters::Mapped(index) => index.sample(id, t).matrix(),
        }
    }

    /// See [`presence`].
    pub fn presence(&self) -> &presence::Presence {
        self.presence
            .0
            .get_or_init(|| presence::Presence::new(self))
    }

    /// The object (its index in the scene and the object table) whose
    /// geometry a dynamic cluster is: its chain shares one GLB among every
    /// instance of a model, so the GLB carries no feature ids and the tree
    /// names the object (its chain's leaf). `None` for the other clusters,
    /// whose GLBs carry them, and for a tree without object tables.
    pub fn dynamic_object(&self, cluster: u32) -> Option<u32> {
        self.objects
            .as_ref()?
            .object_index(self.dynamic_object_id(cluster)?)
    }

    /// The id of the object dynamic cluster `cluster` is: its chain's
    /// leaf's (each level of a chain has one child). `None` for the other
    /// clusters.
    pub fn dynamic_object_id(&self, cluster: u32) -> Option<&str> {
        if (cluster as usize) >= self.cluster_count()
            || self.class_of(cluster) != ClusterClass::Dynamic
        {
            return None;
        }
        let mut c = cluster;
        while let [child] = self.children_of(c)[..] {
            c = child;
        }
        self.first_object(c)
    }

    /// The skeleton that poses cluster `id`, when it is a level of a
    /// skinned object's chain.
    pub fn skeleton_of(&self, id: u32) -> Option<&Skeleton> {
        let skins = self.skins.as_ref().filter(|s| !s.is_empty())?;
        let sources = self.skin_sources.0.get_or_init(|| {
            (0..self.cluster_count() as u32)
                .map(|c| {
                    self.dynamic_object_id(c)
                        .and_then(|o| skins.position(o))
                        .map_or(u32::MAX, |k| k as u32)
                })
                .collect()
        });
        let k = *sources.get(id as usize)?;
        (k != u32::MAX).then(|| skins.at(k as usize))
    }

    pub(crate) fn nodes(&self) -> nodes::NodesRef<'_> {
        match &self.clusters {
            Clusters::Mapped(index) if index.version() >= 3 => nodes::NodesRef {
                nodes: index.nodes(),
                node_of: index.node_of(),
                steps: index.steps(),
            },
            Clusters::Mapped(index) => self
                .nodes
                .0
                .get_or_init(|| nodes::Nodes::of_index(index))
                .as_ref(),
            Clusters::Built(_) => self
                .nodes
                .0
                .get_or_init(|| nodes::Nodes::new(self))
                .as_ref(),
        }
    }

    /// What every present original object costs over time
    /// ([`Baseline::of`]), made once, or as the index stores it.
    pub fn baseline(&self) -> &Baseline {
        self.baseline.0.get_or_init(|| {
            self.index()
                .and_then(index::Index::baseline)
                .unwrap_or_else(|| Baseline::of(self))
        })
    }
}

/// What is read of a cluster for the tree's counts and baseline.
pub(crate) struct Facts<'a> {
    pub class: ClusterClass,
    pub level: u32,
    pub triangles: u64,
    pub eps: f64,
    pub gamma: f64,
    pub leaf: bool,
    pub geometry: bool,
    pub objects: usize,
    pub steps: StepsOf<'a>,
}

/// A cluster's visibility steps `(t, v)`, from either form.
pub(crate) enum StepsOf<'a> {
    Built(std::slice::Iter<'a, (f64, f32)>),
    Mapped(std::slice::Iter<'a, nodes::Step>),
}

impl Iterator for StepsOf<'_> {
    type Item = (f64, f32);

    fn next(&mut self) -> Option<(f64, f32)> {
        match self {
            StepsOf::Built(steps) => steps.next().copied(),
            StepsOf::Mapped(steps) => steps.next().map(|s| (s.t, s.v)),
        }
    }
}

/// Counts of a tree for listings and `inspect`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TreeSummary {
    pub clusters: usize,
    pub leaves: usize,
    pub leaf_triangles: u64,
    /// Clusters per class name (`root`, `static`, `pseudo_dynamic`, `dynamic`).
    pub classes: BTreeMap<&'static str, usize>,
    pub levels: Vec<LevelSummary>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LevelSummary {
    pub level: u32,
    pub clusters: usize,
    pub triangles: u64,
    pub max_eps: f64,
    pub max_gamma: f64,
}

/// 64 lowercase hexadecimal digits: a blake3 hash as the store names blobs.
pub fn is_hash(text: &str) -> bool {
    text.len() == 64 && text.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

impl Tree {
    pub fn root(&self) -> Cow<'_, Cluster> {
        self.cluster(self.root)
    }

    /// The tree's counts, made once, or as the index stores them.
    pub fn summary(&self) -> TreeSummary {
        self.summary
            .0
            .get_or_init(|| {
                self.index()
                    .and_then(index::Index::summary)
                    .unwrap_or_else(|| self.counted_summary())
            })
            .clone()
    }

    /// The counts made from the clusters, whether or not an index stores
    /// them.
    pub fn counted_summary(&self) -> TreeSummary {
        let mut classes: BTreeMap<&'static str, usize> =
            ClusterClass::ALL.iter().map(|c| (c.name(), 0)).collect();
        let mut levels: BTreeMap<u32, LevelSummary> = BTreeMap::new();
        let (mut leaves, mut leaf_triangles) = (0, 0);
        for id in 0..self.cluster_count() as u32 {
            let c = self.facts(id);
            *classes.entry(c.class.name()).or_default() += 1;
            let l = levels.entry(c.level).or_insert(LevelSummary {
                level: c.level,
                clusters: 0,
                triangles: 0,
                max_eps: 0.0,
                max_gamma: 0.0,
            });
            l.clusters += 1;
            l.triangles += c.triangles;
            l.max_eps = l.max_eps.max(c.eps);
            l.max_gamma = l.max_gamma.max(c.gamma);
            if c.leaf && c.class != ClusterClass::Root {
                leaves += 1;
                leaf_triangles += c.triangles;
            }
        }
        TreeSummary {
            clusters: self.cluster_count(),
            leaves,
            leaf_triangles,
            classes,
            levels: levels.into_values().collect(),
        }
    }

    /// Checks every invariant of the format except the presence of the
    /// geometry files (the store does that). `file` names the cluster table
    /// in errors.
    pub fn validate(&self, file: &Path) -> Result<()> {
        let n = self.cluster_count();
        let bad = |i: usize, field: &str, msg: String| {
            Error::invalid(file, format!("clusters[{i}].{field}"), msg)
        };
        if n == 0 {
            return Err(Error::invalid(file, "clusters", "the tree has no clusters"));
        }
        if n > u32::MAX as usize {
            return Err(Error::invalid(file, "clusters", "too many clusters"));
        }
        if self.root as usize >= n {
            return Err(Error::invalid(
                file,
                "manifest.root",
                format!("root {} is not a cluster id", self.root),
            ));
        }
        if !self.time.seconds.is_finite() || self.time.seconds < 0.0 {
            return Err(Error::invalid(
                file,
                "manifest.time.seconds",
                "must be a finite number >= 0",
            ));
        }
        if !self.bounds.min.is_finite() || !self.bounds.max.is_finite() {
            return Err(Error::invalid(file, "manifest.bounds", "non-finite bounds"));
        }
        // A mapped tree's index was checked, every invariant, when opened.
        let Clusters::Built(clusters) = &self.clusters else {
            return Ok(());
        };
        // Each cluster checked against its neighbours on every core; the
        // error reported is the lowest cluster's, as a loop would find.
        use rayon::prelude::*;
        let check = |i: usize, c: &Cluster| -> Result<()> {
            if c.id as usize != i {
                return Err(bad(
                    i,
                    "id",
                    format!(
                        "id {} is not its index {i}: ids must be unique and dense 0..{n}",
                        c.id
                    ),
                ));
            }
            let is_root = c.class == ClusterClass::Root;
            if is_root != (i == self.root as usize) {
                return Err(bad(
                    i,
                    "class",
                    format!(
                        "only the manifest's root ({}) has class \"root\"",
                        self.root
                    ),
                ));
            }
            match c.parent {
                None if !is_root => {
                    return Err(bad(i, "parent", "only the root has no parent".into()));
                }
                Some(_) if is_root => {
                    return Err(bad(i, "parent", "the root has no parent".into()));
                }
                Some(p) => {
                    let ok = clusters
                        .get(p as usize)
                        .is_some_and(|pc| pc.children.contains(&c.id));
                    if !ok {
                        return Err(bad(
                            i,
                            "parent",
                            format!("cluster {p} does not list {i} among its children"),
                        ));
                    }
                }
                None => {}
            }
            for &ch in &c.children {
                if clusters.get(ch as usize).and_then(|cc| cc.parent) != Some(c.id) {
                    return Err(bad(
                        i,
                        "children",
                        format!("child {ch} does not name {i} as its parent"),
                    ));
                }
            }
            if !c.bounds.min.is_finite()
                || !c.bounds.max.is_finite()
                || c.bounds.min.cmpgt(c.bounds.max).any()
            {
                return Err(bad(
                    i,
                    "bounds",
                    "bounds must be finite with min <= max".into(),
                ));
            }
            for (field, x) in [("w", c.w), ("eps", c.eps), ("gamma", c.gamma)] {
                if !x.is_finite() || x < 0.0 {
                    return Err(bad(i, field, format!("{x} is not a finite number >= 0")));
                }
            }
            if (c.class == ClusterClass::Dynamic) != c.motion.is_some() {
                return Err(bad(
                    i,
                    "motion",
                    "dynamic clusters, and only they, have a motion".into(),
                ));
            }
            match &c.geometry {
                None if !is_root => {
                    return Err(bad(i, "geometry", "only the root has no geometry".into()));
                }
                Some(_) if is_root => {
                    return Err(bad(i, "geometry", "the root has no geometry".into()));
                }
                Some(h) if !is_hash(h) => {
                    return Err(bad(
                        i,
                        "geometry",
                        format!("{h:?} is not a blake3 hex hash"),
                    ));
                }
                _ => {}
            }
            Ok(())
        };
        if let Some(e) = clusters
            .par_iter()
            .enumerate()
            .find_map_first(|(i, c)| check(i, c).err())
        {
            return Err(e);
        }
        // Every cluster has one parent that lists it; all reachable from the
        // root means there is no cycle and no stray subtree.
        let mut stack = vec![self.root];
        let mut reached = 0usize;
        while let Some(i) = stack.pop() {
            reached += 1;
            if reached > n {
                break;
            }
            stack.extend_from_slice(&clusters[i as usize].children);
        }
        if reached != n {
            return Err(Error::invalid(
                file,
                "clusters",
                "not every cluster hangs under the root (a cycle or a stray subtree)",
            ));
        }
        Ok(())
    }

    /// The on-disk records of this tree.
    pub fn to_records(&self) -> (format::ManifestRecord, format::ClustersRecord) {
        let clusters = (0..self.cluster_count() as u32)
            .map(|id| self.cluster_record(id))
            .collect();
        (self.manifest_record(), format::ClustersRecord { clusters })
    }

    /// The record of `manifest.json`, in the format the writer writes
    /// (whatever the layout the tree was loaded from).
    pub fn manifest_record(&self) -> format::ManifestRecord {
        format::ManifestRecord {
            format: format::FORMAT.into(),
            scene: self.scene.clone(),
            time: format::TimeRecord {
                start: format_date(self.time.start),
                end: format_date(self.time.end()),
                seconds: self.time.seconds,
            },
            bounds: bounds_record(&self.bounds),
            up: self.up,
            georeference: self.georeference,
            root: self.root,
            config: self.config.clone(),
            stats: self.stats.clone(),
        }
    }

    /// The highest ancestor of `id` (itself included) with the same
    /// keyframes as `id`, when it has a motion: the top of its LOD chain,
    /// whose keyframes the chain shares (the cut samples them once, and
    /// `clusters.json` holds them once).
    pub(crate) fn motion_source(&self, id: u32) -> Option<u32> {
        let sources = self.motion_sources.0.get_or_init(|| {
            let n = self.cluster_count();
            let mut sources = vec![u32::MAX; n];
            // From the last id down: a built tree numbers parents after
            // their children, so a parent's source is known before its
            // children's, and a chain's keyframes are compared once a link
            // rather than once a pair of links (tens of milliseconds at
            // paper scale, twice per write). A parent numbered before its
            // child is walked up from.
            for id in (0..n as u32).rev() {
                let c = self.cluster(id);
                let Some(motion) = c.motion.as_ref() else {
                    continue;
                };
                let same = |p: u32| self.cluster(p).motion.as_ref() == Some(motion);
                sources[id as usize] = match c.parent {
                    Some(p) if p > id && same(p) => sources[p as usize],
                    Some(p) if same(p) => {
                        let mut source = p;
                        while let Some(parent) = self.cluster(source).parent
                            && same(parent)
                        {
                            source = parent;
                        }
                        source
                    }
                    _ => id,
                };
            }
            sources
        });
        Some(sources[id as usize]).filter(|&s| s != u32::MAX)
    }

    /// The record of cluster `id` in `clusters.json`: a cluster that shares
    /// its keyframes with the top of its LOD chain names it
    /// (`motion_from`) rather than repeating them.
    pub fn cluster_record(&self, id: u32) -> format::ClusterRecord {
        let c = self.cluster(id);
        let motion_from = self.motion_source(id).filter(|&s| s != id);
        format::ClusterRecord {
            id: c.id,
            parent: c.parent,
            children: c.children.clone(),
            level: c.level,
            class: c.class,
            bounds: bounds_record(&c.bounds),
            w: c.w,
            eps: c.eps,
            gamma: c.gamma,
            visibility: c
                .visibility
                .steps()
                .iter()
                .map(|&(t, v)| (t, f64::from(v)))
                .collect(),
            motion_from,
            motion: c
                .motion
                .as_ref()
                .filter(|_| motion_from.is_none())
                .map(|m| {
                    m.keyframes()
                        .iter()
                        .map(|k| format::KeyframeRecord {
                            t: k.t,
                            translation: k.translation.to_array(),
                            rotation: k.rotation.to_array(),
                            scale: k.scale.to_array(),
                        })
                        .collect()
                }),
            geometry: c.geometry.clone(),
            triangles: c.triangles,
            objects: c.objects.clone(),
        }
    }

    /// The tree of on-disk records, validated. `dir` names the files in errors.
    pub fn from_records(
        manifest: format::ManifestRecord,
        clusters: format::ClustersRecord,
        dir: &Path,
    ) -> Result<Tree> {
        let cfile = dir.join(format::CLUSTERS_FILE);
        let aabb =
            |b: format::BoundsRecord| Aabb::new(DVec3::from_array(b.min), DVec3::from_array(b.max));
        let mut tree = Tree::from_manifest(manifest, dir)?;
        // The keyframes of the clusters others share (`motion_from`), made
        // first: a chain's top comes after the clusters below it.
        let shared: std::collections::HashSet<u32> = clusters
            .clusters
            .iter()
            .filter_map(|r| r.motion_from)
            .collect();
        let mut sources: std::collections::HashMap<u32, Motion> = Default::default();
        for (i, r) in clusters.clusters.iter().enumerate() {
            if shared.contains(&r.id)
                && let Some(keys) = &r.motion
            {
                let at = format!("clusters[{i}].motion");
                sources.insert(
                    r.id,
                    motion_of(keys).map_err(|m| Error::invalid(&cfile, at, m))?,
                );
            }
        }
        let mut out = Vec::with_capacity(clusters.clusters.len());
        for (i, r) in clusters.clusters.into_iter().enumerate() {
            let bad = |field: &str, msg: String| {
                Error::invalid(&cfile, format!("clusters[{i}].{field}"), msg)
            };
            let steps = r
                .visibility
                .iter()
                .map(|&(t, v)| (t, v as f32))
                .collect::<Vec<_>>();
            let visibility = Steps::new(steps).map_err(|m| bad("visibility", m.to_string()))?;
            let motion = match (r.motion, r.motion_from) {
                (None, None) => None,
                (Some(_), Some(_)) => {
                    return Err(bad(
                        "motion_from",
                        "a cluster has its own keyframes or shares another's, not both".into(),
                    ));
                }
                (None, Some(from)) => Some(sources.get(&from).cloned().ok_or_else(|| {
                    bad(
                        "motion_from",
                        format!("cluster {from} has no keyframes of its own to share"),
                    )
                })?),
                (Some(keys), None) => match sources.get(&r.id).cloned() {
                    Some(m) => Some(m),
                    None => Some(motion_of(&keys).map_err(|m| bad("motion", m))?),
                },
            };
            out.push(Cluster {
                id: r.id,
                parent: r.parent,
                children: r.children,
                level: r.level,
                class: r.class,
                bounds: aabb(r.bounds),
                w: r.w,
                eps: r.eps,
                gamma: r.gamma,
                visibility,
                motion,
                geometry: r.geometry,
                triangles: r.triangles,
                objects: r.objects,
            });
        }
        tree.clusters = Clusters::Built(out);
        tree.validate(&cfile)?;
        Ok(tree)
    }

    /// A tree of the manifest's fields and no clusters yet.
    pub(crate) fn from_manifest(manifest: format::ManifestRecord, dir: &Path) -> Result<Tree> {
        let mfile = dir.join(format::MANIFEST_FILE);
        let layout = layout_of(&manifest, &mfile)?;
        let start = parse_date(&manifest.time.start)
            .map_err(|m| Error::invalid(&mfile, "time.start", m.to_string()))?;
        let aabb =
            |b: format::BoundsRecord| Aabb::new(DVec3::from_array(b.min), DVec3::from_array(b.max));
        let mut tree = Tree::new(
            manifest.scene,
            TimeSpan {
                start,
                seconds: manifest.time.seconds,
            },
            aabb(manifest.bounds),
            manifest.up,
            manifest.root,
            Vec::new(),
        );
        tree.georeference = manifest.georeference;
        tree.layout = layout;
        tree.config = manifest.config;
        tree.stats = manifest.stats;
        Ok(tree)
    }

    /// Maps a mapped tree's index afresh, so that the pages read while
    /// loading are not kept resident (what was derived from them stays).
    pub(crate) fn remap(&mut self) -> Result<()> {
        if let Clusters::Mapped(index) = &self.clusters {
            self.clusters = Clusters::Mapped(index.remap()?);
        }
        Ok(())
    }
}

/// The geometry layout of a tree whose manifest, read from `path`, is
/// `manifest`; an error for a format this reader does not read.
pub(crate) fn layout_of(manifest: &format::ManifestRecord, path: &Path) -> Result<Layout> {
    Layout::of_format(&manifest.format).ok_or_else(|| {
        Error::invalid(
            path,
            "format",
            format!(
                "{:?} is not {:?} nor {:?}",
                manifest.format,
                format::FORMAT,
                format::FORMAT_FLAT
            ),
        )
    })
}

/// The motion of a cluster record's keyframes.
fn motion_of(keys: &[format::KeyframeRecord]) -> std::result::Result<Motion, String> {
    if keys.windows(2).any(|w| w[0].t >= w[1].t) {
        return Err("keyframe times must strictly increase".into());
    }
    let keys = keys
        .iter()
        .map(|k| Keyframe {
            t: k.t,
            translation: Vec3::from_array(k.translation),
            rotation: Quat::from_array(k.rotation),
            scale: Vec3::from_array(k.scale),
        })
        .collect();
    Motion::new(keys).map_err(|m| m.to_string())
}

fn bounds_record(b: &Aabb) -> format::BoundsRecord {
    format::BoundsRecord {
        min: b.min.to_array(),
        max: b.max.to_array(),
    }
}
