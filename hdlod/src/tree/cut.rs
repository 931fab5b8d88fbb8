//! The cut (Semenov et al. 2020, appendix 1; docs/method.md section 4): the
//! clusters a viewer draws at time `t` for a view.
//!
//! ```text
//! display(c): if v_c(t) == 0: return
//!             if box of c at t is outside the frustum: return
//!             if delta_c(t) / distance(eye, box) < r: (emit c if v_c(t) >= 0.5); return
//!             for child in children(c): display(child)
//! ```
//!
//! Two readings the pseudo-code leaves open: a leaf cannot be refined, so it
//! is emitted (when `v >= 0.5`) even if its error is too large, which happens
//! only at distance 0 (the eye inside its box) since a leaf's `delta` is 0
//! unless its visibility is fractional; and the root has no geometry, so it
//! is always refined. Beside the paper's rule, [`Presence::Exact`] draws
//! what is present at `t` for clients that hide absent objects inside a
//! cluster by their feature ids: a cluster at least half present is drawn
//! as the paper draws it, one less than half present is refined to its
//! children (where the paper leaves it out), and a leaf with any presence
//! is drawn. The root's children are taken from its presence
//! index (`presence`): those that may be present at `t`, in order, rather
//! than every one of them. The traversal reads the tree's compact copy
//! (`nodes`), is iterative with one reused stack;
//! children are pushed in reverse so that clusters come out in the order of
//! the recursive definition.
//!
//! [`present_leaves_into`] is the comparison the paper draws against (its
//! "none" column): every present leaf, whatever the view.

use glam::Mat4;

use super::{Tree, View};

/// Which partly present clusters the cut draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Presence {
    /// The paper's rule: a cluster is drawn when `v_c(t) >= 0.5`, so an
    /// object may be missing (its cluster mostly absent) or drawn while
    /// absent (its cluster mostly present).
    #[default]
    Paper,
    /// What is present at `t`: the client hides the features absent at
    /// `t` by their ids, so nothing present is missing and nothing absent
    /// is drawn. A cluster less than half present is refined to its
    /// children rather than drawn: drawing it would spend most of its
    /// triangles and bytes on hidden objects (at the start of a
    /// construction a coarse cluster of the whole tower may be a few
    /// percent present). At least half present, it is drawn whole, as by
    /// the paper's rule; a leaf with any presence is drawn.
    Exact,
}

impl Presence {
    /// The least `v_c(t)` of a drawn cluster.
    fn threshold(self) -> f32 {
        match self {
            Presence::Paper => 0.5,
            Presence::Exact => f32::MIN_POSITIVE,
        }
    }

    /// Below this `v_c(t)` a cluster with children is refined, however
    /// fine it is.
    fn split_below(self) -> f32 {
        match self {
            Presence::Paper => 0.0,
            Presence::Exact => 0.5,
        }
    }
}

/// Whether a viewer draws the cut or everything present.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Lod {
    /// The cut: levels of detail within the pixel error, culled to the view.
    #[default]
    Hdlod,
    /// No levels of detail: every present leaf at full detail, in view or
    /// not ([`present_leaves_into`]).
    None,
}

/// One emitted cluster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutItem {
    pub id: u32,
    /// The cluster's pose at `t` (dynamic clusters only).
    pub transform: Option<Mat4>,
    /// A skinned cluster's joint matrices at `t`, in [`Cut::joints`]
    /// ([`Cut::joints_of`]): kept beside the items so that an item stays
    /// a plain copy and a cut of rigid clusters allocates nothing.
    pub joints: Option<JointRange>,
    /// `v_c(t)`.
    pub visibility: f32,
    /// `delta_c(t)`, in world units.
    pub error: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CutStats {
    pub clusters: usize,
    pub triangles: u64,
    /// Clusters examined (calls of `display`).
    pub visited: usize,
}

/// Where an item's joint matrices lie in [`Cut::joints`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JointRange {
    pub first: u32,
    pub count: u32,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cut {
    pub items: Vec<CutItem>,
    pub stats: CutStats,
    /// The joint matrices of the skinned items, one run per item: each
    /// joint's world transform at `t` after its inverse bind matrix (glTF
    /// 2.0 section 3.7.3). They place the item's vertices in the world by
    /// themselves, as glTF's skinning does; the item's `transform` places
    /// its box.
    pub joints: Vec<Mat4>,
}

impl Cut {
    /// The joint matrices of `item`, empty for a rigid one.
    pub fn joints_of(&self, item: &CutItem) -> &[Mat4] {
        item.joints.map_or(&[], |r| {
            &self.joints[r.first as usize..(r.first + r.count) as usize]
        })
    }
}

/// The cut of `tree` at `t` (seconds since the scene's start) for `view`,
/// by the paper's rule.
pub fn cut(tree: &Tree, view: &View, t: f64) -> Cut {
    let mut out = Cut::default();
    let mut stack = Vec::new();
    cut_into(tree, view, t, Presence::Paper, &mut out, &mut stack);
    out
}

