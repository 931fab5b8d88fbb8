//! IFC geometry: each building element of an IFC 2x3, IFC4 or IFC4X3 file
//! becomes one object, meshed in-process by the `ifc-lite-geometry` crate
//! (<https://github.com/LTplus-AG/ifc-lite>, extrusions, breps, mapped items,
//! booleans, openings subtracted from their hosts) over the STEP decoder of
//! `ifc-lite-core`. This file adds what a 4D scene needs around the meshes:
//! GlobalIds, storeys (`ifc_spatial.rs`), colours (`ifc_styles.rs`), the
//! property-set values the linking rules name (`psets.rs`), the count of
//! what was left out and why, and a warning for each element whose
//! geometry failed (`ifc_checks.rs` finds what the mesher passes over).
//!
//! References: ISO 10303-21 (STEP physical files), IFC 2x3 TC1, IFC 4.0
//! ADD2 TC1 and IFC 4.3 ADD2 (buildingSMART).

use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::Read;
use std::path::Path;

use glam::{DVec3, Vec3};
use ifc_lite_core::{EntityDecoder, EntityScanner, IfcType};
use ifc_lite_geometry::SubMeshCollection;

use super::ScheduleTask;
use super::ifc_checks::Checks;
use super::ifc_spatial::storeys;
use super::ifc_styles::Styles;
pub use super::ifc_styles::{MIN_ALPHA, default_color};
use crate::error::{Error, Result};
use crate::geometry::Mesh;
use crate::scene::Georeference;

/// One building element of an IFC file, meshed.
#[derive(Debug, Clone)]
pub struct Element {
    /// The IFC GlobalId.
    pub id: String,
    /// The entity's class as the schema spells it, e.g. `IfcWallStandardCase`.
    pub class: String,
    pub name: String,
    /// Name of the `IfcBuildingStorey` holding the element (or its whole).
    pub storey: Option<String>,
    /// The property-set values asked for (`Pset.Property` -> value).
    pub properties: BTreeMap<String, String>,
    /// The mesh in metres, relative to `origin`; vertex colours carry the
    /// styles of its parts when they differ.
    pub mesh: Mesh,
    /// World position (metres, z up) of the mesh's own origin.
    pub origin: DVec3,
    /// The element's colour (linear RGBA); white when the mesh has vertex
    /// colours.
    pub color: [f32; 4],
    /// Whether the file styles it (an item, its material or its type's),
    /// rather than the class's default colour.
    pub styled: bool,
}

/// What one IFC file gave.
#[derive(Debug, Clone, Default)]
pub struct Model {
    /// `FILE_SCHEMA` of the header, e.g. `IFC2X3`.
    pub schema: String,
    pub elements: Vec<Element>,
    /// Entities left out: IFC class -> reason -> count.
    pub skipped: BTreeMap<String, BTreeMap<String, usize>>,
    /// Elements with a body that gave no mesh (geometry that failed or came
    /// out empty), one line each: the file, the entity and why.
    pub warnings: Vec<String>,
    /// The tasks of the file's work schedules.
    pub tasks: Vec<ScheduleTask>,
    /// Where the IFC origin is on Earth or on a map, if the file says
    /// (`placement.rs`), and what of it was left out.
    pub georeference: Option<Georeference>,
    pub georeference_warning: Option<String>,
}

impl Model {
    fn skip(&mut self, class: &str, reason: &str) {
        *self
            .skipped
            .entry(class.to_string())
            .or_default()
            .entry(reason.to_string())
            .or_default() += 1;
    }
}

