//! Where a scene is on Earth, and the transform from its local frame to
//! Earth-centred, Earth-fixed (ECEF) coordinates, which 3D Tiles clients
//! (CesiumJS, cesium-native) expect of a georeferenced tileset.
//!
//! A scene gives its local origin either as WGS 84 latitude, longitude and
//! height with the heading of its north ([`Geographic`]), or as map
//! coordinates in a projected CRS named by its EPSG code, with the heading
//! of its north from grid north and a scale ([`Projected`], what IFC4's
//! `IfcMapConversion` holds). A projected origin without a CRS keeps where
//! the scene's origin was in its source's own coordinates (an IFC model at
//! map coordinates made local on import) without placing it on Earth.
//!
//! References: NIMA TR8350.2, "Department of Defense World Geodetic System
//! 1984" (the ellipsoid's constants, geodetic to ECEF); J. Zhu, "Conversion
//! of Earth-centered Earth-fixed coordinates to geodetic coordinates", IEEE
//! Trans. Aerospace and Electronic Systems 30(3), 1994 (the inverse, here
//! by Bowring's iteration); the east-north-up axes as in CesiumJS's
//! `Transforms.eastNorthUpToFixedFrame`; projections and datum shifts by
//! `proj4rs` (PROJ.4's algorithms) with the EPSG definitions of
//! `crs-definitions`; buildingSMART IFC 4.0 `IfcMapConversion`.

use glam::{DMat4, DVec3, DVec4};
use serde::{Deserialize, Serialize};

/// WGS 84 semi-major axis, metres.
const A: f64 = 6_378_137.0;
/// WGS 84 flattening.
const F: f64 = 1.0 / 298.257_223_563;

/// The scene's place on Earth: the map from its frame turned z-up (x east,
/// y north, z up before the heading) to the world.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Fields", into = "Fields")]
pub enum Georeference {
    Geographic(Geographic),
    Projected(Projected),
}

/// The local origin on the WGS 84 ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geographic {
    /// Of the local origin, degrees north (WGS 84).
    pub latitude: f64,
    /// Degrees east.
    pub longitude: f64,
    /// Metres above the ellipsoid.
    pub height: f64,
    /// Degrees clockwise from true north to the scene's north: its `-z`
    /// axis when y is up, its `y` axis when z is up.
    pub heading: f64,
}

/// The local origin in map coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projected {
    /// The EPSG code of the projected CRS; `None`: the source's own
    /// coordinates, not placed on Earth.
    pub crs: Option<u16>,
    /// Metres.
    pub easting: f64,
    pub northing: f64,
    /// Metres, taken as above the WGS 84 ellipsoid when placed on Earth.
    pub height: f64,
    /// Degrees clockwise from grid north to the scene's north.
    pub heading: f64,
    /// Map metres per scene metre (IFC's `Scale` once units are metres).
    pub scale: f64,
}

/// The JSON form: one object, the fields of one kind.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Fields {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    latitude: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    longitude: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    crs: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    easting: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    northing: Option<f64>,
    #[serde(default)]
    height: f64,
    #[serde(default)]
    heading: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scale: Option<f64>,
}

impl TryFrom<Fields> for Georeference {
    type Error = String;

    fn try_from(f: Fields) -> Result<Self, String> {
        let geographic = f.latitude.is_some() || f.longitude.is_some();
        let projected = f.easting.is_some() || f.northing.is_some();
        match (geographic, projected) {
            (true, true) => {
                Err("give latitude and longitude, or easting and northing, not both".into())
            }
            (false, false) => Err("give latitude and longitude, or easting and northing".into()),
            (true, false) => {
                if let Some(field) = [("crs", f.crs.is_some()), ("scale", f.scale.is_some())]
                    .into_iter()
                    .find_map(|(name, set)| set.then_some(name))
                {
                    return Err(format!(
                        "{field} is for easting and northing, not latitude and longitude"
                    ));
                }
                let (Some(latitude), Some(longitude)) = (f.latitude, f.longitude) else {
                    return Err("latitude and longitude go together".into());
                };
                Ok(Georeference::Geographic(Geographic {
                    latitude,
                    longitude,
                    height: f.height,
                    heading: f.heading,
                }))
            }
            (false, true) => {
                let (Some(easting), Some(northing)) = (f.easting, f.northing) else {
                    return Err("easting and northing go together".into());
                };
                let crs = f.crs.as_deref().map(epsg_code).transpose()?;
                Ok(Georeference::Projected(Projected {
                    crs,
                    easting,
                    northing,
                    height: f.height,
                    heading: f.heading,
                    scale: f.scale.unwrap_or(1.0),
                }))
            }
        }
    }
}

