//! IFC geometry: each building element of an IFC 2x3 or IFC4 file becomes
//! one object, meshed in-process by the `ifc-lite-geometry` crate
//! (<https://github.com/LTplus-AG/ifc-lite>, extrusions, breps, mapped items,
//! booleans, openings subtracted from their hosts) over the STEP decoder of
//! `ifc-lite-core`. This file adds what a 4D scene needs around the meshes:
//! GlobalIds, storeys, colours (item style, then material style, then a
//! default per class), the property-set values the linking rules name
//! (`psets.rs`) and the count of what was left out and why.
//!
//! References: ISO 10303-21 (STEP physical files), IFC 2x3 TC1 and IFC 4.0
//! ADD2 TC1 (buildingSMART): `IfcRelContainedInSpatialStructure`,
//! `IfcRelAggregates`, `IfcStyledItem`, `IfcMaterialDefinitionRepresentation`.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::Read;
use std::path::Path;

use glam::{DVec3, Vec3};
use ifc_lite_core::{DecodedEntity, EntityDecoder, EntityScanner, IfcType};
use ifc_lite_geometry::SubMeshCollection;

use super::ScheduleTask;
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
}

/// What one IFC file gave.
#[derive(Debug, Clone, Default)]
pub struct Model {
    /// `FILE_SCHEMA` of the header, e.g. `IFC2X3`.
    pub schema: String,
    pub elements: Vec<Element>,
    /// Entities left out: IFC class -> reason -> count.
    pub skipped: BTreeMap<String, BTreeMap<String, usize>>,
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
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
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
        let mut out = Vec::with_capacity(entry.size() as usize);
        entry
            .read_to_end(&mut out)
            .map_err(|e| bad(format!("{name}: {e}")))?;
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
    let voids = ifc_lite_geometry::void_index_from_content(&step, &mut decoder);
    let router = super::placement::router(&mut decoder);

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
        // The mesher runs on arbitrary user geometry: should it panic on an
        // element, that element is skipped like one it cannot mesh.
        let parts = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            if voids.contains_key(&id) {
                router.process_element_with_submeshes_and_voids(&entity, &mut decoder, &voids)
            } else {
                router.process_element_with_submeshes(&entity, &mut decoder)
            }
        }));
        let Ok(parts) = parts else {
            model.skip(&class, "geometry failed (mesher panicked)");
            continue;
        };
        let parts = match parts {
            Ok(p) if !p.is_empty() => p,
            Ok(_) if voids.contains_key(&id) => {
                model.skip(&class, "nothing left once its openings are cut");
                continue;
            }
            Ok(_) => {
                model.skip(&class, "empty geometry");
                continue;
            }
            Err(e) => {
                tracing::debug!("{}: #{id}: {e}", path.display());
                model.skip(&class, "geometry failed");
                continue;
            }
        };
        let fallback = colors
            .of_element(id)
            .unwrap_or_else(|| default_color(&class));
        let Some((mesh, origin, color)) = to_mesh(&parts, &colors, fallback) else {
            model.skip(&class, "empty geometry");
            continue;
        };
        model.elements.push(Element {
            id: guid.to_string(),
            class,
            name: entity.get_string(2).unwrap_or_default().to_string(),
            storey: storeys.get(&id).cloned(),
            properties: values.remove(&id).unwrap_or_default(),
            mesh,
            origin,
            color,
        });
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
struct Index {
    /// Every record: id -> type.
    types: HashMap<u32, IfcType>,
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

    fn of_type(&self, ty: IfcType) -> impl Iterator<Item = u32> + '_ {
        self.types
            .iter()
            .filter(move |(_, t)| **t == ty)
            .map(|(&id, _)| id)
    }
}

