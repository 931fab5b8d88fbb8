//! Nearest-point queries on a triangle mesh: our search over an `obvhs`
//! BVH (`geometry::TriangleSet`, what the Hausdorff bound uses) against
//! parry3d's `TriMesh` point projection (its own BVH), on the same query
//! points: the vertices, edge midpoints and centroids of horse's 10%
//! version against the full horse. Build and query are timed apart.
//!
//! `HDLOD_DATA=/abs/path/to/data cargo bench -p hdlod --bench closest` (the
//! directory whose `meshes/` holds horse.ply).

mod common;

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use hdlod::geometry::{Mesh, SimplifyOptions, TriangleSet, edge_collapse};
use parry3d::na::Point3;
use parry3d::query::PointQuery;
use parry3d::shape::TriMesh;

fn queries(mesh: &Mesh) -> Vec<Vec3> {
    let low = edge_collapse(
        mesh,
        &SimplifyOptions {
            max_error: f32::INFINITY,
            target_triangles: Some(mesh.triangle_count() / 10),
            prune: false,
        },
    );
    let mut out = low.positions.clone();
    for [a, b, c] in low.triangles() {
        out.extend([
            (a + b) * 0.5,
            (b + c) * 0.5,
            (c + a) * 0.5,
            (a + b + c) / 3.0,
        ]);
    }
    out
}

fn parry(mesh: &Mesh) -> TriMesh {
    let vertices = mesh
        .positions
        .iter()
        .map(|p| Point3::new(p.x, p.y, p.z))
        .collect();
    let indices = mesh
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    TriMesh::new(vertices, indices).expect("horse is a valid TriMesh")
}

fn nearest(c: &mut Criterion) {
    let mesh = common::horse();
    let points = queries(&mesh);
    let ours = TriangleSet::new(mesh.triangles());
    let theirs = parry(&mesh);

    // Both must answer the same distances, or the race means nothing.
    let worst = points
        .iter()
        .map(|p| {
            let a = ours.nearest(*p, None).unwrap().distance_squared.sqrt();
            let q = Point3::new(p.x, p.y, p.z);
            let b = (theirs.project_local_point(&q, false).point - q).norm();
            (a - b).abs()
        })
        .fold(0.0f32, f32::max);
    println!(
        "{} query points; largest difference between the two answers: {worst:e}",
        points.len()
    );

    let mut g = c.benchmark_group("closest_build");
    g.throughput(Throughput::Elements(mesh.triangle_count() as u64));
    g.bench_function("obvhs", |b| b.iter(|| TriangleSet::new(mesh.triangles())));
    g.bench_function("parry3d", |b| b.iter(|| parry(&mesh)));
    g.finish();

    let mut g = c.benchmark_group("closest_query");
    g.throughput(Throughput::Elements(points.len() as u64));
    g.bench_function("obvhs", |b| {
        b.iter(|| {
            points
                .iter()
                .map(|p| ours.nearest(*p, None).unwrap().distance_squared)
                .sum::<f32>()
        })
    });
    // As the Hausdorff bound queries: each answer seeds the next query.
    g.bench_function("obvhs_hinted", |b| {
        b.iter(|| {
            let mut hint = None;
            points
                .iter()
                .map(|p| {
                    let n = ours.nearest(*p, hint).unwrap();
                    hint = Some(n.triangle);
                    n.distance_squared
                })
                .sum::<f32>()
        })
    });
    g.bench_function("parry3d", |b| {
        b.iter(|| {
            points
                .iter()
                .map(|p| {
                    let q = Point3::new(p.x, p.y, p.z);
                    (theirs.project_local_point(&q, false).point - q).norm_squared()
                })
                .sum::<f32>()
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = nearest
}
criterion_main!(benches);
