//! Merging placed parts into one welded mesh.

use glam::{Mat4, Vec3};
use hdlod::geometry::{Mesh, Part, measure, merge};

fn triangle() -> Mesh {
    Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        indices: vec![0, 1, 2],
        ..Mesh::default()
    }
}

fn part(mesh: &Mesh, transform: Mat4, color: [f32; 4]) -> Part<'_> {
    Part {
        mesh,
        transform,
        color,
        feature: None,
    }
}

const RED: [f32; 4] = [1.0, 0.0, 0.0, 1.0];
const BLUE: [f32; 4] = [0.0, 0.0, 1.0, 1.0];

#[test]
fn transforms_colours_and_normals_are_applied() {
    let t = triangle();
    let m = merge(&[part(&t, Mat4::from_translation(Vec3::Z * 2.0), RED)], 0.0);
    assert_eq!(
        m.positions,
        vec![
            Vec3::Z * 2.0,
            Vec3::new(1.0, 0.0, 2.0),
            Vec3::new(0.0, 1.0, 2.0)
        ]
    );
    assert_eq!(m.colors, vec![RED; 3]);
    assert_eq!(m.normals, vec![Vec3::Z; 3]);
    m.validate().unwrap();
}

#[test]
fn coincident_vertices_weld_only_with_equal_attributes() {
    let t = triangle();
    // The second copy is mirrored onto the first's edge x = 0..1: it shares
    // two corners, within a tolerance of the first.
    let mirror = Mat4::from_translation(Vec3::new(1.0 + 4e-4, 0.0, 0.0))
        * Mat4::from_rotation_z(std::f32::consts::PI);
    let same = merge(
        &[part(&t, Mat4::IDENTITY, RED), part(&t, mirror, RED)],
        1e-3,
    );
    assert_eq!(same.positions.len(), 4, "{:?}", same.positions);
    assert_eq!(same.triangle_count(), 2);
    let other_colour = merge(
        &[part(&t, Mat4::IDENTITY, RED), part(&t, mirror, BLUE)],
        1e-3,
    );
    assert_eq!(other_colour.positions.len(), 6);
    let no_tolerance = merge(&[part(&t, Mat4::IDENTITY, RED), part(&t, mirror, RED)], 0.0);
    assert_eq!(no_tolerance.positions.len(), 6);
}

#[test]
fn welding_across_a_cell_boundary() {
    // 0.0999 and 0.1001 fall in different cells of size 0.1 yet are
    // 0.0002 apart.
    let a = Mesh {
        positions: vec![
            Vec3::new(0.0999, 0.0, 0.0),
            Vec3::new(0.0999, 1.0, 0.0),
            Vec3::new(0.0999, 0.0, 1.0),
        ],
        indices: vec![0, 1, 2],
        ..Mesh::default()
    };
    let b = a.transformed(&Mat4::from_translation(Vec3::X * 0.0002));
    let m = merge(
        &[part(&a, Mat4::IDENTITY, RED), part(&b, Mat4::IDENTITY, RED)],
        0.1,
    );
    assert_eq!(m.positions.len(), 3);
    // Both copies become the same triangle; the duplicate stays (it is not
    // degenerate), as a polygon soup may have it.
    assert_eq!(m.triangle_count(), 2);
}

#[test]
fn vertex_colours_win_over_the_part_colour_and_bad_triangles_are_skipped() {
    let mut t = triangle();
    t.colors = vec![BLUE; 3];
    t.positions.push(Vec3::NAN);
    t.colors.push(BLUE);
    t.indices.extend([0, 1, 3, 0, 1, 77]);
    let m = merge(&[part(&t, Mat4::IDENTITY, RED)], 0.0);
    assert_eq!(m.triangle_count(), 1);
    assert_eq!(m.colors, vec![BLUE; 3]);
    m.validate().unwrap();
    assert_eq!(merge(&[], 0.1), Mesh::default());
}

#[test]
fn merged_area_is_the_sum_of_the_parts() {
    let t = triangle();
    let parts: Vec<Part> = (0..10)
        .map(|i| part(&t, Mat4::from_scale(Vec3::splat(1.0 + i as f32)), RED))
        .collect();
    let expected: f64 = (0..10).map(|i| 0.5 * (1.0 + i as f64).powi(2)).sum();
    assert!((measure::area(&merge(&parts, 1e-4)) - expected).abs() < 1e-3);
}
