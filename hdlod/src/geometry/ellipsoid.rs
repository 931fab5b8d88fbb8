//! A round part's stand-in: a polytope with near-regular faces (the
//! octahedron, the icosahedron, the icosahedron subdivided once) stretched
//! over the part's box. A tree's crown, a head or a hard hat is a sphere
//! or an ellipsoid of a few hundred triangles; edge collapse takes its
//! rings away unevenly, and its box stands 0.73 of a radius off it. A
//! regular polytope spreads the error evenly: inflated so that its
//! vertices lie as far outside the sphere as its face centres lie inside,
//! the icosahedron's 20 triangles are within 0.11 of a radius, the
//! subdivided one's 80 within 0.03, where edge collapse with vertex
//! placement took 80 triangles to come within 0.12 of the fixture's tree
//! crowns (docs/benchmarks.md). `reduce::reduce_parts` measures the
//! result like any other stand-in.
//!
//! The polytopes: the octahedron and the icosahedron (Platonic solids),
//! and the geodesic sphere of frequency 2 (each face cut in four, the new
//! vertices pushed onto the sphere), as in R. Buckminster Fuller's and
//! every graphics text's icospheres.

use std::sync::LazyLock;

use glam::Vec3;

use super::Mesh;
use super::proxy::Look;

/// One of the polytopes, coarsest first.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Shape {
    Octahedron,
    Icosahedron,
    Geodesic,
}

impl Shape {
    pub(super) const ALL: [Shape; 3] = [Shape::Octahedron, Shape::Icosahedron, Shape::Geodesic];

    pub(super) fn triangles(self) -> usize {
        self.polytope().faces.len()
    }

    fn polytope(self) -> &'static Polytope {
        static SHAPES: LazyLock<[Polytope; 3]> = LazyLock::new(|| {
            let icosahedron = icosahedron();
            let geodesic = icosahedron.subdivided();
            [octahedron(), icosahedron, geodesic].map(|mut p| {
                p.inflation = p.balanced();
                p
            })
        });
        match self {
            Shape::Octahedron => &SHAPES[0],
            Shape::Icosahedron => &SHAPES[1],
            Shape::Geodesic => &SHAPES[2],
        }
    }
}

/// Vertices on the unit sphere and triangles facing out.
struct Polytope {
    vertices: Vec<Vec3>,
    faces: Vec<[usize; 3]>,
    /// The scale that balances the error on the unit sphere.
    inflation: f32,
}

impl Polytope {
    /// The scale `a` at which the vertices (at `a`) lie as far outside the
    /// unit sphere as the nearest face plane (at `a * rho`) lies inside:
    /// `a - 1 = 1 - a * rho`.
    fn balanced(&self) -> f32 {
        let rho = (self.faces.iter())
            .map(|&[a, b, c]| {
                let [a, b, c] = [a, b, c].map(|i| self.vertices[i]);
                (b - a).cross(c - a).normalize().dot(a).abs()
            })
            .fold(1.0f32, f32::min);
        2.0 / (1.0 + rho)
    }

    /// Each face cut in four at its edges' midpoints, pushed onto the
    /// sphere.
    fn subdivided(&self) -> Polytope {
        let mut vertices = self.vertices.clone();
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: usize, b: usize| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                vertices.push((vertices[a] + vertices[b]).normalize());
                vertices.len() - 1
            })
        };
        let mut faces = Vec::with_capacity(self.faces.len() * 4);
        for &[a, b, c] in &self.faces {
            let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
            faces.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        Polytope {
            vertices,
            faces,
            inflation: 1.0,
        }
    }
}

