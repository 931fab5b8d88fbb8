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
//! its largest value over the triangle is at a corner, another bound (see
//! `triangle_upper`). Any exact `d(p)` is a lower bound of the supremum. Triangles whose
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
        one_way(a, b, tolerance, Some(seed), f32::INFINITY)
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
    one_way(&tris, b, tolerance, None, f32::INFINITY)
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
    let tris_a = finite_triangles(a);
    let tris_b = finite_triangles(b);
    if tris_a.is_empty() || tris_b.is_empty() {
        let bound = if tris_a.is_empty() && tris_b.is_empty() {
            0.0
        } else {
            f32::INFINITY
        };
        return (bound <= budget).then_some(bound);
    }
    let (tolerance, slack) = search_scale(&tris_a, &tris_b, tolerance);
    let within = budget - slack;
    // The smaller mesh's search structure first: it is the cheaper to
    // build, and a failing candidate may never need the other.
    let (first, second) = if tris_a.len() <= tris_b.len() {
        (&tris_a, &tris_b)
    } else {
        (&tris_b, &tris_a)
    };
    let mut bound = 0.0f32;
    for (from, to) in [(second, first), (first, second)] {
        let set = TriangleSet::new(to.iter().copied());
        bound = bound.max(one_way(from, &set, tolerance, None, within)?.upper);
    }
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

fn finite_triangles(m: &Mesh) -> Vec<[Vec3; 3]> {
    let n = m.positions.len();
    m.indices
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| (i as usize) < n))
        .map(|t| {
            [
                m.positions[t[0] as usize],
                m.positions[t[1] as usize],
                m.positions[t[2] as usize],
            ]
        })
        .filter(|t| t.iter().all(|p| p.is_finite()))
        .collect()
}

/// When the corners' nearest triangles do not settle a triangle, the one
/// nearest to its centroid may: on coincident surfaces a corner is equally
/// near to every triangle around it, the centroid only to the right one.
/// The centroid's distance also raises the lower bound.
fn centroid_bound(
    distance: &mut impl FnMut(Vec3, Option<u32>) -> (f32, u32),
    b: &TriangleSet,
    c: &[Vec3; 3],
    d: &[f32; 3],
    nearest: &[u32; 3],
    upper: f32,
    lower: &mut f32,
) -> f32 {
    let (dc, tc) = distance((c[0] + c[1] + c[2]) / 3.0, Some(nearest[0]));
    *lower = lower.max(dc);
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
/// - the same for two of those triangles that share an edge and make a
///   convex quadrilateral, flat within `delta` (see `flat_pair`): the
///   distance to their union is then at most `2 delta` above a convex
///   function's, so its maximum over `c` is at most the corners' largest
///   plus `2 delta`. A rectangle's two halves (every face of a box, a wall,
///   a slab) are such a pair; without this bound a triangle of A lying
///   across their diagonal is split along it down to the tolerance.
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
        if let Some(delta) = flat_pair(b, t, u) {
            best =
                best.min(union_bound(b, c, d, nearest, &[t, u], best - 2.0 * delta) + 2.0 * delta);
        }
    }
    best
}

/// If triangles `t` and `u` of B share an edge and, with `u` projected onto
/// `t`'s plane, make a convex quadrilateral, how far `u`'s far corner is
/// from that plane (`delta`). Let `Q` be that quadrilateral and `T` the
/// union of `t` and `u`: every point of `u` is within `delta` of `Q` and
/// the other way round, so for any point `p`, `d(p, T) <= d(p, Q) + delta`,
/// and `d(., Q)` is convex (`Q` is a convex set), so over a triangle it is
/// at most its largest value at a corner, which is at most
/// `d(corner, T) + delta`. In double
/// precision: the side tests decide whether the argument holds.
fn flat_pair(b: &TriangleSet, t: u32, u: u32) -> Option<f32> {
    let tc = b.corners(t).map(|p| p.as_dvec3());
    let uc = b.corners(u).map(|p| p.as_dvec3());
    // The shared edge `p q`, `t`'s apex `r`, `u`'s apex `s`.
    let mut shared = (0..3).filter(|&k| uc.contains(&tc[k]));
    let (Some(k0), Some(k1), None) = (shared.next(), shared.next(), shared.next()) else {
        return None;
    };
    let (p, q, r) = (tc[k0], tc[k1], tc[3 - k0 - k1]);
    let s = *uc.iter().find(|x| **x != p && **x != q)?;
    let n = (q - p).cross(r - p).try_normalize()?;
    let height = (s - p).dot(n);
    let s = s - n * height;
    let side =
        |x: glam::DVec3, from: glam::DVec3, to: glam::DVec3| (to - from).cross(x - from).dot(n);
    // `r` is on the positive side of `p q` by the choice of `n`; `s` must
    // be on the other, and `p`, `q` on either side of `r s`.
    let convex = side(s, p, q) <= 0.0 && side(p, r, s) * side(q, r, s) <= 0.0;
    convex.then_some(height.abs() as f32)
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
    if a.is_empty() {
        return Some(0.0);
    }
    if b.is_empty() {
        return None;
    }
    one_way(a, b, tolerance, None, within)
        .map(|w| w.upper)
        .filter(|&d| d <= within)
}

/// Bounds `sup_{a in A} d(a, B)` for the triangles `a` of A against the
/// non-empty set `b`, and, given a seed, samples A's surface for the mean
/// and RMS. `None` as soon as a measured distance exceeds `budget`.
fn one_way(
    a: &[[Vec3; 3]],
    b: &TriangleSet,
    tolerance: f32,
    seed: Option<u64>,
    budget: f32,
) -> Option<OneWay> {
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
    let mut known: std::collections::HashMap<[u32; 3], (f32, u32)> =
        std::collections::HashMap::with_capacity(a.len());
    for t in a {
        let mut d = [0.0; 3];
        let mut near = [0; 3];
        for (k, p) in t.iter().enumerate() {
            let key = p.to_array().map(f32::to_bits);
            (d[k], near[k]) = *known.entry(key).or_insert_with(|| distance(*p, None));
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
        let mut upper = triangle_upper(b, t, d, near);
        if upper > lower + tolerance {
            upper = centroid_bound(&mut distance, b, t, d, near, upper, &mut lower);
        }
        if upper <= lower + tolerance {
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
        if t.upper <= lower + tolerance || t.depth >= MAX_DEPTH || open.len() >= MAX_OPEN {
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
            let (e, k) = distance(m, Some(t.nearest[a]));
            lower = lower.max(e);
            let (cs, ds, ns) = (t.corners, t.distances, t.nearest);
            let first = ([cs[a], m, cs[c]], [ds[a], e, ds[c]], [ns[a], k, ns[c]]);
            let second = ([m, cs[b], cs[c]], [e, ds[b], ds[c]], [k, ns[b], ns[c]]);
            ([first, second, first, second], 2)
        } else {
            let (m01, m12, m20) = ((p0 + p1) * 0.5, (p1 + p2) * 0.5, (p2 + p0) * 0.5);
            let (e01, k01) = distance(m01, Some(n0));
            let (e12, k12) = distance(m12, Some(n1));
            let (e20, k20) = distance(m20, Some(n2));
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
            let mut u = triangle_upper(b, &c, &d, &near);
            if u > lower + tolerance {
                u = centroid_bound(&mut distance, b, &c, &d, &near, u, &mut lower);
            }
            if u <= lower + tolerance {
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
