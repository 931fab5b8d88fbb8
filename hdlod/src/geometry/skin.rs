//! Skinned meshes: linear blend skinning (glTF 2.0 specification, section
//! 3.7.3 "Skins": a vertex moves with up to four joints, each joint's
//! matrix its world transform after its inverse bind matrix, weighted),
//! and levels of detail that keep the deformation right in every pose, not
//! only the bind pose.
//!
//! The multi-pose reduction follows the skinned-mesh LOD literature
//! (Mohr and Gleicher, "Deformation sensitive decimation", 2003; Kho and
//! Garland's pose-averaged quadrics): the error of a collapse is summed
//! over sampled poses. Here meshoptimizer carries it: each vertex's
//! position in every sampled pose is an attribute of the vertex
//! (`meshopt_simplifyWithAttributes`), so a collapse that is harmless in
//! the bind pose but tears the mesh where a joint bends costs what it
//! costs there. The reduction keeps a subset of the vertices (no vertex is
//! placed), so a kept vertex keeps its own joints and weights, which are
//! already normalised to the four largest influences; nothing is
//! interpolated. Each level's error is measured, not estimated: the
//! largest, over the sampled poses, of the Hausdorff bound between the
//! posed full mesh and the posed level.

use glam::{Mat4, Vec3};
use meshopt::SimplifyOptions;

use super::{HausdorffOptions, Mesh, hausdorff};

/// At most this many poses go into one reduction: meshoptimizer weighs at
/// most 32 attributes per vertex, three per pose.
pub const MAX_POSES: usize = 10;

/// The joints and weights of each vertex of a mesh (`JOINTS_0`,
/// `WEIGHTS_0`).
#[derive(Debug, Clone, PartialEq)]
pub struct Skin {
    pub joints: Vec<[u16; 4]>,
    pub weights: Vec<[f32; 4]>,
}

impl Skin {
    /// Why the skin cannot deform `mesh` with `joint_count` joints, if it
    /// cannot: one entry per vertex, joints in range, weights finite, not
    /// negative and summing to 1 (within glTF's tolerance of 2e-7 per
    /// non-zero weight, loosened to 1e-3 for data written in 8 bits).
    pub fn problem(&self, mesh: &Mesh, joint_count: usize) -> Option<String> {
        let n = mesh.positions.len();
        if self.joints.len() != n || self.weights.len() != n {
            return Some(format!(
                "{} joint sets and {} weight sets for {n} vertices",
                self.joints.len(),
                self.weights.len()
            ));
        }
        for (v, (j, w)) in self.joints.iter().zip(&self.weights).enumerate() {
            if let Some(k) = (0..4).find(|&k| w[k] > 0.0 && usize::from(j[k]) >= joint_count) {
                return Some(format!(
                    "vertex {v}: joint {} of {joint_count} (influence {k})",
                    j[k]
                ));
            }
            if w.iter().any(|x| !x.is_finite() || *x < 0.0) {
                return Some(format!(
                    "vertex {v}: weights {w:?} are not all finite and >= 0"
                ));
            }
            let sum: f32 = w.iter().sum();
            if (sum - 1.0).abs() > 1e-3 {
                return Some(format!("vertex {v}: weights {w:?} sum to {sum}, not 1"));
            }
        }
        None
    }

    /// `mesh` (in its bind pose) deformed by `matrices`: each joint's world
    /// transform after its inverse bind matrix.
    pub fn pose(&self, mesh: &Mesh, matrices: &[Mat4]) -> Mesh {
        let blend = |v: usize| -> Mat4 {
            let (j, w) = (self.joints[v], self.weights[v]);
            (0..4)
                .filter(|&k| w[k] > 0.0)
                .map(|k| matrices[usize::from(j[k])] * w[k])
                .fold(Mat4::ZERO, |a, b| a + b)
        };
        let mut out = mesh.clone();
        for (v, p) in out.positions.iter_mut().enumerate() {
            *p = blend(v).transform_point3(*p);
        }
        for (v, n) in out.normals.iter_mut().enumerate() {
            *n = blend(v).transform_vector3(*n).normalize_or_zero();
        }
        out
    }
}

/// How far a level strays from the full mesh over sampled poses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseError {
    /// The largest Hausdorff bound over the poses.
    pub largest: f64,
    /// Their mean.
    pub mean: f64,
}

/// The error of `level` (indices into `mesh`'s vertices) against `mesh`
/// over `poses`, each the joint matrices of one pose.
pub fn pose_error(mesh: &Mesh, level: &[u32], skin: &Skin, poses: &[Vec<Mat4>]) -> PoseError {
    let options = HausdorffOptions::default();
    let bounds: Vec<f64> = poses
        .iter()
        .map(|pose| {
            let full = skin.pose(mesh, pose);
            let reduced = Mesh {
                indices: level.to_vec(),
                ..full.clone()
            };
            f64::from(hausdorff(&full, &reduced, &options).bound)
        })
        .collect();
    PoseError {
        largest: bounds.iter().copied().fold(0.0, f64::max),
        mean: bounds.iter().sum::<f64>() / bounds.len().max(1) as f64,
    }
}

