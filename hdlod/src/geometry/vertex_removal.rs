//! Vertex removal: Schroeder, Zarge and Lorensen, "Decimation of triangle
//! meshes", SIGGRAPH 1992 (Computer Graphics 26(2), 65-70).
//!
//! Each vertex is classified by the loop of its neighbours and the feature
//! edges around it (dihedral angle above the feature angle):
//! - simple: a closed loop, no feature edge;
//! - boundary: an open loop (the vertex is on the mesh's border);
//! - interior edge: a closed loop, exactly two feature edges;
//! - corner: a closed loop with one or three or more feature edges;
//! - complex: anything else (non-manifold fan, a loop that meets itself).
//!
//! Simple, boundary and interior-edge vertices are candidates. Their
//! priority is the paper's decimation criterion: the distance to the
//! area-weighted average plane of the triangles around the vertex (simple),
//! or to the line through the two boundary or feature neighbours (boundary,
//! interior edge). The candidate of least distance is removed first; its
//! triangles go, and the hole is re-triangulated by recursive loop
//! splitting: a split line between two non-adjacent loop vertices, with the
//! plane through it orthogonal to the average plane, is valid when the rest
//! of the loop lies strictly on both sides of that plane; of the valid
//! splits the one of best aspect ratio (least distance of a loop vertex to
//! the split plane over the split line's length) is taken. A vertex whose
//! loop has no valid triangulation is skipped, and tried again only when a
//! neighbour's removal changes its loop.
//!
//! Choices the paper (and the theses that reimplement it) leave open:
//! - One global priority queue with lazy updates (a removal queues its
//!   neighbours anew with their new distance; an entry whose distance is
//!   no longer its vertex's current one is stale and skipped) instead
//!   of the paper's repeated passes with a growing threshold. It removes
//!   vertices in the same order of distance, in one pass.
//! - The criterion is the local distance, not accumulated over removals
//!   (as in the 1992 paper); the measured Hausdorff bound is what counts.
//!   The error budget stops the queue when the least distance exceeds it.
//! - Feature angle 30 degrees by default. A triangle of zero area has no
//!   normal: its edges count as feature edges, so the vertices around it
//!   stay (a conservative choice that never folds a sliver).
//! - A boundary vertex with a feature edge inside its fan is a corner.
//! - An interior-edge vertex's loop is split first along the line between
//!   its two feature neighbours, so the feature survives; each half is then
//!   split against its own area-weighted normal.
//! - A split is also refused when its line is already an edge of the mesh
//!   elsewhere, and a new triangle when it already exists or faces against
//!   the loop's normal: either would fold or make the mesh non-manifold.
//! - Loops longer than `MAX_LOOP` are not re-triangulated (skipped): the
//!   split search is cubic in the loop length.
//! - The input is welded first by exact position (vertices duplicated by a
//!   file format for normals or texture seams would otherwise be borders);
//!   a welded vertex keeps the attributes of its first copy. Triangles with
//!   a repeated corner are dropped.
//!
//! Each removal takes 2 triangles (1 at a boundary) so the result may be
//! one triangle under the target.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

use glam::Vec3;

use super::Mesh;
use super::simplify::{SimplifyOptions, cleaned, compact};

/// The default feature angle, in degrees.
pub const FEATURE_ANGLE_DEGREES: f32 = 30.0;
/// Loops longer than this are not re-triangulated.
const MAX_LOOP: usize = 32;
/// Loop vertices closer to a split plane than this share of the split
/// line's length count as on it: the split is then invalid.
const MIN_SPLIT_RATIO: f32 = 1e-4;
/// Not a distance's bits (a NaN's).
const NOT_QUEUED: u32 = u32::MAX;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Class {
    Simple,
    Boundary,
    InteriorEdge,
    Corner,
}

/// The fan around a vertex: its neighbours in loop order and its
/// triangles, triangle `i` spanning `(v, ring[i], ring[i + 1])`. Fixed
/// arrays rather than vectors: fans are built for every neighbour of every
/// removed vertex, and allocating them was a third of the time.
struct Fan {
    class: Class,
    ring: Small,
    tris: Small,
    /// Loop positions of the two feature (interior edge) or end (boundary)
    /// neighbours.
    ends: (usize, usize),
}

