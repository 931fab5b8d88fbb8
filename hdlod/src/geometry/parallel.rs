//! Quadric edge collapse of a large mesh in parallel, by spatial partition:
//! the triangles are split at centroid medians along the longest axis
//! (a kd-tree's leaves), each part is simplified on its own thread with the
//! vertices it shares with another part locked, and the parts' results are
//! concatenated. Because meshoptimizer only selects vertices (it never moves
//! one) and the shared vertices are locked, the parts still meet exactly at
//! the cuts: the seams need no re-welding.
//!
//! References: meshoptimizer's README ("Simplification": `SimplifySparse`
//! and vertex locks for simplifying subsets of a large mesh independently);
//! Karis, Stubbe and Wihlidal, "Nanite: a deep dive" (SIGGRAPH 2021
//! course), which simplifies groups of clusters independently with their
//! shared boundaries locked; meshoptimizer's `demo/clusterlod.h`, the same.
//!
//! The price is quality: every part is reduced by the same ratio, where one
//! global pass would spend more collapses in flat regions, and the cut
//! vertices survive. docs/benchmarks.md measures both against the single
//! pass on horse.

use glam::Vec3;
use meshopt::SimplifyOptions as Flags;
use rayon::prelude::*;

use super::Mesh;
use super::simplify::adapter;

/// Meshes with fewer triangles take the single-thread path: a tree
/// builder's clusters are smaller, and the builder already runs them in
/// parallel with each other.
pub(super) const PARALLEL_MIN_TRIANGLES: usize = 40_000;
/// Each part keeps at least this many triangles, so that the locked cut
/// vertices stay a small share of a part.
const MIN_PART_TRIANGLES: usize = 20_000;
/// At most this many parts: more adds seams without adding speed.
const MAX_PARTS: usize = 8;

/// How many parts `triangles` triangles are split into: a power of two
/// fixed by the size alone (not by the machine's thread count), so that
/// the result is the same on every machine.
pub(super) fn part_count(triangles: usize) -> usize {
    if triangles < PARALLEL_MIN_TRIANGLES {
        return 1;
    }
    let mut parts = 1;
    while parts * 2 <= MAX_PARTS && triangles / (parts * 2) >= MIN_PART_TRIANGLES {
        parts *= 2;
    }
    parts
}

/// Each part goes to this many times its share of the target; one pass
/// over the joined parts then goes to the target itself. That pass can
/// collapse the cut vertices and redistribute the reduction between the
/// parts, which per-part targets alone cannot: on horse to 2%, four parts
/// without it double the Hausdorff bound and triple the mean distance.
const PART_SLACK: f64 = 2.0;

/// One meshoptimizer call: the triangles `indices` (into the whole vertex
/// buffer), `locks` one per vertex, the target in indices, the error
/// absolute. Returns indices into the same vertex buffer and the error
/// meshoptimizer reached.
pub(super) type Collapse<'a> =
    dyn Fn(&[u32], &[bool], usize, f32, Flags) -> (Vec<u32>, f32) + Sync + 'a;

/// Simplifies `mesh` (cleaned) in `parts` parts
/// to `target_triangles` in total within the absolute error `max_error`
/// (never more triangles than asked, as one pass).
pub(super) fn collapse_in_parts(
    mesh: &Mesh,
    parts: usize,
    target_triangles: usize,
    max_error: f32,
    flags: Flags,
    collapse: &Collapse<'_>,
) -> Vec<u32> {
    let (positions, indices) = (&mesh.positions, &mesh.indices);
    let n = indices.len() / 3;
    let mut order: Vec<u32> = (0..n as u32).collect();
    let centroids: Vec<Vec3> = indices
        .chunks_exact(3)
        .map(|t| {
            (positions[t[0] as usize] + positions[t[1] as usize] + positions[t[2] as usize]) / 3.0
        })
        .collect();
    let mut slices = Vec::with_capacity(parts);
    split(&mut order, &centroids, parts, &mut slices);

    // A vertex is shared when two parts use it, or use two vertices at the
    // same position (an attribute seam): meshoptimizer treats coincident
    // vertices as one, so all of them must be locked together.
    let same_position = meshopt::generate_position_remap(&adapter(mesh));
    const SHARED: u32 = u32::MAX - 1;
    let mut owner = vec![u32::MAX; positions.len()];
    for (p, slice) in slices.iter().enumerate() {
        for &t in *slice {
            for &v in &indices[3 * t as usize..3 * t as usize + 3] {
                let o = &mut owner[same_position[v as usize] as usize];
                if *o == u32::MAX {
                    *o = p as u32;
                } else if *o != p as u32 {
                    *o = SHARED;
                }
            }
        }
    }
    let locks: Vec<bool> = same_position
        .iter()
        .map(|&r| owner[r as usize] == SHARED)
        .collect();

    let results: Vec<(Vec<u32>, f32)> = slices
        .par_iter()
        .map(|slice| {
            let part: Vec<u32> = slice
                .iter()
                .flat_map(|&t| indices[3 * t as usize..3 * t as usize + 3].iter().copied())
                .collect();
            let share =
                (slice.len() as f64 * target_triangles as f64 / n as f64 * PART_SLACK) as usize;
            collapse(
                &part,
                &locks,
                3 * share.min(slice.len()),
                max_error,
                flags | Flags::Sparse | Flags::ErrorAbsolute,
            )
        })
        .collect();
    let reached = results.iter().map(|r| r.1).fold(0.0, f32::max);
    let joined: Vec<u32> = results.into_iter().flat_map(|r| r.0).collect();
    if joined.len() <= 3 * target_triangles {
        return joined;
    }
    // The second pass starts from the parts' results, so its error adds to
    // theirs: it gets what is left of the budget.
    let unlocked = vec![false; positions.len()];
    collapse(
        &joined,
        &unlocked,
        3 * target_triangles,
        (max_error - reached).max(0.0),
        flags | Flags::Sparse | Flags::ErrorAbsolute,
    )
    .0
}

/// Splits `order` (triangle ids) into `parts` slices of near equal size at
/// centroid medians along the longest axis of each slice's centroids.
fn split<'a>(order: &'a mut [u32], centroids: &[Vec3], parts: usize, out: &mut Vec<&'a [u32]>) {
    if parts <= 1 || order.len() < 2 {
        out.push(order);
        return;
    }
    let (lo, hi) = order.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &t| (lo.min(centroids[t as usize]), hi.max(centroids[t as usize])),
    );
    let axis = (hi - lo).max_position();
    let left_parts = parts / 2;
    let mid = order.len() * left_parts / parts;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(mid);
    split(left, centroids, left_parts, out);
    split(right, centroids, parts - left_parts, out);
}