/// Reads the STEP text of an `.ifc` file, or of the first `.ifc` inside an
/// `.ifczip`.
pub fn read_step(path: &Path) -> Result<Vec<u8>> {
    let bytes = crate::input::read(path)?;
    if !bytes.starts_with(b"PK") {
        return Ok(bytes);
    }
    let bad = |m: String| Error::invalid(path, "zip archive", m);
    let mut zip =
        zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(|e| bad(e.to_string()))?;
    for i in 0..zip.len() {
        let mut entry = zip.by_index(i).map_err(|e| bad(e.to_string()))?;
        let name = entry.name().map_err(|e| bad(e.to_string()))?.into_owned();
        if !name.to_ascii_lowercase().ends_with(".ifc") {
            continue;
        }
        // The archive's own word for the size is not trusted: inflated, an
        // entry obeys the same cap as a file.
        let cap = crate::input::limits().max_bytes;
        let mut out = Vec::with_capacity(entry.size().min(cap).min(1 << 30) as usize);
        (&mut entry)
            .take(cap.saturating_add(1))
            .read_to_end(&mut out)
            .map_err(|e| bad(format!("{name}: {e}")))?;
        if out.len() as u64 > cap {
            return Err(bad(format!(
                "{name} inflates to over {cap} bytes, the cap on an input file \
                 (--max-input-bytes)"
            )));
        }
        return Ok(out);
    }
    Err(bad("holds no .ifc file".into()))
}

/// The id of the STEP record starting at `at` (`#123=`), for messages.
fn record_id(step: &[u8], at: usize) -> String {
    let tail = &step[at.min(step.len())..];
    let digits: String = tail
        .iter()
        .skip(1)
        .take_while(|b| b.is_ascii_digit())
        .map(|&b| b as char)
        .collect();
    if digits.is_empty() {
        format!("byte {at}")
    } else {
        format!("#{digits}")
    }
}

/// Reads and meshes one IFC file. A file that is not valid STEP is an error
/// naming the entity; an element that cannot be meshed is skipped and
/// counted.
pub fn read(path: &Path) -> Result<Model> {
    read_with(path, &HashSet::new())
}

