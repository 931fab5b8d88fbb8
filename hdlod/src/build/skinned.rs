//! A skinned object's LOD chain (docs/method.md, "Skinned objects"): an
//! object whose joints move is dynamic, its clusters in the world frame
//! (the joints place a skinned mesh, glTF 2.0 section 3.7.3.1, so the
//! chain's motion is the identity) and posed at any time by its joints,
//! which the tree keeps once per object (`tree::skins`).
//!
//! Its coarser versions are reduced over sampled poses
//! (`geometry::skin::reduce_posed`), each keeping a subset of the
//! vertices with their own joints and weights, and their error is
//! measured in those poses: a level reduced and measured in the bind pose
//! alone can tear where a joint bends. Its box holds the mesh in every
//! pose ([`posed_bounds`]).

use rustc_hash::FxHashMap;

use glam::{DVec3, Mat4, Vec3};

use super::context::Context;
use super::dynamic::Version;
use crate::Result;
use crate::geometry::Mesh;
use crate::geometry::skin::{self, Skin};
use crate::scene::{Keyframe, Motion, Object, ObjectSkin, Scene, Visibility};
use crate::tree::{Aabb, ClusterClass, Skeleton, Skins, Tree};

/// True when `o` is built as a skinned object: it has a skin whose joints
/// move. A skin that stands still poses nothing over time, and its object
/// is built as the others are.
pub(super) fn is_skinned(o: &Object) -> bool {
    o.skin.as_ref().is_some_and(|s| s.moves())
}

/// The skeletons of the skinned objects of `scene` that are dynamic
/// leaves of `tree` (`None` when there are none): those whose chains
/// were made by [`chain`], in a build or an update.
pub(super) fn skeletons(scene: &Scene, tree: &Tree) -> Option<Skins> {
    skeletons_of(scene, &dynamic_leaf_objects(tree))
}

/// The objects of the dynamic leaves of `tree`: those [`skeletons`] may
/// be of.
pub(super) fn dynamic_leaf_objects(tree: &Tree) -> Vec<String> {
    (0..tree.cluster_count() as u32)
        .filter(|&c| tree.class_of(c) == ClusterClass::Dynamic && tree.children_of(c).is_empty())
        .flat_map(|c| tree.objects_of(c).into_iter().map(str::to_owned))
        .collect()
}

/// The skeletons of the skinned objects of `scene` among `objects`
/// (`None` when there are none).
pub(super) fn skeletons_of(scene: &Scene, objects: &[String]) -> Option<Skins> {
    // The skinned objects alone: an update makes the skeletons again over a
    // scene of tens of thousands of objects, a few hundred of them skinned.
    let skinned: FxHashMap<&str, &ObjectSkin> = (scene.objects.iter())
        .filter_map(|o| Some((o.id.as_str(), &**o.skin.as_ref().filter(|_| is_skinned(o))?)))
        .collect();
    if skinned.is_empty() {
        return None;
    }
    let skins = Skins::new(objects.iter().filter_map(|id| {
        let (&id, skin) = skinned.get_key_value(id.as_str())?;
        Some((id.to_owned(), Skeleton::of(skin)))
    }));
    (!skins.is_empty()).then_some(skins)
}

/// Poses sampled per chain: enough to catch a joint's bend between its
/// ends, within what meshoptimizer weighs ([`skin::MAX_POSES`]).
pub(super) const POSES: usize = 8;
const _: () = assert!(POSES <= skin::MAX_POSES);

/// The times of the poses a chain is reduced and measured in: spread
/// evenly over where the object is present while its joints move (the
/// poses the cut can draw), both ends included. Where the joints move
/// only while it is absent, the one pose it is seen in.
pub(super) fn pose_times(skin: &ObjectSkin, visibility: &Visibility, span: f64) -> Vec<f64> {
    let present = visibility.clipped(span);
    let keys = skin.times();
    let (Some(first), Some(last)) = (present.first(), present.last()) else {
        return vec![0.0];
    };
    let (p0, p1) = (first.0, last.1);
    let (k0, k1) = match (keys.first(), keys.last()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => (p0, p0),
    };
    let (lo, hi) = (p0.max(k0), p1.min(k1));
    if hi <= lo {
        return vec![p0.clamp(k0, k1)];
    }
    (0..POSES)
        .map(|k| lo + (hi - lo) * k as f64 / (POSES - 1) as f64)
        .collect()
}

