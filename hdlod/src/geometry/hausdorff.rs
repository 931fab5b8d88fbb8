//! A conservative upper bound of the symmetric Hausdorff distance between
//! two triangle meshes, by branch and bound over the triangles of each mesh
//! (after Tang, Lee and Kim, "Interactive Hausdorff distance computation for
//! general polygonal models", SIGGRAPH 2009).
//!
//! The distance to the other surface, `d(p)`, is 1-Lipschitz. For a triangle
//! with exact corner distances `d_i`, every point `p` of it satisfies
//! `d(p) <= d_i + |p - c_i| <= d_i + max_j |c_j - c_i|` for each corner `i`,
//! so `min_i (d_i + max_j |c_j - c_i|)` bounds `d` over the whole triangle;
//! and the distance to any single triangle of the other mesh is convex, so
//! its largest value over a convex polygon is at a corner: over the
//! triangle, or over the parts of it cut along a crease or into the
//! sectors of a fan of the other mesh, each part held to its own triangle
//! (see `triangle_upper`, `cut_pair_bound`, `star_bound`). Any exact
//! `d(p)` is a lower bound of the supremum. Triangles whose
//! upper bound could still raise the running lower bound are split, largest
//! bound first, until the gap between the two is at most the tolerance:
//! 4 ways at their edge midpoints, or, when thin, in two across their
//! longest edge (longest-edge bisection, Rivara 1984). A sliver split 4
//! ways stays a sliver, and its Lipschitz bound (which carries its longest
//! edge) settles only once that edge is under the tolerance: a 1 m sliver
//! 0.1 mm wide took millions of pieces at a tolerance of 0.17 mm where
//! bisection, whose pieces become round once they are as short as the
//! sliver is wide, takes a few thousand. Every number returned as a bound
//! is one.
//!
//! Mean and RMS come from an area-weighted random sample of each surface
//! (seeded, so deterministic), pooled over both directions.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f32::consts::TAU;

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::Mesh;
use super::closest::TriangleSet;

/// A triangle's pieces are not split past this depth, a 4-way split
/// counting 2 and a bisection 1 (both about halve the longest edge): its
/// bound then stands as it is (still a bound, only looser).
const MAX_DEPTH: u8 = 32;
/// A triangle whose longest edge is more than this many times the height
/// over it is bisected rather than split 4 ways.
const THIN: f32 = 4.0;
/// Open triangles kept at once; past this the search stops with the bound
/// it has, to keep memory bounded on pathological inputs.
const MAX_OPEN: usize = 1 << 20;
/// Tolerances below this fraction of the scene diagonal are raised to it:
/// finer than float precision is not meaningful and would not terminate.
const MIN_RELATIVE_TOLERANCE: f32 = 1e-6;
/// Float rounding of the closest-point computations, as a multiple of the
/// largest coordinate, added to the upper bound so that it stays one.
const ROUNDING_SLACK: f32 = 16.0 * f32::EPSILON;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HausdorffOptions {
    /// Refinement stops when `upper - lower <= tolerance` (scene units).
    /// Zero or less means as tight as float precision allows.
    pub tolerance: f32,
    /// Seed of the surface sample that gives the mean and RMS.
    pub seed: u64,
}

impl Default for HausdorffOptions {
    fn default() -> Self {
        HausdorffOptions {
            tolerance: 0.0,
            seed: 0,
        }
    }
}

/// The distances between two meshes `A` and `B`.
///
/// Empty meshes: between two empty meshes every field is 0; between an empty
/// and a non-empty one every field is `f32::INFINITY` (no point of the empty
/// one is near the other). Triangles with a non-finite corner are ignored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hausdorff {
    /// Conservative upper bound of the symmetric Hausdorff distance.
    pub bound: f32,
    /// A lower bound of it: the largest exactly measured distance.
    pub lower: f32,
    /// Mean of the sampled point-to-surface distances, both directions.
    pub mean: f32,
    /// Root mean square of the same sample.
    pub rms: f32,
    /// Upper bound of `sup_{a in A} d(a, B)`.
    pub ab: f32,
    /// Upper bound of `sup_{b in B} d(b, A)`.
    pub ba: f32,
}