/// [`read`], with the values of the property-set properties `psets`
/// (`Pset_WallCommon.FireRating`) of each element.
pub fn read_with(path: &Path, psets: &HashSet<String>) -> Result<Model> {
    let step = read_step(path)?;
    let mut model = Model {
        schema: header_schema(&step).ok_or_else(|| {
            Error::invalid(path, "HEADER", "no FILE_SCHEMA: not an IFC (STEP) file")
        })?,
        ..Model::default()
    };
    let index = Index::scan(path, &step)?;
    let mut decoder = EntityDecoder::new(&step);
    let mut in_file_order: Vec<(u32, IfcType)> =
        index.types.iter().map(|(&id, t)| (id, t.clone())).collect();
    in_file_order.sort_unstable_by_key(|(id, _)| *id);
    (model.georeference, model.georeference_warning) =
        super::placement::read(path, &mut decoder, &in_file_order)?;
    let decode = |d: &mut EntityDecoder, id: u32| {
        d.decode_by_id(id)
            .map_err(|e| Error::invalid(path, format!("#{id}"), e.to_string()))
    };

    let colors = Styles::read(&index, &mut decoder, path)?;
    let storeys = storeys(&index, &mut decoder, path)?;
    let mut values = super::psets::read(
        path,
        &mut decoder,
        &index
            .of_type(IfcType::IfcRelDefinesByProperties)
            .collect::<Vec<_>>(),
        &index
            .of_type(IfcType::IfcRelDefinesByType)
            .collect::<Vec<_>>(),
        psets,
    )?;
    let checks = Checks::scan(&index, &mut decoder);
    let voids = ifc_lite_geometry::void_index_from_content(&step, &mut decoder);
    let router = super::placement::router(&mut decoder);
    let file = path.file_name().map_or_else(
        || path.display().to_string(),
        |f| f.to_string_lossy().into_owned(),
    );
    // Elements with a body the mesher was given.
    let mut tried = 0;

    for (id, ty) in index.products.iter().cloned() {
        let class = ty.name().to_string();
        let entity = decode(&mut decoder, id)?;
        if ty.is_subtype_of(IfcType::IfcFeatureElementSubtraction) {
            model.skip(&class, "opening: subtracted from its host");
            continue;
        }
        if ty.is_subtype_of(IfcType::IfcSpatialElement)
            || ty.is_subtype_of(IfcType::IfcSpatialStructureElement)
        {
            if entity.get_ref(6).is_some() {
                model.skip(&class, "space or spatial structure");
            }
            continue;
        }
        if entity.get_ref(6).is_none() {
            // Wholes such as an IfcStair made of flights: their parts are
            // elements of their own.
            if ty.is_subtype_of(IfcType::IfcElement) {
                model.skip(&class, "no representation");
            }
            continue;
        }
        if !ty.is_subtype_of(IfcType::IfcElement) {
            model.skip(&class, "not a building element");
            continue;
        }
        let Some(guid) = entity.get_string(0).filter(|g| !g.is_empty()) else {
            return Err(Error::invalid(path, format!("#{id}"), "no GlobalId"));
        };
        tried += 1;
        // An element whose body gives nothing is named: the model the user
        // sees lacks it.
        let lost = |model: &mut Model, reason: &str, why: String| {
            model.skip(&class, reason);
            model
                .warnings
                .push(format!("{file}: #{id} ({class} {guid}): {reason}: {why}"));
        };
        if checks.any()
            && let Some(why) = checks.fault(&index, &mut decoder, &entity)
        {
            lost(&mut model, "geometry failed", why);
            continue;
        }
        // The mesher runs on arbitrary user geometry: should it panic on an
        // element, that element is skipped like one it cannot mesh.
        let parts = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            if voids.contains_key(&id) {
                router.process_element_with_submeshes_and_voids(&entity, &mut decoder, &voids)
            } else {
                router.process_element_with_submeshes(&entity, &mut decoder)
            }
        }))
        .map_err(|_| "the mesher panicked".to_string())
        .and_then(|r| r.map_err(|e| e.to_string()));
        let parts = match parts {
            Ok(p) if !p.is_empty() => p,
            Ok(_) if voids.contains_key(&id) => {
                model.skip(&class, "nothing left once its openings are cut");
                continue;
            }
            Ok(_) => {
                match checks.fault(&index, &mut decoder, &entity) {
                    Some(why) => lost(&mut model, "geometry failed", why),
                    None => lost(
                        &mut model,
                        "empty geometry",
                        "its body gave no triangles".into(),
                    ),
                }
                continue;
            }
            Err(why) => {
                lost(&mut model, "geometry failed", why);
                continue;
            }
        };
        let material = colors.of_element(id);
        let styled = material.is_some()
            || parts.iter().any(|p| {
                colors
                    .of_part(p.geometry_id, parts.ids_are_materials)
                    .is_some()
            });
        let fallback = material.unwrap_or_else(|| default_color(&class));
        let Some((mesh, origin, color)) = to_mesh(&parts, &colors, fallback) else {
            lost(
                &mut model,
                "empty geometry",
                "its body gave no triangles".into(),
            );
            continue;
        };
        model.elements.push(Element {
            id: guid.to_string(),
            class,
            name: entity.get_string(2).unwrap_or_default().to_string(),
            storey: storeys.of(id).map(str::to_string),
            properties: values.remove(&id).unwrap_or_default(),
            mesh,
            origin,
            color,
            styled,
        });
    }
    if model.elements.is_empty() && tried > 0 {
        let first = model.warnings.first().map_or_else(
            || "nothing is left of them once their openings are cut".to_string(),
            |w| {
                format!(
                    "the first: {}",
                    w.strip_prefix(&format!("{file}: ")).unwrap_or(w)
                )
            },
        );
        return Err(Error::invalid(
            path,
            "DATA",
            format!("none of its {tried} elements with a body could be imported; {first}"),
        ));
    }
    model.tasks = super::ifc_tasks::read(path, &model.schema, &step)?;
    Ok(model)
}

