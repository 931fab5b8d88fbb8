//! Property-set values of elements, for the linking rules: only those a
//! rule names (`Pset_WallCommon.FireRating`), since a model carries
//! thousands and a scene keeps every property it is given. An element's
//! own property sets (`IfcRelDefinesByProperties`) win over its type's
//! (`IfcRelDefinesByType`, the type's `HasPropertySets`), as IfcOpenShell's
//! `get_psets` merges them. A value is the single value's nominal value as
//! written: text, a number, `true`/`false` for a boolean.
//!
//! Reference: IFC 2x3 TC1 and IFC 4.0 ADD2 TC1: IfcRelDefinesByProperties
//! (RelatedObjects 4, RelatingPropertyDefinition 5), IfcRelDefinesByType
//! (RelatedObjects 4, RelatingType 5), IfcTypeObject (HasPropertySets 5),
//! IfcPropertySet (Name 2, HasProperties 4), IfcPropertySingleValue (Name 0,
//! NominalValue 2).

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use ifc_lite_core::{AttributeValue, EntityDecoder};

use crate::error::{Error, Result};

/// Element -> `Pset.Property` -> value, for the wanted keys.
pub type Values = HashMap<u32, BTreeMap<String, String>>;

/// The values of the `wanted` properties (`Pset.Property`) of the elements,
/// from the file's `IfcRelDefinesByProperties` and `IfcRelDefinesByType`
/// records.
pub fn read(
    path: &Path,
    d: &mut EntityDecoder,
    by_properties: &[u32],
    by_type: &[u32],
    wanted: &HashSet<String>,
) -> Result<Values> {
    let mut out = Values::new();
    if wanted.is_empty() {
        return Ok(out);
    }
    let psets: HashSet<&str> = wanted
        .iter()
        .filter_map(|k| k.split_once('.'))
        .map(|(p, _)| p)
        .collect();
    let mut decode = |id: u32| {
        d.decode_by_id(id)
            .map_err(|e| Error::invalid(path, format!("#{id}"), e.to_string()))
    };
    // A property set's wanted values, by its id (read once).
    let mut sets: HashMap<u32, Vec<(String, String)>> = HashMap::new();
    let mut values_of = |set: u32,
                         decode: &mut dyn FnMut(u32) -> Result<ifc_lite_core::DecodedEntity>|
     -> Result<Vec<(String, String)>> {
        if let Some(v) = sets.get(&set) {
            return Ok(v.clone());
        }
        let s = decode(set)?;
        let mut values = Vec::new();
        if let Some(name) = s.get_string(2).filter(|n| psets.contains(n)) {
            for p in s.get_refs(4).unwrap_or_default() {
                let prop = decode(p)?;
                let Some(key) = prop.get_string(0).map(|n| format!("{name}.{n}")) else {
                    continue;
                };
                if let Some(v) = prop.get(2).and_then(text).filter(|_| wanted.contains(&key)) {
                    values.push((key, v));
                }
            }
        }
        sets.insert(set, values.clone());
        Ok(values)
    };
    // Types first: an element's own sets then override them.
    for &rel in by_type {
        let r = decode(rel)?;
        let Some(ty) = r.get_ref(5) else { continue };
        let type_sets = decode(ty)?.get_refs(5).unwrap_or_default();
        let mut values = Vec::new();
        for set in type_sets {
            values.extend(values_of(set, &mut decode)?);
        }
        for element in r.get_refs(4).unwrap_or_default() {
            out.entry(element)
                .or_default()
                .extend(values.iter().cloned());
        }
    }
    for &rel in by_properties {
        let r = decode(rel)?;
        let Some(set) = r.get_ref(5) else { continue };
        let values = values_of(set, &mut decode)?;
        if values.is_empty() {
            continue;
        }
        for element in r.get_refs(4).unwrap_or_default() {
            out.entry(element)
                .or_default()
                .extend(values.iter().cloned());
        }
    }
    Ok(out)
}

/// A nominal value as text: `IFCLABEL('x')` -> `x`, `IFCBOOLEAN(.T.)` ->
/// `true`, numbers as written.
fn text(v: &AttributeValue) -> Option<String> {
    if let Some(e) = v.as_enum() {
        return Some(
            match e {
                "T" => "true",
                "F" => "false",
                "U" => "unknown",
                other => other,
            }
            .to_string(),
        );
    }
    if let Some(s) = v.as_string() {
        return Some(s.to_string());
    }
    if let Some(i) = v.as_int() {
        return Some(i.to_string());
    }
    v.as_float().map(|f| f.to_string())
}