pub fn hausdorff(a: &Mesh, b: &Mesh, options: &HausdorffOptions) -> Hausdorff {
    let tris_a = finite_triangles(a);
    let tris_b = finite_triangles(b);
    match (tris_a.is_empty(), tris_b.is_empty()) {
        (true, true) => {
            return Hausdorff {
                bound: 0.0,
                lower: 0.0,
                mean: 0.0,
                rms: 0.0,
                ab: 0.0,
                ba: 0.0,
            };
        }
        (false, false) => {}
        _ => {
            let inf = f32::INFINITY;
            return Hausdorff {
                bound: inf,
                lower: inf,
                mean: inf,
                rms: inf,
                ab: inf,
                ba: inf,
            };
        }
    }
    let (tolerance, slack) = search_scale(&tris_a, &tris_b, options.tolerance);
    let set_a = TriangleSet::new(tris_a.iter().copied());
    let set_b = TriangleSet::new(tris_b.iter().copied());
    let full = |a, b, seed| {
        one_way(a, b, tolerance, Some(seed), f32::INFINITY, 0.0)
            .expect("no distance exceeds an infinite budget")
    };
    let ab = full(&tris_a, &set_b, options.seed);
    let ba = full(&tris_b, &set_a, options.seed ^ 0x9e37_79b9_7f4a_7c15);
    let n = (ab.samples + ba.samples).max(1) as f64;
    Hausdorff {
        bound: ab.upper.max(ba.upper) + slack,
        lower: ab.lower.max(ba.lower),
        mean: ((ab.sum + ba.sum) / n) as f32,
        rms: ((ab.sum_squares + ba.sum_squares) / n).sqrt() as f32,
        ab: ab.upper + slack,
        ba: ba.upper + slack,
    }
}

/// A conservative upper bound of `sup_{a in A} d(a, B)` alone, against a
/// set `B` prepared once and searched for many `A` (no mean or RMS). An
/// empty `B` gives infinity, an empty `A` zero.
pub fn one_sided_bound(a: &Mesh, b: &TriangleSet, tolerance: f32) -> f32 {
    let tris = finite_triangles(a);
    if tris.is_empty() {
        return 0.0;
    }
    if b.is_empty() {
        return f32::INFINITY;
    }
    let (lo, hi) = tris
        .iter()
        .flatten()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    // B is near A wherever the bound matters, so A's extent sets the
    // rounding scale.
    let max_coordinate = lo.abs().max(hi.abs()).max_element();
    let tolerance = tolerance.max(MIN_RELATIVE_TOLERANCE * (hi - lo).length());
    one_way(&tris, b, tolerance, None, f32::INFINITY, 0.0)
        .expect("no distance exceeds an infinite budget")
        .upper
        + ROUNDING_SLACK * max_coordinate
}

/// A conservative bound of the symmetric Hausdorff distance between `a`
/// and `b`, within `tolerance` of it as [`hausdorff`]'s `bound` is, if the
/// bound is at most `budget`; `None` if it is not. Without the mean and RMS sample,
/// and the search stops at the first measured distance over the budget:
/// a tree build measures many candidates against budgets and keeps the
/// bound only of those that fit, so most of a failing candidate's queries
/// and every candidate's sample would be spent for nothing.
pub fn bound_within(a: &Mesh, b: &Mesh, tolerance: f32, budget: f32) -> Option<f32> {
    bound_within_target(a, &mut Target::new(b), tolerance, budget)
}

/// A mesh that candidates are measured against, one after another (a
/// part against its stand-ins): its triangles, and their search structure
/// once a candidate first needs it. Made again for each candidate, that
/// structure was a few percent of a steel model's build.
pub(crate) struct Target {
    triangles: Vec<[Vec3; 3]>,
    set: Option<TriangleSet>,
}

impl Target {
    pub(crate) fn new(m: &Mesh) -> Target {
        Target {
            triangles: finite_triangles(m),
            set: None,
        }
    }
}

/// [`bound_within`] of `a` against the mesh of `target`.
pub(crate) fn bound_within_target(
    a: &Mesh,
    target: &mut Target,
    tolerance: f32,
    budget: f32,
) -> Option<f32> {
    let tris_a = finite_triangles(a);
    let Target {
        triangles: tris_b,
        set: set_b,
    } = target;
    if tris_a.is_empty() || tris_b.is_empty() {
        let bound = if tris_a.is_empty() && tris_b.is_empty() {
            0.0
        } else {
            f32::INFINITY
        };
        return (bound <= budget).then_some(bound);
    }
    let (tolerance, slack) = search_scale(&tris_a, tris_b, tolerance);
    let within = budget - slack;
    let a_set = || TriangleSet::new(tris_a.iter().copied());
    // The smaller mesh's search structure first: a failing candidate may
    // never need the other. The second direction need only be measured as
    // far as it could raise the first's bound.
    let bound = if tris_a.len() <= tris_b.len() {
        let first = one_way(tris_b, &a_set(), tolerance, None, within, 0.0)?.upper;
        let b_set = set_b.get_or_insert_with(|| TriangleSet::new(tris_b.iter().copied()));
        first.max(one_way(&tris_a, b_set, tolerance, None, within, first)?.upper)
    } else {
        let b_set = set_b.get_or_insert_with(|| TriangleSet::new(tris_b.iter().copied()));
        let first = one_way(&tris_a, b_set, tolerance, None, within, 0.0)?.upper;
        first.max(one_way(tris_b, &a_set(), tolerance, None, within, first)?.upper)
    };
    let bound = bound + slack;
    (bound <= budget).then_some(bound)
}