impl From<Georeference> for Fields {
    fn from(g: Georeference) -> Fields {
        match g {
            Georeference::Geographic(g) => Fields {
                latitude: Some(g.latitude),
                longitude: Some(g.longitude),
                crs: None,
                easting: None,
                northing: None,
                height: g.height,
                heading: g.heading,
                scale: None,
            },
            Georeference::Projected(p) => Fields {
                latitude: None,
                longitude: None,
                crs: p.crs.map(|c| format!("EPSG:{c}")),
                easting: Some(p.easting),
                northing: Some(p.northing),
                height: p.height,
                heading: p.heading,
                scale: (p.scale != 1.0).then_some(p.scale),
            },
        }
    }
}

/// `EPSG:28992` (or `28992`) as its code.
pub fn epsg_code(crs: &str) -> Result<u16, String> {
    let digits = crs.trim();
    let digits = digits
        .strip_prefix("EPSG:")
        .or_else(|| digits.strip_prefix("epsg:"))
        .unwrap_or(digits);
    digits
        .parse()
        .map_err(|_| format!("crs {crs:?} is not an EPSG code such as \"EPSG:28992\""))
}

impl Georeference {
    /// Checks the ranges and that a CRS is one this build can project; the
    /// message names the field.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let finite = |checks: &[(&'static str, f64)]| {
            for &(field, v) in checks {
                if !v.is_finite() {
                    return Err((field, format!("{v} is not a finite number")));
                }
            }
            Ok(())
        };
        match self {
            Georeference::Geographic(g) => g.validate(),
            Georeference::Projected(p) => {
                finite(&[
                    ("easting", p.easting),
                    ("northing", p.northing),
                    ("height", p.height),
                    ("heading", p.heading),
                    ("scale", p.scale),
                ])?;
                if !(-360.0..=360.0).contains(&p.heading) {
                    return Err(("heading", format!("{} is not within -360..360", p.heading)));
                }
                if p.scale <= 0.0 {
                    return Err(("scale", format!("{} is not above 0", p.scale)));
                }
                if let Some(code) = p.crs {
                    projection(code).map_err(|m| ("crs", m))?;
                }
                Ok(())
            }
        }
    }

    /// The origin on the ellipsoid, or `None` for map coordinates without a
    /// CRS. The error names what cannot be projected.
    pub fn geographic(&self) -> Result<Option<Geographic>, String> {
        match self {
            Georeference::Geographic(g) => Ok(Some(*g)),
            Georeference::Projected(p) => p.crs.map(|code| p.on_earth(code)).transpose(),
        }
    }

    /// The map from the scene's frame turned z-up to ECEF (see
    /// [`Geographic::to_ecef`]), scaled by a projected origin's scale;
    /// `None` for map coordinates without a CRS.
    pub fn to_ecef(&self) -> Result<Option<DMat4>, String> {
        let scale = match self {
            Georeference::Geographic(_) => 1.0,
            Georeference::Projected(p) => p.scale,
        };
        Ok(self
            .geographic()?
            .map(|g| g.to_ecef() * DMat4::from_scale(DVec3::splat(scale))))
    }

    /// The same place for the scene moved by `-offset`: the origin taken
    /// to the point `offset` (metres, z up) of the present frame. Exact for
    /// map coordinates; along the tangent plane at the origin for a
    /// geographic one (the east-north-up frame at the new origin turns from
    /// the old by the offset over the Earth's radius, 1.6e-4 rad a km).
    pub fn moved(&self, offset: DVec3) -> Georeference {
        match self {
            Georeference::Geographic(g) => {
                let (latitude, longitude, height) = geodetic(g.to_ecef().transform_point3(offset));
                Georeference::Geographic(Geographic {
                    latitude,
                    longitude,
                    height,
                    heading: g.heading,
                })
            }
            Georeference::Projected(p) => {
                let turn = -p.heading.to_radians();
                let (sin, cos) = turn.sin_cos();
                Georeference::Projected(Projected {
                    easting: p.easting + p.scale * (cos * offset.x - sin * offset.y),
                    northing: p.northing + p.scale * (sin * offset.x + cos * offset.y),
                    height: p.height + p.scale * offset.z,
                    ..*p
                })
            }
        }
    }
}

