//! The clusters as the cut reads them: one compact record each, in
//! breadth-first order from the root, so that a cluster's children are
//! consecutive records and its visibility steps one flat array. A
//! [`Cluster`](super::Cluster) spreads what the cut needs over four cache
//! lines and three heap blocks (children, steps, the record itself);
//! a server answers thousands of cuts a second, each visiting thousands of
//! clusters, and spent most of that time waiting on memory. The records are
//! plain old data: the serving index (`index.rs`) stores them as they are,
//! and a mapped tree's cut reads them in place.

use bytemuck::{Pod, Zeroable};

use super::index::{Index, NONE};
use super::{Aabb, Tree, delta};

#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct Node {
    pub bounds: Aabb,
    pub eps: f64,
    pub w: f64,
    /// The cluster's id in the tree.
    pub id: u32,
    /// Index of the first child's node; the children are consecutive.
    pub first_child: u32,
    pub child_count: u32,
    /// The visibility steps: `steps[first_step..first_step + step_count]`.
    pub first_step: u32,
    pub step_count: u32,
    /// 1 when the cluster has geometry (all but the root).
    pub has_geometry: u32,
    /// For a dynamic cluster, the id of the cluster whose motion it uses:
    /// the top of its LOD chain, whose levels all share one motion, so that
    /// the cut samples it once per chain. `u32::MAX` for the others.
    pub motion: u32,
    /// The cluster's triangles, which the cut adds up for every cluster it
    /// draws: here rather than read from the cluster's record, a second
    /// random read per drawn cluster. [`NONE`] when they do not fit (then
    /// read from the record). Version 3 of the index on; padding before.
    pub triangles: u32,
}

/// One visibility step: `v` from `t` on.
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct Step {
    pub t: f64,
    pub v: f32,
    _pad: u32,
}

impl Node {
    /// The cluster's triangles.
    #[inline]
    pub fn triangles(&self, tree: &Tree) -> u64 {
        if self.triangles == NONE {
            tree.triangles_of(self.id)
        } else {
            u64::from(self.triangles)
        }
    }

    /// As `Cluster::delta`.
    pub fn delta(&self, v: f32) -> f64 {
        delta(self.eps, self.w, v)
    }
}

#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct Nodes {
    pub nodes: Vec<Node>,
    /// Cluster id -> node index.
    pub node_of: Vec<u32>,
    /// Node index -> cluster id: a cluster's children are a slice of it.
    pub order: Vec<u32>,
    pub steps: Vec<Step>,
}

/// The cut's records, owned (a tree built or read from JSON) or mapped.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NodesRef<'a> {
    pub nodes: &'a [Node],
    pub node_of: &'a [u32],
    pub steps: &'a [Step],
}

impl Nodes {
    pub fn new(tree: &Tree) -> Nodes {
        let n = tree.cluster_count();
        let mut order: Vec<u32> = Vec::with_capacity(n);
        let mut node_of = vec![u32::MAX; n];
        order.push(tree.root);
        node_of[tree.root as usize] = 0;
        let mut next = 0;
        while next < order.len() {
            for &child in &tree.cluster(order[next]).children {
                node_of[child as usize] = order.len() as u32;
                order.push(child);
            }
            next += 1;
        }
        let mut steps = Vec::new();
        let nodes = order
            .iter()
            .map(|&id| {
                let c = tree.cluster(id);
                let first_step = steps.len() as u32;
                steps.extend(
                    c.visibility
                        .steps()
                        .iter()
                        .map(|&(t, v)| Step { t, v, _pad: 0 }),
                );
                Node {
                    bounds: c.bounds,
                    eps: c.eps,
                    w: c.w,
                    id,
                    first_child: c.children.first().map_or(0, |&f| node_of[f as usize]),
                    child_count: c.children.len() as u32,
                    first_step,
                    step_count: c.visibility.steps().len() as u32,
                    has_geometry: u32::from(c.geometry.is_some()),
                    motion: tree.motion_source(id).unwrap_or(NONE),
                    triangles: triangle_count(c.triangles),
                }
            })
            .collect();
        Nodes {
            nodes,
            node_of,
            order,
            steps,
        }
    }

    /// The records of an index older than version 3, whose nodes lack the
    /// triangle counts: copied, with the counts from the clusters' records.
    pub fn of_index(index: &Index) -> Nodes {
        let nodes = index
            .nodes()
            .iter()
            .map(|node| Node {
                triangles: triangle_count(index.triangles(node.id)),
                ..*node
            })
            .collect();
        Nodes {
            nodes,
            node_of: index.node_of().to_vec(),
            order: index.order().to_vec(),
            steps: index.steps().to_vec(),
        }
    }

    pub fn as_ref(&self) -> NodesRef<'_> {
        NodesRef {
            nodes: &self.nodes,
            node_of: &self.node_of,
            steps: &self.steps,
        }
    }
}

/// The most steps [`NodesRef::visibility`] counts rather than searches.
const LINEAR_STEPS: usize = 32;

impl NodesRef<'_> {
    /// `v_c(t)`, as `Steps::at`. The steps at or before `t` (increasing
    /// times: a prefix) are counted one by one when there are few (nine
    /// clusters in ten have one to three, the paper tree's have at most
    /// 32): the comparisons do not wait on each other as a binary
    /// search's do.
    #[inline]
    pub fn visibility(&self, node: &Node, t: f64) -> f32 {
        let steps =
            &self.steps[node.first_step as usize..(node.first_step + node.step_count) as usize];
        let i = if steps.len() <= LINEAR_STEPS {
            steps.iter().map(|s| usize::from(s.t <= t)).sum()
        } else {
            steps.partition_point(|s| s.t <= t)
        };
        if i == 0 { 0.0 } else { steps[i - 1].v }
    }
}

/// A cluster's triangles as a node stores them.
pub(crate) fn triangle_count(triangles: u64) -> u32 {
    u32::try_from(triangles).unwrap_or(NONE)
}