/// Up to `MAX_LOOP + 1` ids on the stack.
#[derive(Clone, Copy)]
struct Small {
    len: usize,
    ids: [u32; MAX_LOOP + 1],
}

impl Small {
    fn new() -> Self {
        Small {
            len: 0,
            ids: [0; MAX_LOOP + 1],
        }
    }
    fn push(&mut self, id: u32) {
        self.ids[self.len] = id;
        self.len += 1;
    }
    fn as_slice(&self) -> &[u32] {
        &self.ids[..self.len]
    }
    /// The ids at positions `i..=j` of a loop, or `j..` then `..=i` when
    /// `j < i` (wrapping round).
    fn span(ids: &[u32], i: usize, j: usize) -> Small {
        let mut out = Small::new();
        if i <= j {
            ids[i..=j].iter().for_each(|&x| out.push(x));
        } else {
            ids[i..].iter().chain(&ids[..=j]).for_each(|&x| out.push(x));
        }
        out
    }
}

struct Decimator {
    positions: Vec<Vec3>,
    tris: Vec<[u32; 3]>,
    alive: Vec<bool>,
    vertex_tris: Vec<Vec<u32>>,
    /// The distance of each vertex's live queue entry (its bits),
    /// `NOT_QUEUED` if none.
    queued: Vec<u32>,
    cos_feature: f32,
}

/// A queue entry: the distance's bits above the vertex, so that entries
/// order as plain integers (distances are never negative, and the bits of
/// non-negative floats order as the floats do). Smaller is popped first.
fn entry(error: f32, vertex: u32) -> Reverse<u64> {
    Reverse((u64::from(error.to_bits()) << 32) | u64::from(vertex))
}

/// Vertex removal to `options.target_triangles` (0 if none) or until the
/// least vertex distance exceeds `options.max_error`, with the default
/// feature angle. `options.prune` is ignored. Invalid triangles are dropped
/// as by the other simplifiers; never more triangles than given, and the
/// input (cleaned, without unused vertices) when nothing could be removed or
/// everything would be.
pub fn vertex_removal(mesh: &Mesh, options: &SimplifyOptions) -> Mesh {
    vertex_removal_with_angle(mesh, options, FEATURE_ANGLE_DEGREES)
}

/// [`vertex_removal`] with a feature angle in degrees (dihedral angles above
/// it are features; 180 or more: no edge is a feature).
pub fn vertex_removal_with_angle(
    mesh: &Mesh,
    options: &SimplifyOptions,
    feature_angle_degrees: f32,
) -> Mesh {
    let mesh = cleaned(mesh);
    let target = options.target_triangles.unwrap_or(0);
    if mesh.is_empty() || target >= mesh.triangle_count() {
        return compact(&mesh, &mesh.indices);
    }
    let (welded, indices) = weld(&mesh);
    let cos_feature = if feature_angle_degrees.is_finite() {
        feature_angle_degrees.clamp(0.0, 180.0).to_radians().cos()
    } else {
        -1.0
    };
    let mut d = Decimator::new(welded, &indices, cos_feature);
    let max_error = if options.max_error.is_nan() {
        0.0
    } else {
        options.max_error
    };
    d.run(target, max_error);
    let out: Vec<u32> = d
        .tris
        .iter()
        .zip(&d.alive)
        .filter(|(_, a)| **a)
        .flat_map(|(t, _)| *t)
        .collect();
    if out.is_empty() {
        return compact(&mesh, &mesh.indices);
    }
    compact(&mesh, &out)
}