/// The tolerance the search works to (the one asked for, raised to what
/// float precision can resolve at the meshes' size) and the rounding
/// slack added to its bound.
pub(super) fn search_scale(a: &[[Vec3; 3]], b: &[[Vec3; 3]], tolerance: f32) -> (f32, f32) {
    let (lo, hi) = a
        .iter()
        .chain(b)
        .flatten()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let tolerance = if tolerance.is_finite() {
        tolerance
    } else {
        0.0
    }
    .max(MIN_RELATIVE_TOLERANCE * (hi - lo).length());
    (
        tolerance,
        ROUNDING_SLACK * lo.abs().max(hi.abs()).max_element(),
    )
}

pub(super) fn finite_triangles(m: &Mesh) -> Vec<[Vec3; 3]> {
    (0..m.triangle_count())
        .filter_map(|k| finite_triangle(m, k))
        .collect()
}

/// The corners of `m`'s `k`-th triangle, unless an index is out of range
/// or a corner is not finite.
pub(super) fn finite_triangle(m: &Mesh, k: usize) -> Option<[Vec3; 3]> {
    let corner = |c: usize| m.positions.get(m.indices[k * 3 + c] as usize).copied();
    let t = [corner(0)?, corner(1)?, corner(2)?];
    t.iter().all(|p| p.is_finite()).then_some(t)
}

/// The upper bound of `d(p, B)` over the piece `c`: `triangle_upper`,
/// then, while that would leave the piece open, the centroid's and the
/// star's bounds, which cost more.
fn piece_upper(
    distance: &mut impl FnMut(Vec3, Option<u32>) -> (f32, u32),
    b: &TriangleSet,
    c: &[Vec3; 3],
    d: &[f32; 3],
    nearest: &[u32; 3],
    lower: &mut f32,
    settle: Settle,
) -> f32 {
    let mut upper = triangle_upper(b, c, d, nearest);
    if upper > settle.at(*lower) {
        upper = centroid_bound(distance, b, c, d, nearest, upper, lower);
    }
    if upper > settle.at(*lower) {
        upper = star_bound(b, c, nearest, upper);
    }
    upper
}

/// When a piece is settled: its bound within the tolerance of the lower
/// bound, or within the `floor` below which the caller need not know the
/// distance.
#[derive(Clone, Copy)]
struct Settle {
    tolerance: f32,
    floor: f32,
}

impl Settle {
    /// The largest bound of a settled piece, given the lower bound.
    fn at(self, lower: f32) -> f32 {
        (lower + self.tolerance).max(self.floor)
    }
}

/// Where the corners' nearest triangles meet at a corner `v` of B (a fan:
/// a plate tessellated around a hole or from one corner, a disc), a bound
/// of `d(p, B)` over `c` from cutting `c` into the sectors, around `c`'s
/// normal through `v`, of the triangles around `v` that face along it: each
/// part is bounded by the distance to its sector's triangle, which is
/// convex, so by its largest value at the part's corners (`c`'s own and
/// where `c`'s edges cross the sector's sides). It holds where the
/// sectors cover the whole of `c` as seen from `v`'s axis, whichever
/// triangle a point of overlapping sectors is given to. Tessellators make
/// fans of slivers; a piece near their corner has corners nearest to
/// triangles that share only it, and no other bound settles it before the
/// piece is about the tolerance across. That was most of the search on a
/// steel model's plates. `best` where it does not apply or would not beat
/// it.
fn star_bound(b: &TriangleSet, c: &[Vec3; 3], nearest: &[u32; 3], best: f32) -> f32 {
    if nearest[0] == nearest[1] && nearest[1] == nearest[2] {
        return best;
    }
    // The piece's own normal: where it matters, the piece lies along the
    // surface near `v`, whose triangles then face it.
    let [p, q, r] = b.corners(nearest[0]);
    let Some(axis) = (c[1] - c[0])
        .cross(c[2] - c[0])
        .try_normalize()
        .or_else(|| (q - p).cross(r - p).try_normalize())
    else {
        return best;
    };
    let mut best = best;
    for v in [p, q, r] {
        if nearest[1..].iter().all(|&t| b.corners(t).contains(&v)) {
            best = best.min(sectors_bound(b, c, v, axis, best));
        }
    }
    best
}

