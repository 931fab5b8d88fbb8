//! Where an imported scene stands: the georeference an IFC file declares
//! (IFC4 `IfcMapConversion` with its `IfcProjectedCRS`, IFC2x3's
//! `ePSet_MapConversion`, else `IfcSite.RefLatitude`, `RefLongitude` and
//! `RefElevation`), read by `ifc-lite-core`'s extractor, and the scene's
//! local origin.
//!
//! Models are often drawn at map coordinates, hundreds of kilometres from
//! their IFC origin, where `f32` (the scene's placements and meshes) has a
//! grid of centimetres. Element placements are therefore kept in `f64`
//! until the scene's origin is chosen near the model, and the georeference
//! is moved to that origin, so nothing of the model's place is lost.
//!
//! References: buildingSMART IFC 4.0 ADD2 TC1, `IfcMapConversion`
//! (`Eastings`, `Northings`, `OrthogonalHeight`, `XAxisAbscissa`,
//! `XAxisOrdinate`, `Scale`), `IfcProjectedCRS`, `IfcSite`.

use std::path::Path;

use glam::DVec3;
use ifc_lite_core::{EntityDecoder, GeoRefExtractor, GeoRefSource, IfcType};
use ifc_lite_geometry::{GeometryRouter, RouterConfig};

use crate::error::{Error, Result};
use crate::scene::{Geographic, Georeference, Projected, epsg_code};

/// A model whose elements lie farther than this (metres) from its IFC
/// origin gets an origin of its own; nearer, `f32` keeps well under a
/// tenth of a millimetre and the IFC origin stays.
pub const FAR: f64 = 1000.0;

/// The mesher for a file: its length unit (a unit it cannot use, NaN,
/// makes it refuse every element, as `GeometryRouter::with_units` does),
/// and each element's vertices relative to an `f64` origin of its own.
/// Without that, natively, `ifc-lite` places vertices in absolute `f32`,
/// on a grid of 6 to 12 cm at map coordinates.
pub(super) fn router(decoder: &mut EntityDecoder) -> GeometryRouter {
    let unit_scale = decoder
        .project_id()
        .and_then(|id| ifc_lite_core::resolve_length_unit(decoder, id).ok())
        .map_or(1.0, |unit| match unit.unusable_factor {
            Some(_) => f64::NAN,
            None => unit.scale,
        });
    let mut router = GeometryRouter::from_config(RouterConfig {
        unit_scale,
        local_frame: Some(true),
        ..RouterConfig::default()
    });
    router.enable_content_dedup_shared(GeometryRouter::new_dedup_cache());
    router
}

/// The georeference of one file's IFC origin, if it declares one, and what
/// was left out of it (a CRS named otherwise than by an EPSG code, or one
/// this build cannot project).
pub(super) fn read(
    path: &Path,
    decoder: &mut EntityDecoder,
    types: &[(u32, IfcType)],
) -> Result<(Option<Georeference>, Option<String>)> {
    let found = GeoRefExtractor::extract(decoder, types)
        .map_err(|e| Error::invalid(path, "IfcMapConversion", e.to_string()))?;
    let Some(g) = found else {
        return Ok((None, None));
    };
    // Lengths are in the project's unit, a conversion's in its map unit.
    let unit = decoder.length_unit_scale();
    if g.source == Some(GeoRefSource::SiteLocation) {
        let site = Georeference::Geographic(Geographic {
            latitude: g.northings,
            longitude: g.eastings,
            height: g.orthogonal_height * unit,
            heading: 0.0,
        });
        return Ok(match site.validate() {
            Ok(()) => (Some(site), None),
            Err((field, m)) => (None, Some(format!("IfcSite: {field} {m}: no georeference"))),
        });
    }
    let map_unit = g.map_unit_scale.unwrap_or(unit);
    // IFC's Scale converts the project's units to the map's; once both are
    // metres only what is left of it scales. Files that leave it at 1
    // across units are common, and read as no scale.
    let scale = if g.scale == 1.0 {
        1.0
    } else {
        g.scale * map_unit / unit
    };
    let mut warning = None;
    let crs = match g.crs_name.as_deref().map(epsg_code) {
        Some(Ok(code)) => Some(code),
        Some(Err(m)) => {
            warning = Some(format!(
                "IfcProjectedCRS: {m}; kept its map coordinates without a CRS"
            ));
            None
        }
        None => None,
    };
    let mut projected = Projected {
        crs,
        easting: g.eastings * map_unit,
        northing: g.northings * map_unit,
        height: g.orthogonal_height * map_unit,
        // The x axis turned anticlockwise from grid east turns the scene's
        // north the same way from grid north.
        heading: -g.rotation().to_degrees(),
        scale,
    };
    if let Err((field, m)) = Georeference::Projected(projected).validate() {
        if field != "crs" {
            return Ok((
                None,
                Some(format!("IfcMapConversion: {field} {m}: no georeference")),
            ));
        }
        warning = Some(format!(
            "IfcProjectedCRS: {m}; kept its map coordinates without a CRS"
        ));
        projected.crs = None;
    }
    Ok((Some(Georeference::Projected(projected)), warning))
}

/// The scene's origin in the models' coordinates (metres, z up): the IFC
/// origin for a model near it, else the centre of the elements' origins
/// to the whole metre.
pub(super) fn local_origin(origins: &[DVec3]) -> DVec3 {
    let Some(first) = origins.first() else {
        return DVec3::ZERO;
    };
    let (lo, hi) = origins
        .iter()
        .fold((*first, *first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let centre = (lo + hi) / 2.0;
    if centre.abs().max_element() <= FAR {
        DVec3::ZERO
    } else {
        centre.round()
    }
}

/// The scene's georeference for its origin at `origin` of the models'
/// coordinates: the files' moved there, or, for a model moved without
/// one, the map coordinates of its origin without a CRS.
pub(super) fn at_origin(georeference: Option<Georeference>, origin: DVec3) -> Option<Georeference> {
    match georeference {
        Some(g) if origin == DVec3::ZERO => Some(g),
        Some(g) => Some(g.moved(origin)),
        None if origin == DVec3::ZERO => None,
        None => Some(Georeference::Projected(Projected {
            crs: None,
            easting: origin.x,
            northing: origin.y,
            height: origin.z,
            heading: 0.0,
            scale: 1.0,
        })),
    }
}