/// A level of `mesh` with at most `target` triangles, its collapses
/// weighed in every one of `poses` (at most [`MAX_POSES`]); the indices
/// into `mesh`'s vertices. An empty `poses` weighs the bind pose alone:
/// the reduction it is compared against.
pub fn reduce_posed(mesh: &Mesh, skin: &Skin, poses: &[Vec<Mat4>], target: usize) -> Vec<u32> {
    let vertices = super::simplify::adapter(mesh);
    let options = SimplifyOptions::LockBorder;
    let poses = &poses[..poses.len().min(MAX_POSES)];
    if poses.is_empty() {
        return meshopt::simplify(
            &mesh.indices,
            &vertices,
            target * 3,
            f32::MAX,
            options,
            None,
        );
    }
    let stride = 3 * poses.len();
    let mut attributes = vec![0.0f32; mesh.positions.len() * stride];
    for (k, pose) in poses.iter().enumerate() {
        let posed = skin.pose(mesh, pose);
        for (v, p) in posed.positions.iter().enumerate() {
            attributes[v * stride + 3 * k..][..3].copy_from_slice(&p.to_array());
        }
    }
    // meshoptimizer measures the bind positions in the mesh scaled to its
    // extent, the attributes as they are: each pose's positions are scaled
    // alike, and the poses share one bind position's weight. Heavier, the
    // reduction trades the cross-section away to keep rings at the joints
    // (a limb turned to a triangular prism strays in every pose).
    let extent = mesh
        .bounds()
        .map_or(1.0, |(lo, hi)| (hi - lo).max_element())
        .max(f32::MIN_POSITIVE);
    let weights = vec![1.0 / (extent * poses.len() as f32); stride];
    let locks = vec![false; mesh.positions.len()];
    meshopt::simplify_with_attributes_and_locks(
        &mesh.indices,
        &vertices,
        &attributes,
        &weights,
        stride,
        &locks,
        target * 3,
        f32::MAX,
        options,
        None,
    )
}

/// The joint matrices of a chain of joints, each turned by `angles[k]`
/// about `axis` at its own origin, joint `k` at `origins[k]` in the bind
/// pose (bind transforms are translations): what a bent limb or a walker's
/// stride looks like, for tests and the fixture's walker.
pub fn chain_pose(origins: &[Vec3], axis: Vec3, angles: &[f32]) -> Vec<Mat4> {
    let mut world = Mat4::IDENTITY;
    let mut out = Vec::with_capacity(origins.len());
    for (k, origin) in origins.iter().enumerate() {
        let local_origin = if k == 0 {
            *origin
        } else {
            *origin - origins[k - 1]
        };
        world = world
            * Mat4::from_translation(local_origin)
            * Mat4::from_axis_angle(axis, angles.get(k).copied().unwrap_or(0.0));
        // World after the inverse bind (a translation to the joint).
        out.push(world * Mat4::from_translation(-*origin));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One triangle, its corners on two joints: the bottom edge on joint
    /// 0, the top corner on joint 1.
    fn hinge() -> (Mesh, Skin) {
        let mesh = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(0.5, 1.0, 0.0)],
            indices: vec![0, 1, 2],
            ..Mesh::default()
        };
        let skin = Skin {
            joints: vec![[0, 0, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0]],
            weights: vec![[1.0, 0.0, 0.0, 0.0]; 3],
        };
        (mesh, skin)
    }

    #[test]
    fn the_bind_pose_is_the_mesh_and_a_turned_joint_moves_its_vertices() {
        let (mesh, skin) = hinge();
        assert_eq!(skin.problem(&mesh, 2), None);
        let joints = [Vec3::ZERO, Vec3::Y * 0.5];
        let bind = skin.pose(&mesh, &chain_pose(&joints, Vec3::Z, &[0.0, 0.0]));
        assert_eq!(bind.positions, mesh.positions);
        let half_turn = std::f32::consts::PI;
        let turned = skin.pose(&mesh, &chain_pose(&joints, Vec3::Z, &[0.0, half_turn]));
        // The top corner turned half about the joint at (0, 0.5, 0).
        assert!(turned.positions[2].distance(Vec3::new(-0.5, 0.0, 0.0)) < 1e-5);
        assert_eq!(turned.positions[..2], mesh.positions[..2]);
    }

    #[test]
    fn weights_must_cover_every_vertex_and_sum_to_one() {
        let (mesh, mut skin) = hinge();
        assert!(skin.problem(&mesh, 1).unwrap().contains("joint 1 of 1"));
        skin.weights[1] = [0.5, 0.2, 0.0, 0.0];
        assert!(skin.problem(&mesh, 2).unwrap().contains("sum to 0.7"));
        skin.weights.pop();
        assert!(skin.problem(&mesh, 2).unwrap().contains("for 3 vertices"));
    }
}
