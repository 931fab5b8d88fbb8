//! A new version of a scene put in the order of an old tree's objects, so
//! that an update can keep the old tree's feature ids (docs/method.md
//! section 3, "Geometry updates").
//!
//! A feature id is an object's index in the scene the tree was built from,
//! and every geometry file of the tree carries it in its vertices. When a
//! model is revised, objects go, come and move about in the file; matched
//! by id, each object of the new scene takes its old index, the new ones
//! come after the old ones in their own order, and an object that was
//! removed keeps its index as a *tombstone*: an object that is never
//! present, has no task and no geometry of its own, so that no other
//! object's index moves. A full build drops the tombstones.

use std::borrow::Cow;

use rustc_hash::FxHashMap;

use crate::scene::{Object, Scene, Visibility};
use crate::tree::sources::Digest;

/// The digest `sources.bin` keeps for a tombstone: no object's digest is
/// all zeros but by a 2^-128 chance.
pub const TOMBSTONE: Digest = [0; 16];

/// `scene` in the order of a tree's objects.
pub struct Aligned<'a> {
    pub scene: Cow<'a, Scene>,
    /// The indices of the tombstones, increasing.
    pub tombstones: Vec<usize>,
}

/// `scene` with its objects in the order of `old_ids` (the tree's objects,
/// by feature id), tombstones where `old_sources` (their digests) says an
/// object was already removed or `scene` no longer has it; or why it
/// cannot be so put.
pub fn align<'a>(
    scene: &'a Scene,
    old_ids: &[String],
    old_sources: &[Digest],
) -> Result<Aligned<'a>, String> {
    let was_tombstone = |k: usize| old_sources.get(k) == Some(&TOMBSTONE);
    let same_order = scene.objects.len() >= old_ids.len()
        && old_ids
            .iter()
            .zip(&scene.objects)
            .enumerate()
            .all(|(k, (id, o))| *id == o.id && !was_tombstone(k));
    if same_order {
        return Ok(Aligned {
            scene: Cow::Borrowed(scene),
            tombstones: Vec::new(),
        });
    }
    if scene.meshes.is_empty() {
        return Err("the scene has no meshes".into());
    }
    let index: FxHashMap<&str, usize> = scene
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| (o.id.as_str(), i))
        .collect();
    let mut taken = vec![false; scene.objects.len()];
    // Per old index, the scene's object now there, none for a tombstone.
    let mut order: Vec<Option<usize>> = Vec::with_capacity(old_ids.len());
    let mut tombstones = Vec::new();
    for (k, id) in old_ids.iter().enumerate() {
        match index.get(id.as_str()) {
            Some(&i) if was_tombstone(k) => {
                return Err(format!(
                    "object {id:?} (objects[{i}]) was removed and is back: its old index is \
                     a tombstone until the next full build"
                ));
            }
            Some(&i) => {
                taken[i] = true;
                order.push(Some(i));
            }
            None => {
                tombstones.push(k);
                order.push(None);
            }
        }
    }
    order.extend((0..scene.objects.len()).filter(|&i| !taken[i]).map(Some));
    // Copied on every core: a storey's update copies 55,000 objects with
    // their properties.
    use rayon::prelude::*;
    let objects: Vec<Object> = (order.par_iter().enumerate())
        .map(|(k, i)| match i {
            Some(i) => scene.objects[*i].clone(),
            None => tombstone(&old_ids[k]),
        })
        .collect();
    let mut aligned = Scene {
        name: scene.name.clone(),
        up: scene.up,
        time: scene.time,
        meshes: scene.meshes.clone(),
        objects,
        tasks: scene.tasks.clone(),
        schedule_options: scene.schedule_options,
        appearance: scene.appearance.clone(),
        georeference: scene.georeference,
    };
    // A schedule may still name what the model no longer has.
    let gone: rustc_hash::FxHashSet<&str> =
        tombstones.iter().map(|&k| old_ids[k].as_str()).collect();
    (aligned.tasks.par_iter_mut()).for_each(|task| {
        task.objects.retain(|o| !gone.contains(o.as_str()));
    });
    Ok(Aligned {
        scene: Cow::Owned(aligned),
        tombstones,
    })
}

/// The stand-in of a removed object: never present, no geometry drawn.
fn tombstone(id: &str) -> Object {
    Object {
        id: id.to_string(),
        mesh: 0,
        transform: glam::Mat4::IDENTITY,
        color: [0.0; 4],
        visibility: Visibility::never(),
        motion: None,
        skin: None,
        properties: Default::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(ids: &[&str]) -> Scene {
        let mut s = Scene {
            name: "s".into(),
            up: Default::default(),
            time: crate::time::TimeSpan {
                start: chrono::DateTime::UNIX_EPOCH,
                seconds: 10.0,
            },
            meshes: vec![crate::geometry::Mesh::cuboid(
                glam::Vec3::ZERO,
                glam::Vec3::ONE,
                1,
            )],
            objects: Vec::new(),
            tasks: Vec::new(),
            schedule_options: Default::default(),
            appearance: None,
            georeference: None,
        };
        s.objects = ids
            .iter()
            .map(|id| Object {
                visibility: Visibility::always(),
                ..tombstone(id)
            })
            .collect();
        s
    }

    fn ids(s: &Scene) -> Vec<&str> {
        s.objects.iter().map(|o| o.id.as_str()).collect()
    }

    #[test]
    fn objects_keep_their_index_and_removed_ones_leave_a_tombstone() {
        let old: Vec<String> = ["a", "b", "c", "d"].map(String::from).to_vec();
        let sources = vec![[1; 16]; 4];
        let same = scene(&["a", "b", "c", "d", "e"]);
        let aligned = align(&same, &old, &sources).unwrap();
        assert!(matches!(aligned.scene, Cow::Borrowed(_)));

        let moved = scene(&["e", "d", "a", "c"]);
        let aligned = align(&moved, &old, &sources).unwrap();
        assert_eq!(ids(&aligned.scene), ["a", "b", "c", "d", "e"]);
        assert_eq!(aligned.tombstones, [1]);
        let b = &aligned.scene.objects[1];
        assert_eq!(b.visibility, Visibility::never());

        // Once a tombstone, always one until a full build; back is an error.
        let mut sources = sources;
        sources[1] = TOMBSTONE;
        let again = scene(&["a", "c", "d"]);
        assert_eq!(align(&again, &old, &sources).unwrap().tombstones, [1]);
        let back = scene(&["a", "b", "c", "d"]);
        let why = align(&back, &old, &sources).err().unwrap();
        assert!(why.contains("\"b\""), "{why}");
    }
}
