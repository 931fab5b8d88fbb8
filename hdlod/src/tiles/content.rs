//! A time slice's tile content with the 4D review in it: a cluster's
//! geometry whose elements carry their state at the slice's time as
//! per-feature properties (`EXT_structural_metadata` over
//! `EXT_mesh_features`), so that a 3D Tiles style colours the site by task
//! status, deviation or appearance look (docs/tiles.md gives the styles).
//!
//! Feature ids are renumbered for the tile: row `r` of its property table
//! is the `r`-th object of the cluster in index order, whose scene-wide
//! index (the feature id of the tree's own GLBs) is the `index` property.
//! A dynamic cluster's GLB, shared by every instance of a model, carries no
//! ids: the tree names its object, which all its vertices take.

use crate::geometry::Mesh;
use crate::io::glb::{Column, PropertyTable, mesh_to_glb, mesh_to_glb_with_table};
use crate::scene::Profile;
use crate::scene::appearance::Look;
use crate::tree::ObjectTables;

/// The class of the property table, and the id of its schema.
pub const CLASS: &str = "element";

/// The GLB of a tile at `t`: `mesh` (the cluster's geometry) with a
/// property table of its objects' states under `profile`; `object` names
/// the object of a mesh without feature ids. A mesh with neither is
/// written plain.
pub fn content(
    mesh: &Mesh,
    object: Option<u32>,
    tables: &ObjectTables,
    profile: &Profile,
    t: f64,
) -> Vec<u8> {
    let mut mesh = mesh.clone();
    let objects: Vec<u32> = if mesh.features.is_empty() {
        let Some(object) = object else {
            return mesh_to_glb(&mesh);
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
    mesh_to_glb_with_table(&mesh, &table(&objects, tables, profile, t))
}

fn table(objects: &[u32], tables: &ObjectTables, profile: &Profile, t: f64) -> PropertyTable {
    let n = objects.len();
    let mut ids = Vec::with_capacity(n);
    let mut task = Vec::with_capacity(n);
    let mut status = Vec::with_capacity(n);
    let mut deviation = Vec::with_capacity(n);
    let mut color = Vec::with_capacity(n);
    let mut transparency = Vec::with_capacity(n);
    let mut show = Vec::with_capacity(n);
    for &i in objects {
        let state = tables.state_at(i, t, profile);
        ids.push(tables.objects()[i as usize].id.clone());
        task.push(
            state
                .task
                .map_or_else(String::new, |k| tables.tasks()[k as usize].id.clone()),
        );
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
    PropertyTable {
        class: CLASS.into(),
        count: n,
        columns: vec![
            ("id".into(), Column::Strings(ids)),
            ("index".into(), Column::U32(objects.to_vec())),
            ("task".into(), Column::Strings(task)),
            ("status".into(), Column::Strings(status)),
            ("deviation".into(), Column::Strings(deviation)),
            ("color".into(), Column::Strings(color)),
            ("transparency".into(), Column::F32(transparency)),
            ("show".into(), Column::Bool(show)),
        ],
    }
}