/// The PROJ definition of EPSG `code`, or why it cannot be used.
fn projection(code: u16) -> Result<proj4rs::Proj, String> {
    let proj = proj4rs::Proj::from_epsg_code(code)
        .map_err(|e| format!("EPSG:{code} is not a CRS this build knows ({e})"))?;
    if proj.is_latlong() || proj.is_geocent() {
        return Err(format!(
            "EPSG:{code} is not a projected CRS: give latitude and longitude instead"
        ));
    }
    Ok(proj)
}

impl Projected {
    /// The origin's latitude and longitude, and the heading turned from
    /// grid north to true north by the meridian convergence there
    /// (measured: the bearing of a step north on the grid).
    fn on_earth(&self, code: u16) -> Result<Geographic, String> {
        let src = projection(code)?;
        let dst = proj4rs::Proj::from_epsg_code(4326).map_err(|e| e.to_string())?;
        let to_degrees = |e: f64, n: f64| -> Result<(f64, f64), String> {
            let mut p = (e, n, 0.0);
            proj4rs::transform::transform(&src, &dst, &mut p)
                .map_err(|err| format!("EPSG:{code}: ({e}, {n}) cannot be projected: {err}"))?;
            Ok((p.1.to_degrees(), p.0.to_degrees()))
        };
        let (latitude, longitude) = to_degrees(self.easting, self.northing)?;
        let (lat_n, lon_n) = to_degrees(self.easting, self.northing + 100.0)?;
        let origin = Geographic {
            latitude,
            longitude,
            height: self.height,
            heading: 0.0,
        };
        let step = origin.to_ecef().inverse().transform_point3(
            Geographic {
                latitude: lat_n,
                longitude: lon_n,
                ..origin
            }
            .origin_ecef(),
        );
        let convergence = step.x.atan2(step.y).to_degrees();
        Ok(Geographic {
            heading: self.heading + convergence,
            ..origin
        })
    }
}

impl Geographic {
    /// Checks the ranges; the message names the field.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let checks = [
            ("latitude", self.latitude, -90.0, 90.0),
            ("longitude", self.longitude, -180.0, 180.0),
            ("height", self.height, -1e5, 1e7),
            ("heading", self.heading, -360.0, 360.0),
        ];
        for (field, v, lo, hi) in checks {
            if !(lo..=hi).contains(&v) {
                return Err((field, format!("{v} is not within {lo}..{hi}")));
            }
        }
        Ok(())
    }

    /// The origin in ECEF metres.
    pub fn origin_ecef(&self) -> DVec3 {
        let (phi, lambda) = (self.latitude.to_radians(), self.longitude.to_radians());
        let e2 = F * (2.0 - F);
        let n = A / (1.0 - e2 * phi.sin().powi(2)).sqrt();
        DVec3::new(
            (n + self.height) * phi.cos() * lambda.cos(),
            (n + self.height) * phi.cos() * lambda.sin(),
            (n * (1.0 - e2) + self.height) * phi.sin(),
        )
    }

    /// The map from the scene's frame turned z-up (x east, y north, z up
    /// before the heading) to ECEF: the east-north-up frame at the origin,
    /// turned by the heading about its up axis.
    pub fn to_ecef(&self) -> DMat4 {
        let (phi, lambda) = (self.latitude.to_radians(), self.longitude.to_radians());
        let east = DVec3::new(-lambda.sin(), lambda.cos(), 0.0);
        let north = DVec3::new(
            -phi.sin() * lambda.cos(),
            -phi.sin() * lambda.sin(),
            phi.cos(),
        );
        let up = DVec3::new(
            phi.cos() * lambda.cos(),
            phi.cos() * lambda.sin(),
            phi.sin(),
        );
        let enu = DMat4::from_cols(
            east.extend(0.0),
            north.extend(0.0),
            up.extend(0.0),
            DVec4::from((self.origin_ecef(), 1.0)),
        );
        // Clockwise from north is a negative turn about up.
        enu * DMat4::from_rotation_z(-self.heading.to_radians())
    }
}

