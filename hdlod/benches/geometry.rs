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

/// Nanoseconds this thread has spent on a CPU (Linux's schedstat), `None`
/// elsewhere. On a shared machine wall time also counts the waits for a
/// core; this is the time the work itself took.
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Median wall and on-CPU seconds of `runs` runs of `f`.
fn median_seconds(runs: usize, mut f: impl FnMut()) -> (f64, Option<f64>) {
    let mut wall = Vec::with_capacity(runs);
    let mut cpu = Vec::with_capacity(runs);
    for _ in 0..runs {
        let (start, cpu_start) = (Instant::now(), thread_cpu_ns());
        f();
        wall.push(start.elapsed().as_secs_f64());
        if let (Some(a), Some(b)) = (cpu_start, thread_cpu_ns()) {
            cpu.push(b.saturating_sub(a) as f64 * 1e-9);
        }
    }
    wall.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    (wall[runs / 2], (cpu.len() == runs).then(|| cpu[runs / 2]))
}

/// "wall W ms (cpu C ms)", and the rate in millions of `items` per second
/// of CPU time (of wall time where CPU time is not available).
fn timing(t: (f64, Option<f64>), items: usize) -> String {
    let (wall, cpu) = t;
    let rate = items as f64 / cpu.unwrap_or(wall) / 1e6;
    let cpu = cpu.map_or(String::new(), |c| format!(" (cpu {:8.2} ms)", c * 1e3));
    format!("wall {:8.2} ms{cpu}  {rate:7.2} M/s", wall * 1e3)
}

fn per_call(t: (f64, Option<f64>), calls: usize) -> String {
    let us = |s: f64| s / calls as f64 * 1e6;
    let cpu =
        t.1.map_or(String::new(), |c| format!(" (cpu {:8.2} us)", us(c)));
    format!("wall {:8.2} us{cpu} per call", us(t.0))
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
        "qem to 10%            {}  ({} out)",
        timing(t, n),
        qem.triangle_count()
    );
    // The same without the normals as attributes: what the attribute-aware
    // quadrics cost.
    let bare = Mesh {
        normals: Vec::new(),
        ..mesh.clone()
    };
    let t = median_seconds(9, || {
        edge_collapse(&bare, &ten);
    });
    println!("qem to 10%, no normals {}", timing(t, n));
    let mut clustered = Mesh::default();
    let t = median_seconds(9, || clustered = clustering(&mesh, &ten));
    println!(
        "clustering to 10%     {}  ({} out)",
        timing(t, n),
        clustered.triangle_count()
    );
    let t = median_seconds(9, || {
        simplify(&mesh, &ten);
    });
    println!("simplify to 10%       {}", timing(t, n));

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
            "hausdorff horse/{name:<10} {}  bound {:.5} lower {:.5} (tolerance 0.1% of the diagonal {:.3})",
            timing(t, n),
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
    println!("merge 12 boxes        {}", per_call(t, calls));
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
        "hausdorff {} vs {} triangles {}",
        merged.triangle_count(),
        small.triangle_count(),
        per_call(t, calls)
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
