//! Exact point-to-surface distance queries: the closest point on a triangle
//! (Ericson, "Real-Time Collision Detection", 2005, section 5.1.5) and a
//! nearest-triangle search over a BVH.
//!
//! The BVH itself is built by `obvhs` (PLOC, Meister and Bittner 2018). It
//! only offers ray, box and point-containment traversals, so the
//! nearest-neighbour traversal (depth-first, nearer child first, pruned by
//! the squared distance to each node's box) is written here.

use std::sync::OnceLock;

use glam::Vec3A;
use glam::{DVec3, Vec3};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};

/// Below this many triangles a linear scan beats building a tree: the tree
/// builder calls the Hausdorff bound on thousands of small clusters.
const BRUTE_FORCE_MAX: usize = 32;

/// How much farther than the best distance (squared) a triangle's box must
/// be to be passed over: the box distance in `f32` is within a few units
/// in the last place of the true one, far less than this.
const BOX_MARGIN: f32 = 1.0 + 1e-4;

/// The point of triangle `abc` closest to `p`. Degenerate triangles (points,
/// segments) and slivers are handled: the answer is then the closest point
/// of the triangle's edges.
pub fn closest_point_on_triangle(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> Vec3A {
    Prepared::new(a, b, c).closest(p)
}

/// Below this squared sine of the angle between its edges at `a`, a
/// triangle is taken for its edges: its face's barycentric terms cancel
/// even in double precision (they moved the answer by half a millimetre on
/// a 40 m sliver), while its edges lie within a millionth of its length
/// of every point of it, and a distance to them is never less than the
/// true one.
const SLIVER_SINE_SQUARED: f64 = 1e-12;

/// A triangle as closest-point queries use it (Ericson, "Real-Time
/// Collision Detection", 2005, section 5.1.5), in double precision: on
/// long thin triangles (scaffold tubes, rails) the terms cancel badly in
/// `f32`, which moved the answer by millimetres, more than the error
/// budgets the bound must respect. A corner, the two edges from it and
/// their dot products are computed once rather than at every query (a tree
/// build makes millions of them): the dot products with `p - b` and `p -
/// c` follow from those with `p - a`.
#[derive(Clone, Copy)]
struct Prepared {
    a: DVec3,
    ab: DVec3,
    ac: DVec3,
    ab_ab: f64,
    ab_ac: f64,
    ac_ac: f64,
    /// `|ab x ac|^2`, the sum of the face region's terms; zero for a
    /// sliver, answered by its edges.
    area: f64,
}

impl Prepared {
    fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Prepared {
        // Exact: an `f32`'s difference with another fits in an `f64`.
        let a = a.as_dvec3();
        let (ab, ac) = (b.as_dvec3() - a, c.as_dvec3() - a);
        let (ab_ab, ac_ac) = (ab.dot(ab), ac.dot(ac));
        let area = ab.cross(ac).length_squared();
        // NaN (a corner at infinity) too.
        let sliver = area.partial_cmp(&(SLIVER_SINE_SQUARED * ab_ab * ac_ac))
            != Some(std::cmp::Ordering::Greater);
        Prepared {
            a,
            ab,
            ac,
            ab_ab,
            ab_ac: ab.dot(ac),
            ac_ac,
            area: if sliver { 0.0 } else { area },
        }
    }

    fn closest(&self, p: Vec3A) -> Vec3A {
        let Prepared {
            a,
            ab,
            ac,
            ab_ab,
            ab_ac,
            ac_ac,
            area,
        } = *self;
        let p = p.as_dvec3();
        let ap = p - a;
        let d1 = ab.dot(ap);
        let d2 = ac.dot(ap);
        if d1 <= 0.0 && d2 <= 0.0 {
            return a.as_vec3a();
        }
        let (d3, d4) = (d1 - ab_ab, d2 - ab_ac);
        if d3 >= 0.0 && d4 <= d3 {
            return (a + ab).as_vec3a();
        }
        if area == 0.0 {
            return edges_f64(p, a, a + ab, a + ac).as_vec3a();
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            return (a + ab * (d1 / ab_ab)).as_vec3a();
        }
        let (d5, d6) = (d1 - ab_ac, d2 - ac_ac);
        if d6 >= 0.0 && d5 <= d6 {
            return (a + ac).as_vec3a();
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            return (a + ac * (d2 / ac_ac)).as_vec3a();
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return (a + ab + (ac - ab) * w).as_vec3a();
        }
        (a + ab * (vb / area) + ac * (vc / area)).as_vec3a()
    }
}

/// The closest point to `p` on the edges of `abc`.
fn edges_f64(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    [
        segment_f64(p, a, b),
        segment_f64(p, b, c),
        segment_f64(p, c, a),
    ]
    .into_iter()
    .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
    .unwrap_or(a)
}

fn segment_f64(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
}

fn box_distance_squared(p: Vec3A, aabb: &Aabb) -> f32 {
    let d = (aabb.min - p).max(p - aabb.max).max(Vec3A::ZERO);
    d.length_squared()
}

#[derive(Clone, Copy)]
struct Tri {
    a: Vec3A,
    b: Vec3A,
    c: Vec3A,
}

impl obvhs::Boundable for Tri {
    fn aabb(&self) -> Aabb {
        Aabb::new(
            self.a.min(self.b).min(self.c),
            self.a.max(self.b).max(self.c),
        )
    }
}

/// The triangles of a mesh prepared for nearest-point queries. Triangles
/// with a non-finite corner are left out.
pub struct TriangleSet {
    /// In BVH leaf order, so that a leaf's range indexes this directly.
    tris: Vec<Tri>,
    /// `tris` prepared for closest-point queries.
    prepared: Vec<Prepared>,
    /// Each triangle's position in the input, for `input_index`.
    inputs: Vec<u32>,
    bvh: Option<Bvh2>,
    /// Every (corner, triangle) pair, sorted by the corner's bits: the
    /// triangles around a corner (`around`). Made on first use, since most
    /// sets are never asked. Each pair packed into one `u128` (the
    /// corner's three coordinates' bits, then the triangle), so that the
    /// sort compares integers: compared as tuples, the sort was 3.6% of a
    /// steel model's build.
    corners: OnceLock<Vec<u128>>,
}

thread_local! {
    /// The traversal stack of `TriangleSet::nearest`, kept per thread: the
    /// Hausdorff search makes millions of queries, and a stack allocated
    /// per query put the allocator high in a tree build's profile.
    static STACK: std::cell::RefCell<Vec<(u32, f32)>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The result of a nearest query: the squared distance and the triangle
/// (an opaque handle to pass back as a hint).
#[derive(Clone, Copy, Debug)]
pub struct Nearest {
    pub distance_squared: f32,
    pub triangle: u32,
}

impl TriangleSet {
    pub fn new(triangles: impl Iterator<Item = [Vec3; 3]>) -> Self {
        let (inputs, tris): (Vec<u32>, Vec<Tri>) = triangles
            .enumerate()
            .filter(|(_, t)| t.iter().all(|p| p.is_finite()))
            .map(|(i, [a, b, c])| {
                (
                    i as u32,
                    Tri {
                        a: a.into(),
                        b: b.into(),
                        c: c.into(),
                    },
                )
            })
            .unzip();
        if tris.len() <= BRUTE_FORCE_MAX {
            return TriangleSet {
                prepared: tris.iter().map(|t| Prepared::new(t.a, t.b, t.c)).collect(),
                tris,
                inputs,
                bvh: None,
                corners: OnceLock::new(),
            };
        }
        // A minimal search distance builds fastest; the queries only need
        // a reasonable tree, not a ray-tracing quality one.
        let mut bvh = PlocBuilder::with_capacity(tris.len()).build(
            PlocSearchDistance::VeryLow,
            &tris,
            (0..tris.len() as u32).collect(),
            SortPrecision::U64,
            0,
        );
        obvhs::bvh2::leaf_collapser::collapse(&mut bvh, 4, 1.0);
        let tris: Vec<Tri> = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        let inputs = bvh
            .primitive_indices
            .iter()
            .map(|&i| inputs[i as usize])
            .collect();
        TriangleSet {
            prepared: tris.iter().map(|t| Prepared::new(t.a, t.b, t.c)).collect(),
            tris,
            inputs,
            bvh: Some(bvh),
            corners: OnceLock::new(),
        }
    }

    /// The position of `triangle` (a handle from `nearest`) in the
    /// triangles the set was made of.
    pub fn input_index(&self, triangle: u32) -> u32 {
        self.inputs[triangle as usize]
    }

    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// The exact distance from `p` to `triangle` (a handle from `nearest`).
    pub fn distance_to(&self, p: Vec3, triangle: u32) -> f32 {
        let p = Vec3A::from(p);
        self.prepared[triangle as usize].closest(p).distance(p)
    }

    /// The triangles (handles) with a corner at exactly `p`.
    pub fn around(&self, p: Vec3) -> impl Iterator<Item = u32> + '_ {
        let corner = |c: Vec3A| {
            let [x, y, z] = c.to_array().map(|v| u128::from(v.to_bits()));
            x << 96 | y << 64 | z << 32
        };
        let corners = self.corners.get_or_init(|| {
            let mut all: Vec<u128> = self
                .tris
                .iter()
                .enumerate()
                .flat_map(|(i, t)| [t.a, t.b, t.c].map(|c| corner(c) | i as u128))
                .collect();
            all.sort_unstable();
            all
        });
        let key = corner(p.into());
        let first = corners.partition_point(|&k| k < key);
        corners[first..]
            .iter()
            .take_while(move |&&k| k >> 32 == key >> 32)
            .map(|&k| k as u32)
    }

    /// The corners of `triangle` (a handle from `nearest`).
    pub fn corners(&self, triangle: u32) -> [Vec3; 3] {
        let t = &self.tris[triangle as usize];
        [t.a.into(), t.b.into(), t.c.into()]
    }

    /// The first triangle (a handle) the segment from `origin` along `dir`
    /// (a unit vector) meets within `length`, either side of it, and how
    /// far along (Moller and Trumbore, "Fast, minimum storage ray-triangle
    /// intersection", 1997).
    pub fn first_hit(&self, origin: Vec3, dir: Vec3, length: f32) -> Option<(u32, f32)> {
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let inverse = d.recip();
        let mut best: Option<(u32, f32)> = None;
        let visit = |i: usize, best: &mut Option<(u32, f32)>| {
            let t = &self.tris[i];
            let (e1, e2) = (t.b - t.a, t.c - t.a);
            let p = d.cross(e2);
            let det = e1.dot(p);
            if det.abs() <= f32::EPSILON * e1.length() * e2.length() {
                return;
            }
            let s = o - t.a;
            let u = s.dot(p) / det;
            let q = s.cross(e1);
            let v = d.dot(q) / det;
            let along = e2.dot(q) / det;
            let limit = best.map_or(length, |b| b.1);
            if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && (0.0..=limit).contains(&along) {
                *best = Some((i as u32, along));
            }
        };
        let Some(bvh) = &self.bvh else {
            for i in 0..self.tris.len() {
                visit(i, &mut best);
            }
            return best;
        };
        // The slab test: where the segment enters a node's box, if it does.
        let enters = |aabb: &Aabb| {
            let t0 = (aabb.min - o) * inverse;
            let t1 = (aabb.max - o) * inverse;
            let near = t0.min(t1).max_element().max(0.0);
            let far = t0.max(t1).min_element();
            (near <= far).then_some(near)
        };
        let nodes = &bvh.nodes;
        let mut stack: Vec<u32> = vec![0];
        while let Some(index) = stack.pop() {
            let node = &nodes[index as usize];
            match enters(node.aabb()) {
                Some(near) if near <= best.map_or(length, |b| b.1) => {}
                _ => continue,
            }
            if node.is_leaf() {
                let first = node.first_index as usize;
                for i in first..first + node.prim_count as usize {
                    visit(i, &mut best);
                }
                continue;
            }
            stack.extend([node.first_index, node.first_index + 1]);
        }
        best
    }

    /// Calls `visit` on every triangle (a handle) with a point within
    /// `radius` of `p`, until it answers false; answers whether none did.
    pub fn all_within(&self, p: Vec3, radius: f32, mut visit: impl FnMut(u32) -> bool) -> bool {
        let p = Vec3A::from(p);
        let r2 = radius * radius;
        let mut check =
            |i: usize| self.prepared[i].closest(p).distance_squared(p) > r2 || visit(i as u32);
        let Some(bvh) = &self.bvh else {
            return (0..self.tris.len()).all(check);
        };
        let nodes = &bvh.nodes;
        let mut stack: Vec<u32> = vec![0];
        while let Some(index) = stack.pop() {
            let node = &nodes[index as usize];
            if box_distance_squared(p, node.aabb()) > r2 {
                continue;
            }
            if node.is_leaf() {
                let first = node.first_index as usize;
                if !(first..first + node.prim_count as usize).all(&mut check) {
                    return false;
                }
                continue;
            }
            stack.extend([node.first_index, node.first_index + 1]);
        }
        true
    }

    /// The nearest triangle to `p`. `hint`, a triangle from an earlier query
    /// on a nearby point, seeds the search radius. `None` for an empty set.
    pub fn nearest(&self, p: Vec3, hint: Option<u32>) -> Option<Nearest> {
        let p = Vec3A::from(p);
        let mut best = Nearest {
            distance_squared: f32::INFINITY,
            triangle: u32::MAX,
        };
        let visit = |i: usize, best: &mut Nearest| {
            let t = &self.tris[i];
            // The triangle's box is no farther than the triangle: a box
            // farther than the best so far, by more than rounding in `f32`
            // could make it seem, holds no nearer point, and the closest
            // point in double precision is not needed.
            let (lo, hi) = (t.a.min(t.b).min(t.c), t.a.max(t.b).max(t.c));
            let to_box = (lo - p).max(p - hi).max(Vec3A::ZERO).length_squared();
            if to_box > best.distance_squared * BOX_MARGIN {
                return;
            }
            let d = self.prepared[i].closest(p).distance_squared(p);
            if d < best.distance_squared {
                *best = Nearest {
                    distance_squared: d,
                    triangle: i as u32,
                };
            }
        };
        if let Some(h) = hint.filter(|&h| (h as usize) < self.tris.len()) {
            visit(h as usize, &mut best);
        }
        let Some(bvh) = &self.bvh else {
            for i in 0..self.tris.len() {
                visit(i, &mut best);
            }
            return (best.triangle != u32::MAX).then_some(best);
        };
        let nodes = &bvh.nodes;
        STACK.with_borrow_mut(|stack| {
            stack.clear();
            stack.push((0, box_distance_squared(p, nodes[0].aabb())));
            while let Some((index, d)) = stack.pop() {
                if d >= best.distance_squared {
                    continue;
                }
                let node = &nodes[index as usize];
                if node.is_leaf() {
                    let first = node.first_index as usize;
                    for i in first..first + node.prim_count as usize {
                        visit(i, &mut best);
                    }
                    continue;
                }
                let left = node.first_index;
                let right = left + 1;
                let dl = box_distance_squared(p, nodes[left as usize].aabb());
                let dr = box_distance_squared(p, nodes[right as usize].aabb());
                // The nearer child is pushed last so that it is searched first
                // and shrinks the radius for its sibling.
                if dl < dr {
                    stack.push((right, dr));
                    stack.push((left, dl));
                } else {
                    stack.push((left, dl));
                    stack.push((right, dr));
                }
            }
        });
        (best.triangle != u32::MAX).then_some(best)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_regions() {
        let a = Vec3A::new(0.0, 0.0, 0.0);
        let b = Vec3A::new(1.0, 0.0, 0.0);
        let c = Vec3A::new(0.0, 1.0, 0.0);
        let q = |x, y, z| closest_point_on_triangle(Vec3A::new(x, y, z), a, b, c);
        let near = |x: Vec3A, y: Vec3A| (x - y).length() < 1e-6;
        assert!(near(q(0.2, 0.2, 5.0), Vec3A::new(0.2, 0.2, 0.0)));
        assert_eq!(q(-1.0, -1.0, 0.0), a);
        assert_eq!(q(2.0, -0.5, 0.0), b);
        assert!(near(q(0.5, -1.0, 1.0), Vec3A::new(0.5, 0.0, 0.0)));
        assert!(near(q(1.0, 1.0, 0.0), Vec3A::new(0.5, 0.5, 0.0)));
    }

    #[test]
    fn degenerate_triangles_give_finite_points() {
        let a = Vec3A::new(0.0, 0.0, 0.0);
        let b = Vec3A::new(1.0, 0.0, 0.0);
        let c = Vec3A::new(2.0, 0.0, 0.0);
        let p = Vec3A::new(1.5, 1.0, 0.0);
        let q = closest_point_on_triangle(p, a, b, c);
        assert!((q - Vec3A::new(1.5, 0.0, 0.0)).length() < 1e-6);
        assert_eq!(closest_point_on_triangle(p, a, a, a), a);
    }

    /// The distance from `p` to `abc` the plain way, in double precision:
    /// to the plane where the foot is inside (the signs of the three
    /// sub-triangles' normals), else to the nearest edge.
    fn reference_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
        let n = (b - a).cross(c - a);
        let edges = edges_f64(p, a, b, c).distance(p);
        if n.length_squared() == 0.0 {
            return edges;
        }
        let foot = p - n * (n.dot(p - a) / n.length_squared());
        let inside = [(a, b), (b, c), (c, a)]
            .iter()
            .all(|&(u, v)| (v - u).cross(foot - u).dot(n) >= 0.0);
        if inside {
            edges.min(foot.distance(p))
        } else {
            edges
        }
    }

    #[test]
    fn closest_points_hold_on_slivers_and_degenerate_triangles() {
        // Corners and points on a coarse lattice: long slivers among them
        // (three corners on one line 45 m long), triangles with two corners
        // at one point, and ordinary ones; every region of each is met.
        let coords = [-20.0f32, -0.001, 0.0, 0.3, 1.0, 20.0];
        let point = |i: usize| {
            Vec3A::new(
                coords[i % 6],
                coords[(i / 6) % 6],
                coords[(i / 36) % 6] * 0.5,
            )
        };
        for t in (0..216).step_by(7) {
            for u in (0..216).step_by(11) {
                let (a, b) = (point(t), point(u));
                for c in [
                    point((t * 5 + u) % 216),
                    a,
                    (a + b) * 0.5 + Vec3A::Y * 0.001,
                ] {
                    let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
                    for i in (0..216).step_by(5) {
                        let p = point(i) + Vec3A::new(0.37, -0.21, 0.13);
                        let want = reference_distance(
                            p.as_dvec3(),
                            a.as_dvec3(),
                            b.as_dvec3(),
                            c.as_dvec3(),
                        );
                        let got = f64::from(closest_point_on_triangle(p, a, b, c).distance(p));
                        // A sliver's edges are within a millionth of its
                        // length of it; the point is rounded to `f32`.
                        let slack = 1e-6 * f64::from(longest) + 1e-5;
                        assert!(
                            (got - want).abs() <= slack,
                            "{a} {b} {c} from {p}: {got} against {want}"
                        );
                    }
                }
            }
        }
    }

    /// 400 small triangles on a staggered grid: enough for a BVH.
    fn grid() -> Vec<[Vec3; 3]> {
        let mut tris = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                let o = Vec3::new(i as f32, (i * j % 7) as f32 * 0.3, j as f32);
                tris.push([o, o + Vec3::X, o + Vec3::Z]);
            }
        }
        tris
    }

    #[test]
    fn triangles_within_a_radius_are_all_visited() {
        let tris = grid();
        let set = TriangleSet::new(tris.iter().copied());
        let p = Vec3::new(7.3, 0.5, 11.2);
        for radius in [0.1, 1.0, 3.5] {
            let mut found = Vec::new();
            assert!(set.all_within(p, radius, |t| {
                found.push(set.input_index(t));
                true
            }));
            found.sort_unstable();
            let near: Vec<u32> = (0..tris.len() as u32)
                .filter(|&i| {
                    let [a, b, c] = tris[i as usize];
                    closest_point_on_triangle(p.into(), a.into(), b.into(), c.into())
                        .distance(p.into())
                        <= radius
                })
                .collect();
            assert_eq!(found, near, "radius {radius}");
        }
        assert!(!set.all_within(p, 3.5, |_| false));
    }

    #[test]
    fn segments_find_their_first_triangle() {
        let mut tris = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                let o = Vec3::new(i as f32, j as f32 * 0.1, 0.0);
                tris.push([o, o + Vec3::X, o + Vec3::Y * 0.1]);
            }
        }
        // A layer in front at z = 1 over part of it.
        let front = Vec3::new(3.0, 0.0, 1.0);
        tris.push([front, front + Vec3::X * 4.0, front + Vec3::Y * 4.0]);
        let set = TriangleSet::new(tris.iter().copied());
        let down = Vec3::NEG_Z;
        let (t, along) = set.first_hit(Vec3::new(3.5, 0.5, 2.0), down, 4.0).unwrap();
        assert_eq!(set.input_index(t), 400);
        assert!((along - 1.0).abs() < 1e-5);
        let (t, along) = set
            .first_hit(Vec3::new(10.2, 0.52, 2.0), down, 4.0)
            .unwrap();
        assert_eq!(set.input_index(t), 10 * 20 + 5);
        assert!((along - 2.0).abs() < 1e-5);
        assert!(
            set.first_hit(Vec3::new(10.2, 0.52, 2.0), down, 1.5)
                .is_none()
        );
        assert!(
            set.first_hit(Vec3::new(30.0, 0.5, 2.0), down, 4.0)
                .is_none()
        );
    }

    #[test]
    fn bvh_search_matches_linear_scan() {
        let tris = grid();
        let set = TriangleSet::new(tris.iter().copied());
        assert!(set.bvh.is_some());
        for k in 0..200 {
            let p = Vec3::new(
                (k * 37 % 23) as f32 - 1.5,
                (k % 5) as f32,
                (k * 11 % 21) as f32,
            );
            let brute = tris
                .iter()
                .map(|[a, b, c]| {
                    closest_point_on_triangle(p.into(), (*a).into(), (*b).into(), (*c).into())
                        .distance_squared(p.into())
                })
                .fold(f32::INFINITY, f32::min);
            let got = set.nearest(p, Some(k % 400)).unwrap().distance_squared;
            assert_eq!(got, brute, "query {k}");
        }
    }
}