/// ECEF metres to latitude and longitude (degrees) and height above the
/// ellipsoid: Bowring's iteration on the reduced latitude, converged to
/// well under a micrometre in three steps anywhere near the surface.
fn geodetic(p: DVec3) -> (f64, f64, f64) {
    let e2 = F * (2.0 - F);
    let b = A * (1.0 - F);
    let ep2 = (A * A - b * b) / (b * b);
    let r = p.x.hypot(p.y);
    let lambda = p.y.atan2(p.x);
    let mut beta = (p.z * A).atan2(r * b);
    let mut phi = 0.0;
    for _ in 0..4 {
        phi = (p.z + ep2 * b * beta.sin().powi(3)).atan2(r - e2 * A * beta.cos().powi(3));
        beta = ((1.0 - F) * phi.tan()).atan();
    }
    let n = A / (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let h = if phi.cos().abs() > 1e-9 {
        r / phi.cos() - n
    } else {
        p.z.abs() - b
    };
    (phi.to_degrees(), lambda.to_degrees(), h)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(latitude: f64, longitude: f64, heading: f64) -> Geographic {
        Geographic {
            latitude,
            longitude,
            height: 0.0,
            heading,
        }
    }

    #[test]
    fn the_frame_at_null_island_and_at_the_pole() {
        let m = at(0.0, 0.0, 0.0).to_ecef();
        assert!(
            m.transform_point3(DVec3::ZERO)
                .abs_diff_eq(DVec3::new(A, 0.0, 0.0), 1e-6)
        );
        // East is +y, north +z, up +x in ECEF there.
        assert!(m.transform_vector3(DVec3::X).abs_diff_eq(DVec3::Y, 1e-12));
        assert!(m.transform_vector3(DVec3::Y).abs_diff_eq(DVec3::Z, 1e-12));
        assert!(m.transform_vector3(DVec3::Z).abs_diff_eq(DVec3::X, 1e-12));
        // The semi-minor axis at the pole.
        let b = A * (1.0 - F);
        let pole = at(90.0, 0.0, 0.0).origin_ecef();
        assert!(pole.abs_diff_eq(DVec3::new(0.0, 0.0, b), 1e-6), "{pole}");
    }

    #[test]
    fn a_heading_of_90_points_the_scenes_north_east() {
        let m = at(0.0, 0.0, 90.0).to_ecef();
        // The scene's north (+y turned z-up) is east (+y in ECEF here).
        assert!(m.transform_vector3(DVec3::Y).abs_diff_eq(DVec3::Y, 1e-12));
        assert!(m.transform_vector3(DVec3::X).abs_diff_eq(-DVec3::Z, 1e-12));
    }

    #[test]
    fn a_known_place() {
        // 52 N 4.36 E at 0 m, as PROJ converts it (pyproj, EPSG:4979 to
        // EPSG:4978): 3923572.9635, 299147.2452, 5002803.3455.
        let p = at(52.0, 4.36, 0.0).origin_ecef();
        let expected = DVec3::new(3_923_572.963_5, 299_147.245_2, 5_002_803.345_5);
        assert!(p.abs_diff_eq(expected, 1e-3), "{p}");
        assert!(at(91.0, 0.0, 0.0).validate().is_err());
    }

    #[test]
    fn ecef_back_to_geodetic() {
        for (lat, lon, h) in [
            (52.0, 4.36, 12.5),
            (-33.9, 151.2, -20.0),
            (89.9, -120.0, 3000.0),
        ] {
            let g = Geographic {
                latitude: lat,
                longitude: lon,
                height: h,
                heading: 0.0,
            };
            let (la, lo, he) = geodetic(g.origin_ecef());
            assert!(
                (la - lat).abs() < 1e-10 && (lo - lon).abs() < 1e-10,
                "{la} {lo}"
            );
            assert!((he - h).abs() < 1e-6, "{he}");
        }
    }

    #[test]
    fn a_projected_origin_lands_where_proj_puts_it() {
        // Rotterdam in RD New (EPSG:28992), as PROJ converts it (pyproj,
        // EPSG:28992 to EPSG:4326 with the towgs84 shift): 92,000 E
        // 437,000 N is about 51.92 N 4.48 E.
        let p = Georeference::Projected(Projected {
            crs: Some(28992),
            easting: 92_000.0,
            northing: 437_000.0,
            height: 0.0,
            heading: 0.0,
            scale: 1.0,
        });
        p.validate().unwrap();
        let g = p.geographic().unwrap().unwrap();
        assert!((g.latitude - 51.92).abs() < 0.01, "{g:?}");
        assert!((g.longitude - 4.48).abs() < 0.01, "{g:?}");
        // West of RD's central meridian (5.387 E) grid north lies west of
        // true north, by about (lon - lon0) sin(lat) = -0.71 degrees: the
        // scene's north, grid north, is 0.71 degrees anticlockwise.
        assert!((g.heading + 0.71).abs() < 0.05, "{}", g.heading);
        // UTM 31N: the same place, within a metre of where RD puts it.
        let utm = Georeference::Projected(Projected {
            crs: Some(32631),
            easting: 602_120.0,
            northing: 5_753_000.0,
            height: 0.0,
            heading: 0.0,
            scale: 1.0,
        });
        utm.geographic().unwrap().unwrap();
        let bad = Georeference::Projected(Projected {
            crs: Some(4326),
            ..match p {
                Georeference::Projected(p) => p,
                Georeference::Geographic(_) => unreachable!(),
            }
        });
        let (field, message) = bad.validate().unwrap_err();
        assert_eq!(field, "crs");
        assert!(message.contains("EPSG:4326"), "{message}");
    }

    #[test]
    fn moving_the_origin_keeps_every_point_in_place() {
        let offset = DVec3::new(1234.5, -678.25, 9.5);
        let p = Georeference::Projected(Projected {
            crs: None,
            easting: 1000.0,
            northing: 2000.0,
            height: 3.0,
            heading: 30.0,
            scale: 1.0,
        });
        let Georeference::Projected(q) = p.moved(offset) else {
            unreachable!()
        };
        // The grid is turned 30 degrees clockwise from the scene: the
        // scene's x axis points to 120 degrees on the grid.
        let turn = -30f64.to_radians();
        let e = 1000.0 + turn.cos() * offset.x - turn.sin() * offset.y;
        assert!((q.easting - e).abs() < 1e-9);
        assert!((q.height - 12.5).abs() < 1e-12);
        let g = Georeference::Geographic(at(51.9, 4.48, 20.0));
        let moved = g.moved(offset);
        let before = g.to_ecef().unwrap().unwrap().transform_point3(offset);
        let after = moved
            .to_ecef()
            .unwrap()
            .unwrap()
            .transform_point3(DVec3::ZERO);
        assert!(before.distance(after) < 1e-6, "{}", before.distance(after));
    }

    #[test]
    fn the_json_forms() {
        let g: Georeference =
            serde_json::from_str(r#"{"crs": "EPSG:28992", "easting": 1, "northing": 2}"#).unwrap();
        assert!(matches!(
            g,
            Georeference::Projected(Projected {
                crs: Some(28992),
                ..
            })
        ));
        let back = serde_json::to_value(g).unwrap();
        assert_eq!(back["crs"], "EPSG:28992");
        for bad in [
            r#"{"latitude": 1, "easting": 2, "northing": 3}"#,
            r#"{"latitude": 1}"#,
            r#"{"easting": 1, "northing": 2, "crs": "RD"}"#,
            r#"{"height": 1}"#,
        ] {
            assert!(serde_json::from_str::<Georeference>(bad).is_err(), "{bad}");
        }
    }
}
