//! What every stage of the build shares: the build's context, a cluster
//! while the level above it is made (`Active`), and the one place a
//! cluster record is written (`Node`, `add`).

use std::sync::{Arc, Mutex, OnceLock};

use glam::Vec3;

use super::config::BuildConfig;
use super::instances::Instance;
use super::outputs::GeometrySink;
use super::steps::StepFunction;
use crate::geometry::bake::{Baked, Source};
use crate::geometry::{Mesh, Parts};
use crate::scene::Motion;
use crate::tree::{Aabb, Cluster, ClusterClass};

pub(super) struct Context<'a> {
    pub config: &'a BuildConfig,
    pub span: f64,
    /// Distinct 0/1 visibility functions of the leaves.
    pub leaf_steps: Vec<StepFunction>,
    pub sink: &'a dyn GeometrySink,
    /// The leaves' repeated shapes, at the origin (`instances`).
    pub shapes: Vec<Arc<Mesh>>,
}

/// A cluster while its level is being built: what the next level needs.
pub(super) struct Active {
    pub id: u32,
    pub lo: Vec3,
    pub hi: Vec3,
    pub w: f64,
    pub eps: f64,
    pub steps: StepFunction,
    /// Ids of the distinct leaf visibility functions below (sorted): the
    /// temporal error is a maximum over these, and objects of one task
    /// share one, so this stays short.
    pub vis: Vec<u32>,
    /// Dropped once the cluster has a parent: memory stays bounded by one
    /// level's geometry (and the originals below kept for the direct
    /// bound, `parent::stored_eps`).
    pub mesh: Arc<Mesh>,
    /// The colour baked into `mesh` where it dropped detail, when it was
    /// (`parent::bake_colour`); dropped with the mesh.
    pub baked: Option<Arc<Baked>>,
    /// The original objects' geometry below, while it has at most
    /// `parent::DIRECT_MAX_TRIANGLES` triangles.
    pub originals: Option<Vec<Arc<Mesh>>>,
    /// A leaf's shape and place, when other leaves share the shape.
    pub instance: Option<Instance>,
    /// Its mesh's parts and what their stand-ins measured, once it has been
    /// reduced alone (`parent::single_parent`): kept while it stays alone.
    pub parts: OnceLock<Mutex<Parts<Arc<Mesh>>>>,
}

/// The box around the boxes of `children`.
pub(super) fn bounds_of<'a>(children: impl IntoIterator<Item = &'a Active>) -> (Vec3, Vec3) {
    children.into_iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), c| (lo.min(c.lo), hi.max(c.hi)),
    )
}

impl Active {
    /// The cluster's geometry as a surface to bake colour from.
    pub fn source(&self) -> Source<'_> {
        Source {
            mesh: &self.mesh,
            baked: self.baked.as_deref(),
        }
    }
}

/// A cluster record before it has an id. `Node::new` sets what every
/// cluster has; the rest is zero or empty until the caller sets it.
pub(super) struct Node {
    pub class: ClusterClass,
    pub level: u32,
    pub bounds: Aabb,
    pub w: f64,
    pub visibility: crate::tree::Steps,
    pub eps: f64,
    pub gamma: f64,
    pub children: Vec<u32>,
    pub motion: Option<Motion>,
    /// The content hash and triangle count of the stored geometry.
    pub geometry: Option<(String, u64)>,
    pub objects: Vec<String>,
}

impl Node {
    /// `w` is the diagonal of the box as the builder measures it, in `f32`
    /// like the geometry it comes from.
    pub fn new(
        class: ClusterClass,
        level: u32,
        (lo, hi): (Vec3, Vec3),
        visibility: &StepFunction,
    ) -> Node {
        Node {
            class,
            level,
            bounds: Aabb::from_f32(lo, hi),
            w: f64::from((hi - lo).length()),
            visibility: visibility.to_tree(),
            eps: 0.0,
            gamma: 0.0,
            children: Vec::new(),
            motion: None,
            geometry: None,
            objects: Vec::new(),
        }
    }
}

/// Appends `node` to `clusters` as the parent of its children; answers
/// its id, which is its index.
pub(super) fn add(clusters: &mut Vec<Cluster>, node: Node) -> u32 {
    let id = clusters.len() as u32;
    for &c in &node.children {
        clusters[c as usize].parent = Some(id);
    }
    let (geometry, triangles) = node.geometry.map_or((None, 0), |(h, n)| (Some(h), n));
    clusters.push(Cluster {
        id,
        parent: None,
        children: node.children,
        level: node.level,
        class: node.class,
        bounds: node.bounds,
        w: node.w,
        eps: node.eps,
        gamma: node.gamma,
        visibility: node.visibility,
        motion: node.motion,
        geometry,
        triangles,
        objects: node.objects,
    });
    id
}
