//! Times `scene::format::save` and `load` on a synthetic scene of the
//! paper's size (56,157 objects, about 4.26 M triangles; docs/method.md
//! section 5). Run with `cargo run --release --example scene_io_bench [DIR]`
//! (a DIR given is kept).

use std::collections::BTreeMap;
use std::time::Instant;

use glam::{Mat4, Quat, Vec3};
use hdlod::geometry::Mesh;
use hdlod::scene::{
    Keyframe, Motion, Object, Scene, SceneSummary, ScheduleOptions, Task, TaskType, Up, Visibility,
};
use hdlod::time::{TimeSpan, parse_date};

/// A wavy `n` x `n` grid of `2 n^2` triangles with normals.
fn grid(n: u32, seed: f32) -> Mesh {
    let mut mesh = Mesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            mesh.positions
                .push(Vec3::new(x, 0.1 * (seed + 7.0 * x).sin() * z, z));
            mesh.normals.push(Vec3::Y);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let b = a + n + 1;
            mesh.indices.extend([a, b, a + 1, a + 1, b, b + 1]);
        }
    }
    mesh
}

fn object(id: String, mesh: usize, at: Vec3) -> Object {
    Object {
        id,
        mesh,
        transform: Mat4::from_translation(at),
        color: [0.7, 0.7, 0.7, 1.0],
        visibility: Visibility::always(),
        motion: None,
        skin: None,
        properties: BTreeMap::new(),
    }
}

fn paper_sized() -> Scene {
    let year = 365.0 * 86400.0;
    let mut meshes = Vec::new();
    let mut objects = Vec::new();
    let mut tasks = Vec::new();
    // Pseudo-dynamic: 40,010 elements of 72 triangles, each its own mesh,
    // built in tasks of 100.
    for i in 0..40_010 {
        meshes.push(grid(6, i as f32));
        let at = Vec3::new(
            (i % 100) as f32,
            (i / 1000) as f32 * 3.5,
            ((i / 100) % 10) as f32,
        );
        objects.push(object(format!("E-{i}"), meshes.len() - 1, at));
        if i % 100 == 0 {
            tasks.push(Task::planned(
                format!("T{}", i / 100),
                "",
                TaskType::Construct,
                (i / 100) as f64 * year / 401.0,
                (i / 100 + 1) as f64 * year / 401.0,
                Vec::new(),
            ));
        }
        tasks.last_mut().unwrap().objects.push(format!("E-{i}"));
    }
    // Static: 498 objects of 134 triangles (an odd grid trimmed).
    for i in 0..498 {
        let mut m = grid(9, -(i as f32));
        m.indices.truncate(134 * 3);
        meshes.push(m);
        objects.push(object(
            format!("S-{i}"),
            meshes.len() - 1,
            Vec3::new(-10.0 - i as f32, 0.0, 0.0),
        ));
    }
    // Dynamic: 15,649 instances of 30 models of 84 triangles, 10 keyframes.
    let first_model = meshes.len();
    for k in 0..30 {
        let mut m = grid(7, k as f32);
        m.indices.truncate(84 * 3);
        meshes.push(m);
    }
    for i in 0..15_649 {
        let mut o = object(format!("D-{i}"), first_model + i % 30, Vec3::ZERO);
        let keys = (0..10)
            .map(|k| Keyframe {
                t: k as f64 * year / 9.0,
                translation: Vec3::new(i as f32 * 0.01, 0.0, k as f32),
                rotation: Quat::from_rotation_y(k as f32 * 0.3),
                scale: Vec3::ONE,
            })
            .collect();
        o.motion = Some(Motion::new(keys).unwrap());
        objects.push(o);
    }
    let mut scene = Scene {
        name: "paper-sized".into(),
        up: Up::Y,
        time: TimeSpan {
            start: parse_date("2025-03-01").unwrap(),
            seconds: year,
        },
        meshes,
        objects,
        tasks,
        schedule_options: ScheduleOptions::default(),
        appearance: None,
        georeference: None,
    };
    scene.apply_schedule();
    scene
}

fn main() {
    // A directory given on the command line is kept for inspection.
    let given = std::env::args().nth(1).map(std::path::PathBuf::from);
    let dir = given
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join("hdlod-scene-io-bench"));
    let scene = paper_sized();
    let t = Instant::now();
    hdlod::scene::format::save(&scene, &dir).unwrap();
    let save_s = t.elapsed().as_secs_f64();
    let glb = std::fs::metadata(dir.join("paper-sized.glb"))
        .unwrap()
        .len();
    let t = Instant::now();
    let back = hdlod::scene::format::load(&dir).unwrap();
    let load_s = t.elapsed().as_secs_f64();
    assert_eq!(back.objects.len(), scene.objects.len());
    assert_eq!(back.meshes.len(), scene.meshes.len());
    let summary = SceneSummary::of(&back);
    println!(
        "{} objects, {} triangles, {} meshes: save {save_s:.2} s, load {load_s:.2} s, GLB {:.0} MB",
        summary.objects,
        summary.triangles,
        summary.meshes,
        glb as f64 / 1e6
    );
    if given.is_none() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
