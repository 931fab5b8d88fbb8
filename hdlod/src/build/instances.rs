//! Lone leaves that are instances of one shape share one reduction.
//!
//! A building repeats its elements: the paper scene's 55,361 objects are
//! 110 shapes (a mesh under one rotation and scale, in one colour) moved
//! about, and BIM models map most of their elements from a few types.
//! At the first level nearly every leaf is alone, so the builder gives
//! each its own parent (`parent::single_parent`), and measuring those
//! reductions one leaf at a time was most of a build's time.
//!
//! Instead each shape is reduced once, at the origin (`canonical`), and
//! the result is moved to each instance. The instance's error is measured,
//! not assumed: with `X` the leaf, `C` the shape at the origin, `R` its
//! reduction and `t` the leaf's translation, `D_H(R + t, X) <= D_H(R, C) +
//! max |X_v - (C_v + t)| + max |(R + t)_v - (R_v + t)|`, the last two
//! measured vertex by vertex in `f64` (floating-point rounding of the
//! moves, a few micrometres). That needs `X` to be `C + t` triangle for
//! triangle: a leaf whose welded triangles differ from the shape's is
//! reduced on its own.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Mat4, Vec3, Vec4};
use rayon::prelude::*;

use super::config::Thresholds;
use super::context::{Active, Context};
use super::digest::mesh_digest;
use super::parent::{Single, bake_colour, reduce_lone, single_parent};
use crate::geometry::{self, Mesh, Part, Parts};

/// A leaf's shape (an index into `Context::shapes`) and where it is.
#[derive(Debug, Clone, Copy)]
pub(super) struct Instance {
    pub shape: u32,
    pub translation: Vec3,
}

/// What makes two leaves one shape: the scene mesh, the linear part of the
/// transform and the colour, as bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct ShapeKey {
    mesh: usize,
    linear: [u32; 9],
    color: [u32; 4],
}

impl ShapeKey {
    fn new(mesh: usize, transform: &Mat4, color: [f32; 4]) -> ShapeKey {
        let cols = [transform.x_axis, transform.y_axis, transform.z_axis];
        let linear = std::array::from_fn(|k| cols[k / 3][k % 3].to_bits());
        ShapeKey {
            mesh,
            linear,
            color: color.map(f32::to_bits),
        }
    }
}

/// The shape of `transform`'s linear part: the leaf's mesh as `merge`
/// makes it, without the translation. The feature id is a placeholder:
/// each instance's own replaces it.
fn canonical(mesh: &Mesh, transform: &Mat4, color: [f32; 4]) -> Mesh {
    let linear = Mat4::from_cols(
        transform.x_axis,
        transform.y_axis,
        transform.z_axis,
        Vec4::W,
    );
    geometry::merge(
        &[Part {
            mesh,
            transform: linear,
            color,
            feature: Some(0),
        }],
        0.0,
    )
}

/// Parents of their own for the lone clusters `alone` of `active`, as
/// `parent::single_parent` makes them; leaves of one shape share one
/// reduction. In the order of `alone`.
pub(super) fn single_parents(
    ctx: &Context,
    active: &[Active],
    alone: &[usize],
    th: &Thresholds,
) -> Vec<Option<Single>> {
    let shared = |a: &Active| (a.eps == 0.0).then_some(a.instance).flatten();
    let mut shapes: Vec<u32> = alone
        .iter()
        .filter_map(|&i| shared(&active[i]).map(|s| s.shape))
        .collect();
    shapes.sort_unstable();
    shapes.dedup();
    let reduced: HashMap<u32, Option<(Mesh, f32)>> = shapes
        .par_iter()
        .map(|&s| {
            let mut parts = Parts::new(&*ctx.shapes[s as usize]);
            (s, reduce_lone(ctx, &mut parts, 0.0, th))
        })
        .collect();
    alone
        .par_iter()
        .map(|&i| {
            let a = &active[i];
            let Some(instance) = shared(a) else {
                return single_parent(ctx, a, th);
            };
            // A shape that does not reduce enough at the origin is tried
            // at each instance: near a budget's edge rounding decides (a
            // slab as thick as twice the budget).
            let shape = &ctx.shapes[instance.shape as usize];
            reduced[&instance.shape]
                .as_ref()
                .and_then(|(r, h)| moved(&a.mesh, shape, r, *h, instance.translation))
                .map(|(mesh, eps)| {
                    // The colour comes from the instance's own originals.
                    let baked = bake_colour(ctx, &mesh, eps, &[a.source()], a.originals.as_deref());
                    Single { mesh, eps, baked }
                })
                .or_else(|| single_parent(ctx, a, th))
        })
        .collect()
}

