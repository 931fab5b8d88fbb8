//! The HDLOD tree: the `hdlod-tree/1` format on disk ([`format`], [`store`]),
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
mod nodes;
pub mod objects;
pub mod presence;
pub mod store;

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DMat4, DVec3, Quat, Vec3};
use serde::Serialize;

use crate::error::{Error, Result};
use crate::scene::{Georeference, Keyframe, Motion, Up};
use crate::time::{TimeSpan, format_date, parse_date};

pub use baseline::Baseline;
pub use camera::{CameraSpec, View, Viewport};
pub use cut::{Cut, CutItem, CutStats, cut};
pub use format::ClusterClass;
pub use objects::ObjectTables;
pub use store::{TreeWriter, load};

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
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

    /// `delta_c(t) = eps_c + 2 w_c min(v, 1 - v)` (docs/method.md section 2).
    pub fn delta(&self, v: f32) -> f64 {
        delta(self.eps, self.w, v)
    }
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
    pub clusters: Vec<Cluster>,
    /// The object and task tables (`objects.json`), when the tree has them.
    /// The cut never reads them.
    pub objects: Option<ObjectTables>,
    /// The root's children by time, made on the first cut (the clusters
    /// must not change after it).
    pub(crate) presence: Derived<presence::Presence>,
    /// The cut's compact copy of the clusters, made on the first cut.
    pub(crate) nodes: Derived<nodes::Nodes>,
}

/// Data derived from a tree's clusters on first use: not part of what the
/// tree is, so any two compare equal.
#[derive(Debug, Clone, Default)]
pub(crate) struct Derived<T>(std::sync::OnceLock<T>);

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
            clusters,
            objects: None,
            presence: Derived::default(),
            nodes: Derived::default(),
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
        let mut c = self.clusters.get(cluster as usize)?;
        if c.class != ClusterClass::Dynamic {
            return None;
        }
        while let [child] = c.children[..] {
            c = &self.clusters[child as usize];
        }
        c.objects.first().map(String::as_str)
    }

    pub(crate) fn nodes(&self) -> &nodes::Nodes {
        self.nodes.0.get_or_init(|| nodes::Nodes::new(self))
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
    pub fn root(&self) -> &Cluster {
        &self.clusters[self.root as usize]
    }

    pub fn summary(&self) -> TreeSummary {
        let mut classes: BTreeMap<&'static str, usize> =
            ClusterClass::ALL.iter().map(|c| (c.name(), 0)).collect();
        let mut levels: BTreeMap<u32, LevelSummary> = BTreeMap::new();
        let (mut leaves, mut leaf_triangles) = (0, 0);
        for c in &self.clusters {
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
            if c.is_leaf() && c.class != ClusterClass::Root {
                leaves += 1;
                leaf_triangles += c.triangles;
            }
        }
        TreeSummary {
            clusters: self.clusters.len(),
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
        let n = self.clusters.len();
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
        for (i, c) in self.clusters.iter().enumerate() {
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
                    let ok = self
                        .clusters
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
                if self.clusters.get(ch as usize).and_then(|cc| cc.parent) != Some(c.id) {
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
            stack.extend_from_slice(&self.clusters[i as usize].children);
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
        let bounds = |b: &Aabb| format::BoundsRecord {
            min: b.min.to_array(),
            max: b.max.to_array(),
        };
        let manifest = format::ManifestRecord {
            format: format::FORMAT.into(),
            scene: self.scene.clone(),
            time: format::TimeRecord {
                start: format_date(self.time.start),
                end: format_date(self.time.end()),
                seconds: self.time.seconds,
            },
            bounds: bounds(&self.bounds),
            up: self.up,
            georeference: self.georeference,
            root: self.root,
            config: self.config.clone(),
            stats: self.stats.clone(),
        };
        let clusters = self
            .clusters
            .iter()
            .map(|c| format::ClusterRecord {
                id: c.id,
                parent: c.parent,
                children: c.children.clone(),
                level: c.level,
                class: c.class,
                bounds: bounds(&c.bounds),
                w: c.w,
                eps: c.eps,
                gamma: c.gamma,
                visibility: c
                    .visibility
                    .steps()
                    .iter()
                    .map(|&(t, v)| (t, f64::from(v)))
                    .collect(),
                motion: c.motion.as_ref().map(|m| {
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
            })
            .collect();
        (manifest, format::ClustersRecord { clusters })
    }

    /// The tree of on-disk records, validated. `dir` names the files in errors.
    pub fn from_records(
        manifest: format::ManifestRecord,
        clusters: format::ClustersRecord,
        dir: &Path,
    ) -> Result<Tree> {
        let mfile = dir.join(format::MANIFEST_FILE);
        let cfile = dir.join(format::CLUSTERS_FILE);
        if manifest.format != format::FORMAT {
            return Err(Error::invalid(
                &mfile,
                "format",
                format!("{:?} is not {:?}", manifest.format, format::FORMAT),
            ));
        }
        let start = parse_date(&manifest.time.start)
            .map_err(|m| Error::invalid(&mfile, "time.start", m.to_string()))?;
        let aabb =
            |b: format::BoundsRecord| Aabb::new(DVec3::from_array(b.min), DVec3::from_array(b.max));
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
            let motion = match r.motion {
                None => None,
                Some(keys) => {
                    if keys.windows(2).any(|w| w[0].t >= w[1].t) {
                        return Err(bad(
                            "motion",
                            "keyframe times must strictly increase".into(),
                        ));
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
                    Some(Motion::new(keys).map_err(|m| bad("motion", m.to_string()))?)
                }
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
        let tree = Tree {
            scene: manifest.scene,
            time: TimeSpan {
                start,
                seconds: manifest.time.seconds,
            },
            bounds: aabb(manifest.bounds),
            up: manifest.up,
            georeference: manifest.georeference,
            root: manifest.root,
            config: manifest.config,
            stats: manifest.stats,
            clusters: out,
            objects: None,
            presence: Derived::default(),
            nodes: Derived::default(),
        };
        tree.validate(&cfile)?;
        Ok(tree)
    }
}
