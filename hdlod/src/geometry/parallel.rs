//! Quadric edge collapse of a large mesh in parallel, by spatial partition,
//! in two rounds. Each round splits the triangles at centroid medians (a
//! kd-tree's leaves), simplifies each part on its own thread with the
//! vertices it shares with another part locked, and concatenates the
//! parts' results. The first round takes the bulk of the reduction; the
//! second cuts across another axis, so that the first round's cut vertices
//! are free to collapse, and takes the rest. Because meshoptimizer only
//! selects vertices (it never moves one) and the shared vertices are
//! locked, the parts still meet exactly at the cuts: the seams need no
//! re-welding.
//!
//! References: meshoptimizer's README ("Simplification": `SimplifySparse`
//! and vertex locks for simplifying subsets of a large mesh independently);
//! Karis, Stubbe and Wihlidal, "Nanite: a deep dive" (SIGGRAPH 2021
//! course), which simplifies groups of clusters independently with their
//! shared boundaries locked, and regroups them between levels so that no
//! boundary stays locked for long; meshoptimizer's `demo/clusterlod.h`.
//!
//! The price is quality: each second-round part is reduced by the same
//! ratio, where one global pass would spend more collapses in flat regions.
//! docs/benchmarks.md measures it against the single pass on horse and
//! bunny.

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

/// Each part goes to this many times its share of the target in the first
/// round; the second round, over differently cut parts, goes to the target
/// itself. That round collapses the first round's cut vertices and
/// redistributes the reduction within each of its parts, which per-part
/// targets alone cannot: on horse to 2%, four parts without it double the
/// Hausdorff bound and triple the mean distance.
const PART_SLACK: f64 = 2.0;
/// The second round's parts: its input is small (twice the target), and
/// with one cut it crosses the first round's cuts at few vertices.
const SECOND_ROUND_PARTS: usize = 2;

/// One meshoptimizer call: the triangles `indices` (into the whole vertex
/// buffer), `locks` one per vertex, the target in indices, the error
/// absolute. Returns indices into the same vertex buffer and the error
/// meshoptimizer reached.
pub(super) type Collapse<'a> =
    dyn Fn(&[u32], &[bool], usize, f32, Flags) -> (Vec<u32>, f32) + Sync + 'a;

/// Simplifies `mesh` (cleaned) in `parts` parts
/// to `target_triangles` in total within the absolute error `max_error`
/// (never more triangles than asked, as one pass).
///
/// Two rounds, each in parallel: `parts` parts cut at medians along the
/// longest axes, each to `PART_SLACK` times its share; then two parts cut
/// across another axis, each to its share of the target, with what is left
/// of the error budget. A vertex stays locked through both rounds only where
/// the two rounds' cuts cross.
pub(super) fn collapse_in_parts(
    mesh: &Mesh,
    parts: usize,
    target_triangles: usize,
    max_error: f32,
    flags: Flags,
    collapse: &Collapse<'_>,
) -> Vec<u32> {
    // meshoptimizer treats coincident vertices (an attribute seam) as one,
    // so a cut locks all of them together.
    let same_position = meshopt::generate_position_remap(&adapter(mesh));
    let n = mesh.indices.len() / 3;
    let first = round(
        mesh,
        &same_position,
        &mesh.indices,
        parts,
        None,
        |part| ((part as f64 * target_triangles as f64 / n as f64 * PART_SLACK) as usize).min(part),
        max_error,
        flags,
        collapse,
    );
    if first.indices.len() <= 3 * target_triangles {
        return first.indices;
    }
    let m = first.indices.len() / 3;
    round(
        mesh,
        &same_position,
        &first.indices,
        SECOND_ROUND_PARTS,
        Some(first.axis),
        |part| (part as f64 * target_triangles as f64 / m as f64) as usize,
        // The second round starts from the first's result, so its error
        // adds to the first's: it gets what is left of the budget.
        (max_error - first.reached).max(0.0),
        flags,
        collapse,
    )
    .indices
}

/// What one round of parts produced.
struct Round {
    /// The parts' results, concatenated.
    indices: Vec<u32>,
    /// The largest error meshoptimizer reached in a part.
    reached: f32,
    /// The axis of the round's first cut.
    axis: usize,
}

/// Simplifies the triangles `indices` (into `mesh`'s vertices) in `parts`
/// parts on parallel threads, each to `share(its triangle count)`
/// triangles, with the vertices two parts share locked. The first cut runs
/// across the longest axis other than `avoid`.
#[allow(clippy::too_many_arguments)]
fn round(
    mesh: &Mesh,
    same_position: &[u32],
    indices: &[u32],
    parts: usize,
    avoid: Option<usize>,
    share: impl Fn(usize) -> usize + Sync,
    max_error: f32,
    flags: Flags,
    collapse: &Collapse<'_>,
) -> Round {
    let positions = &mesh.positions;
    let centroids: Vec<Vec3> = indices
        .chunks_exact(3)
        .map(|t| {
            (positions[t[0] as usize] + positions[t[1] as usize] + positions[t[2] as usize]) / 3.0
        })
        .collect();
    let mut order: Vec<u32> = (0..centroids.len() as u32).collect();
    let mut slices = Vec::with_capacity(parts);
    let axis = split(&mut order, &centroids, parts, avoid, &mut slices);

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
            collapse(
                &part,
                &locks,
                3 * share(slice.len()),
                max_error,
                flags | Flags::Sparse | Flags::ErrorAbsolute,
            )
        })
        .collect();
    Round {
        reached: results.iter().map(|r| r.1).fold(0.0, f32::max),
        indices: results.into_iter().flat_map(|r| r.0).collect(),
        axis,
    }
}

/// Splits `order` (triangle ids) into `parts` slices of near equal size at
/// centroid medians along the longest axis of each slice's centroids (at
/// the top, the longest other than `avoid`). Returns the top cut's axis.
fn split<'a>(
    order: &'a mut [u32],
    centroids: &[Vec3],
    parts: usize,
    avoid: Option<usize>,
    out: &mut Vec<&'a [u32]>,
) -> usize {
    let (lo, hi) = order.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &t| (lo.min(centroids[t as usize]), hi.max(centroids[t as usize])),
    );
    let mut extent = hi - lo;
    if let Some(a) = avoid {
        extent[a] = f32::NEG_INFINITY;
    }
    let axis = extent.max_position();
    if parts <= 1 || order.len() < 2 {
        out.push(order);
        return axis;
    }
    let left_parts = parts / 2;
    let mid = order.len() * left_parts / parts;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(mid);
    split(left, centroids, left_parts, None, out);
    split(right, centroids, parts - left_parts, None, out);
    axis
}
