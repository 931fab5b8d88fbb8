//! The clusters as the cut reads them: one compact record each, in
//! breadth-first order from the root, so that a cluster's children are
//! consecutive records and its visibility steps one flat array. A
//! [`Cluster`](super::Cluster) spreads what the cut needs over four cache
//! lines and three heap blocks (children, steps, the record itself);
//! a server answers thousands of cuts a second, each visiting thousands of
//! clusters, and spent most of that time waiting on memory.

use glam::DVec3;

use super::{Aabb, Tree, delta, step_at};

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Node {
    pub min: DVec3,
    pub max: DVec3,
    pub eps: f64,
    pub w: f64,
    /// The cluster's id in `Tree::clusters`.
    pub id: u32,
    /// Index of the first child's node; the children are consecutive.
    pub first_child: u32,
    pub child_count: u32,
    /// The visibility steps: `steps[first_step..first_step + step_count]`.
    pub first_step: u32,
    pub step_count: u32,
    pub has_geometry: bool,
    /// For a dynamic cluster, the id of the cluster whose motion it uses:
    /// the top of its LOD chain, whose levels all share one motion, so that
    /// the cut samples it once per chain. `u32::MAX` for the others.
    pub motion: u32,
}

impl Node {
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.min,
            max: self.max,
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
    steps: Vec<(f64, f32)>,
}

impl Nodes {
    pub fn new(tree: &Tree) -> Nodes {
        let n = tree.clusters.len();
        let mut order: Vec<u32> = Vec::with_capacity(n);
        let mut node_of = vec![u32::MAX; n];
        order.push(tree.root);
        node_of[tree.root as usize] = 0;
        let mut next = 0;
        while next < order.len() {
            let c = &tree.clusters[order[next] as usize];
            for &child in &c.children {
                node_of[child as usize] = order.len() as u32;
                order.push(child);
            }
            next += 1;
        }
        let mut steps = Vec::new();
        let nodes = order
            .iter()
            .map(|&id| {
                let c = &tree.clusters[id as usize];
                let first_step = steps.len() as u32;
                steps.extend_from_slice(c.visibility.steps());
                Node {
                    min: c.bounds.min,
                    max: c.bounds.max,
                    eps: c.eps,
                    w: c.w,
                    id,
                    first_child: c.children.first().map_or(0, |&f| node_of[f as usize]),
                    child_count: c.children.len() as u32,
                    first_step,
                    step_count: c.visibility.steps().len() as u32,
                    has_geometry: c.geometry.is_some(),
                    motion: motion_source(tree, id),
                }
            })
            .collect();
        Nodes {
            nodes,
            node_of,
            steps,
        }
    }

    /// `v_c(t)`, as `Steps::at`.
    #[inline]
    pub fn visibility(&self, node: &Node, t: f64) -> f32 {
        step_at(
            &self.steps[node.first_step as usize..(node.first_step + node.step_count) as usize],
            t,
        )
    }
}

/// The highest ancestor of `id` (itself included) with the same motion as
/// `id`, or `u32::MAX` when `id` has none.
fn motion_source(tree: &Tree, id: u32) -> u32 {
    let Some(motion) = &tree.clusters[id as usize].motion else {
        return u32::MAX;
    };
    let mut source = id;
    while let Some(parent) = tree.clusters[source as usize].parent
        && tree.clusters[parent as usize].motion.as_ref() == Some(motion)
    {
        source = parent;
    }
    source
}