/// Indices rewritten so that vertices at the same position are one (the
/// first), without triangles that repeat a corner. Positions stay those of
/// `mesh`, so `compact` can take attributes from it.
fn weld(mesh: &Mesh) -> (Vec<Vec3>, Vec<u32>) {
    let mut first: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    let map: Vec<u32> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            // -0.0 and 0.0 are the same place.
            let key = (*p + Vec3::ZERO).to_array().map(f32::to_bits);
            *first.entry(key).or_insert(i as u32)
        })
        .collect();
    let indices = mesh
        .indices
        .chunks_exact(3)
        .map(|t| [map[t[0] as usize], map[t[1] as usize], map[t[2] as usize]])
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0])
        .flatten()
        .collect();
    (mesh.positions.clone(), indices)
}

fn normal_area(p: [Vec3; 3]) -> Vec3 {
    (p[1] - p[0]).cross(p[2] - p[0])
}

fn distance_to_line(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 {
        return p.distance(a);
    }
    (p - a).cross(ab).length() / len2.sqrt()
}

impl Decimator {
    fn new(positions: Vec<Vec3>, indices: &[u32], cos_feature: f32) -> Self {
        let tris: Vec<[u32; 3]> = indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        let mut vertex_tris = vec![Vec::new(); positions.len()];
        for (i, t) in tris.iter().enumerate() {
            for &v in t {
                vertex_tris[v as usize].push(i as u32);
            }
        }
        Decimator {
            queued: vec![NOT_QUEUED; positions.len()],
            alive: vec![true; tris.len()],
            positions,
            tris,
            vertex_tris,
            cos_feature,
        }
    }

    fn corners(&self, t: u32) -> [Vec3; 3] {
        self.tris[t as usize].map(|i| self.positions[i as usize])
    }

    fn run(&mut self, target: usize, max_error: f32) {
        let mut count = self.tris.len();
        let mut heap = BinaryHeap::with_capacity(self.positions.len());
        for v in 0..self.positions.len() as u32 {
            self.queue(v, &mut heap);
        }
        while count > target {
            let Some(Reverse(e)) = heap.pop() else { break };
            let (bits, v) = ((e >> 32) as u32, e as u32);
            if bits != self.queued[v as usize] {
                continue;
            }
            self.queued[v as usize] = NOT_QUEUED;
            if f32::from_bits(bits) > max_error {
                break;
            }
            let Some(fan) = self.fan(v) else {
                continue;
            };
            let Some(new) = self.retriangulate(v, &fan) else {
                // Skipped until a neighbour's removal changes its loop.
                continue;
            };
            count = count - fan.tris.len + new.len();
            self.apply(v, &fan, new);
            for &n in fan.ring.as_slice() {
                self.queue(n, &mut heap);
            }
        }
    }

    /// Queues `v` with its current distance (if it is a candidate); any
    /// older entry of it becomes stale.
    fn queue(&mut self, v: u32, heap: &mut BinaryHeap<Reverse<u64>>) {
        self.queued[v as usize] = NOT_QUEUED;
        if let Some(fan) = self.fan(v)
            && let Some(error) = self.priority(v, &fan)
            && !error.is_nan()
        {
            self.queued[v as usize] = error.to_bits();
            heap.push(entry(error, v));
        }
    }

