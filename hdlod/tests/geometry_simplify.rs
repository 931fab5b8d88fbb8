//! Simplification: real meshes reach their targets with the right
//! strategy, bad input gets a defined result, and (proptest) random soups
//! never yield NaN or more triangles than they had.

use glam::{Mat4, Vec3};
use hdlod::geometry::{
    HausdorffOptions, Mesh, Part, SimplifyOptions, Strategy, clustering, edge_collapse, hausdorff,
    merge, simplify,
};
use proptest::prelude::*;
use proptest::strategy::Strategy as _;

/// `shared/data` beside the repository (a clone) or two levels up (a
/// worktree).
fn bunny() -> Mesh {
    let here = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let path = [
        here.join("../../shared/data/meshes"),
        here.join("../../../shared/data/meshes"),
    ]
    .into_iter()
    .find(|d| d.exists())
    .expect("shared/data/meshes next to the repository")
    .join("stanford-bunny.obj");
    hdlod::io::obj::read_mesh(&path).expect("the bunny from shared/data")
}

fn ratio(target: usize) -> SimplifyOptions {
    SimplifyOptions {
        max_error: f32::INFINITY,
        target_triangles: Some(target),
        prune: false,
    }
}

#[test]
fn bunny_to_ten_percent_by_edge_collapse() {
    let mesh = bunny();
    let n = mesh.triangle_count();
    let s = simplify(&mesh, &ratio(n / 10));
    assert_eq!(s.strategy, Strategy::EdgeCollapse);
    assert!(
        s.triangles <= n / 10 && s.triangles > n / 20,
        "{}",
        s.triangles
    );
    s.mesh.validate().unwrap();
    let h = hausdorff(
        &mesh,
        &s.mesh,
        &HausdorffOptions {
            tolerance: 1e-4,
            seed: 1,
        },
    );
    let (lo, hi) = mesh.bounds().unwrap();
    assert!(h.bound < 0.02 * (hi - lo).length(), "{h:?}");
}

#[test]
fn an_error_budget_is_met_as_measured() {
    let mesh = bunny();
    let (lo, hi) = mesh.bounds().unwrap();
    let budget = 0.002 * (hi - lo).length();
    let s = simplify(
        &mesh,
        &SimplifyOptions {
            max_error: budget,
            target_triangles: None,
            prune: false,
        },
    );
    assert!(s.triangles < mesh.triangle_count() / 2, "{}", s.triangles);
    let h = hausdorff(
        &mesh,
        &s.mesh,
        &HausdorffOptions {
            tolerance: budget * 0.05,
            seed: 1,
        },
    );
    // meshoptimizer's error is an estimate; the measured bound stays near it.
    assert!(h.bound < 3.0 * budget, "{h:?} budget {budget}");
}

/// Many small separate boxes: edge collapse cannot remove a closed box's
/// last triangles, so only clustering reaches a small target.
fn box_field(count: usize) -> Mesh {
    let cube = {
        let positions = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * 0.3)
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        Mesh {
            positions,
            indices: quads
                .iter()
                .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
                .collect(),
            ..Mesh::default()
        }
    };
    let parts: Vec<Part> = (0..count)
        .map(|i| Part {
            mesh: &cube,
            transform: Mat4::from_translation(Vec3::new(
                (i % 10) as f32,
                (i / 100) as f32,
                ((i / 10) % 10) as f32,
            )),
            color: [1.0, 0.5, 0.25, 1.0],
        })
        .collect();
    merge(&parts, 1e-5)
}

#[test]
fn many_small_parts_fall_back_to_clustering() {
    let mesh = box_field(500);
    assert_eq!(mesh.triangle_count(), 6000);
    // A budget of the boxes' spacing: edge collapse either keeps each box or
    // removes it whole; clustering merges neighbouring boxes.
    let budget = SimplifyOptions {
        max_error: 1.0,
        target_triangles: None,
        prune: false,
    };
    let s = simplify(&mesh, &budget);
    assert_eq!(
        s.strategy,
        Strategy::Clustering,
        "{} triangles",
        s.triangles
    );
    assert!(s.triangles > 0 && s.triangles < 600, "{}", s.triangles);
    // With a target edge collapse can reach, it stays the choice.
    let s = simplify(
        &mesh,
        &SimplifyOptions {
            max_error: 3.0,
            target_triangles: Some(600),
            prune: true,
        },
    );
    assert_eq!((s.strategy, s.triangles), (Strategy::EdgeCollapse, 600));
}

#[test]
fn colours_survive_edge_collapse() {
    let mesh = box_field(20);
    let s = edge_collapse(&mesh, &ratio(100));
    assert_eq!(s.colors.len(), s.positions.len());
    assert_eq!(s.normals.len(), s.positions.len());
    assert!(s.colors.iter().all(|c| *c == [1.0, 0.5, 0.25, 1.0]));
}

#[test]
fn targets_at_or_above_the_input_leave_it_unchanged() {
    let mesh = box_field(3);
    for target in [36, 37, 1000] {
        let s = simplify(&mesh, &ratio(target));
        assert_eq!((s.strategy, s.triangles), (Strategy::Unchanged, 36));
        assert_eq!(s.mesh, mesh);
    }
    assert_eq!(clustering(&mesh, &ratio(1000)), mesh);
}

#[test]
fn bad_input_gets_defined_results() {
    let empty = simplify(&Mesh::default(), &ratio(0));
    assert_eq!((empty.strategy, empty.triangles), (Strategy::Unchanged, 0));
    // Out-of-range indices and NaN corners are dropped, not passed to C.
    let mut m = box_field(2);
    m.positions.push(Vec3::NAN);
    let nan = m.positions.len() as u32 - 1;
    m.indices.extend([0, 1, nan, 0, 1, 9999]);
    // Duplicate and degenerate triangles, a non-manifold fan on one edge.
    m.indices
        .extend([0, 1, 2, 0, 1, 2, 3, 3, 3, 0, 1, 5, 0, 1, 6, 0, 1, 7]);
    let s = simplify(&m, &ratio(4));
    assert!(s.triangles <= m.triangle_count() && s.triangles > 0);
    s.mesh.validate().unwrap();
}

fn soup() -> impl proptest::strategy::Strategy<Value = Mesh> {
    prop::collection::vec(
        prop::array::uniform3(prop::array::uniform3(-4.0f32..4.0)),
        1..80,
    )
    .prop_flat_map(|tris| {
        let n = tris.len() * 3;
        // Shared corners: each triangle picks among the soup's points.
        prop::collection::vec(0..n as u32, n).prop_map(move |indices| Mesh {
            positions: tris
                .iter()
                .flatten()
                .map(|p| Vec3::from_array(*p))
                .collect(),
            indices,
            ..Mesh::default()
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn random_soups_simplify_sanely(mesh in soup(), target in 0usize..100, error in 0.0f32..2.0, prune: bool) {
        let options = SimplifyOptions { max_error: error, target_triangles: Some(target), prune };
        for out in [simplify(&mesh, &options).mesh, edge_collapse(&mesh, &options), clustering(&mesh, &options)] {
            prop_assert!(out.triangle_count() <= mesh.triangle_count());
            prop_assert!(out.triangle_count() > 0);
            prop_assert!(out.validate().is_ok());
            let h = hausdorff(&mesh, &out, &HausdorffOptions { tolerance: 0.05, seed: 3 });
            prop_assert!(h.bound.is_finite() && h.mean.is_finite());
        }
    }
}
