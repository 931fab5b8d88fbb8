use crate::error::{Error, Result};
use rustc_hash::FxHashMap;

use glam::{Mat4, Vec3};

/// An indexed triangle mesh: a polygon soup as far as any algorithm may
/// assume (no manifoldness, no connectivity). `normals`, `colors` and
/// `features` are either empty or one per position; colours are linear
/// RGBA. A feature is the scene object a vertex belongs to (its index in
/// the scene); every stage that makes triangles keeps the three corners of
/// a triangle on one feature, so that a viewer can pick, hide and colour
/// objects inside a merged and simplified cluster.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub colors: Vec<[f32; 4]>,
    pub features: Vec<u32>,
    pub indices: Vec<u32>,
}

impl Mesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// The triangles as corner positions.
    pub fn triangles(&self) -> impl Iterator<Item = [Vec3; 3]> + '_ {
        self.indices.chunks_exact(3).map(|t| {
            [
                self.positions[t[0] as usize],
                self.positions[t[1] as usize],
                self.positions[t[2] as usize],
            ]
        })
    }

    /// Axis-aligned bounds `(min, max)` of the referenced vertices, `None`
    /// for a mesh without triangles.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.indices.iter().map(|&i| self.positions[i as usize]);
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// The mesh moved by `m` (normals by its inverse transpose).
    pub fn transformed(&self, m: &Mat4) -> Mesh {
        let normal_m = m.inverse().transpose();
        Mesh {
            positions: self
                .positions
                .iter()
                .map(|p| m.transform_point3(*p))
                .collect(),
            normals: self
                .normals
                .iter()
                .map(|n| normal_m.transform_vector3(*n).normalize_or_zero())
                .collect(),
            colors: self.colors.clone(),
            features: self.features.clone(),
            indices: self.indices.clone(),
        }
    }

    /// The feature of each triangle (its first corner's), `None` for a
    /// mesh without features.
    pub fn triangle_features(&self) -> Option<impl Iterator<Item = u32> + '_> {
        (!self.features.is_empty()).then(|| {
            self.indices
                .chunks_exact(3)
                .map(|t| self.features[t[0] as usize])
        })
    }

    /// The box from `lo` to `hi` with each face cut into `k x k` quads
    /// (`k` at least 1: `12 k^2` triangles), flat-shaded: every face has its
    /// own vertices with its outward normal, and is wound outwards. Faces
    /// come in the order +x, -x, +y, -y, +z, -z, a face's vertices row by
    /// row with every other row reversed: an undivided face then lists its
    /// corners around it and is split along the diagonal from its first
    /// corner, as the box proxies of built trees always were (their
    /// geometry is named by the hash of its bytes).
    pub fn cuboid(lo: Vec3, hi: Vec3, k: u32) -> Mesh {
        let k = k.max(1);
        // The ends exactly: `lo + (hi - lo)` may round to a neighbour of `hi`.
        let at = |along: usize, i: u32| match i {
            0 => lo[along],
            _ if i == k => hi[along],
            _ => lo[along] + (hi[along] - lo[along]) * (i as f32 / k as f32),
        };
        let vertices = 6 * (k as usize + 1).pow(2);
        let mut mesh = Mesh {
            positions: Vec::with_capacity(vertices),
            normals: Vec::with_capacity(vertices),
            colors: Vec::new(),
            features: Vec::new(),
            indices: Vec::with_capacity(36 * (k as usize).pow(2)),
        };
        for axis in 0..3 {
            for high in [true, false] {
                // (s, t) span the face, s x t pointing out of the box.
                let (s, t) = if high {
                    ((axis + 1) % 3, (axis + 2) % 3)
                } else {
                    ((axis + 2) % 3, (axis + 1) % 3)
                };
                let mut normal = Vec3::ZERO;
                normal[axis] = if high { 1.0 } else { -1.0 };
                let base = mesh.positions.len() as u32;
                let column = |i: u32, j: u32| if j.is_multiple_of(2) { i } else { k - i };
                for j in 0..=k {
                    for n in 0..=k {
                        let mut p = Vec3::ZERO;
                        p[axis] = if high { hi[axis] } else { lo[axis] };
                        p[s] = at(s, column(n, j));
                        p[t] = at(t, j);
                        mesh.positions.push(p);
                        mesh.normals.push(normal);
                    }
                }
                let vertex = |i: u32, j: u32| base + j * (k + 1) + column(i, j);
                for j in 0..k {
                    for i in 0..k {
                        let (a, b) = (vertex(i, j), vertex(i + 1, j));
                        let (c, d) = (vertex(i + 1, j + 1), vertex(i, j + 1));
                        mesh.indices.extend([a, b, c, a, c, d]);
                    }
                }
            }
        }
        mesh
    }

    /// The mesh with its vertices merged by position (normals dropped, the
    /// first colour kept, unused vertices gone), never across features: a
    /// flat-shaded mesh repeats each corner per face, and edge collapse
    /// cannot move a vertex along such a seam.
    pub fn welded(&self) -> Mesh {
        let mut index: FxHashMap<([u32; 3], u32), u32> =
            FxHashMap::with_capacity_and_hasher(self.positions.len(), Default::default());
        let mut out = Mesh::default();
        for &i in &self.indices {
            let p = self.positions[i as usize];
            let feature = self.features.get(i as usize).copied();
            let key = (p.to_array().map(f32::to_bits), feature.unwrap_or(0));
            let at = *index.entry(key).or_insert_with(|| {
                out.positions.push(p);
                if let Some(c) = self.colors.get(i as usize) {
                    out.colors.push(*c);
                }
                out.features.extend(feature);
                out.positions.len() as u32 - 1
            });
            out.indices.push(at);
        }
        out
    }

    /// Checks the internal consistency a reader must guarantee: indices in
    /// range, a whole number of triangles, attribute lengths, finite values.
    pub fn validate(&self) -> Result<()> {
        if !self.indices.len().is_multiple_of(3) {
            return Err(Error::value(format!(
                "{} indices is not a whole number of triangles",
                self.indices.len()
            )));
        }
        let n = self.positions.len();
        if let Some(i) = self.indices.iter().find(|&&i| i as usize >= n) {
            return Err(Error::value(format!(
                "index {i} is out of range ({n} vertices)"
            )));
        }
        if !self.normals.is_empty() && self.normals.len() != n {
            return Err(Error::value(format!(
                "{} normals for {n} vertices",
                self.normals.len()
            )));
        }
        if !self.colors.is_empty() && self.colors.len() != n {
            return Err(Error::value(format!(
                "{} colours for {n} vertices",
                self.colors.len()
            )));
        }
        if !self.features.is_empty() && self.features.len() != n {
            return Err(Error::value(format!(
                "{} feature ids for {n} vertices",
                self.features.len()
            )));
        }
        if let Some((i, p)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(Error::value(format!(
                "vertex {i} has a non-finite coordinate {p}"
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::measure;

    #[test]
    fn cuboids_are_closed_flat_and_wound_outwards() {
        let (lo, hi) = (Vec3::new(-1.0, 0.5, 2.0), Vec3::new(0.1, 3.0, 2.3));
        let size = (hi - lo).as_dvec3();
        for k in 1..4 {
            let m = Mesh::cuboid(lo, hi, k);
            m.validate().unwrap();
            assert_eq!(m.triangle_count(), 12 * (k * k) as usize);
            assert_eq!(m.bounds(), Some((lo, hi)));
            let volume = size.x * size.y * size.z;
            let area = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
            assert!((measure::volume(&m) - volume).abs() < 1e-5, "k = {k}");
            assert!((measure::area(&m) - area).abs() < 1e-5, "k = {k}");
            for t in m.indices.chunks_exact(3) {
                let [a, b, c] = [0, 1, 2].map(|i| m.positions[t[i] as usize]);
                let n = m.normals[t[0] as usize];
                assert!((b - a).cross(c - a).normalize().dot(n) > 0.999);
                assert!(t.iter().all(|&i| m.normals[i as usize] == n));
            }
        }
        // Welded, the faces share their edges: 8 corners, and for k = 3 two
        // points on each of the 12 edges and 4 inside each face.
        let corners = Mesh::cuboid(lo, hi, 1).welded();
        assert_eq!(corners.positions.len(), 8);
        assert_eq!(corners.triangle_count(), 12);
        assert!(corners.normals.is_empty());
        assert_eq!(
            Mesh::cuboid(lo, hi, 3).welded().positions.len(),
            8 + 24 + 24
        );
    }
}
