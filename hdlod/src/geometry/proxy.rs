//! Connected parts of a mesh and proxies for them: a part replaced by its
//! axis-aligned box (12 triangles), the coarse representation BIM viewers
//! fall back to, or, when the part is thin across one axis, by that box
//! squashed to its mid-plane (one quad, 2 triangles: a slab, a wall, a
//! panel, a beam or a tube once the budget exceeds half its thickness).
//! Both work where edge collapse and vertex clustering fail: many small
//! elements, each already near its minimum triangle count for its shape
//! (round columns, tubes, frames).
//! `reduce::reduce_parts` decides part by part and measures the result.

use rustc_hash::FxHashMap;

use glam::Vec3;

use super::Mesh;
use super::union_find::UnionFind;

/// The connected parts of `mesh` as lists of triangle indices, in order of
/// first appearance. Parts are connected through shared vertices or
/// coincident positions (flat-shaded meshes repeat corners per face) of
/// one feature: two objects are never one part.
pub(super) fn parts(mesh: &Mesh) -> Vec<Vec<usize>> {
    let n = mesh.positions.len();
    let mut sets = UnionFind::new(n);
    let mut same_place: FxHashMap<([u32; 3], u32), u32> =
        FxHashMap::with_capacity_and_hasher(n, Default::default());
    for (i, p) in mesh.positions.iter().enumerate() {
        let feature = mesh.features.get(i).copied().unwrap_or(0);
        let key = (p.to_array().map(f32::to_bits), feature);
        let first = *same_place.entry(key).or_insert(i as u32);
        sets.union(first, i as u32);
    }
    for t in mesh.indices.chunks_exact(3) {
        sets.union(t[0], t[1]);
        sets.union(t[0], t[2]);
    }
    let mut index: FxHashMap<u32, usize> = FxHashMap::default();
    let mut out: Vec<Vec<usize>> = Vec::new();
    for (k, t) in mesh.indices.chunks_exact(3).enumerate() {
        let root = sets.find(t[0]);
        let at = *index.entry(root).or_insert_with(|| {
            out.push(Vec::new());
            out.len() - 1
        });
        out[at].push(k);
    }
    out
}

/// The bounds of some triangles of `mesh`.
pub(super) fn part_bounds(mesh: &Mesh, triangles: &[usize]) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for &k in triangles {
        for &i in &mesh.indices[k * 3..k * 3 + 3] {
            lo = lo.min(mesh.positions[i as usize]);
            hi = hi.max(mesh.positions[i as usize]);
        }
    }
    (lo, hi)
}

/// The colour and feature a proxy gives its vertices.
pub(super) type Look = ([f32; 4], Option<u32>);

/// The colour that covers most of a part's area and the part's feature
/// (that of its first vertex; a part is one object): a proxy stands in
/// for the part in both, and the colour bound holds the rest of the
/// part's colours to it.
pub(super) fn part_look(mesh: &Mesh, triangles: &[usize]) -> Look {
    let first = mesh.indices[triangles[0] * 3] as usize;
    let mut areas: Vec<([f32; 4], f32)> = Vec::new();
    for &k in triangles {
        let t = &mesh.indices[k * 3..k * 3 + 3];
        let color = mesh.colors.get(t[0] as usize).copied().unwrap_or([1.0; 4]);
        let [a, b, c] = [0, 1, 2].map(|i| mesh.positions[t[i] as usize]);
        let area = (b - a).cross(c - a).length();
        match areas.iter_mut().find(|(c, _)| *c == color) {
            Some((_, sum)) => *sum += area,
            None => areas.push((color, area)),
        }
    }
    let color = areas
        .iter()
        .fold(None::<&([f32; 4], f32)>, |best, x| match best {
            Some(b) if b.1 >= x.1 => Some(b),
            _ => Some(x),
        })
        .map_or([1.0; 4], |x| x.0);
    (color, mesh.features.get(first).copied())
}