/// The chain of a skinned object (finest first): its mesh, then one
/// version per configured budget (a share of the mesh's size), each the
/// fewest triangles [`reduce_posed`](skin::reduce_posed) reaches, halving,
/// whose error over the poses at `times` fits the budget, kept only when
/// it has at most `min_reduction` of the triangles of the version below,
/// as the rigid chain keeps its versions. `eps` is the largest, over the
/// poses, of the Hausdorff bound between the posed mesh and the posed
/// version, kept monotone. `mesh` carries the object's colour; `name`
/// names the joints' animation in the GLBs.
pub(super) fn chain(
    ctx: &Context,
    name: &str,
    mesh: &Mesh,
    skin: &ObjectSkin,
    times: &[f64],
) -> Result<Vec<Version>> {
    let poses: Vec<Vec<Mat4>> = times.iter().map(|&t| skin.matrices(t)).collect();
    // One box for every version: each keeps a subset of the vertices, so
    // the box of the whole holds it.
    let bounds = posed_bounds(mesh, skin);
    let store = |indices: &[u32]| {
        let (mesh, vertices) = compacted(mesh, &skin.vertices, indices);
        let skin = ObjectSkin {
            vertices,
            inverse_bind: skin.inverse_bind.clone(),
            joints: skin.joints.clone(),
        };
        ctx.sink.put_skinned(&mesh, &skin, name)
    };
    let mut out = vec![Version {
        hash: store(&mesh.indices)?,
        triangles: mesh.triangle_count() as u64,
        eps: 0.0,
        bounds,
    }];
    let size = mesh
        .bounds()
        .map_or(0.0, |(lo, hi)| f64::from((hi - lo).length()));
    for &share in &ctx.config.dynamic_budgets {
        let previous = out.last().expect("chain starts with the original");
        let budget = share * size;
        if budget <= previous.eps {
            continue;
        }
        let most = previous.triangles as f64 * ctx.config.min_reduction;
        let Some((level, h)) = reduce_over_poses(mesh, &skin.vertices, &poses, budget, most) else {
            continue;
        };
        let eps = h.max(previous.eps);
        out.push(Version {
            hash: store(&level)?,
            triangles: (level.len() / 3) as u64,
            eps,
            bounds,
        });
    }
    Ok(out)
}

/// The fewest triangles of `mesh` (at most `most`) whose largest error
/// over `poses` is within `budget`, and that error: the reduction to
/// `most`, then halved while it fits and keeps going down.
fn reduce_over_poses(
    mesh: &Mesh,
    skin: &Skin,
    poses: &[Vec<Mat4>],
    budget: f64,
    most: f64,
) -> Option<(Vec<u32>, f64)> {
    let mut target = most.floor() as usize;
    let mut best: Option<(Vec<u32>, f64)> = None;
    while target > 0 {
        let level = skin::reduce_posed(mesh, skin, poses, target);
        let triangles = level.len() / 3;
        let fewer = best.as_ref().is_none_or(|(b, _)| level.len() < b.len());
        if triangles == 0 || triangles as f64 > most || !fewer {
            break;
        }
        let error = skin::pose_error(mesh, &level, skin, poses).largest;
        if error > budget {
            break;
        }
        best = Some((level, error));
        target = triangles / 2;
    }
    best
}

/// The vertices `indices` use, in their order of first use, with their
/// joints and weights; the indices renumbered.
fn compacted(mesh: &Mesh, skin: &Skin, indices: &[u32]) -> (Mesh, Skin) {
    let mut new_of = vec![u32::MAX; mesh.positions.len()];
    let mut kept: Vec<usize> = Vec::new();
    let indices = indices
        .iter()
        .map(|&i| {
            let slot = &mut new_of[i as usize];
            if *slot == u32::MAX {
                *slot = kept.len() as u32;
                kept.push(i as usize);
            }
            *slot
        })
        .collect();
    fn pick<T: Copy>(values: &[T], kept: &[usize]) -> Vec<T> {
        // An attribute the mesh lacks stays empty.
        kept.iter()
            .filter_map(|&v| values.get(v).copied())
            .collect()
    }
    let out = Mesh {
        positions: pick(&mesh.positions, &kept),
        normals: pick(&mesh.normals, &kept),
        colors: pick(&mesh.colors, &kept),
        features: pick(&mesh.features, &kept),
        indices,
    };
    let skin = Skin {
        joints: kept.iter().map(|&v| skin.joints[v]).collect(),
        weights: kept.iter().map(|&v| skin.weights[v]).collect(),
    };
    (out, skin)
}

