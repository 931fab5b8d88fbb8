use std::collections::HashMap;
use std::sync::Mutex;

use glam::{Mat4, Quat, Vec3};
use hdlod::cluster::{BuildConfig, GeometrySink, Silent, build};
use hdlod::tree::ClusterClass;
use hdlod::geometry::Mesh;
use hdlod::scene::{Keyframe, Motion, Object, Scene, ScheduleOptions, Task, TaskType, Up, Visibility};
use hdlod::time::{TimeSpan, parse_date};

struct Memory(Mutex<HashMap<String, Mesh>>);

impl GeometrySink for Memory {
    fn put(&self, mesh: &Mesh) -> hdlod::Result<String> {
        let mut h = blake3::Hasher::new();
        for p in &mesh.positions {
            h.update(&p.x.to_le_bytes());
            h.update(&p.y.to_le_bytes());
            h.update(&p.z.to_le_bytes());
        }
        for i in &mesh.indices {
            h.update(&i.to_le_bytes());
        }
        let hash = h.finalize().to_hex().to_string();
        self.0.lock().unwrap().insert(hash.clone(), mesh.clone());
        Ok(hash)
    }
}

fn cube() -> Mesh {
    let mut m = Mesh::default();
    let c = [
        Vec3::new(0., 0., 0.), Vec3::new(1., 0., 0.), Vec3::new(1., 1., 0.), Vec3::new(0., 1., 0.),
        Vec3::new(0., 0., 1.), Vec3::new(1., 0., 1.), Vec3::new(1., 1., 1.), Vec3::new(0., 1., 1.),
    ];
    let faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 4, 7, 3]];
    for f in faces {
        let n = (c[f[1]] - c[f[0]]).cross(c[f[2]] - c[f[0]]).normalize();
        let base = m.positions.len() as u32;
        for &i in &f {
            m.positions.push(c[i]);
            m.normals.push(n);
        }
        m.indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    m
}

fn scene(n: usize) -> Scene {
    let span = 100.0 * 86400.0;
    let mut objects = Vec::new();
    let mut tasks = Vec::new();
    for i in 0..n {
        let (x, y, z) = ((i % 10) as f32, (i / 100) as f32, ((i / 10) % 10) as f32);
        objects.push(Object {
            id: format!("box-{i}"),
            mesh: 0,
            transform: Mat4::from_scale_rotation_translation(Vec3::splat(0.9), Quat::IDENTITY, Vec3::new(x, y, z)),
            color: [0.5, 0.5, 0.5, 1.0],
            visibility: Visibility::always(),
            motion: None,
            properties: Default::default(),
        });
        if y > 0.0 {
            tasks.push(Task {
                id: format!("T{i}"),
                name: format!("floor {y}"),
                kind: TaskType::Construct,
                start: y as f64 * 86400.0 * 10.0,
                finish: y as f64 * 86400.0 * 10.0 + 3600.0,
                objects: vec![format!("box-{i}")],
            });
        }
    }
    for k in 0..3 {
        objects.push(Object {
            id: format!("truck-{k}"),
            mesh: 0,
            transform: Mat4::IDENTITY,
            color: [1.0, 0.8, 0.0, 1.0],
            visibility: Visibility::always(),
            motion: Some(Motion::new(vec![
                Keyframe { t: 0.0, translation: Vec3::new(-5.0, 0.0, k as f32), rotation: Quat::IDENTITY, scale: Vec3::ONE },
                Keyframe { t: span, translation: Vec3::new(15.0, 0.0, k as f32), rotation: Quat::IDENTITY, scale: Vec3::ONE },
            ]).unwrap()),
            properties: Default::default(),
        });
    }
    let mut s = Scene {
        name: "boxes".into(),
        up: Up::Y,
        time: TimeSpan { start: parse_date("2025-01-01").unwrap(), seconds: span },
        meshes: vec![cube()],
        objects,
        tasks,
        schedule_options: ScheduleOptions::default(),
    };
    s.apply_schedule();
    s
}

#[test]
fn builds_a_grid() {
    let s = scene(500);
    let sink = Memory(Mutex::new(HashMap::new()));
    let (tree, stats) = build(&s, &BuildConfig::default(), &sink, &Silent).unwrap();
    eprintln!("{:#?}", stats);
    let leaves = tree.clusters.iter().filter(|c| c.children.is_empty() && c.class != ClusterClass::Root).count();
    assert_eq!(leaves, 503);
}

#[test]
fn simplify_probe() {
    use hdlod::geometry::{merge, simplify, hausdorff, Part, SimplifyOptions, HausdorffOptions};
    let c = cube();
    let ts: Vec<Mat4> = (0..64).map(|i| Mat4::from_scale_rotation_translation(Vec3::splat(0.9), Quat::IDENTITY, Vec3::new((i % 4) as f32, (i / 16) as f32, ((i / 4) % 4) as f32))).collect();
    let parts: Vec<Part> = ts.iter().map(|t| Part { mesh: &c, transform: *t, color: [1.0; 4] }).collect();
    let u = merge(&parts, 0.0);
    for e in [0.05f32, 0.1, 0.2, 0.4, 0.8, 1.6] {
        let s = simplify(&u, &SimplifyOptions { max_error: e, target_triangles: None, prune: true });
        let h = hausdorff(&s.mesh, &u, &HausdorffOptions { tolerance: e * 0.1, seed: 0 });
        eprintln!("budget {e}: {:?} {} -> {} tris, bound {} lower {}", s.strategy, u.triangle_count(), s.triangles, h.bound, h.lower);
    }
}