/// Copies some triangles of `mesh` to `out` (unshared vertices).
pub(super) fn push_triangles(out: &mut Mesh, mesh: &Mesh, triangles: &[usize]) {
    for &k in triangles {
        for &i in &mesh.indices[k * 3..k * 3 + 3] {
            push_vertex(out, mesh, i as usize);
        }
    }
}

fn push_vertex(out: &mut Mesh, mesh: &Mesh, i: usize) {
    out.indices.push(out.positions.len() as u32);
    out.positions.push(mesh.positions[i]);
    out.normals
        .push(mesh.normals.get(i).copied().unwrap_or(Vec3::ZERO));
    out.colors
        .push(mesh.colors.get(i).copied().unwrap_or([1.0; 4]));
    out.features.extend(mesh.features.get(i));
}

/// The part's box (`Mesh::cuboid`), flat-shaded in the part's colour, of
/// the part's feature.
pub(super) fn push_box(out: &mut Mesh, lo: Vec3, hi: Vec3, look: Look) {
    let cuboid = Mesh::cuboid(lo, hi, 1);
    let base = out.positions.len() as u32;
    out.positions.extend(&cuboid.positions);
    out.normals.extend(&cuboid.normals);
    out.colors
        .extend(std::iter::repeat_n(look.0, cuboid.positions.len()));
    if let Some(f) = look.1 {
        out.features
            .extend(std::iter::repeat_n(f, cuboid.positions.len()));
    }
    out.indices.extend(cuboid.indices.iter().map(|i| base + i));
}

/// The part's box squashed to its mid-plane across its thinnest axis: one
/// quad, facing along that axis (the material is double-sided).
pub(super) fn push_quad(out: &mut Mesh, lo: Vec3, hi: Vec3, look: Look) {
    let axis = (hi - lo).min_position();
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let mid = (lo[axis] + hi[axis]) / 2.0;
    let corner = |a: f32, b: f32| {
        let mut p = Vec3::ZERO;
        p[axis] = mid;
        p[u] = a;
        p[v] = b;
        p
    };
    let normal = Vec3::AXES[axis];
    let base = out.positions.len() as u32;
    for p in [
        corner(lo[u], lo[v]),
        corner(hi[u], lo[v]),
        corner(hi[u], hi[v]),
        corner(lo[u], hi[v]),
    ] {
        out.positions.push(p);
        out.normals.push(normal);
        out.colors.push(look.0);
        out.features.extend(look.1);
    }
    out.indices
        .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{HausdorffOptions, hausdorff};

    fn tube(segments: usize, radius: f32, length: f32, x: f32) -> Mesh {
        let mut m = Mesh::default();
        for s in 0..segments {
            let a = s as f32 / segments as f32 * std::f32::consts::TAU;
            let b = (s + 1) as f32 / segments as f32 * std::f32::consts::TAU;
            let p = |ang: f32, y: f32| Vec3::new(x + radius * ang.cos(), y, radius * ang.sin());
            let base = m.positions.len() as u32;
            m.positions
                .extend([p(a, 0.0), p(b, 0.0), p(b, length), p(a, length)]);
            m.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        m
    }

    #[test]
    fn finds_parts_and_boxes_them() {
        let mut m = tube(16, 0.05, 4.0, 0.0);
        let other = tube(16, 0.05, 4.0, 1.0);
        let offset = m.positions.len() as u32;
        m.positions.extend(&other.positions);
        m.indices.extend(other.indices.iter().map(|i| i + offset));
        let found = parts(&m);
        assert_eq!(found.len(), 2);
        assert_eq!(found[0], (0..32).collect::<Vec<_>>());
        let mut proxies = Mesh::default();
        for p in &found {
            let (lo, hi) = part_bounds(&m, p);
            push_box(&mut proxies, lo, hi, part_look(&m, p));
        }
        assert_eq!(proxies.triangle_count(), 24);
        let h = hausdorff(
            &proxies,
            &m,
            &HausdorffOptions {
                tolerance: 1e-3,
                seed: 0,
            },
        );
        // The box of a thin tube is within its radius of it.
        assert!(h.bound < 0.08, "{h:?}");
        assert!(proxies.validate().is_ok());
    }
}
