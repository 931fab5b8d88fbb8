//! Merging the triangles of many placed objects into one indexed mesh (one
//! draw call per cluster), welding coincident vertices of one object; the
//! vertices of two objects never weld, so that every triangle keeps its
//! object's feature id and no simplifier's edge joins two objects.
//!
//! The weld is a uniform grid of cell size `tolerance` with a search of the
//! 27 neighbouring cells, so that two vertices within the tolerance always
//! meet whatever side of a cell boundary they fall on (plain snapping to a
//! grid would miss those pairs). Written here because meshoptimizer's
//! vertex remap only merges bit-identical vertices.

use rustc_hash::FxHashMap;

use glam::{Mat4, Vec3};

use super::Mesh;

/// One object to merge: its mesh, where it is, its colour (used where the
/// mesh has no vertex colours) and its feature (given to every vertex;
/// `None` keeps the mesh's own feature ids).
#[derive(Debug, Clone, Copy)]
pub struct Part<'a> {
    pub mesh: &'a Mesh,
    pub transform: Mat4,
    pub color: [f32; 4],
    pub feature: Option<u32>,
}

/// Normals closer than this (`1 - cos` of the angle, for unit normals)
/// count as the same; as a squared distance, so zero normals match too.
const NORMAL_TOLERANCE: f32 = 1e-4;
/// Colours closer than this in every channel count as the same.
const COLOR_TOLERANCE: f32 = 1.0 / 512.0;

/// Merges `parts` into one mesh with per-vertex colours and normals, and
/// feature ids when every part has them (its own or the part's). Parts
/// without normals get area-weighted vertex normals of their own triangles.
/// Vertices within `weld_tolerance` of each other and with the same normal,
/// colour and feature become one (at the first one's position); a triangle
/// that loses a corner to the weld is dropped. Triangles with an
/// out-of-range index or a non-finite corner (after the transform) are
/// left out.
pub fn merge(parts: &[Part<'_>], weld_tolerance: f32) -> Mesh {
    let tolerance = if weld_tolerance.is_finite() {
        weld_tolerance.max(0.0)
    } else {
        0.0
    };
    let with_features = parts
        .iter()
        .all(|p| p.feature.is_some() || p.mesh.features.len() == p.mesh.positions.len());
    // Sized for no weld up front: growing the welder's table and the
    // vectors was most of the time of merging an object's parts, which an
    // update does for every original below the clusters it remakes.
    let vertices: usize = parts.iter().map(|p| p.mesh.positions.len()).sum();
    let mut welder = Welder::new(tolerance, vertices);
    let mut out = Mesh::default();
    out.positions.reserve(vertices);
    out.normals.reserve(vertices);
    out.colors.reserve(vertices);
    if with_features {
        out.features.reserve(vertices);
    }
    out.indices
        .reserve(parts.iter().map(|p| p.mesh.indices.len()).sum());
    for part in parts {
        let mesh = part.mesh;
        let n = mesh.positions.len();
        let own_features = mesh.features.len() == n;
        let positions: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| part.transform.transform_point3(*p))
            .collect();
        let normals = if mesh.normals.len() == n {
            let m = part.transform.inverse().transpose();
            mesh.normals
                .iter()
                .map(|v| m.transform_vector3(*v).normalize_or_zero())
                .collect()
        } else {
            vertex_normals(&positions, &mesh.indices)
        };
        // Welded ids of this part's vertices, made on first use.
        let mut ids = vec![u32::MAX; n];
        for t in mesh.indices.chunks_exact(3) {
            if t.iter()
                .any(|&i| i as usize >= n || !positions[i as usize].is_finite())
            {
                continue;
            }
            let mut tri = [0u32; 3];
            for (k, &i) in t.iter().enumerate() {
                let i = i as usize;
                if ids[i] == u32::MAX {
                    let color = mesh
                        .colors
                        .get(i)
                        .copied()
                        .filter(|_| mesh.colors.len() == n);
                    let feature = with_features
                        .then(|| part.feature.or(own_features.then(|| mesh.features[i])))
                        .flatten();
                    ids[i] = welder.insert(
                        &mut out,
                        positions[i],
                        normals[i],
                        color.unwrap_or(part.color),
                        feature,
                    );
                }
                tri[k] = ids[i];
            }
            if tri[0] != tri[1] && tri[1] != tri[2] && tri[2] != tri[0] {
                out.indices.extend(tri);
            }
        }
    }
    out
}

/// Area-weighted vertex normals (the cross product's length is twice the
/// area). Vertices of no triangle, or only degenerate ones, get zero.
fn vertex_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        if t.iter().any(|&i| i as usize >= positions.len()) {
            continue;
        }
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        let n = (b - a).cross(c - a);
        if n.is_finite() {
            for &i in t {
                normals[i as usize] += n;
            }
        }
    }
    normals.iter().map(|n| n.normalize_or_zero()).collect()
}

struct Welder {
    tolerance: f32,
    /// Cell -> welded vertices in it.
    cells: FxHashMap<[i32; 3], Vec<u32>>,
    /// With a zero tolerance only identical vertices weld: exact keys.
    exact: FxHashMap<[u32; 11], u32>,
}

impl Welder {
    /// A welder for at most `vertices` vertices.
    fn new(tolerance: f32, vertices: usize) -> Self {
        let (cells, exact) = if tolerance == 0.0 {
            (0, vertices)
        } else {
            (vertices, 0)
        };
        Welder {
            tolerance,
            cells: FxHashMap::with_capacity_and_hasher(cells, Default::default()),
            exact: FxHashMap::with_capacity_and_hasher(exact, Default::default()),
        }
    }

    fn cell(&self, p: Vec3) -> [i32; 3] {
        // Saturating float-to-int casts keep far-away points in the
        // outermost cells instead of wrapping.
        (p / self.tolerance).floor().to_array().map(|x| x as i32)
    }

    fn insert(&mut self, out: &mut Mesh, p: Vec3, n: Vec3, c: [f32; 4], f: Option<u32>) -> u32 {
        let next = out.positions.len() as u32;
        let id = if self.tolerance == 0.0 {
            let mut key = [0u32; 11];
            key[10] = f.unwrap_or(0);
            for (k, x) in p
                .to_array()
                .into_iter()
                .chain(n.to_array())
                .chain(c)
                .enumerate()
            {
                // +0.0 and -0.0 are the same vertex.
                key[k] = (x + 0.0).to_bits();
            }
            *self.exact.entry(key).or_insert(next)
        } else {
            let home = self.cell(p);
            let mut found = None;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let key = [
                            home[0].saturating_add(dx),
                            home[1].saturating_add(dy),
                            home[2].saturating_add(dz),
                        ];
                        let Some(list) = self.cells.get(&key) else {
                            continue;
                        };
                        for &v in list {
                            let i = v as usize;
                            if out.features.get(i).copied() == f
                                && out.positions[i].distance(p) <= self.tolerance
                                && out.normals[i].distance_squared(n) <= 2.0 * NORMAL_TOLERANCE
                                && out.colors[i]
                                    .iter()
                                    .zip(c)
                                    .all(|(a, b)| (a - b).abs() <= COLOR_TOLERANCE)
                            {
                                found = Some(v);
                                break 'search;
                            }
                        }
                    }
                }
            }
            match found {
                Some(v) => v,
                None => {
                    self.cells.entry(home).or_default().push(next);
                    next
                }
            }
        };
        if id == next {
            out.positions.push(p);
            out.normals.push(n);
            out.colors.push(c);
            out.features.extend(f);
        }
        id
    }
}
