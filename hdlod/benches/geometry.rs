//! Geometry kernel benchmark against the targets of the geometry issue:
//! QEM to 10% of horse at >= 2 M input triangles/s, clustering at >= 10 M/s,
//! the Hausdorff bound between horse and its 10% version under 1 s; plus
//! the per-call cost on the small meshes the tree builder works on.
//!
//! `cargo bench -p hdlod --bench geometry` prints the median of several runs
//! of each. A plain timing loop (no criterion): the medians are all the
//! report needs, and it keeps a large dependency off a 2-core build.

use std::path::Path;
use std::time::Instant;

use glam::{Mat4, Vec3};
use hdlod::geometry::{
    HausdorffOptions, Mesh, Part, SimplifyOptions, clustering, edge_collapse, hausdorff, merge,
    simplify,
};

fn median_seconds(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[runs / 2]
}

fn horse() -> Mesh {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = [
        here.join("../../shared/data/meshes"),
        here.join("../../../shared/data/meshes"),
    ]
    .into_iter()
    .find(|d| d.exists())
    .expect("shared/data/meshes next to the repository");
    hdlod::io::ply::read_mesh(&dir.join("horse.ply")).expect("horse.ply")
}

fn main() {
    // `cargo test --benches` runs this with `--bench` absent: stay quick.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let mesh = horse();
    let n = mesh.triangle_count();
    let ten = SimplifyOptions {
        max_error: f32::INFINITY,
        target_triangles: Some(n / 10),
        prune: false,
    };
    println!("horse: {n} triangles; medians");

    let mut qem = Mesh::default();
    let t = median_seconds(9, || qem = edge_collapse(&mesh, &ten));
    println!(
        "qem to 10%            {:8.2} ms  {:6.2} M input triangles/s  ({} out)",
        t * 1e3,
        n as f64 / t / 1e6,
        qem.triangle_count()
    );
    let mut clustered = Mesh::default();
    let t = median_seconds(9, || clustered = clustering(&mesh, &ten));
    println!(
        "clustering to 10%     {:8.2} ms  {:6.2} M input triangles/s  ({} out)",
        t * 1e3,
        n as f64 / t / 1e6,
        clustered.triangle_count()
    );
    let t = median_seconds(9, || {
        simplify(&mesh, &ten);
    });
    println!("simplify to 10%       {:8.2} ms", t * 1e3);

    let (lo, hi) = mesh.bounds().unwrap();
    let diagonal = (hi - lo).length();
    for (name, other) in [("qem", &qem), ("clustering", &clustered)] {
        let mut h = None;
        let options = HausdorffOptions {
            tolerance: 1e-3 * diagonal,
            seed: 1,
        };
        let t = median_seconds(5, || h = Some(hausdorff(&mesh, other, &options)));
        let h = h.unwrap();
        println!(
            "hausdorff horse/{name:<10} {:8.2} ms  bound {:.5} lower {:.5} (tolerance 0.1% of the diagonal {:.3})",
            t * 1e3,
            h.bound,
            h.lower,
            diagonal
        );
    }

    // Tree-builder sized work: a 12-box cluster, merged, simplified, measured.
    let cube = cube();
    let parts: Vec<Part> = (0..12)
        .map(|i| Part {
            mesh: &cube,
            transform: Mat4::from_translation(Vec3::new(i as f32 * 1.1, 0.0, (i % 3) as f32)),
            color: [0.8, 0.8, 0.8, 1.0],
        })
        .collect();
    let calls = 2000;
    let t = median_seconds(5, || {
        for _ in 0..calls {
            merge(&parts, 1e-4);
        }
    });
    println!(
        "merge 12 boxes        {:8.2} us per call",
        t / calls as f64 * 1e6
    );
    let merged = merge(&parts, 1e-4);
    let small = simplify(
        &merged,
        &SimplifyOptions {
            max_error: 0.5,
            target_triangles: None,
            prune: true,
        },
    )
    .mesh;
    let t = median_seconds(5, || {
        for _ in 0..calls {
            hausdorff(
                &merged,
                &small,
                &HausdorffOptions {
                    tolerance: 0.01,
                    seed: 1,
                },
            );
        }
    });
    println!(
        "hausdorff {} vs {} triangles {:8.2} us per call",
        merged.triangle_count(),
        small.triangle_count(),
        t / calls as f64 * 1e6
    );
}

fn cube() -> Mesh {
    let positions = (0..8)
        .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
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
}
