//! The leaves: each object's life split where it stands still, and each
//! static or pseudo-dynamic piece stored as a leaf cluster in the world
//! frame (docs/method.md section 3).

use rustc_hash::FxHashMap;
use std::sync::Arc;

use glam::{Mat4, Vec3};
use rayon::prelude::*;

use super::context::{Active, Context, Node, add};
use super::instances::shapes_of;
use super::outputs::Progress;
use super::parent::DIRECT_MAX_TRIANGLES;
use super::steps::StepFunction;
use crate::Result;
use crate::geometry::{self, Mesh, Part};
use crate::scene::{Class, Scene, Visibility, VisibilityType};
use crate::tree::{Cluster, ClusterClass};

/// A part of an object's life that becomes one leaf.
pub(super) struct Piece {
    pub object: usize,
    pub class: Class,
    pub transform: Mat4,
    pub visibility: Visibility,
}

impl Piece {
    /// The class of the leaf cluster it becomes.
    pub fn cluster_class(&self) -> ClusterClass {
        match self.class {
            Class::Static => ClusterClass::Static,
            Class::PseudoDynamic => ClusterClass::PseudoDynamic,
            _ => ClusterClass::Dynamic,
        }
    }
}

/// Each object's pieces (by object index), in the order of its leaves in a
/// built tree: the static and pseudo-dynamic ones first, as the build
/// numbers the leaves. What an update matches an object's old leaves with.
pub(super) fn pieces_by_object(pieces: &[Piece]) -> FxHashMap<usize, Vec<usize>> {
    // Most objects are one piece: sized for them up front.
    let mut out: FxHashMap<usize, Vec<usize>> =
        FxHashMap::with_capacity_and_hasher(pieces.len(), Default::default());
    for (i, p) in pieces.iter().enumerate() {
        out.entry(p.object).or_default().push(i);
    }
    for of_object in out.values_mut() {
        of_object.sort_by_key(|&i| pieces[i].class == Class::Dynamic);
    }
    out
}

/// Splits each moving object where it stands still. Before its first and
/// after its last keyframe its pose is held, so those parts of its
/// visibility are a pseudo-dynamic (or static) object at that pose, which
/// clusters with its neighbours; only the part in between stays dynamic.
/// A steel beam hoisted into place is then a moving object during its lift
/// and part of the structure afterwards. The cut draws the same geometry at
/// every time either way.
pub(super) fn split_at_rest(scene: &Scene, classes: &[Class]) -> Vec<Piece> {
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

/// A static or pseudo-dynamic piece's leaf geometry: its object's mesh
/// moved into the world frame, coloured, each vertex carrying the object's
/// feature id.
pub(super) fn leaf_mesh(scene: &Scene, piece: &Piece) -> Mesh {
    let o = &scene.objects[piece.object];
    geometry::merge(
        &[Part {
            mesh: &scene.meshes[o.mesh],
            transform: piece.transform,
            color: o.color,
            feature: Some(piece.object as u32),
        }],
        0.0,
    )
}

/// The leaf clusters of the static and the pseudo-dynamic pieces (in that
/// order): each object's mesh moved into the world frame, coloured, and
/// stored. Records the distinct leaf visibilities in `ctx.leaf_steps`.
pub(super) fn leaves(
    scene: &Scene,
    pieces: &[Piece],
    ctx: &mut Context,
    clusters: &mut Vec<Cluster>,
    progress: &dyn Progress,
) -> Result<[Vec<Active>; 2]> {
    let span = scene.time.seconds;
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
    let sink = ctx.sink;
    let leaf_meshes: Vec<Result<(Mesh, String)>> = members
        .par_iter()
        .map(|&(p, _)| {
            let mesh = leaf_mesh(scene, p);
            // A leaf is the object itself: exact, its `eps` 0.
            let hash = sink.put(&mesh, None, 0.0)?.hash;
            progress.advance(1);
            Ok((mesh, hash))
        })
        .collect();
    let (shapes, instances) = shapes_of(
        &scene.meshes,
        &members
            .iter()
            .map(|&(p, _)| {
                let o = &scene.objects[p.object];
                (o.mesh, p.transform, o.color)
            })
            .collect::<Vec<_>>(),
    );
    ctx.shapes = shapes;
    // Objects of one task share one visibility: the temporal error is a
    // maximum over the distinct ones.
    let mut vis_ids: FxHashMap<Vec<(u64, u64)>, u32> = FxHashMap::default();
    for ((&(p, tree), made), instance) in members.iter().zip(leaf_meshes).zip(instances) {
        let (mesh, hash) = made?;
        let o = &scene.objects[p.object];
        let steps = StepFunction::of_visibility(&p.visibility, span);
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
        let class = if tree == 0 {
            ClusterClass::Static
        } else {
            ClusterClass::PseudoDynamic
        };
        let node = Node {
            geometry: Some((hash, mesh.triangle_count() as u64)),
            objects: vec![o.id.clone()],
            ..Node::new(class, 0, (lo, hi), &steps)
        };
        let w = node.w;
        let id = add(clusters, node);
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
            baked: None,
            instance,
            parts: Default::default(),
        });
    }
    Ok(leaves)
}