/// Element id -> storey name, through `IfcRelContainedInSpatialStructure`
/// and, for parts, the `IfcRelAggregates` of their whole.
fn storeys(index: &Index, d: &mut EntityDecoder, path: &Path) -> Result<HashMap<u32, String>> {
    let mut decode = |id: u32| {
        d.decode_by_id(id)
            .map_err(|e| Error::invalid(path, format!("#{id}"), e.to_string()))
    };
    let mut names = HashMap::new();
    for id in index.of_type(IfcType::IfcBuildingStorey) {
        let e = decode(id)?;
        let name = e
            .get_string(2)
            .or_else(|| e.get_string(7))
            .unwrap_or("unnamed storey");
        names.insert(id, name.to_string());
    }
    let mut of = HashMap::new();
    for id in index.of_type(IfcType::IfcRelContainedInSpatialStructure) {
        let e = decode(id)?;
        if let Some(name) = e.get_ref(5).and_then(|s| names.get(&s)) {
            for el in e.get_refs(4).unwrap_or_default() {
                of.insert(el, name.clone());
            }
        }
    }
    // Parts take their whole's storey; wholes may nest, so repeat until
    // nothing changes (bounded by the nesting depth).
    let mut parts = Vec::new();
    for id in index.of_type(IfcType::IfcRelAggregates) {
        let e = decode(id)?;
        if let Some(whole) = e.get_ref(4) {
            for part in e.get_refs(5).unwrap_or_default() {
                parts.push((whole, part));
            }
        }
    }
    loop {
        let mut changed = false;
        for &(whole, part) in &parts {
            if !of.contains_key(&part)
                && let Some(name) = of.get(&whole).cloned()
            {
                of.insert(part, name);
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    Ok(of)
}

/// Surface colours: representation item -> colour, material -> colour, and
/// element -> colour of its material.
#[derive(Default)]
struct Styles {
    items: HashMap<u32, [f32; 4]>,
    materials: HashMap<u32, [f32; 4]>,
    elements: HashMap<u32, [f32; 4]>,
}

impl Styles {
    fn read(index: &Index, d: &mut EntityDecoder, path: &Path) -> Result<Styles> {
        let mut styles = Styles::default();
        let mut styled = Vec::new();
        for id in index.of_type(IfcType::IfcStyledItem) {
            let e = d
                .decode_by_id(id)
                .map_err(|e| Error::invalid(path, format!("#{id}"), e.to_string()))?;
            if let Some(color) = style_color(d, e.get(1)) {
                match e.get_ref(0) {
                    Some(item) => {
                        styles.items.insert(item, color);
                    }
                    None => styled.push((id, color)),
                }
            }
        }
        // Material colours: IfcMaterialDefinitionRepresentation ->
        // IfcStyledRepresentation -> IfcStyledItem (without an item).
        let styled: HashMap<u32, [f32; 4]> = styled.into_iter().collect();
        for id in index.of_type(IfcType::IfcMaterialDefinitionRepresentation) {
            let Ok(e) = d.decode_by_id(id) else { continue };
            let Some(material) = e.get_ref(3) else {
                continue;
            };
            let color = e.get_refs(2).unwrap_or_default().into_iter().find_map(|r| {
                let rep = d.decode_by_id(r).ok()?;
                rep.get_refs(3)?
                    .into_iter()
                    .find_map(|i| styled.get(&i).copied())
            });
            if let Some(c) = color {
                styles.materials.insert(material, c);
            }
        }
        for id in index.of_type(IfcType::IfcRelAssociatesMaterial) {
            let Ok(e) = d.decode_by_id(id) else { continue };
            let Some(color) = e
                .get_ref(5)
                .and_then(|m| material_color(d, &styles.materials, m, 0))
            else {
                continue;
            };
            for el in e.get_refs(4).unwrap_or_default() {
                styles.elements.insert(el, color);
            }
        }
        Ok(styles)
    }

    fn of_element(&self, id: u32) -> Option<[f32; 4]> {
        self.elements.get(&id).copied()
    }
}

/// The colour of a material select: an `IfcMaterial`, or the first layer or
/// constituent with one (layer sets, usages, lists).
fn material_color(
    d: &mut EntityDecoder,
    colors: &HashMap<u32, [f32; 4]>,
    id: u32,
    depth: u32,
) -> Option<[f32; 4]> {
    if let Some(&c) = colors.get(&id) {
        return Some(c);
    }
    if depth > 4 {
        return None;
    }
    let e = d.decode_by_id(id).ok()?;
    let refs: Vec<u32> = e
        .attributes
        .iter()
        .flat_map(|a| match a.as_list() {
            Some(list) => list.iter().filter_map(|v| v.as_entity_ref()).collect(),
            None => a.as_entity_ref().into_iter().collect::<Vec<_>>(),
        })
        .collect();
    refs.into_iter()
        .find_map(|r| material_color(d, colors, r, depth + 1))
}

/// The surface colour of an `IfcStyledItem.Styles` value: IFC2x3 goes
/// through `IfcPresentationStyleAssignment`, IFC4 may list the
/// `IfcSurfaceStyle` directly.
fn style_color(
    d: &mut EntityDecoder,
    styles: Option<&ifc_lite_core::AttributeValue>,
) -> Option<[f32; 4]> {
    let refs: Vec<u32> = styles?
        .as_list()?
        .iter()
        .filter_map(|v| v.as_entity_ref())
        .collect();
    for r in refs {
        let e = d.decode_by_id(r).ok()?;
        let found = match e.ifc_type {
            IfcType::IfcPresentationStyleAssignment => {
                let inner = e.get(0).cloned();
                style_color(d, inner.as_ref())
            }
            IfcType::IfcSurfaceStyle => surface_color(d, &e),
            _ => None,
        };
        if found.is_some() {
            return found;
        }
    }
    None
}

fn surface_color(d: &mut EntityDecoder, style: &DecodedEntity) -> Option<[f32; 4]> {
    for r in style.get_refs(2)? {
        let e = d.decode_by_id(r).ok()?;
        if !matches!(
            e.ifc_type,
            IfcType::IfcSurfaceStyleRendering | IfcType::IfcSurfaceStyleShading
        ) {
            continue;
        }
        let rgb = d.decode_by_id(e.get_ref(0)?).ok()?;
        let channel = |i| {
            rgb.get_float(i)
                .map(|v| srgb_to_linear(v.clamp(0.0, 1.0) as f32))
        };
        // Some exporters write Transparency 1 for surfaces meant to be seen
        // (ArchiCAD roofs here); a floor keeps such elements visible.
        let transparency = e.get_float(1).unwrap_or(0.0).clamp(0.0, 1.0) as f32;
        return Some([
            channel(1)?,
            channel(2)?,
            channel(3)?,
            (1.0 - transparency).max(MIN_ALPHA),
        ]);
    }
    None
}

/// The least opacity an imported surface keeps.
pub const MIN_ALPHA: f32 = 0.25;

/// IFC colours are display colours (sRGB); the scene holds linear ones.
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// A default colour per class, when the file styles nothing (linear RGBA).
pub fn default_color(class: &str) -> [f32; 4] {
    let srgb = |r: f32, g: f32, b: f32, a: f32| {
        [srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b), a]
    };
    let c = class.to_ascii_lowercase();
    if c.starts_with("ifcwindow") {
        srgb(0.55, 0.75, 0.9, 0.5)
    } else if c.starts_with("ifcdoor") {
        srgb(0.6, 0.45, 0.3, 1.0)
    } else if c.starts_with("ifcslab") || c.starts_with("ifcroof") {
        srgb(0.7, 0.7, 0.68, 1.0)
    } else if c.starts_with("ifcbeam") || c.starts_with("ifccolumn") || c.starts_with("ifcmember") {
        srgb(0.55, 0.57, 0.6, 1.0)
    } else if c.starts_with("ifcrailing") || c.starts_with("ifcstair") {
        srgb(0.45, 0.45, 0.5, 1.0)
    } else if c.starts_with("ifcwall") {
        srgb(0.85, 0.83, 0.78, 1.0)
    } else {
        srgb(0.75, 0.75, 0.75, 1.0)
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
        let color = if parts.ids_are_materials {
            styles.materials.get(&part.geometry_id)
        } else {
            styles.items.get(&part.geometry_id)
        }
        .copied()
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