/// `reduced` (of `shape`, within `h`) moved by `t` to stand for `leaf`,
/// and its measured error; `None` when `leaf` is not `shape` moved by `t`
/// triangle for triangle.
fn moved(leaf: &Mesh, shape: &Mesh, reduced: &Mesh, h: f32, t: Vec3) -> Option<(Mesh, f64)> {
    if leaf.indices != shape.indices || leaf.positions.len() != shape.positions.len() {
        return None;
    }
    let mut out = reduced.clone();
    for p in &mut out.positions {
        *p += t;
    }
    let leaf_moved = farthest(&leaf.positions, &shape.positions, t);
    let rounded = farthest(&out.positions, &reduced.positions, t);
    match leaf.features.first() {
        Some(&f) => out.features.iter_mut().for_each(|g| *g = f),
        None => out.features.clear(),
    }
    // The sum in `f64` of three small terms: one part in 10^12 covers its
    // rounding.
    let eps = (f64::from(h) + leaf_moved + rounded) * (1.0 + 1e-12);
    Some((out, eps))
}

/// The largest distance, in `f64`, of a point of `at` from its match in
/// `from` moved by `t`.
pub(super) fn farthest(at: &[Vec3], from: &[Vec3], t: Vec3) -> f64 {
    let t = t.as_dvec3();
    at.iter()
        .zip(from)
        .map(|(a, f)| (a.as_dvec3() - (f.as_dvec3() + t)).length())
        .fold(0.0, f64::max)
}

/// For each mesh, the first mesh with the same content: exporters write one
/// mesh per element even where elements repeat (the public Tekla model's
/// 2,636 meshes are 1,580 distinct ones), and leaves of equal meshes are
/// one shape.
fn same_meshes(meshes: &[Mesh]) -> Vec<usize> {
    let digests: Vec<blake3::Hash> = meshes.par_iter().map(mesh_digest).collect();
    let mut first: HashMap<blake3::Hash, usize> = HashMap::new();
    digests
        .iter()
        .enumerate()
        .map(|(i, d)| *first.entry(*d).or_insert(i))
        .collect()
}