/// Most triangles a corner of B may have around it for `star_bound`.
const MAX_STAR: usize = 64;
/// The triangles around `v` that take part in `star_bound`: those within
/// about 11 degrees of facing along the axis (the fan a piece lies on)
/// and, where those do not cover the piece, within about 45 degrees (a
/// gently curved fan). A triangle seen edge-on from the axis has a sector
/// of nearly nothing or of half a turn, and one of a chamfer next to the
/// fan overlaps the fan's sectors and is far from the piece.
const FACING: [f32; 2] = [0.98, 0.7];
/// Gaps between sectors up to this angle (radians) are float rounding;
/// the bound covers them (see `sectors_bound`).
const MAX_GAP: f32 = 1e-4;

/// A triangle around a corner `v` of B, seen along an axis through `v`.
struct Sector {
    triangle: u32,
    /// Its two edges from `v`, flattened across the axis.
    sides: [Vec3; 2],
    /// Its interval of angle around the axis.
    start: f32,
    width: f32,
    /// `|cos|` of the angle between its normal and the axis.
    facing: f32,
}

/// The bound of `star_bound` for the triangles around `v` and `axis`.
fn sectors_bound(b: &TriangleSet, c: &[Vec3; 3], v: Vec3, axis: Vec3, best: f32) -> f32 {
    let flat = |e: Vec3| e - axis * e.dot(axis);
    let (fx, fy) = axis.any_orthonormal_pair();
    let angle = |e: Vec3| e.dot(fy).atan2(e.dot(fx)).rem_euclid(TAU);
    let mut sectors: Vec<Sector> = Vec::new();
    for t in b.around(v) {
        let corners = b.corners(t);
        let Some(k) = corners.iter().position(|p| *p == v) else {
            continue;
        };
        let (x, y) = (corners[(k + 1) % 3] - v, corners[(k + 2) % 3] - v);
        let Some(facing) = x.cross(y).try_normalize().map(|n| n.dot(axis).abs()) else {
            continue;
        };
        if facing < FACING[1] {
            continue;
        }
        let (x, y) = (flat(x), flat(y));
        let width = axis.dot(x.cross(y)).atan2(x.dot(y));
        sectors.push(Sector {
            triangle: t,
            sides: [x, y],
            start: angle(if width > 0.0 { x } else { y }),
            width: width.abs(),
            facing,
        });
        if sectors.len() > MAX_STAR {
            return best;
        }
    }
    // The arc of `c` seen from the axis: the whole turn where the axis
    // passes through `c`, else the turn less the largest gap between its
    // corners' angles (a corner on the axis, where a piece of A has a
    // corner at `v`, has no angle: its edges' directions are the other
    // corners').
    let seen = c.map(|p| flat(p - v));
    let normal = (seen[1] - seen[0]).cross(seen[2] - seen[0]);
    let through = (0..3).all(|k| seen[k].cross(seen[(k + 1) % 3]).dot(normal) > 0.0);
    let arc = if through {
        (0.0, TAU)
    } else {
        let mut angles: Vec<f32> = seen
            .iter()
            .filter(|e| e.length_squared() > 0.0)
            .map(|&e| angle(e))
            .collect();
        if angles.len() < 2 {
            return best;
        }
        angles.sort_by(f32::total_cmp);
        let n = angles.len();
        let (k, gap) = (0..n)
            .map(|k| {
                let next = if k + 1 < n {
                    angles[k + 1]
                } else {
                    angles[0] + TAU
                };
                (k, next - angles[k])
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0));
        (angles[(k + 1) % n], TAU - gap)
    };
    for facing in FACING {
        let chosen: Vec<&Sector> = sectors.iter().filter(|s| s.facing >= facing).collect();
        if let Some(gap) = uncovered(&chosen, arc) {
            // A point of `c` in a gap is within `radius * gap` of a side
            // of a sector, and `d` is 1-Lipschitz.
            let radius = c.iter().map(|p| p.distance(v)).fold(0.0, f32::max);
            return parts_bound(b, c, v, axis, &chosen, radius * gap, best);
        }
    }
    best
}

/// The largest gap (radians) the `sectors` leave in the `arc` (its start
/// and length), if none is over `MAX_GAP`.
fn uncovered(sectors: &[&Sector], (from, length): (f32, f32)) -> Option<f32> {
    // Each sector also a turn earlier, so that one that starts before the
    // arc counts.
    let mut spans: Vec<(f32, f32)> = sectors
        .iter()
        .flat_map(|s| {
            let start = (s.start - from).rem_euclid(TAU);
            [
                (start, start + s.width),
                (start - TAU, start - TAU + s.width),
            ]
        })
        .collect();
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut reach, mut gap) = (0.0f32, 0.0f32);
    for (start, end) in spans {
        if reach >= length {
            break;
        }
        gap = gap.max(start - reach);
        reach = reach.max(end);
    }
    gap = gap.max(length - reach);
    (gap <= MAX_GAP).then_some(gap)
}

