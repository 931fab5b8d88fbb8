//! A scene in numbers, as `hdlod inspect` prints it and the server reports
//! it: objects and triangles per class, the time span, the bounds, and how
//! many objects have each of the paper's visibility types.

use std::collections::BTreeMap;

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

use super::{Class, Object, Scene, VisibilityType};
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
