//! The generated skyscraper site: counts of the paper's table 1, determinism,
//! valid geometry, the schedule and the motions.

use std::collections::HashSet;

use chrono::{Datelike, Timelike, Weekday};
use hdlod::fixture::{Scale, TABLE_1, check_table_1, skyscraper};
use hdlod::scene::{Class, Scene, Summary, VisibilityType};

#[test]
fn paper_scale_matches_table_1_within_3_percent() {
    let scene = skyscraper(Scale::Paper, 1);
    let census = Summary::of(&scene);
    for (class, objects, triangles) in TABLE_1 {
        for (what, got, want) in [
            ("objects", census.classes[&class].objects, objects),
            ("triangles", census.classes[&class].triangles, triangles),
        ] {
            let off = (got as f64 - want as f64).abs() / want as f64;
            assert!(
                off <= 0.03,
                "{} {what}: {got} vs {want} ({:.1}%)",
                class.name(),
                off * 100.0
            );
        }
    }
    assert!(check_table_1(&census).is_ok());
    // A handful of absent objects at most.
    assert!(census.classes[&Class::Absent].objects <= 10);
    let years = scene.time.seconds / (365.0 * 86_400.0);
    assert!((1.0..=2.0).contains(&years), "{years} years");
}

#[test]
fn same_seed_same_scene_other_seed_other_scene() {
    let a = skyscraper(Scale::Tiny, 7);
    assert!(a == skyscraper(Scale::Tiny, 7));
    let b = skyscraper(Scale::Tiny, 8);
    assert!(a != b);
    // The seed moves things, not the counts.
    assert_eq!(Summary::of(&a).classes, Summary::of(&b).classes);
}

fn check_consistent(scene: &Scene) {
    let mut ids = HashSet::new();
    for o in &scene.objects {
        assert!(ids.insert(o.id.as_str()), "duplicate id {}", o.id);
        let mesh = &scene.meshes[o.mesh];
        assert!(!mesh.is_empty(), "{}: empty mesh", o.id);
        assert!(o.transform.is_finite(), "{}", o.id);
        assert!(o.color.iter().all(|c| (0.0..=1.0).contains(c)), "{}", o.id);
    }
    for (i, m) in scene.meshes.iter().enumerate() {
        m.validate().unwrap_or_else(|e| panic!("mesh {i}: {e}"));
        assert_eq!(m.normals.len(), m.positions.len(), "mesh {i}");
        assert!(
            m.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-3),
            "mesh {i}"
        );
        assert!(scene.objects.iter().any(|o| o.mesh == i), "mesh {i} unused");
    }
    for t in &scene.tasks {
        assert!(t.start < t.finish, "task {} {}", t.id, t.name);
        assert!(!t.objects.is_empty(), "task {} {}", t.id, t.name);
        for id in &t.objects {
            assert!(
                ids.contains(id.as_str()),
                "task {} names unknown {id}",
                t.id
            );
        }
        // Dated on working days, within the working day or just before.
        let start = scene.time.date_at(t.start);
        assert!(
            !matches!(start.weekday(), Weekday::Sat | Weekday::Sun),
            "task {} {} starts on a {}",
            t.id,
            t.name,
            start.weekday()
        );
        assert!((6..17).contains(&start.hour()), "task {} at {start}", t.id);
    }
}

#[test]
fn every_object_has_valid_geometry_and_the_schedule_is_consistent() {
    for scale in [Scale::Tiny, Scale::Small] {
        check_consistent(&skyscraper(scale, 1));
    }
}

#[test]
fn the_small_scale_is_the_demo_size_and_tiny_is_small() {
    let small = skyscraper(Scale::Small, 1);
    assert!(
        (4_000..6_000).contains(&small.objects.len()),
        "{}",
        small.objects.len()
    );
    let tiny = skyscraper(Scale::Tiny, 1);
    assert!(
        (200..800).contains(&tiny.objects.len()),
        "{}",
        tiny.objects.len()
    );
}

#[test]
fn every_visibility_type_and_class_occurs() {
    let scene = skyscraper(Scale::Tiny, 1);
    let census = Summary::of(&scene);
    for kind in VisibilityType::ALL {
        assert!(
            census.visibility_types.get(&kind).copied().unwrap_or(0) > 0,
            "no {kind:?}"
        );
    }
    for class in Class::ALL {
        assert!(census.classes[&class].objects > 0, "no {}", class.name());
    }
}

#[test]
fn equipment_moves_and_hoisted_beams_end_in_place() {
    let scene = skyscraper(Scale::Tiny, 1);
    let span = scene.time.seconds;
    let mut beams = 0;
    for o in &scene.objects {
        let Some(motion) = &o.motion else { continue };
        let keys = motion.keyframes();
        let (first, last) = (keys[0].t, keys[keys.len() - 1].t);
        if scene.class_of(o) == Class::Dynamic {
            let poses: Vec<_> = (0..=20)
                .map(|k| o.pose(first + (last - first) * k as f64 / 20.0))
                .collect();
            assert!(
                poses.windows(2).any(|w| !w[0].abs_diff_eq(w[1], 1e-3)),
                "{} does not move",
                o.id
            );
        }
        if o.properties.get("type").map(String::as_str) == Some("IfcBeam") {
            beams += 1;
            assert!(o.pose(span).abs_diff_eq(o.transform, 1e-4), "{}", o.id);
            assert!(
                o.pose(first).w_axis.y < 1.0,
                "{} starts off the ground",
                o.id
            );
        }
    }
    assert!(beams > 0);
    // The crane's jib slews: its rotation takes several values.
    let top = scene
        .objects
        .iter()
        .find(|o| o.id == "TC1-TOP")
        .expect("a crane");
    let keys = top.motion.as_ref().expect("a slewing crane").keyframes();
    let distinct = keys
        .windows(2)
        .filter(|w| w[0].rotation.angle_between(w[1].rotation) > 0.05)
        .count();
    assert!(distinct > 5, "{distinct}");
}

#[test]
fn scale_names_parse_and_bad_ones_are_reported() {
    assert_eq!(Scale::parse("paper").unwrap(), Scale::Paper);
    let err = Scale::parse("huge").unwrap_err().to_string();
    assert!(err.contains("--scale") && err.contains("huge"), "{err}");
}

/// The committed tiny fixture is what the generator makes for seed 1: if the
/// generator changes, regenerate it (fixtures/README.md says how).
#[test]
fn committed_tiny_fixture_is_the_generators_output() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/skyscraper-tiny");
    let committed = hdlod::scene::format::load(&dir).expect("the committed fixture loads");
    let generated = skyscraper(Scale::Tiny, 1);
    let ids = |s: &Scene| s.objects.iter().map(|o| o.id.clone()).collect::<Vec<_>>();
    assert_eq!(ids(&committed), ids(&generated));
    assert_eq!(Summary::of(&committed), Summary::of(&generated));
    assert_eq!(committed.tasks, generated.tasks);
}
