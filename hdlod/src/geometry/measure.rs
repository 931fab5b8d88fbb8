//! Surface area and enclosed volume, for the area and volume ratios that
//! compare a simplified mesh with its original (the decimation theses).
//!
//! The volume is the signed sum over triangles of the tetrahedra they span
//! with the origin (the divergence theorem): exact for a closed, consistently
//! oriented mesh, positive when its triangles face outwards, and a
//! well-defined but not physical number for an open one. Sums are in `f64`
//! so that large meshes do not lose the small triangles. Triangles with an
//! out-of-range index are skipped.

use glam::DVec3;

use super::Mesh;

fn triangles(mesh: &Mesh) -> impl Iterator<Item = [DVec3; 3]> + '_ {
    let n = mesh.positions.len();
    mesh.indices
        .chunks_exact(3)
        .filter(move |t| t.iter().all(|&i| (i as usize) < n))
        .map(|t| [0, 1, 2].map(|k| mesh.positions[t[k] as usize].as_dvec3()))
}

pub fn area(mesh: &Mesh) -> f64 {
    triangles(mesh)
        .map(|[a, b, c]| (b - a).cross(c - a).length() * 0.5)
        .sum()
}

pub fn volume(mesh: &Mesh) -> f64 {
    triangles(mesh)
        .map(|[a, b, c]| a.dot(b.cross(c)) / 6.0)
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn unit_cube_measures() {
        let cube = Mesh::cuboid(Vec3::ZERO, Vec3::ONE, 1);
        assert!((area(&cube) - 6.0).abs() < 1e-9);
        assert!((volume(&cube) - 1.0).abs() < 1e-9);
        let moved = cube.transformed(&glam::Mat4::from_translation(Vec3::new(5.0, -3.0, 2.0)));
        assert!((volume(&moved) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn empty_mesh_measures_zero() {
        assert_eq!(area(&Mesh::default()), 0.0);
        assert_eq!(volume(&Mesh::default()), 0.0);
    }
}
