//! Malformed geometry the mesher passes over: it drops a face whose index
//! is out of range and meshes the rest, and an item that names a record the
//! file does not hold comes out empty without a word. IfcOpenShell refuses
//! such elements; so do we, saying why.
//!
//! References: IFC 4.0 ADD2 TC1 (buildingSMART): `IfcTriangulatedFaceSet`
//! (`CoordIndex`, `PnIndex`), `IfcPolygonalFaceSet`,
//! `IfcIndexedPolygonalFace(WithVoids)`, `IfcCartesianPointList3D`.

use std::collections::{HashMap, HashSet};

use ifc_lite_core::{AttributeValue, DecodedEntity, EntityDecoder, IfcType};

use super::ifc::Index;

/// The face sets of a file with an index out of range, and why.
pub(super) struct Checks {
    bad: HashMap<u32, String>,
}

impl Checks {
    pub(super) fn scan(index: &Index, d: &mut EntityDecoder) -> Checks {
        let mut bad = HashMap::new();
        for (&id, ty) in &index.types {
            let fault = match ty {
                IfcType::IfcTriangulatedFaceSet => triangulated(d, id),
                IfcType::IfcPolygonalFaceSet => polygonal(d, id),
                _ => None,
            };
            if let Some(f) = fault {
                bad.insert(id, f);
            }
        }
        Checks { bad }
    }

    /// Whether any face set of the file is broken: only then must every
    /// element be looked through before it is meshed.
    pub(super) fn any(&self) -> bool {
        !self.bad.is_empty()
    }

    /// The first fault below an element's placement and representation: a
    /// broken face set, or a reference to a record the file does not hold.
    pub(super) fn fault(
        &self,
        index: &Index,
        d: &mut EntityDecoder,
        element: &DecodedEntity,
    ) -> Option<String> {
        let mut seen = HashSet::new();
        let mut todo: Vec<(u32, u32)> = [5, 6]
            .into_iter()
            .filter_map(|a| element.get_ref(a))
            .map(|r| (element.id, r))
            .collect();
        while let Some((from, id)) = todo.pop() {
            if !seen.insert(id) {
                continue;
            }
            if let Some(f) = self.bad.get(&id) {
                return Some(f.clone());
            }
            if !index.types.contains_key(&id) {
                let class = index.types.get(&from).map_or("?", |t| t.name());
                return Some(format!(
                    "#{from} ({class}) refers to #{id}, which is not in the file"
                ));
            }
            let Ok(e) = d.decode_by_id(id) else { continue };
            for a in e.attributes.iter() {
                refs(a, &mut |r| todo.push((id, r)));
            }
        }
        None
    }
}

/// Every entity reference in a value, lists nested.
fn refs(value: &AttributeValue, out: &mut impl FnMut(u32)) {
    match value {
        AttributeValue::EntityRef(r) => out(*r),
        AttributeValue::List(items) => items.iter().for_each(|v| refs(v, out)),
        _ => {}
    }
}

/// The 1-based indices of a list of them, or of a list of such lists.
fn indices(value: Option<&AttributeValue>) -> Vec<i64> {
    fn walk(v: &AttributeValue, out: &mut Vec<i64>) {
        match v {
            AttributeValue::List(items) => items.iter().for_each(|i| walk(i, out)),
            other => out.extend(other.as_int()),
        }
    }
    let mut out = Vec::new();
    if let Some(v) = value {
        walk(v, &mut out);
    }
    out
}

/// The points a face set's indices may name: its `PnIndex`, checked
/// against the coordinates, else the coordinates themselves.
fn points(d: &mut EntityDecoder, set: &DecodedEntity, pn: usize) -> Result<usize, String> {
    let coordinates = set.get_ref(0).ok_or("no Coordinates")?;
    let list = d
        .decode_by_id(coordinates)
        .map_err(|e| format!("its Coordinates #{coordinates}: {e}"))?;
    let n = list.get_list(0).map_or(0, <[_]>::len);
    let pn = indices(set.get(pn));
    if pn.is_empty() {
        return Ok(n);
    }
    match pn.iter().find(|&&i| i < 1 || i as usize > n) {
        Some(i) => Err(format!(
            "PnIndex index {i} is out of range: #{coordinates} has {n} points"
        )),
        None => Ok(pn.len()),
    }
}

fn out_of_range(indices: &[i64], n: usize) -> Option<i64> {
    indices.iter().copied().find(|&i| i < 1 || i as usize > n)
}

fn triangulated(d: &mut EntityDecoder, id: u32) -> Option<String> {
    let set = d.decode_by_id(id).ok()?;
    let at = |m: String| Some(format!("#{id} (IfcTriangulatedFaceSet): {m}"));
    let n = match points(d, &set, 4) {
        Ok(n) => n,
        Err(m) => return at(m),
    };
    let i = out_of_range(&indices(set.get(3)), n)?;
    at(format!("CoordIndex index {i} is out of range: {n} points"))
}

fn polygonal(d: &mut EntityDecoder, id: u32) -> Option<String> {
    let set = d.decode_by_id(id).ok()?;
    let n = match points(d, &set, 3) {
        Ok(n) => n,
        Err(m) => return Some(format!("#{id} (IfcPolygonalFaceSet): {m}")),
    };
    for face in set.get_refs(2).unwrap_or_default() {
        let Ok(f) = d.decode_by_id(face) else {
            continue;
        };
        // CoordIndex, and the inner loops of a face with voids.
        let mut all = indices(f.get(0));
        all.extend(indices(f.get(1)));
        if let Some(i) = out_of_range(&all, n) {
            return Some(format!(
                "#{face} ({}) of #{id} (IfcPolygonalFaceSet): index {i} is out of range: {n} points",
                f.ifc_type.name()
            ));
        }
    }
    None
}
