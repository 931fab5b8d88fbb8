//! A tile's content: a cluster's geometry whose elements carry their
//! properties as per-feature properties (`EXT_structural_metadata` over
//! `EXT_mesh_features`), so that a 3D Tiles client picks an element and
//! shows what it is, and a 3D Tiles style colours the site by it
//! (docs/tiles.md gives the styles).
//!
//! By default only what never changes with the date: the element's id,
//! index, name, class, storey and task. Such content has one URL whatever
//! the slice's date, so a client's cache serves it to every date. With
//! [`State`] it also holds each element's state at the slice's time (task
//! status, deviation, look), content made for that one time.
//!
//! Feature ids are renumbered for the tile: row `r` of its property table
//! is the `r`-th object of the cluster in index order, whose scene-wide
//! index (the feature id of the tree's own GLBs) is the `index` property.
//! A dynamic cluster's GLB, shared by every instance of a model, carries no
//! ids: the tree names its object, which all its vertices take.
//!
//! A skinned cluster's GLB holds its mesh in the bind pose, which 3D Tiles
//! clients would draw as it is (they do not animate content): its content
//! at a time is the mesh posed by its skeleton then ([`cluster`]), written
//! as plain glTF without the skin.

use std::path::Path;

use crate::error::Result;
use crate::geometry::Mesh;
use crate::io::glb::{
    Column, Encoding, PropertyTable, mesh_to_glb_with_table, textured_mesh_to_glb,
};
use crate::io::texture::Texture;
use crate::scene::appearance::Look;
use crate::scene::{Profile, property};
use crate::tree::{ObjectTables, Tree};

/// The class of the property table, and the id of its schema.
pub const CLASS: &str = "element";

/// The elements' state at a time `t` under an appearance profile.
#[derive(Debug, Clone, Copy)]
pub struct State<'a> {
    pub profile: &'a Profile,
    pub t: f64,
}

/// The GLB of a tile: `mesh` (the cluster's geometry) with its colour
/// texture (baked colour, as the cluster's GLB has it) and a property
/// table of its objects, and of their state when `state` is given;
/// `object` names the object of a mesh without feature ids. A mesh with
/// neither is written without the table.
pub fn content(
    mesh: &Mesh,
    texture: Option<&Texture>,
    object: Option<u32>,
    tables: &ObjectTables,
    state: Option<State>,
) -> Vec<u8> {
    let mut mesh = mesh.clone();
    let objects: Vec<u32> = if mesh.features.is_empty() {
        let Some(object) = object else {
            return textured_mesh_to_glb(&mesh, texture);
        };
        mesh.features = vec![0; mesh.positions.len()];
        vec![object]
    } else {
        let mut distinct = mesh.features.clone();
        distinct.sort_unstable();
        distinct.dedup();
        for f in &mut mesh.features {
            *f = distinct.binary_search(f).expect("each id is among them") as u32;
        }
        distinct
    };
    mesh_to_glb_with_table(
        &mesh,
        texture,
        &table(&objects, tables, state),
        Encoding::Plain,
    )
}

/// The content of cluster `id` of `tree`, read from its GLB `file`: a
/// skinned cluster posed by its skeleton at `pose` (its bind pose without
/// a time), the elements' state when `state` is given.
pub fn cluster(
    tree: &Tree,
    tables: &ObjectTables,
    id: u32,
    file: &Path,
    pose: Option<f64>,
    state: Option<State>,
) -> Result<Vec<u8>> {
    let object = tree.dynamic_object(id);
    if let (Some(skeleton), Some(t)) = (tree.skeleton_of(id), pose) {
        let (mesh, skin) = crate::io::gltf::read_skinned_mesh(file, skeleton.joints.len())?;
        let mut matrices = Vec::with_capacity(skeleton.joints.len());
        skeleton.matrices_into(t, &mut matrices);
        // Skinned GLBs carry no baked colour: no texture to keep.
        return Ok(content(
            &skin.pose(&mesh, &matrices),
            None,
            object,
            tables,
            state,
        ));
    }
    let (mesh, texture) = crate::io::read_textured_mesh(file)?;
    Ok(content(&mesh, texture.as_ref(), object, tables, state))
}

fn table(objects: &[u32], tables: &ObjectTables, state: Option<State>) -> PropertyTable {
    let n = objects.len();
    let text = |f: &dyn Fn(u32) -> String| objects.iter().map(|&i| f(i)).collect::<Vec<_>>();
    let rows = tables.rows();
    // The task shown: the one governing at the slice's time, else the
    // element's first (in most schedules the one that builds it).
    let task = move |i: u32| match state {
        Some(s) => tables.governing_task(i, s.t),
        None => rows.tasks(i).first().copied(),
    };
    let task_entry = move |i: u32| task(i).map(|k| &tables.tasks()[k as usize]);
    let mut columns = vec![
        (
            "id".into(),
            Column::Strings(text(&|i| rows.id(i).to_owned())),
        ),
        ("index".into(), Column::U32(objects.to_vec())),
        (
            "name".into(),
            Column::Strings(text(&|i| rows.name(i).unwrap_or_default().to_owned())),
        ),
        (
            "class".into(),
            Column::Strings(text(&|i| rows.class(i).unwrap_or_default().to_owned())),
        ),
        (
            "storey".into(),
            Column::Strings(text(&|i| {
                rows.property(i, property::STOREY)
                    .unwrap_or_default()
                    .to_owned()
            })),
        ),
        (
            "task".into(),
            Column::Strings(text(&|i| {
                task_entry(i).map_or_else(String::new, |k| k.id.clone())
            })),
        ),
        (
            "task_name".into(),
            Column::Strings(text(&|i| {
                task_entry(i)
                    .and_then(|k| k.name.clone())
                    .unwrap_or_default()
            })),
        ),
    ];
    if let Some(State { profile, t }) = state {
        columns.extend(state_columns(objects, tables, profile, t));
    }
    PropertyTable {
        class: CLASS.into(),
        count: n,
        columns,
    }
}

/// Each element's state at `t`: its task's status and deviation and its
/// look under `profile`.
fn state_columns(
    objects: &[u32],
    tables: &ObjectTables,
    profile: &Profile,
    t: f64,
) -> Vec<(String, Column)> {
    let n = objects.len();
    let mut status = Vec::with_capacity(n);
    let mut deviation = Vec::with_capacity(n);
    let mut color = Vec::with_capacity(n);
    let mut transparency = Vec::with_capacity(n);
    let mut show = Vec::with_capacity(n);
    for &i in objects {
        let state = tables.state_at(i, t, profile);
        status.push(state.progress.map_or("", |p| p.name()).to_owned());
        deviation.push(state.deviation.map_or("", |d| d.name()).to_owned());
        let (hex, alpha, shown) = match state.look {
            Look::Model => ("#ffffff".to_owned(), 0.0, true),
            Look::Hidden => ("#ffffff".to_owned(), 0.0, false),
            Look::Colour { rgb, transparency } => (
                format!("#{:02x}{:02x}{:02x}", rgb[0], rgb[1], rgb[2]),
                transparency,
                true,
            ),
        };
        color.push(hex);
        transparency.push(alpha);
        show.push(shown);
    }
    vec![
        ("status".into(), Column::Strings(status)),
        ("deviation".into(), Column::Strings(deviation)),
        ("color".into(), Column::Strings(color)),
        ("transparency".into(), Column::F32(transparency)),
        ("show".into(), Column::Bool(show)),
    ]
}