/// The largest distance from a corner of `c`'s part in each sector to the
/// sector's triangle, starting from `worst`; `best` once it is reached.
fn parts_bound(
    b: &TriangleSet,
    c: &[Vec3; 3],
    v: Vec3,
    axis: Vec3,
    sectors: &[&Sector],
    mut worst: f32,
    best: f32,
) -> f32 {
    for s in sectors {
        // A side is the plane through `v` with the axis and one edge; the
        // sector is on the side of it where the other edge is.
        let mut part = Polygon::of(c);
        for (edge, other) in [(s.sides[0], s.sides[1]), (s.sides[1], s.sides[0])] {
            let normal = axis.cross(edge);
            let normal = if normal.dot(other) < 0.0 {
                -normal
            } else {
                normal
            };
            part = part.clipped(|p| normal.dot(p - v));
        }
        for &p in part.corners() {
            worst = worst.max(b.distance_to(p, s.triangle));
            if worst >= best {
                return best;
            }
        }
    }
    worst
}

/// A convex polygon of a triangle clipped by two planes: at most five
/// corners.
struct Polygon {
    corners: [Vec3; 5],
    len: usize,
}

impl Polygon {
    fn of(c: &[Vec3; 3]) -> Polygon {
        Polygon {
            corners: [c[0], c[1], c[2], Vec3::ZERO, Vec3::ZERO],
            len: 3,
        }
    }

    fn corners(&self) -> &[Vec3] {
        &self.corners[..self.len]
    }

    /// The part where `side` is not negative (Sutherland and Hodgman).
    fn clipped(&self, side: impl Fn(Vec3) -> f32) -> Polygon {
        let mut out = Polygon {
            corners: [Vec3::ZERO; 5],
            len: 0,
        };
        let mut push = |p: Vec3| {
            if out.len < out.corners.len() {
                out.corners[out.len] = p;
                out.len += 1;
            }
        };
        let points = self.corners();
        for (k, &p) in points.iter().enumerate() {
            let q = points[(k + 1) % points.len()];
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                push(p + (q - p) * (sp / (sp - sq)));
            }
        }
        out
    }
}

/// When the corners' nearest triangles do not settle a triangle, the one
/// nearest to its centroid may: on coincident surfaces a corner is equally
/// near to every triangle around it, the centroid only to the right one.
/// The centroid's own distance bounds the triangle too, by Lipschitz from
/// the centroid, which is about half as far from the farthest point as a
/// corner is: where the surface is near but broken into triangles smaller
/// than the piece, that settles a piece twice as large. The centroid's
/// distance also raises the lower bound.
fn centroid_bound(
    distance: &mut impl FnMut(Vec3, Option<u32>) -> (f32, u32),
    b: &TriangleSet,
    c: &[Vec3; 3],
    d: &[f32; 3],
    nearest: &[u32; 3],
    upper: f32,
    lower: &mut f32,
) -> f32 {
    let centroid = (c[0] + c[1] + c[2]) / 3.0;
    let (dc, tc) = distance(centroid, Some(nearest[0]));
    *lower = lower.max(dc);
    let radius = c.iter().map(|p| p.distance(centroid)).fold(0.0, f32::max);
    let upper = upper.min(dc + radius);
    if nearest.contains(&tc) {
        return upper;
    }
    union_bound(b, c, d, nearest, &[tc], upper)
}

struct OneWay {
    upper: f32,
    lower: f32,
    sum: f64,
    sum_squares: f64,
    samples: usize,
}

/// A triangle still open in the search, ordered by its upper bound.
struct Open {
    upper: f32,
    corners: [Vec3; 3],
    /// Exact distance of each corner to B, and B's triangle that attains it.
    distances: [f32; 3],
    nearest: [u32; 3],
    depth: u8,
}

