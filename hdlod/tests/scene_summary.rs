//! `SceneSummary::of`: counts per class and visibility type, bounds over poses.

mod common;

use common::sample_scene;
use hdlod::scene::{Class, SceneSummary, VisibilityType};

#[test]
fn counts_classes_and_visibility_types() {
    let s = SceneSummary::of(&sample_scene());
    assert_eq!((s.objects, s.meshes, s.triangles), (4, 2, 3 * 12 + 4));
    let c = |class| s.classes[&class];
    assert_eq!(
        (c(Class::Static).objects, c(Class::Static).triangles),
        (0, 0)
    );
    assert_eq!(
        (
            c(Class::PseudoDynamic).objects,
            c(Class::PseudoDynamic).triangles
        ),
        (3, 36)
    );
    assert_eq!(
        (c(Class::Dynamic).objects, c(Class::Dynamic).triangles),
        (1, 4)
    );
    assert_eq!(c(Class::Absent).objects, 0);
    let v = |t| s.visibility_types[&t];
    assert_eq!(v(VisibilityType::Appearing), 2);
    assert_eq!(v(VisibilityType::Temporary), 1);
    assert_eq!(v(VisibilityType::Static), 1, "the truck is always present");
    assert_eq!(s.visibility_types.len(), 8, "every type is listed");
    assert_eq!(s.time.start, "2025-03-01T00:00:00Z");
    assert_eq!(s.time.end, "2025-03-11T00:00:00Z");
}

#[test]
fn bounds_cover_every_keyframe_of_moving_objects() {
    let b = SceneSummary::of(&sample_scene()).bounds.unwrap();
    // The truck's tetrahedron, turned half round at (10, 0, -3), gives max x
    // and min z; the scaffold box at (-5, 1, 2) min x and max z; the beam
    // (0.3 high at y = 3) max y.
    let close = |a: [f32; 3], e: [f32; 3]| a.iter().zip(e).all(|(a, e)| (a - e).abs() < 1e-5);
    assert!(close(b.min, [-5.5, 0.0, -4.0]), "{b:?}");
    assert!(close(b.max, [10.0, 3.15, 2.5]), "{b:?}");
}

#[test]
fn serialises_with_the_documented_keys() {
    let json = serde_json::to_value(SceneSummary::of(&sample_scene())).unwrap();
    for class in ["static", "pseudo_dynamic", "dynamic", "absent"] {
        assert!(json["classes"][class]["objects"].is_u64(), "{json}");
    }
    assert!(
        json["visibility_types"]["re_disappearing"].is_u64(),
        "{json}"
    );
    assert_eq!(json["kind"], "scene");
}