fn octahedron() -> Polytope {
    let vertices = vec![
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    let mut faces = Vec::new();
    for x in [0, 1] {
        for y in [2, 3] {
            for z in [4, 5] {
                faces.push(outward(&vertices, [x, y, z]));
            }
        }
    }
    Polytope {
        vertices,
        faces,
        inflation: 1.0,
    }
}

fn icosahedron() -> Polytope {
    let phi = (1.0 + 5f32.sqrt()) / 2.0;
    let mut vertices = Vec::with_capacity(12);
    for (a, b) in [(-1.0, phi), (1.0, phi), (-1.0, -phi), (1.0, -phi)] {
        vertices.push(Vec3::new(a, b, 0.0).normalize());
        vertices.push(Vec3::new(0.0, a, b).normalize());
        vertices.push(Vec3::new(b, 0.0, a).normalize());
    }
    // The faces are the triples of mutually nearest vertices: an edge is
    // as long as the nearest pair.
    let edge = (0..12)
        .flat_map(|i| (i + 1..12).map(move |j| (i, j)))
        .map(|(i, j)| vertices[i].distance(vertices[j]))
        .fold(f32::INFINITY, f32::min);
    let near = |i: usize, j: usize| (vertices[i].distance(vertices[j]) - edge).abs() < 1e-4;
    let mut faces = Vec::with_capacity(20);
    for a in 0..12 {
        for b in a + 1..12 {
            for c in b + 1..12 {
                if near(a, b) && near(b, c) && near(a, c) {
                    faces.push(outward(&vertices, [a, b, c]));
                }
            }
        }
    }
    Polytope {
        vertices,
        faces,
        inflation: 1.0,
    }
}

/// The triangle wound counter-clockwise seen from outside.
fn outward(vertices: &[Vec3], [a, b, c]: [usize; 3]) -> [usize; 3] {
    let [p, q, r] = [a, b, c].map(|i| vertices[i]);
    if (q - p).cross(r - p).dot(p + q + r) >= 0.0 {
        [a, b, c]
    } else {
        [a, c, b]
    }
}

/// How far the farthest of `positions` lies from the ellipsoid inscribed
/// in the box `lo..hi`, along its ray from the centre: a stand-in near the
/// ellipsoid cannot come within the budget of a part farther off than
/// that, and measuring it would be wasted. Infinite for a flat box.
pub(super) fn off_ellipsoid(positions: impl IntoIterator<Item = Vec3>, lo: Vec3, hi: Vec3) -> f32 {
    let (centre, half) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
    if half.min_element() <= 1e-6 * half.max_element().max(1e-30) {
        return f32::INFINITY;
    }
    positions
        .into_iter()
        .map(|p| {
            let r = ((p - centre) / half).length();
            if r <= 1e-6 {
                half.min_element()
            } else {
                (p - centre).length() * (1.0 - 1.0 / r).abs()
            }
        })
        .fold(0.0, f32::max)
}

/// `shape` stretched over the box `lo..hi` and inflated, flat-shaded in
/// the part's look.
pub(super) fn push_ellipsoid(out: &mut Mesh, lo: Vec3, hi: Vec3, look: Look, shape: Shape) {
    let polytope = shape.polytope();
    let (centre, half) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
    let place = |v: Vec3| centre + half * v * polytope.inflation;
    for &[a, b, c] in &polytope.faces {
        let [p, q, r] = [a, b, c].map(|i| place(polytope.vertices[i]));
        let normal = (q - p).cross(r - p).normalize_or_zero();
        for p in [p, q, r] {
            out.indices.push(out.positions.len() as u32);
            out.positions.push(p);
            out.normals.push(normal);
            out.colors.push(look.0);
            out.features.extend(look.1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_polytopes_are_closed_and_face_outwards() {
        for (shape, faces, vertices) in [
            (Shape::Octahedron, 8, 6),
            (Shape::Icosahedron, 20, 12),
            (Shape::Geodesic, 80, 42),
        ] {
            let p = shape.polytope();
            assert_eq!(
                (p.faces.len(), p.vertices.len()),
                (faces, vertices),
                "{shape:?}"
            );
            // Closed: every edge is shared by two faces, once each way.
            let mut edges = std::collections::HashMap::new();
            for &[a, b, c] in &p.faces {
                for e in [(a, b), (b, c), (c, a)] {
                    *edges.entry(e).or_insert(0) += 1;
                }
                let [a, b, c] = [a, b, c].map(|i| p.vertices[i]);
                assert!((b - a).cross(c - a).dot(a + b + c) > 0.0, "{shape:?}");
            }
            assert!(
                edges
                    .iter()
                    .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1)),
                "{shape:?}"
            );
        }
    }

    #[test]
    fn an_inflated_polytope_balances_its_error_about_the_sphere() {
        // The icosahedron's inradius is 0.7947 of its circumradius.
        let a = Shape::Icosahedron.polytope().inflation;
        assert!((a - 2.0 / 1.7947).abs() < 1e-3, "{a}");
        let mut m = Mesh::default();
        push_ellipsoid(
            &mut m,
            Vec3::splat(-1.0),
            Vec3::splat(1.0),
            ([1.0; 4], None),
            Shape::Geodesic,
        );
        assert_eq!(m.triangle_count(), 80);
        let far = m
            .positions
            .iter()
            .map(|p| p.length())
            .fold(0.0f32, f32::max);
        assert!(far > 1.0 && far < 1.04, "{far}");
    }

    #[test]
    fn a_sphere_is_near_its_ellipsoid_and_a_cube_is_not() {
        let (lo, hi) = (Vec3::splat(-2.0), Vec3::splat(2.0));
        let sphere = (0..100).map(|i| {
            let (a, b) = (i as f32 * 0.37, i as f32 * 0.11);
            2.0 * Vec3::new(a.cos() * b.cos(), b.sin(), a.sin() * b.cos())
        });
        assert!(off_ellipsoid(sphere, lo, hi) < 1e-5);
        let corner = off_ellipsoid([Vec3::splat(2.0)], lo, hi);
        assert!(
            (corner - 2.0 * (3f32.sqrt() - 1.0)).abs() < 1e-4,
            "{corner}"
        );
        assert_eq!(
            off_ellipsoid([Vec3::ZERO], lo, Vec3::new(2.0, 2.0, -2.0)),
            f32::INFINITY
        );
    }
}