impl PartialEq for Open {
    fn eq(&self, other: &Self) -> bool {
        self.upper.total_cmp(&other.upper) == Ordering::Equal
    }
}
impl Eq for Open {}
impl PartialOrd for Open {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Open {
    fn cmp(&self, other: &Self) -> Ordering {
        self.upper.total_cmp(&other.upper)
    }
}

/// An upper bound of `d(p, B)` over triangle `c`, the least of three:
/// - Lipschitz: `min_i (d_i + max_j |c_j - c_i|)`;
/// - convexity: for any one triangle `t` of B, `p -> d(p, t)` is convex, so
///   its maximum over `c` is at a corner, and `d(p, B) <= d(p, t)`; the
///   triangles nearest to the corners are the candidates for `t`. This one
///   is exact where a triangle of A lies over a single triangle of B (above
///   all, coincident surfaces, where the first would need splitting down to
///   the tolerance);
/// - two of those triangles that share an edge, each over its side of a
///   plane through that edge (see `cut_pair_bound`). A rectangle's two
///   halves (every face of a box, a wall, a slab) and the facets either
///   side of a crease are such pairs; without this bound a triangle of A
///   lying across their shared edge is split along it down to the
///   tolerance.
fn triangle_upper(b: &TriangleSet, c: &[Vec3; 3], d: &[f32; 3], nearest: &[u32; 3]) -> f32 {
    let lipschitz = (0..3)
        .map(|i| {
            let far = c[(i + 1) % 3]
                .distance(c[i])
                .max(c[(i + 2) % 3].distance(c[i]));
            d[i] + far
        })
        .fold(f32::INFINITY, f32::min);
    let mut best = lipschitz;
    for (k, &t) in nearest.iter().enumerate() {
        if !nearest[..k].contains(&t) {
            best = union_bound(b, c, d, nearest, &[t], best);
        }
    }
    let mut pairs = [(0u32, 0u32); 3];
    let mut count = 0;
    for (i, j) in [(0, 1), (1, 2), (0, 2)] {
        let pair = (nearest[i].min(nearest[j]), nearest[i].max(nearest[j]));
        if pair.0 != pair.1 && !pairs[..count].contains(&pair) {
            pairs[count] = pair;
            count += 1;
        }
    }
    for &(t, u) in &pairs[..count] {
        best = best.min(cut_pair_bound(b, c, d, nearest, t, u, best));
    }
    best
}

/// For triangles `t` and `u` of B that share an edge, a bound of `d(p, B)`
/// over triangle `c` from cutting `c` in two by a plane through that edge:
/// the part on `t`'s side is bounded by `d(p, t)`, the other by `d(p, u)`.
/// Each part is a convex polygon and `d(., t)` is convex, so its largest
/// value over a part is at one of the part's corners: `c`'s own, or where
/// `c`'s edges cross the plane. The plane runs along the shared edge,
/// between the two apexes: where the triangles are coplanar it is the
/// boundary between the points nearest to each, and across a crease it is
/// near it. Without this bound, a triangle of A lying across a crease of
/// B (the facets of a tube, a fillet, a chamfer) is split along the crease
/// down to the tolerance: pieces by the tens of thousands along a steel
/// section's length. `best` when the triangles share no edge or the bound
/// would not beat it.
fn cut_pair_bound(
    b: &TriangleSet,
    c: &[Vec3; 3],
    d: &[f32; 3],
    nearest: &[u32; 3],
    t: u32,
    u: u32,
    best: f32,
) -> f32 {
    let (tc, uc) = (b.corners(t), b.corners(u));
    let mut shared = (0..3).filter(|&k| uc.contains(&tc[k]));
    let (Some(k0), Some(k1), None) = (shared.next(), shared.next(), shared.next()) else {
        return best;
    };
    let (p, q, r) = (tc[k0], tc[k1], tc[3 - k0 - k1]);
    let Some(s) = uc.iter().find(|x| **x != p && **x != q) else {
        return best;
    };
    let edge = (q - p).normalize_or_zero();
    let across = r - *s;
    let Some(normal) = (across - edge * across.dot(edge)).try_normalize() else {
        return best;
    };
    let sides = c.map(|x| normal.dot(x - p));
    // The exact distance of corner `i` to `tri`: the one measured where
    // that is its nearest.
    let to = |i: usize, tri: u32| {
        if nearest[i] == tri {
            d[i]
        } else {
            b.distance_to(c[i], tri)
        }
    };
    let mut worst = 0.0f32;
    for (i, side) in sides.iter().enumerate() {
        worst = worst.max(if *side >= 0.0 { to(i, t) } else { to(i, u) });
        if worst >= best {
            return best;
        }
    }
    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
        if (sides[i] >= 0.0) != (sides[j] >= 0.0) {
            let x = c[i] + (c[j] - c[i]) * (sides[i] / (sides[i] - sides[j]));
            worst = worst.max(b.distance_to(x, t)).max(b.distance_to(x, u));
            if worst >= best {
                return best;
            }
        }
    }
    worst
}