    /// The vertex's fan, `None` if it has no triangle or is complex (the
    /// fifth class, never a candidate).
    fn fan(&self, v: u32) -> Option<Fan> {
        let around = &self.vertex_tris[v as usize];
        if around.is_empty() || around.len() > MAX_LOOP {
            return None;
        }
        // Each triangle as the directed edge opposite v.
        let mut edges = [(0u32, 0u32, 0u32); MAX_LOOP];
        let k = around.len();
        for (slot, &t) in edges.iter_mut().zip(around) {
            let [a, b, c] = self.tris[t as usize];
            let (x, y) = if a == v {
                (b, c)
            } else if b == v {
                (c, a)
            } else {
                (a, b)
            };
            *slot = (x, y, t);
        }
        let edges = &edges[..k];
        // Manifold: no neighbour starts or ends two edges. The open loop
        // starts at the one edge nobody leads into.
        let mut start = None;
        for (i, e) in edges.iter().enumerate() {
            let (mut from, mut to, mut into) = (0, 0, false);
            for f in edges {
                from += usize::from(f.0 == e.0);
                to += usize::from(f.1 == e.1);
                into |= f.1 == e.0;
            }
            if from > 1 || to > 1 {
                return None;
            }
            if !into {
                if start.is_some() {
                    return None;
                }
                start = Some(i);
            }
        }
        let open = start.is_some();
        let mut ring = Small::new();
        let mut tris = Small::new();
        let mut e = edges[start.unwrap_or(0)];
        loop {
            ring.push(e.0);
            tris.push(e.2);
            match edges.iter().find(|f| f.0 == e.1) {
                Some(f) if tris.len < k => e = *f,
                _ => break,
            }
        }
        if tris.len != k {
            // More than one loop around the vertex: a non-manifold fan.
            return None;
        }
        if open {
            ring.push(e.1);
        } else if e.1 != ring.ids[0] {
            return None;
        }
        if ring.as_slice().contains(&v) {
            return None;
        }

        // Feature edges: between consecutive triangles of the fan.
        let mut normals = [Vec3::ZERO; MAX_LOOP];
        for (n, &t) in normals.iter_mut().zip(tris.as_slice()) {
            *n = normal_area(self.corners(t)).normalize_or_zero();
        }
        let mut features = (0, [0usize; 2]);
        for i in if open { 1..k } else { 0..k } {
            let (a, b) = (normals[(i + k - 1) % k], normals[i]);
            if a == Vec3::ZERO || b == Vec3::ZERO || a.dot(b) < self.cos_feature {
                if features.0 < 2 {
                    features.1[features.0] = i;
                }
                features.0 += 1;
            }
        }
        let features = (features.0, features.1);
        let (class, ends) = match (open, features.0) {
            (true, 0) => (Class::Boundary, (0, ring.len - 1)),
            (true, _) => (Class::Corner, (0, 0)),
            (false, 0) => (Class::Simple, (0, 0)),
            (false, 2) => (Class::InteriorEdge, (features.1[0], features.1[1])),
            (false, _) => (Class::Corner, (0, 0)),
        };
        Some(Fan {
            class,
            ring,
            tris,
            ends,
        })
    }

    /// The area-weighted average plane of triangles: unit normal and a point.
    fn average_plane(&self, tris: &[u32]) -> Option<(Vec3, Vec3)> {
        let (mut n, mut x, mut area) = (Vec3::ZERO, Vec3::ZERO, 0.0);
        for &t in tris {
            let c = self.corners(t);
            let na = normal_area(c);
            let a = na.length();
            n += na;
            x += (c[0] + c[1] + c[2]) / 3.0 * a;
            area += a;
        }
        let n = n.try_normalize()?;
        (area > 0.0).then(|| (n, x / area))
    }

    /// The decimation criterion of a candidate, `None` for corners and
    /// complex vertices.
    fn priority(&self, v: u32, fan: &Fan) -> Option<f32> {
        let p = self.positions[v as usize];
        match fan.class {
            Class::Simple => {
                let (n, x) = self.average_plane(fan.tris.as_slice())?;
                Some(n.dot(p - x).abs())
            }
            Class::Boundary | Class::InteriorEdge => {
                let a = self.positions[fan.ring.ids[fan.ends.0] as usize];
                let b = self.positions[fan.ring.ids[fan.ends.1] as usize];
                Some(distance_to_line(p, a, b))
            }
            Class::Corner => None,
        }
    }

    /// The triangles that fill the hole left by `v`, `None` if its loop
    /// cannot be split validly.
    fn retriangulate(&self, v: u32, fan: &Fan) -> Option<Vec<[u32; 3]>> {
        let mut out = Vec::with_capacity(fan.ring.len);
        let ring = fan.ring.as_slice();
        let tris = fan.tris.as_slice();
        match fan.class {
            Class::Simple | Class::Boundary => {
                let (n, _) = self.average_plane(tris)?;
                let last = ring.len() - 1;
                // A boundary loop's closing chord becomes a new edge.
                if fan.class == Class::Boundary
                    && last >= 2
                    && self.edge_exists(v, ring[0], ring[last])
                {
                    return None;
                }
                self.split(v, &fan.ring, n, &mut out)?;
            }
            Class::InteriorEdge => {
                let (i, j) = fan.ends;
                if self.edge_exists(v, ring[i], ring[j]) {
                    return None;
                }
                // Triangle `t` of the fan spans ring[t]..ring[t + 1]: the
                // first half holds triangles i..j, the second the others.
                let (n1, _) = self.average_plane(&tris[i..j])?;
                let mut rest = Small::new();
                tris[j..]
                    .iter()
                    .chain(&tris[..i])
                    .for_each(|&t| rest.push(t));
                let (n2, _) = self.average_plane(rest.as_slice())?;
                self.split(v, &Small::span(ring, i, j), n1, &mut out)?;
                self.split(v, &Small::span(ring, j, i), n2, &mut out)?;
            }
            Class::Corner => return None,
        }
        Some(out)
    }