/// The distinct shapes of `leaves` (mesh, transform, colour) used by more
/// than one leaf, made at the origin, and each leaf's instance of one.
pub(super) fn shapes_of(
    scene_meshes: &[Mesh],
    leaves: &[(usize, Mat4, [f32; 4])],
) -> (Vec<Arc<Mesh>>, Vec<Option<Instance>>) {
    let same = same_meshes(scene_meshes);
    let keys: Vec<ShapeKey> = leaves
        .iter()
        .map(|(mesh, transform, color)| ShapeKey::new(same[*mesh], transform, *color))
        .collect();
    let mut count: HashMap<ShapeKey, usize> = HashMap::new();
    for k in &keys {
        *count.entry(*k).or_default() += 1;
    }
    // Only shapes that repeat: a unique leaf's shape would be reduced
    // once either way, and held twice. Numbered in order of first use.
    let mut shape_of: HashMap<ShapeKey, u32> = HashMap::new();
    let mut first: Vec<usize> = Vec::new();
    let instances = leaves
        .iter()
        .zip(&keys)
        .enumerate()
        .map(|(i, ((_, transform, _), k))| {
            (count[k] > 1).then(|| Instance {
                shape: *shape_of.entry(*k).or_insert_with(|| {
                    first.push(i);
                    first.len() as u32 - 1
                }),
                translation: transform.w_axis.truncate(),
            })
        })
        .collect();
    let shapes: Vec<Arc<Mesh>> = first
        .par_iter()
        .map(|&i| {
            let (mesh, transform, color) = &leaves[i];
            Arc::new(canonical(&scene_meshes[*mesh], transform, *color))
        })
        .collect();
    (shapes, instances)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{HausdorffOptions, hausdorff};

    /// A moved reduction's error bounds the distance to the leaf it
    /// stands for, measured afresh.
    #[test]
    fn a_moved_reduction_keeps_a_true_bound() {
        let mesh = Mesh::cuboid(Vec3::ZERO, Vec3::new(0.3, 3.0, 0.4), 4);
        let rotation = Mat4::from_rotation_y(0.7);
        let color = [0.5, 0.6, 0.7, 1.0];
        let shape = canonical(&mesh, &rotation, color);
        let reduced = geometry::reduce_parts(&shape, 0.3, 1e-3, geometry::ErrorMetric::Geometry);
        assert!(reduced.mesh.triangle_count() < shape.triangle_count());
        for t in [Vec3::new(123.456, 7.5, -88.125), Vec3::new(-0.1, 0.2, 3e3)] {
            let transform = Mat4::from_translation(t) * rotation;
            let leaf = geometry::merge(
                &[Part {
                    mesh: &mesh,
                    transform,
                    color,
                    feature: Some(7),
                }],
                0.0,
            );
            let (out, eps) = moved(&leaf, &shape, &reduced.mesh, reduced.bound, t)
                .expect("the leaf is the shape moved");
            assert!(out.features.iter().all(|&f| f == 7));
            // The moves' rounding is measured: above nothing, far below a
            // millimetre.
            let rounding = eps - f64::from(reduced.bound);
            assert!(rounding > 0.0 && rounding < 1e-3, "{rounding} at {t}");
            let truth = hausdorff(
                &out,
                &leaf,
                &HausdorffOptions {
                    tolerance: 1e-5,
                    seed: 0,
                },
            );
            // `lower` is a distance found between the two: no bound may be
            // below it.
            assert!(
                f64::from(truth.lower) <= eps,
                "measured {} > stored {eps} at {t}",
                truth.lower
            );
        }
    }

    #[test]
    fn a_leaf_that_is_not_the_shape_is_not_moved() {
        let shape = Mesh::cuboid(Vec3::ZERO, Vec3::ONE, 1);
        let other = Mesh::cuboid(Vec3::ZERO, Vec3::ONE, 2);
        assert!(moved(&other, &shape, &shape, 0.0, Vec3::X).is_none());
    }

    #[test]
    fn equal_meshes_are_one_shape() {
        let cube = Mesh::cuboid(Vec3::ZERO, Vec3::ONE, 1);
        let finer = Mesh::cuboid(Vec3::ZERO, Vec3::ONE, 2);
        let meshes = vec![cube.clone(), finer, cube];
        let grey = [0.5; 4];
        let at = |x: f32| Mat4::from_translation(Vec3::new(x, 0.0, 0.0));
        let leaves = [(0, at(1.0), grey), (1, at(5.0), grey), (2, at(9.0), grey)];
        let (shapes, instances) = shapes_of(&meshes, &leaves);
        assert_eq!(shapes.len(), 1);
        assert_eq!(instances[0].map(|i| i.shape), Some(0));
        assert!(instances[1].is_none(), "a mesh of its own is unique");
        assert_eq!(instances[2].map(|i| i.shape), Some(0));
    }

    #[test]
    fn only_repeated_shapes_are_shared() {
        let meshes = vec![Mesh::cuboid(Vec3::ZERO, Vec3::ONE, 1)];
        let grey = [0.5; 4];
        let at = |x: f32| Mat4::from_translation(Vec3::new(x, 0.0, 0.0));
        let leaves = [
            (0, at(1.0), grey),
            (0, at(5.0), grey),
            (0, at(9.0), [1.0; 4]),
        ];
        let (shapes, instances) = shapes_of(&meshes, &leaves);
        assert_eq!(shapes.len(), 1);
        assert_eq!(instances[0].map(|i| i.shape), Some(0));
        assert_eq!(
            instances[1].map(|i| i.translation),
            Some(Vec3::new(5.0, 0.0, 0.0))
        );
        assert!(
            instances[2].is_none(),
            "a colour of its own is a shape of its own"
        );
    }
}
