//! The colours of an IFC file's elements, as IfcOpenShell finds them:
//! the `IfcStyledItem` of a representation item (or of the first operand of
//! a boolean result that has none of its own), else the style of the
//! element's material, else that of its type's material, else a default
//! per class.
//!
//! References: IFC 2x3 TC1 and IFC 4.0 ADD2 TC1 (buildingSMART):
//! `IfcStyledItem`, `IfcBooleanResult`, `IfcMaterialDefinitionRepresentation`,
//! `IfcRelAssociatesMaterial`, `IfcRelDefinesByType`,
//! `IfcSurfaceStyleRendering` (its `DiffuseColour`, a colour or a factor of
//! `SurfaceColour`).

use std::collections::HashMap;
use std::path::Path;

use ifc_lite_core::{AttributeValue, DecodedEntity, EntityDecoder, IfcType};

use super::ifc::Index;
use crate::error::{Error, Result};

/// Surface colours (linear RGBA): of representation items, of materials,
/// of the elements and types a material is associated with, and each
/// element's type.
#[derive(Default)]
pub(super) struct Styles {
    items: HashMap<u32, [f32; 4]>,
    materials: HashMap<u32, [f32; 4]>,
    /// Elements and types -> the colour of their material.
    associated: HashMap<u32, [f32; 4]>,
    /// Element -> its type (`IfcRelDefinesByType`).
    types: HashMap<u32, u32>,
}

impl Styles {
    pub(super) fn read(index: &Index, d: &mut EntityDecoder, path: &Path) -> Result<Styles> {
        let mut styles = Styles::default();
        let mut styled = Vec::new();
        for id in index.of_type(IfcType::IfcStyledItem) {
            let e = decode(d, path, id)?;
            if let Some(color) = style_color(d, e.get(1)) {
                match e.get_ref(0) {
                    Some(item) => {
                        styles.items.insert(item, color);
                    }
                    None => styled.push((id, color)),
                }
            }
        }
        styles.inherit_through_booleans(index, d);
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
        // The related objects of a material association are elements or
        // their types (`IfcColumnType`...); both are kept.
        for id in index.of_type(IfcType::IfcRelAssociatesMaterial) {
            let Ok(e) = d.decode_by_id(id) else { continue };
            let Some(color) = e
                .get_ref(5)
                .and_then(|m| material_color(d, &styles.materials, m, 0))
            else {
                continue;
            };
            for object in e.get_refs(4).unwrap_or_default() {
                styles.associated.insert(object, color);
            }
        }
        for id in index.of_type(IfcType::IfcRelDefinesByType) {
            let e = decode(d, path, id)?;
            if let Some(ty) = e.get_ref(5) {
                for element in e.get_refs(4).unwrap_or_default() {
                    styles.types.insert(element, ty);
                }
            }
        }
        Ok(styles)
    }

    /// A boolean result without a style of its own shows its first
    /// operand's (Tekla and Revit style the clipped solid, not the
    /// clipping), as IfcOpenShell does; operands nest.
    fn inherit_through_booleans(&mut self, index: &Index, d: &mut EntityDecoder) {
        let booleans: HashMap<u32, Option<u32>> = index
            .types
            .iter()
            .filter(|(_, ty)| ty.is_subtype_of(IfcType::IfcBooleanResult))
            .map(|(&id, _)| (id, d.decode_by_id(id).ok().and_then(|e| e.get_ref(1))))
            .collect();
        for &id in booleans.keys() {
            if self.items.contains_key(&id) {
                continue;
            }
            // A chain longer than the file's booleans is a cycle.
            let mut operand = booleans[&id];
            for _ in 0..=booleans.len() {
                let Some(o) = operand else { break };
                if let Some(&c) = self.items.get(&o) {
                    self.items.insert(id, c);
                    break;
                }
                operand = booleans.get(&o).copied().flatten();
            }
        }
    }

    /// The colour of a mesher's part: of its representation item, or of
    /// its material when the mesher sliced the element by material layers.
    pub(super) fn of_part(&self, id: u32, is_material: bool) -> Option<[f32; 4]> {
        if is_material {
            self.materials.get(&id)
        } else {
            self.items.get(&id)
        }
        .copied()
    }

    /// The colour of an element's material, else of its type's.
    pub(super) fn of_element(&self, id: u32) -> Option<[f32; 4]> {
        self.associated.get(&id).copied().or_else(|| {
            self.types
                .get(&id)
                .and_then(|ty| self.associated.get(ty))
                .copied()
        })
    }
}

fn decode(d: &mut EntityDecoder, path: &Path, id: u32) -> Result<DecodedEntity> {
    d.decode_by_id(id)
        .map_err(|e| Error::invalid(path, format!("#{id}"), e.to_string()))
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
fn style_color(d: &mut EntityDecoder, styles: Option<&AttributeValue>) -> Option<[f32; 4]> {
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

/// The displayed colour of an `IfcSurfaceStyleShading` or `-Rendering`:
/// the rendering's `DiffuseColour` when it gives one, its factor times the
/// surface colour when it gives a factor (IfcOpenShell's diffuse), else the
/// surface colour.
fn surface_color(d: &mut EntityDecoder, style: &DecodedEntity) -> Option<[f32; 4]> {
    for r in style.get_refs(2)? {
        let e = d.decode_by_id(r).ok()?;
        if !matches!(
            e.ifc_type,
            IfcType::IfcSurfaceStyleRendering | IfcType::IfcSurfaceStyleShading
        ) {
            continue;
        }
        let surface = rgb(d, e.get_ref(0)?)?;
        let diffuse = match (&e.ifc_type, e.get(2)) {
            (IfcType::IfcSurfaceStyleRendering, Some(AttributeValue::EntityRef(colour))) => {
                rgb(d, *colour)
            }
            (IfcType::IfcSurfaceStyleRendering, Some(factor)) => factor
                .as_float()
                .map(|f| surface.map(|c| c * f.clamp(0.0, 1.0) as f32)),
            _ => None,
        }
        .unwrap_or(surface);
        // Some exporters write Transparency 1 for surfaces meant to be seen
        // (ArchiCAD roofs here); a floor keeps such elements visible.
        let transparency = e.get_float(1).unwrap_or(0.0).clamp(0.0, 1.0) as f32;
        let [r, g, b] = diffuse.map(srgb_to_linear);
        return Some([r, g, b, (1.0 - transparency).max(MIN_ALPHA)]);
    }
    None
}

/// An `IfcColourRgb`'s channels, clamped to [0, 1].
fn rgb(d: &mut EntityDecoder, id: u32) -> Option<[f32; 3]> {
    let rgb = d.decode_by_id(id).ok()?;
    let channel = |i| rgb.get_float(i).map(|v| v.clamp(0.0, 1.0) as f32);
    Some([channel(1)?, channel(2)?, channel(3)?])
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