/// [`cut`] under a `presence` rule into reused buffers: no allocation once
/// they have grown. The stack holds node indices of the tree's compact copy
/// (`nodes`).
pub fn cut_into(
    tree: &Tree,
    view: &View,
    t: f64,
    presence: Presence,
    out: &mut Cut,
    stack: &mut Vec<u32>,
) {
    let drawn = start(presence, out, stack);
    let split_below = presence.split_below();
    let nodes = tree.nodes();
    let r = view.r();
    let mut sampled = Posed::NONE;
    while let Some(i) = stack.pop() {
        out.stats.visited += 1;
        let c = &nodes.nodes[i as usize];
        let v = nodes.visibility(c, t);
        if v <= 0.0 {
            continue;
        }
        let posed = pose(tree, c, t, &mut sampled);
        let transform = posed.map(|p| p.matrix);
        // A static node's box is tested where it lies: copied out first, it
        // was read back across the copy's two stores, which stalled.
        let moved;
        let bounds = match transform {
            Some(m) => {
                moved = c.bounds.transformed(&m.as_dmat4());
                &moved
            }
            None => &c.bounds,
        };
        if view.outside(bounds) {
            continue;
        }
        let delta = c.delta(v) * posed.map_or(1.0, |p| p.scale);
        let leaf = c.child_count == 0;
        let refine =
            !leaf && (c.has_geometry == 0 || v < split_below || delta >= r * view.distance(bounds));
        if refine {
            push_children(tree, &nodes, i, t, stack);
        } else if v >= drawn && c.has_geometry != 0 {
            emit(tree, out, c, transform, v, delta, t);
        }
    }
}

/// Every leaf with `v(t)` at least `presence`'s threshold, in view or not,
/// into reused buffers: what drawing without levels of detail draws (the
/// paper's "none" column). Its triangles are the baseline's
/// (`hdlod::tree::Baseline`) under the paper's rule.
pub fn present_leaves_into(
    tree: &Tree,
    t: f64,
    presence: Presence,
    out: &mut Cut,
    stack: &mut Vec<u32>,
) {
    let drawn = start(presence, out, stack);
    let nodes = tree.nodes();
    let mut sampled = Posed::NONE;
    while let Some(i) = stack.pop() {
        out.stats.visited += 1;
        let c = &nodes.nodes[i as usize];
        let v = nodes.visibility(c, t);
        if v <= 0.0 {
            continue;
        }
        if i == 0 || c.child_count > 0 {
            push_children(tree, &nodes, i, t, stack);
        } else if v >= drawn && c.has_geometry != 0 {
            let posed = pose(tree, c, t, &mut sampled);
            let delta = c.delta(v) * posed.map_or(1.0, |p| p.scale);
            emit(tree, out, c, posed.map(|p| p.matrix), v, delta, t);
        }
    }
}

/// Clears the buffers and pushes the root; answers the least `v_c(t)` drawn.
fn start(presence: Presence, out: &mut Cut, stack: &mut Vec<u32>) -> f32 {
    out.items.clear();
    out.joints.clear();
    out.stats = CutStats::default();
    stack.clear();
    stack.push(0);
    presence.threshold()
}

/// Pushes node `i`'s children, in reverse so that they come out in order:
/// the root's from its presence index (those that may be present at `t`),
/// any other's from its range of nodes.
fn push_children(
    tree: &Tree,
    nodes: &super::nodes::NodesRef,
    i: u32,
    t: f64,
    stack: &mut Vec<u32>,
) {
    if i == 0 {
        let candidates = tree.presence().candidates(t);
        stack.extend(
            candidates
                .iter()
                .rev()
                .map(|&id| nodes.node_of[id as usize]),
        );
    } else {
        let c = &nodes.nodes[i as usize];
        stack.extend((c.first_child..c.first_child + c.child_count).rev());
    }
}

/// A motion sampled at `t`.
#[derive(Clone, Copy)]
struct Posed {
    /// The motion's source cluster (`u32::MAX` before the first sample).
    source: u32,
    matrix: Mat4,
    /// The largest factor by which `matrix` (a rotation, scale and
    /// translation) stretches a distance, its longest axis: a pose that
    /// scales a cluster (a crane's cable paying out) stretches its error
    /// with it.
    scale: f64,
}

impl Posed {
    const NONE: Posed = Posed {
        source: u32::MAX,
        matrix: Mat4::IDENTITY,
        scale: 1.0,
    };
}

/// A dynamic node's pose at `t`, `None` for others. `sampled` keeps the
/// last motion sampled: the levels of a chain come one after another and
/// share it.
fn pose(tree: &Tree, c: &super::nodes::Node, t: f64, sampled: &mut Posed) -> Option<Posed> {
    if c.motion == u32::MAX {
        return None;
    }
    if sampled.source != c.motion {
        let matrix = tree.pose_at(c.motion, t);
        let scale = [matrix.x_axis, matrix.y_axis, matrix.z_axis]
            .iter()
            .map(|a| a.truncate().length())
            .fold(0.0, f32::max);
        *sampled = Posed {
            source: c.motion,
            matrix,
            scale: f64::from(scale),
        };
    }
    Some(*sampled)
}

fn emit(
    tree: &Tree,
    out: &mut Cut,
    c: &super::nodes::Node,
    transform: Option<Mat4>,
    visibility: f32,
    error: f64,
    t: f64,
) {
    out.stats.clusters += 1;
    out.stats.triangles += c.triangles(tree);
    let joints = (c.motion != u32::MAX)
        .then(|| tree.skeleton_of(c.id))
        .flatten()
        .map(|skeleton| {
            let first = out.joints.len();
            skeleton.matrices_into(t, &mut out.joints);
            JointRange {
                first: first as u32,
                count: (out.joints.len() - first) as u32,
            }
        });
    out.items.push(CutItem {
        id: c.id,
        transform,
        joints,
        visibility,
        error,
    });
}
