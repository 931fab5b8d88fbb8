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
    let n = mesh.indices.len() / 3;
    // meshoptimizer treats coincident vertices (an attribute seam) as one,
    // so a cut locks all of them together.
    let (same_position, first_cut) = rayon::join(
        || meshopt::generate_position_remap(&adapter(mesh)),
        || Partition::new(&mesh.positions, &mesh.indices, parts, None),
    );
    let (first, reached) = round(
        mesh,
        &same_position,
        &mesh.indices,
        &first_cut,
        |part| ((part as f64 * target_triangles as f64 / n as f64 * PART_SLACK) as usize).min(part),
        max_error,
        flags,
        collapse,
    );
    if first.len() <= 3 * target_triangles {
        return first;
    }
    let m = first.len() / 3;
    let second_cut = Partition::new(
        &mesh.positions,
        &first,
        SECOND_ROUND_PARTS,
        Some(first_cut.axis),
    );
    round(
        mesh,
        &same_position,
        &first,
        &second_cut,
        |part| (part as f64 * target_triangles as f64 / m as f64) as usize,
        // The second round starts from the first's result, so its error
        // adds to the first's: it gets what is left of the budget.
        (max_error - reached).max(0.0),
        flags,
        collapse,
    )
    .0
}

/// Simplifies the triangles `indices` (into `mesh`'s vertices), split as
/// `cut` says, on parallel threads, each part to `share(its triangle
/// count)` triangles, with the vertices two parts share locked. Returns the
/// parts' results concatenated and the largest error meshoptimizer reached.
#[allow(clippy::too_many_arguments)]
fn round(
    mesh: &Mesh,
    same_position: &[u32],
    indices: &[u32],
    cut: &Partition,
    share: impl Fn(usize) -> usize + Sync,
    max_error: f32,
    flags: Flags,
    collapse: &Collapse<'_>,
) -> (Vec<u32>, f32) {
    let mut part_of = vec![0u32; indices.len() / 3];
    for (p, part) in cut.parts().enumerate() {
        for &t in part {
            part_of[t as usize] = p as u32;
        }
    }
    // In triangle order, so that the index buffer is read in sequence.
    const SHARED: u32 = u32::MAX - 1;
    let mut owner = vec![u32::MAX; mesh.positions.len()];
    for (t, &p) in indices.chunks_exact(3).zip(&part_of) {
        for &v in t {
            let o = &mut owner[same_position[v as usize] as usize];
            if *o == u32::MAX {
                *o = p;
            } else if *o != p {
                *o = SHARED;
            }
        }
    }
    let locks: Vec<bool> = same_position
        .iter()
        .map(|&r| owner[r as usize] == SHARED)
        .collect();

    let results: Vec<(Vec<u32>, f32)> = cut
        .parts()
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|part| {
            let triangles: Vec<u32> = part
                .iter()
                .flat_map(|&t| indices[3 * t as usize..3 * t as usize + 3].iter().copied())
                .collect();
            collapse(
                &triangles,
                &locks,
                3 * share(part.len()),
                max_error,
                flags | Flags::Sparse | Flags::ErrorAbsolute,
            )
        })
        .collect();
    let reached = results.iter().map(|r| r.1).fold(0.0, f32::max);
    (results.into_iter().flat_map(|r| r.0).collect(), reached)
}

/// Triangles split into parts of near equal size at centroid medians along
/// the longest axis of each part's centroids (a kd-tree's leaves).
struct Partition {
    /// Triangle ids, part after part.
    order: Vec<u32>,
    /// Where each part ends in `order`.
    ends: Vec<usize>,
    /// The axis of the first cut.
    axis: usize,
}

impl Partition {
    /// `parts` parts of the triangles `indices`; the first cut runs across
    /// the longest axis other than `avoid`.
    fn new(positions: &[Vec3], indices: &[u32], parts: usize, avoid: Option<usize>) -> Self {
        let centroids: Vec<Vec3> = indices
            .chunks_exact(3)
            .map(|t| {
                (positions[t[0] as usize] + positions[t[1] as usize] + positions[t[2] as usize])
                    / 3.0
            })
            .collect();
        let mut order: Vec<u32> = (0..centroids.len() as u32).collect();
        let mut ends = Vec::with_capacity(parts);
        let axis = split(&mut order, 0, &centroids, parts, avoid, &mut ends);
        Partition { order, ends, axis }
    }

    fn parts(&self) -> impl Iterator<Item = &[u32]> {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts.zip(&self.ends).map(|(a, &b)| &self.order[a..b])
    }
}

/// Splits `order` (triangle ids, starting at `offset` in the whole order)
/// into `parts` slices of near equal size, pushing where each ends. The
/// cut at the top runs across the longest axis other than `avoid`; that
/// axis is returned.
fn split(
    order: &mut [u32],
    offset: usize,
    centroids: &[Vec3],
    parts: usize,
    avoid: Option<usize>,
    ends: &mut Vec<usize>,
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
        ends.push(offset + order.len());
        return axis;
    }
    let left_parts = parts / 2;
    let mid = order.len() * left_parts / parts;
    // The coordinate and the id in one integer: selecting among these
    // reads no centroid, and ties fall to the id, the same on every run.
    let mut keyed: Vec<u64> = order
        .iter()
        .map(|&t| (u64::from(ordered_bits(centroids[t as usize][axis])) << 32) | u64::from(t))
        .collect();
    keyed.select_nth_unstable(mid);
    for (o, k) in order.iter_mut().zip(&keyed) {
        *o = *k as u32;
    }
    let (left, right) = order.split_at_mut(mid);
    split(left, offset, centroids, left_parts, None, ends);
    split(
        right,
        offset + mid,
        centroids,
        parts - left_parts,
        None,
        ends,
    );
    axis
}

/// The bits of a finite float as an integer of the same order.
fn ordered_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 { !b } else { b | 1 << 31 }
}