/// `min(best, max_i d(c_i, T))` for `T` the union of the triangles `ts`,
/// stopping early once it cannot beat `best`.
fn union_bound(
    b: &TriangleSet,
    c: &[Vec3; 3],
    d: &[f32; 3],
    nearest: &[u32; 3],
    ts: &[u32],
    best: f32,
) -> f32 {
    let mut worst = 0.0f32;
    for i in 0..3 {
        worst = worst.max(if ts.contains(&nearest[i]) {
            d[i]
        } else {
            ts.iter()
                .map(|&t| b.distance_to(c[i], t))
                .fold(f32::INFINITY, f32::min)
        });
        if worst >= best {
            return best;
        }
    }
    worst
}

/// A bound of `sup_{a in A} d(a, B)` for the triangles `a` of A against
/// `b`, if at most `within` (no slack added); 0 for no triangles.
pub(super) fn one_way_within(
    a: &[[Vec3; 3]],
    b: &TriangleSet,
    tolerance: f32,
    within: f32,
) -> Option<f32> {
    one_way_above(a, b, tolerance, within, 0.0)
}

/// [`one_way_within`] for a second direction: a piece whose bound is
/// within `floor` is settled, so only the larger of the result and `floor`
/// bounds the distance.
pub(super) fn one_way_above(
    a: &[[Vec3; 3]],
    b: &TriangleSet,
    tolerance: f32,
    within: f32,
    floor: f32,
) -> Option<f32> {
    if a.is_empty() {
        return Some(floor);
    }
    if b.is_empty() {
        return None;
    }
    one_way(a, b, tolerance, None, within, floor)
        .map(|w| w.upper.max(floor))
        .filter(|&d| d <= within)
}

/// The distance of `p` (and the triangle that attains it), measured once:
/// two pieces that share an edge and both split it (4 ways, or bisected
/// across it) split it at the same midpoint. Measured again, those were
/// an eighth of the nearest queries of a steel model's build.
fn measured(
    known: &mut rustc_hash::FxHashMap<[u32; 3], (f32, u32)>,
    distance: &mut impl FnMut(Vec3, Option<u32>) -> (f32, u32),
    p: Vec3,
    hint: Option<u32>,
) -> (f32, u32) {
    *known
        .entry(p.to_array().map(f32::to_bits))
        .or_insert_with(|| distance(p, hint))
}