    /// Whether an edge `a`-`b` exists in a live triangle not around `v`.
    fn edge_exists(&self, v: u32, a: u32, b: u32) -> bool {
        self.vertex_tris[a as usize].iter().any(|&t| {
            let t = self.tris[t as usize];
            t.contains(&b) && !t.contains(&v)
        })
    }

    fn triangle_exists(&self, v: u32, t: [u32; 3]) -> bool {
        self.vertex_tris[t[0] as usize].iter().any(|&s| {
            let s = self.tris[s as usize];
            !s.contains(&v) && s.contains(&t[1]) && s.contains(&t[2])
        })
    }

    /// Recursive loop splitting of `ring` (in loop order) against the
    /// plane normal `n`, appending triangles to `out`.
    fn split(&self, v: u32, ring: &Small, n: Vec3, out: &mut Vec<[u32; 3]>) -> Option<()> {
        let k = ring.len;
        let ids = ring.as_slice();
        if k < 3 {
            return Some(());
        }
        let mut p = [Vec3::ZERO; MAX_LOOP + 1];
        for (q, &i) in p.iter_mut().zip(ids) {
            *q = self.positions[i as usize];
        }
        if k == 3 {
            let t = [ids[0], ids[1], ids[2]];
            let facing = normal_area([p[0], p[1], p[2]]).dot(n) > 0.0;
            if !facing || self.triangle_exists(v, t) {
                return None;
            }
            out.push(t);
            return Some(());
        }
        let mut best: Option<(f32, usize, usize)> = None;
        for i in 0..k {
            for j in i + 2..k {
                if i == 0 && j == k - 1 {
                    continue;
                }
                let (a, b) = (p[i], p[j]);
                let length = a.distance(b);
                let Some(m) = (b - a).cross(n).try_normalize() else {
                    continue;
                };
                // One half strictly on the positive side, the other on the
                // negative one; the aspect ratio is the least distance.
                let mut least = f32::INFINITY;
                let ok = (0..k).filter(|&x| x != i && x != j).all(|x| {
                    let s = m.dot(p[x] - a);
                    least = least.min(s.abs());
                    if x > i && x < j { s > 0.0 } else { s < 0.0 }
                });
                let ratio = least / length;
                if ok
                    && ratio > MIN_SPLIT_RATIO
                    && best.is_none_or(|(r, _, _)| ratio > r)
                    && !self.edge_exists(v, ids[i], ids[j])
                {
                    best = Some((ratio, i, j));
                }
            }
        }
        let (_, i, j) = best?;
        self.split(v, &Small::span(ids, i, j), n, out)?;
        self.split(v, &Small::span(ids, j, i), n, out)
    }

    fn apply(&mut self, v: u32, fan: &Fan, new: Vec<[u32; 3]>) {
        for &t in fan.tris.as_slice() {
            self.alive[t as usize] = false;
        }
        for &n in fan.ring.as_slice() {
            let alive = &self.alive;
            self.vertex_tris[n as usize].retain(|&t| alive[t as usize]);
        }
        self.vertex_tris[v as usize].clear();
        for t in new {
            let id = self.tris.len() as u32;
            self.tris.push(t);
            self.alive.push(true);
            for c in t {
                self.vertex_tris[c as usize].push(id);
            }
        }
    }
}