/// `FILE_SCHEMA(('IFC2X3'))` of the header.
pub(crate) fn header_schema(step: &[u8]) -> Option<String> {
    let head = &step[..step.len().min(64 * 1024)];
    let text = String::from_utf8_lossy(head);
    let at = text.find("FILE_SCHEMA")?;
    let rest = &text[at..];
    let open = rest.find('\'')? + 1;
    let close = open + rest[open..].find('\'')?;
    Some(rest[open..close].trim().to_ascii_uppercase())
}

/// The records of a file by id and the products among them.
pub(super) struct Index {
    /// Every record: id -> type.
    pub(super) types: HashMap<u32, IfcType>,
    /// Products (anything with a placement and a representation slot), in
    /// file order.
    products: Vec<(u32, IfcType)>,
}

impl Index {
    /// Scans every record. A record the scanner cannot delimit, or one whose
    /// attributes do not decode, makes the file invalid.
    fn scan(path: &Path, step: &[u8]) -> Result<Index> {
        let mut scanner = EntityScanner::new(step);
        let decoder = EntityDecoder::new(step);
        let mut types = HashMap::new();
        let mut products = Vec::new();
        while let Some((id, keyword, start, end)) = scanner.next_entity() {
            let ty = IfcType::from_str(keyword);
            if let Err(e) = decoder.decode_at_uncached(start, end) {
                return Err(Error::invalid(
                    path,
                    format!("#{id}"),
                    format!("bad STEP record: {e}"),
                ));
            }
            if ty.is_subtype_of(IfcType::IfcProduct) {
                products.push((id, ty.clone()));
            }
            types.insert(id, ty);
        }
        if let Some(&at) = scanner.malformed_record_starts().first() {
            return Err(Error::invalid(
                path,
                record_id(step, at),
                "bad STEP record: it does not end with ');'",
            ));
        }
        if types.is_empty() {
            return Err(Error::invalid(path, "DATA", "no STEP records"));
        }
        Ok(Index { types, products })
    }

    pub(super) fn of_type(&self, ty: IfcType) -> impl Iterator<Item = u32> + '_ {
        self.types
            .iter()
            .filter(move |(_, t)| **t == ty)
            .map(|(&id, _)| id)
    }
}

/// Joins the element's parts into one mesh relative to the first part's
/// origin, each part coloured by its style. Returns the mesh, its origin
/// and the object's colour.
fn to_mesh(
    parts: &SubMeshCollection,
    styles: &Styles,
    fallback: [f32; 4],
) -> Option<(Mesh, DVec3, [f32; 4])> {
    let origin = parts
        .iter()
        .find(|p| !p.mesh.indices.is_empty())
        .map(|p| DVec3::from(p.mesh.origin))?;
    let mut mesh = Mesh::default();
    for part in parts.iter() {
        let m = &part.mesh;
        if m.indices.is_empty() {
            continue;
        }
        let color = styles
            .of_part(part.geometry_id, parts.ids_are_materials)
            .unwrap_or(fallback);
        let shift = (DVec3::from(m.origin) - origin).as_vec3();
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2]) + shift),
        );
        if m.normals.len() == m.positions.len() {
            mesh.normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|n| Vec3::new(n[0], n[1], n[2])),
            );
        } else {
            mesh.normals.resize(mesh.positions.len(), Vec3::Z);
        }
        mesh.colors.resize(mesh.positions.len(), color);
        mesh.indices.extend(m.indices.iter().map(|i| base + i));
    }
    if mesh.is_empty() {
        return None;
    }
    // One colour: the object's colour, no vertex colours (the scene GLB
    // would multiply the two). Several: vertex colours under white.
    let first = mesh.colors[0];
    let color = if mesh.colors.iter().all(|c| *c == first) {
        mesh.colors.clear();
        first
    } else {
        [1.0; 4]
    };
    Some((mesh, origin, color))
}