/// Bounds `sup_{a in A} d(a, B)` for the triangles `a` of A against the
/// non-empty set `b`, and, given a seed, samples A's surface for the mean
/// and RMS. `None` as soon as a measured distance exceeds `budget`. A piece
/// whose bound is within `floor` is settled however far it is from the
/// lower bound: the caller takes the larger of the result and `floor`.
fn one_way(
    a: &[[Vec3; 3]],
    b: &TriangleSet,
    tolerance: f32,
    seed: Option<u64>,
    budget: f32,
    floor: f32,
) -> Option<OneWay> {
    let settle = Settle { tolerance, floor };
    let mut hint = None;
    let mut distance = |p: Vec3, h: Option<u32>| -> (f32, u32) {
        // `b` is not empty, so a nearest triangle always exists.
        let n = b
            .nearest(p, h.or(hint))
            .map_or((0.0, 0), |n| (n.distance_squared.sqrt(), n.triangle));
        hint = Some(n.1);
        n
    };

    let mut lower = 0.0f32;
    let mut corners = Vec::with_capacity(a.len());
    // Meshes share corners between triangles: measure each distinct point
    // once, in triangle order so that consecutive queries are near each
    // other and the previous answer is a good starting radius.
    let mut known: rustc_hash::FxHashMap<[u32; 3], (f32, u32)> =
        rustc_hash::FxHashMap::with_capacity_and_hasher(a.len(), Default::default());
    for t in a {
        let mut d = [0.0; 3];
        let mut near = [0; 3];
        for (k, p) in t.iter().enumerate() {
            (d[k], near[k]) = measured(&mut known, &mut distance, *p, None);
        }
        lower = lower.max(d[0]).max(d[1]).max(d[2]);
        if lower > budget {
            return None;
        }
        corners.push((d, near));
    }

    let areas: Vec<f64> = a
        .iter()
        .map(|[p, q, r]| f64::from((*q - *p).cross(*r - *p).length() * 0.5))
        .collect();
    let total_area: f64 = areas.iter().sum();
    let (mut sum, mut sum_squares, mut samples) = (0.0f64, 0.0f64, 0usize);
    if let Some(seed) = seed.filter(|_| total_area > 0.0 && total_area.is_finite()) {
        let mut cdf = Vec::with_capacity(areas.len());
        let mut acc = 0.0;
        for x in &areas {
            acc += x;
            cdf.push(acc);
        }
        let count = (2 * a.len()).clamp(256, 20_000);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..count {
            let x = rng.random::<f64>() * total_area;
            let i = cdf.partition_point(|&c| c <= x).min(a.len() - 1);
            let [p, q, r] = a[i];
            let (u, v): (f32, f32) = (rng.random(), rng.random());
            let su = u.sqrt();
            let point = p * (1.0 - su) + q * (su * (1.0 - v)) + r * (su * v);
            let (d, _) = distance(point, Some(corners[i].1[0]));
            lower = lower.max(d);
            sum += f64::from(d);
            sum_squares += f64::from(d) * f64::from(d);
            samples += 1;
        }
    } else {
        // A surface of zero area: its corners are all there is to sample.
        for (d, _) in &corners {
            for x in d {
                sum += f64::from(*x);
                sum_squares += f64::from(*x) * f64::from(*x);
                samples += 1;
            }
        }
    }

    // The largest bound of the triangles settled without splitting: they
    // could not raise the lower bound by more than the tolerance.
    let mut settled = 0.0f32;
    let mut open = BinaryHeap::new();
    for (t, (d, near)) in a.iter().zip(&corners) {
        if lower > budget {
            return None;
        }
        let upper = piece_upper(&mut distance, b, t, d, near, &mut lower, settle);
        if upper <= settle.at(lower) {
            settled = settled.max(upper);
        } else {
            open.push(Open {
                upper,
                corners: *t,
                distances: *d,
                nearest: *near,
                depth: 0,
            });
        }
    }
    while let Some(t) = open.pop() {
        if lower > budget {
            return None;
        }
        if t.upper <= settle.at(lower) || t.depth >= MAX_DEPTH || open.len() >= MAX_OPEN {
            // The largest open bound: nothing left open can exceed it.
            settled = settled.max(t.upper);
            break;
        }
        let [p0, p1, p2] = t.corners;
        let [d0, d1, d2] = t.distances;
        let [n0, n1, n2] = t.nearest;
        let edges = [
            p0.distance_squared(p1),
            p1.distance_squared(p2),
            p2.distance_squared(p0),
        ];
        let longest = (0..3)
            .max_by(|&i, &j| edges[i].total_cmp(&edges[j]))
            .unwrap_or(0);
        let twice_area = (p1 - p0).cross(p2 - p0).length();
        // Four pieces at most, the last two unused by a bisection.
        let (children, count) = if edges[longest] > THIN * twice_area {
            // Across the longest edge `a b`, from its midpoint to `c`.
            let (a, b, c) = (longest, (longest + 1) % 3, (longest + 2) % 3);
            let m = (t.corners[a] + t.corners[b]) * 0.5;
            let (e, k) = measured(&mut known, &mut distance, m, Some(t.nearest[a]));
            lower = lower.max(e);
            let (cs, ds, ns) = (t.corners, t.distances, t.nearest);
            let first = ([cs[a], m, cs[c]], [ds[a], e, ds[c]], [ns[a], k, ns[c]]);
            let second = ([m, cs[b], cs[c]], [e, ds[b], ds[c]], [k, ns[b], ns[c]]);
            ([first, second, first, second], 2)
        } else {
            let (m01, m12, m20) = ((p0 + p1) * 0.5, (p1 + p2) * 0.5, (p2 + p0) * 0.5);
            let (e01, k01) = measured(&mut known, &mut distance, m01, Some(n0));
            let (e12, k12) = measured(&mut known, &mut distance, m12, Some(n1));
            let (e20, k20) = measured(&mut known, &mut distance, m20, Some(n2));
            lower = lower.max(e01).max(e12).max(e20);
            (
                [
                    ([p0, m01, m20], [d0, e01, e20], [n0, k01, k20]),
                    ([m01, p1, m12], [e01, d1, e12], [k01, n1, k12]),
                    ([m20, m12, p2], [e20, e12, d2], [k20, k12, n2]),
                    ([m01, m12, m20], [e01, e12, e20], [k01, k12, k20]),
                ],
                4,
            )
        };
        let step = if count == 2 { 1 } else { 2 };
        for &(c, d, near) in &children[..count] {
            let u = piece_upper(&mut distance, b, &c, &d, &near, &mut lower, settle);
            if u <= settle.at(lower) {
                settled = settled.max(u);
            } else {
                open.push(Open {
                    upper: u,
                    corners: c,
                    distances: d,
                    nearest: near,
                    depth: t.depth + step,
                });
            }
        }
    }
    Some(OneWay {
        upper: settled.max(lower),
        lower,
        sum,
        sum_squares,
        samples,
    })
    .filter(|w| w.upper <= budget)
}
