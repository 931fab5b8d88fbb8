//! Each element's storey: the `IfcBuildingStorey` nearest above it in the
//! spatial structure. An element is contained in a spatial element
//! (`IfcRelContainedInSpatialStructure`: a storey, or a space that is part
//! of one) or is part of a whole (`IfcRelAggregates`: a stair's flight; a
//! space of a storey); the walk goes up from container to whole until it
//! meets a storey.
//!
//! References: IFC 2x3 TC1 and IFC 4.0 ADD2 TC1 (buildingSMART):
//! `IfcRelContainedInSpatialStructure`, `IfcRelAggregates`,
//! `IfcBuildingStorey`, `IfcSpace`.

use std::collections::HashMap;
use std::path::Path;

use ifc_lite_core::{EntityDecoder, IfcType};

use super::ifc::Index;
use crate::error::{Error, Result};

/// The spatial structure of a file, as far as storeys need it.
pub(super) struct Storeys {
    /// Storey id -> its name.
    names: HashMap<u32, String>,
    /// Element or spatial element -> what holds it: its container, else
    /// its whole.
    parent: HashMap<u32, u32>,
}

impl Storeys {
    /// The name of the storey above `id`, if any.
    pub(super) fn of(&self, id: u32) -> Option<&str> {
        let mut at = id;
        // A walk longer than the structure has links is a cycle.
        for _ in 0..=self.parent.len() {
            if let Some(name) = self.names.get(&at) {
                return Some(name);
            }
            at = *self.parent.get(&at)?;
        }
        None
    }
}

/// Reads the storeys, containment and aggregation of a file.
pub(super) fn storeys(index: &Index, d: &mut EntityDecoder, path: &Path) -> Result<Storeys> {
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
    let mut parent = HashMap::new();
    for id in index.of_type(IfcType::IfcRelContainedInSpatialStructure) {
        let e = decode(id)?;
        if let Some(structure) = e.get_ref(5) {
            for element in e.get_refs(4).unwrap_or_default() {
                parent.insert(element, structure);
            }
        }
    }
    // Containment says where an element is; a part's whole only when
    // nothing contains the part itself.
    for id in index.of_type(IfcType::IfcRelAggregates) {
        let e = decode(id)?;
        if let Some(whole) = e.get_ref(4) {
            for part in e.get_refs(5).unwrap_or_default() {
                parent.entry(part).or_insert(whole);
            }
        }
    }
    Ok(Storeys { names, parent })
}