/// The identity, held: the motion of a skinned chain, whose joints place
/// it in the world.
pub(super) fn world_frame() -> Motion {
    Motion::new(vec![Keyframe::of_matrix(0.0, &Mat4::IDENTITY)])
        .expect("one finite keyframe is a motion")
}

/// A box (world frame) that holds `mesh` posed by `skin` at every time.
///
/// Why it holds: a posed vertex is `sum_k w_k J_k(t) B_k p` with weights
/// `w_k >= 0` summing to 1, so it lies in the convex hull of the points
/// `J_k(t) B_k p` of its joints `k` (`B_k` the inverse bind matrix,
/// `J_k(t)` the joint's world transform). `B_k p` lies in the box of the
/// vertices joint `k` influences, in its bind frame; an affine map takes
/// a box into the box of its moved corners. At every keyframe of the
/// joint that box is moved exactly. Between two keyframes the joint
/// interpolates (translation and scale linearly, rotation by slerp at a
/// constant rate): a point `x` of the bind box moves on a curve whose
/// second derivative in the interpolation parameter is at most
/// `r (theta^2 s + 2 theta ds)` (`r` the largest `|x|`, `theta` the
/// turn, `s` the largest scale, `ds` its change), and a curve strays from
/// the chord between two of its points `h` apart by at most `h^2 / 8`
/// times that. The interval is cut in pieces, their ends moved exactly,
/// and the box grown by the chord error of a piece; a chord lies in the
/// box of its ends. The union over the joints is a box, so convex, and
/// holds every such hull. Weights summing to 1 within the file's
/// tolerance stray from the hull by that share of the farthest point:
/// the box is grown by it too.
pub(super) fn posed_bounds(mesh: &Mesh, skin: &ObjectSkin) -> (Vec3, Vec3) {
    let n = skin.joints.len();
    let mut local: Vec<Option<Aabb>> = vec![None; n];
    let mut weight_slack = 0.0f64;
    for (v, p) in mesh.positions.iter().enumerate() {
        let (joints, weights) = (skin.vertices.joints[v], skin.vertices.weights[v]);
        let sum: f32 = weights.iter().sum();
        weight_slack = weight_slack.max(f64::from((sum - 1.0).abs()));
        for k in (0..4).filter(|&k| weights[k] > 0.0) {
            let j = usize::from(joints[k]);
            let q = skin.inverse_bind[j].transform_point3(*p).as_dvec3();
            let b = Aabb::new(q, q);
            local[j] = Some(local[j].map_or(b, |a| a.union(&b)));
        }
    }
    let mut out: Option<Aabb> = None;
    let mut grow = |b: Aabb| out = Some(out.map_or(b, |a| a.union(&b)));
    for (joint, local) in skin.joints.iter().zip(&local) {
        let Some(local) = local else {
            continue;
        };
        let moved = |m: Mat4| local.transformed(&m.as_dmat4());
        let Some(motion) = &joint.motion else {
            grow(moved(joint.transform));
            continue;
        };
        let r = corners(local)
            .iter()
            .map(|c| c.length())
            .fold(0.0, f64::max);
        let keys = motion.keyframes();
        let mut joint_box = moved(keys[0].matrix());
        let mut chord = 0.0f64;
        for pair in keys.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let theta = f64::from(a.rotation.angle_between(b.rotation));
            let s = f64::from(a.scale.abs().max(b.scale.abs()).max_element());
            let ds = f64::from((b.scale - a.scale).abs().max_element());
            // glam slerps a small turn by a normalised lerp, whose rate
            // is not constant: twice the bound covers it.
            let bend = 2.0 * r * (theta * theta * s + 2.0 * theta * ds);
            let pieces = ((bend / (8.0 * r.max(f64::MIN_POSITIVE) * CHORD_SHARE)).sqrt())
                .ceil()
                .clamp(1.0, MAX_PIECES);
            for i in 1..=pieces as usize {
                let key = if i == pieces as usize {
                    b
                } else {
                    let t = a.t + (b.t - a.t) * i as f64 / pieces;
                    Motion::between(a, b, t)
                };
                joint_box = joint_box.union(&moved(key.matrix()));
            }
            chord = chord.max(bend / (8.0 * pieces * pieces));
        }
        grow(Aabb::new(
            joint_box.min - DVec3::splat(chord),
            joint_box.max + DVec3::splat(chord),
        ));
    }
    let Some(b) = out else {
        return (Vec3::ZERO, Vec3::ZERO);
    };
    let far = b.min.abs().max(b.max.abs()).max_element();
    // `f32` rounding of the matrices and of the box's corners.
    let slack = weight_slack * far + 1e-6 * (far + 1.0);
    (
        (b.min - DVec3::splat(slack)).as_vec3(),
        (b.max + DVec3::splat(slack)).as_vec3(),
    )
}

