//! A scene in numbers, as `hdlod inspect` prints it and the server reports
//! it: objects and triangles per class, the time span, the bounds, how
//! many objects have each of the paper's visibility types, and the
//! schedule's work breakdown and links.

use std::collections::{BTreeMap, HashMap};

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

use super::{Class, Object, Scene, Task, VisibilityType};
use crate::time::format_date;

/// Objects and triangles (instances counted each time) of one class.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counts {
    pub objects: usize,
    pub triangles: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TimeSummary {
    /// ISO 8601.
    pub start: String,
    pub end: String,
    pub seconds: f64,
}

/// An axis-aligned box in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneSummary {
    /// Always `"scene"` (a tree summary will say `"tree"`).
    pub kind: String,
    pub name: String,
    /// Distinct meshes (instancing shares them).
    pub meshes: usize,
    pub objects: usize,
    pub triangles: usize,
    /// Every class, also those without objects.
    pub classes: BTreeMap<Class, Counts>,
    pub time: TimeSummary,
    /// Of every object at every pose it takes (for a moving object, the
    /// union over its keyframes); `None` for a scene without geometry.
    pub bounds: Option<Bounds>,
    /// Every visibility type, also those without objects.
    pub visibility_types: BTreeMap<VisibilityType, usize>,
    /// The schedule's work breakdown and logic.
    #[serde(default)]
    pub schedule: ScheduleSummary,
}

/// A schedule's shape: its tasks, their work breakdown (summary tasks and
/// depth) and their logic links.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ScheduleSummary {
    pub tasks: usize,
    /// Tasks that are some task's parent.
    pub summary_tasks: usize,
    /// Levels of the work breakdown: 0 without tasks, 1 when no task has
    /// a parent.
    pub depth: usize,
    /// Tasks with a predecessor or a successor, and the links.
    pub linked_tasks: usize,
    pub links: usize,
}

impl ScheduleSummary {
    pub fn of(tasks: &[Task]) -> ScheduleSummary {
        let index: HashMap<&str, usize> = tasks
            .iter()
            .enumerate()
            .map(|(k, t)| (t.id.as_str(), k))
            .collect();
        let parent = |k: usize| {
            tasks[k]
                .parent
                .as_deref()
                .and_then(|p| index.get(p).copied())
        };
        let mut summary = vec![false; tasks.len()];
        let mut linked = vec![false; tasks.len()];
        let mut links = 0;
        for (k, t) in tasks.iter().enumerate() {
            if let Some(p) = parent(k) {
                summary[p] = true;
            }
            for p in &t.predecessors {
                if let Some(&j) = index.get(p.task.as_str()) {
                    linked[j] = true;
                    linked[k] = true;
                    links += 1;
                }
            }
        }
        // Levels by memo: a task's is its parent's plus one (parents form
        // a tree; a stray cycle is cut after as many steps as tasks).
        let mut level = vec![0usize; tasks.len()];
        for k in 0..tasks.len() {
            let mut chain = vec![k];
            while let Some(p) = parent(*chain.last().expect("not empty")) {
                if level[p] > 0 || chain.len() > tasks.len() {
                    break;
                }
                chain.push(p);
            }
            let top = *chain.last().expect("not empty");
            let mut at = match parent(top) {
                Some(p) if level[p] > 0 => level[p],
                _ => 0,
            };
            for &c in chain.iter().rev() {
                at += 1;
                level[c] = at;
            }
        }
        ScheduleSummary {
            tasks: tasks.len(),
            summary_tasks: summary.iter().filter(|&&s| s).count(),
            depth: level.into_iter().max().unwrap_or(0),
            linked_tasks: linked.iter().filter(|&&l| l).count(),
            links,
        }
    }
}

impl SceneSummary {
    pub fn of(scene: &Scene) -> SceneSummary {
        let span = scene.time.seconds;
        let mut classes: BTreeMap<Class, Counts> =
            Class::ALL.iter().map(|&c| (c, Counts::default())).collect();
        let mut visibility_types: BTreeMap<VisibilityType, usize> =
            VisibilityType::ALL.iter().map(|&v| (v, 0)).collect();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for object in &scene.objects {
            let mesh = &scene.meshes[object.mesh];
            let counts = classes.entry(object.class(span)).or_default();
            counts.objects += 1;
            counts.triangles += mesh.triangle_count();
            *visibility_types
                .entry(object.visibility.kind(span))
                .or_default() += 1;
            for pose in poses(object) {
                for p in &mesh.positions {
                    let w = pose.transform_point3(*p);
                    lo = lo.min(w);
                    hi = hi.max(w);
                }
            }
        }
        SceneSummary {
            kind: "scene".into(),
            name: scene.name.clone(),
            meshes: scene.meshes.len(),
            objects: scene.objects.len(),
            triangles: classes.values().map(|c| c.triangles).sum(),
            classes,
            time: TimeSummary {
                start: format_date(scene.time.start),
                end: format_date(scene.time.end()),
                seconds: span,
            },
            bounds: (lo.x <= hi.x).then(|| Bounds {
                min: lo.to_array(),
                max: hi.to_array(),
            }),
            visibility_types,
            schedule: ScheduleSummary::of(&scene.tasks),
        }
    }
}

/// The poses whose union bounds an object: its keyframes, or its transform.
fn poses(object: &Object) -> Vec<Mat4> {
    match &object.motion {
        Some(m) => m.keyframes().iter().map(|k| k.matrix()).collect(),
        None => vec![object.transform],
    }
}
