//! Where a scene is on Earth: its local origin's latitude, longitude and
//! height on the WGS 84 ellipsoid and the heading of its north axis, and
//! the transform from the local east-north-up frame there to Earth-centred,
//! Earth-fixed (ECEF) coordinates, which 3D Tiles clients (CesiumJS,
//! cesium-native) expect of a georeferenced tileset.
//!
//! Reference: NIMA TR8350.2, "Department of Defense World Geodetic System
//! 1984" (the ellipsoid's constants, geodetic to ECEF); the east-north-up
//! axes as in CesiumJS's `Transforms.eastNorthUpToFixedFrame`.

use glam::{DMat4, DVec3, DVec4};
use serde::{Deserialize, Serialize};

/// WGS 84 semi-major axis, metres.
const A: f64 = 6_378_137.0;
/// WGS 84 flattening.
const F: f64 = 1.0 / 298.257_223_563;

/// The scene's place on Earth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Georeference {
    /// Of the local origin, degrees north (WGS 84).
    pub latitude: f64,
    /// Degrees east.
    pub longitude: f64,
    /// Metres above the ellipsoid.
    #[serde(default)]
    pub height: f64,
    /// Degrees clockwise from true north to the scene's north: its `-z`
    /// axis when y is up, its `y` axis when z is up.
    #[serde(default)]
    pub heading: f64,
}

impl Georeference {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn at(latitude: f64, longitude: f64, heading: f64) -> Georeference {
        Georeference {
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
}