/// A piece between two keyframes strays from its chord by at most this
/// share of the farthest bind point from its joint, unless that takes
/// more than [`MAX_PIECES`] pieces (the box is then grown by more).
const CHORD_SHARE: f64 = 1e-3;
const MAX_PIECES: f64 = 64.0;

fn corners(b: &Aabb) -> [DVec3; 8] {
    std::array::from_fn(|i| {
        DVec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Joint;
    use glam::Quat;

    /// A bar along Y from 0 to 2, its top half on joint 1 (at y = 1), its
    /// bottom on joint 0 (at the origin), the middle ring blended; joint 1
    /// turns a quarter about X over 10 s.
    fn bar() -> (Mesh, ObjectSkin) {
        let mut mesh = Mesh::default();
        let mut skin = Skin {
            joints: Vec::new(),
            weights: Vec::new(),
        };
        for r in 0..5 {
            let y = 0.5 * r as f32;
            for k in 0..4 {
                let a = std::f32::consts::TAU * k as f32 / 4.0;
                mesh.positions
                    .push(Vec3::new(0.1 * a.cos(), y, 0.1 * a.sin()));
                let top = ((y - 0.5) / 1.0).clamp(0.0, 1.0);
                skin.joints.push([0, 1, 0, 0]);
                skin.weights.push([1.0 - top, top, 0.0, 0.0]);
            }
        }
        for r in 0..4u32 {
            for k in 0..4u32 {
                let at = |r: u32, k: u32| r * 4 + k % 4;
                let (a, b, c, d) = (at(r, k), at(r, k + 1), at(r + 1, k), at(r + 1, k + 1));
                mesh.indices.extend([a, c, b, b, c, d]);
            }
        }
        let turn = |t: f64, angle: f32| Keyframe {
            t,
            translation: Vec3::Y,
            rotation: Quat::from_rotation_x(angle),
            scale: Vec3::ONE,
        };
        let joints = vec![
            Joint {
                name: None,
                transform: Mat4::IDENTITY,
                motion: None,
            },
            Joint {
                name: None,
                transform: Mat4::from_translation(Vec3::Y),
                motion: Some(
                    Motion::new(vec![
                        turn(0.0, 0.0),
                        turn(10.0, std::f32::consts::FRAC_PI_2),
                    ])
                    .unwrap(),
                ),
            },
        ];
        let skin = ObjectSkin {
            vertices: skin,
            inverse_bind: vec![Mat4::IDENTITY, Mat4::from_translation(-Vec3::Y)],
            joints,
        };
        (mesh, skin)
    }

    #[test]
    fn the_box_holds_the_mesh_between_keyframes() {
        let (mesh, skin) = bar();
        let (lo, hi) = posed_bounds(&mesh, &skin);
        for k in 0..=100 {
            let t = 0.1 * k as f64;
            for p in skin.pose(&mesh, t).positions {
                assert!(
                    p.cmpge(lo).all() && p.cmple(hi).all(),
                    "t {t}: {p} outside {lo}..{hi}"
                );
            }
        }
        // The top half sweeps a quarter turn: the box reaches z = 1.1
        // (the top ring at radius 1 from the joint, 0.1 off its axis) but
        // not far beyond.
        assert!(hi.z > 1.0 && hi.z < 1.2, "{hi}");
    }

    #[test]
    fn a_compacted_level_keeps_each_kept_vertex_s_influences() {
        let (mesh, skin) = bar();
        let level = [16u32, 4, 19];
        let (m, s) = compacted(&mesh, &skin.vertices, &level);
        assert_eq!(m.indices, [0, 1, 2]);
        assert_eq!(m.positions, [16, 4, 19].map(|v| mesh.positions[v]));
        assert_eq!(s.weights[0], skin.vertices.weights[16]);
        assert_eq!(s.joints[1], skin.vertices.joints[4]);
    }
}
