//! The view of a cut: the camera's frustum planes, its eye and the angle `r`
//! of one pixel-error budget (docs/method.md section 4).
//!
//! A camera is given either by position, target, up, vertical field of view,
//! aspect, near and far, or by a column-major 4x4 view-projection matrix
//! (clip = M * world, as WebGL and three.js store them). Frustum planes are
//! taken from the matrix rows (Gribb and Hartmann, "Fast extraction of
//! viewing frustum planes from the world-view-projection matrix", 2001).
//! The near plane is tested as `w + z >= 0` (the OpenGL depth range), which
//! is the looser test for matrices with a `[0, w]` depth range too: it never
//! culls anything in front of the near plane.
//!
//! For a matrix `M = P * V` with a perspective `P` and a rigid `V`, row 1 of
//! `M` is `f * (row 1 of V)` and row 3 is `-(row 2 of V)`, with
//! `f = 1 / tan(fov_y / 2)`; so `tan(fov_y / 2) = |row3.xyz| / |row1.xyz|`,
//! independent of any uniform scale of `M`. The eye is the point that `M`
//! sends to `x = y = w = 0`: `M^-1 * (0, 0, 1, 0)`, dehomogenised.

use glam::{DMat4, DVec3, DVec4};
use serde::{Deserialize, Serialize};

use super::Aabb;
use crate::error::{Error, Result};

/// A camera as a request or a file gives it; every field is checked by
/// [`View::new`], which names the field at fault.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<[f64; 3]>,
    /// Defaults to the scene's up axis.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
    /// Defaults to 60 degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fov_y_deg: Option<f64>,
    /// Defaults to the viewport's width / height.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub aspect: Option<f64>,
    /// Defaults to 0.1.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub near: Option<f64>,
    /// Without it there is no far plane.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub far: Option<f64>,
    /// 16 numbers, column-major; excludes every other field.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub view_projection: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Viewport {
    pub width: u32,
    pub height: u32,
}

impl Default for Viewport {
    fn default() -> Self {
        Viewport {
            width: 1920,
            height: 1080,
        }
    }
}

pub const DEFAULT_FOV_Y_DEG: f64 = 60.0;
pub const DEFAULT_NEAR: f64 = 0.1;

/// The bounds of a camera given by position and target. Past them the
/// view-projection matrix loses its precision or overflows, and the
/// failure would surface at the matrix, which the request did not send:
/// each bound names the field that crossed it. A site is kilometres wide;
/// these leave room for any georeferenced scene.
pub const MAX_COORDINATE: f64 = 1e12;
pub const MIN_FOV_Y_DEG: f64 = 1e-4;
pub const MIN_NEAR: f64 = 1e-6;
/// The far plane at most this many times the near one.
pub const MAX_FAR_OVER_NEAR: f64 = 1e12;

/// What the cut needs of a camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    planes: [DVec4; 6],
    plane_count: usize,
    eye: DVec3,
    r: f64,
}

fn finite3(at: &str, v: [f64; 3]) -> Result<DVec3> {
    let v = DVec3::from_array(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::argument(at, "must be three finite numbers"))
    }
}

/// A point of the camera: finite and within [`MAX_COORDINATE`].
fn point(at: &str, v: [f64; 3]) -> Result<DVec3> {
    let v = finite3(at, v)?;
    if v.abs().max_element() > MAX_COORDINATE {
        return Err(Error::argument(
            at,
            format!("must be within {MAX_COORDINATE:e} of the origin on each axis"),
        ));
    }
    Ok(v)
}

impl View {
    /// `default_up` is the scene's up axis, used when the camera has none.
    pub fn new(
        camera: &CameraSpec,
        viewport: Viewport,
        pixel_error: f64,
        default_up: DVec3,
    ) -> Result<View> {
        if viewport.width == 0 {
            return Err(Error::argument("viewport.width", "must be at least 1"));
        }
        if viewport.height == 0 {
            return Err(Error::argument("viewport.height", "must be at least 1"));
        }
        if !(pixel_error.is_finite() && pixel_error > 0.0) {
            return Err(Error::argument(
                "pixel_error",
                "must be a finite number > 0",
            ));
        }
        let (m, tan_half_fov, use_far) = match &camera.view_projection {
            Some(vp) => {
                let others = [
                    ("position", camera.position.is_some()),
                    ("target", camera.target.is_some()),
                    ("up", camera.up.is_some()),
                    ("fov_y_deg", camera.fov_y_deg.is_some()),
                    ("aspect", camera.aspect.is_some()),
                    ("near", camera.near.is_some()),
                    ("far", camera.far.is_some()),
                ];
                if let Some((name, _)) = others.iter().find(|(_, set)| *set) {
                    return Err(Error::argument(
                        format!("camera.{name}"),
                        "not allowed together with camera.view_projection",
                    ));
                }
                let at = "camera.view_projection";
                if vp.len() != 16 || vp.iter().any(|x| !x.is_finite()) {
                    return Err(Error::argument(at, "must be 16 finite numbers"));
                }
                let m = DMat4::from_cols_slice(vp);
                let row1 = m.row(1).truncate().length();
                let row3 = m.row(3).truncate().length();
                if m.determinant().abs() < 1e-300 || row1 < 1e-300 || row3 < 1e-12 * row1 {
                    return Err(Error::argument(
                        at,
                        "not an invertible perspective view-projection matrix",
                    ));
                }
                (m, row3 / row1, true)
            }
            None => {
                let position = point(
                    "camera.position",
                    camera.position.ok_or_else(|| {
                        Error::argument(
                            "camera.position",
                            "is required (or camera.view_projection)",
                        )
                    })?,
                )?;
                let target = point(
                    "camera.target",
                    camera.target.ok_or_else(|| {
                        Error::argument("camera.target", "is required (or camera.view_projection)")
                    })?,
                )?;
                let up = match camera.up {
                    // Only its direction matters: scaled to its largest
                    // component first, its length cannot overflow.
                    Some(u) => {
                        let u = finite3("camera.up", u)?;
                        let largest = u.abs().max_element();
                        if largest > 0.0 { u / largest } else { u }
                    }
                    None => default_up,
                };
                let dir = target - position;
                if dir.length() < 1e-12 {
                    return Err(Error::argument(
                        "camera.target",
                        "must differ from camera.position",
                    ));
                }
                if up.length() < 1e-12 || dir.normalize().cross(up.normalize()).length() < 1e-9 {
                    return Err(Error::argument(
                        "camera.up",
                        "must be non-zero and not along the view direction",
                    ));
                }
                let fov = camera.fov_y_deg.unwrap_or(DEFAULT_FOV_Y_DEG);
                if !(fov.is_finite() && (MIN_FOV_Y_DEG..180.0).contains(&fov)) {
                    return Err(Error::argument(
                        "camera.fov_y_deg",
                        format!("must be in (0, 180) degrees, at least {MIN_FOV_Y_DEG:e}"),
                    ));
                }
                let aspect = camera
                    .aspect
                    .unwrap_or(f64::from(viewport.width) / f64::from(viewport.height));
                if !(aspect.is_finite() && aspect > 0.0) {
                    return Err(Error::argument(
                        "camera.aspect",
                        "must be a finite number > 0",
                    ));
                }
                let near = camera.near.unwrap_or(DEFAULT_NEAR);
                if !(near.is_finite() && (MIN_NEAR..=MAX_COORDINATE).contains(&near)) {
                    return Err(Error::argument(
                        "camera.near",
                        format!("must be a number from {MIN_NEAR:e} to {MAX_COORDINATE:e}"),
                    ));
                }
                // Without a far plane the matrix still needs one; its plane is
                // simply not tested.
                let far = camera.far.unwrap_or(near * 2.0);
                if !(far.is_finite() && far > near && far <= near * MAX_FAR_OVER_NEAR) {
                    return Err(Error::argument(
                        "camera.far",
                        format!(
                            "must be a finite number > camera.near and at most \
                             {MAX_FAR_OVER_NEAR:e} times it"
                        ),
                    ));
                }
                let fov = fov.to_radians();
                let m = glam::dcamera::rh::proj::opengl::perspective(fov, aspect, near, far)
                    * glam::dcamera::rh::view::look_at_mat4(position, target, up.normalize());
                (m, (fov / 2.0).tan(), camera.far.is_some())
            }
        };
        let eye = m.inverse() * DVec4::new(0.0, 0.0, 1.0, 0.0);
        if eye.w.abs() < 1e-300 || !eye.is_finite() {
            // Within the bounds above a position camera always has an eye;
            // should one not, the camera as a whole is at fault, not a
            // matrix the request did not send.
            let at = match camera.view_projection {
                Some(_) => "camera.view_projection",
                None => "camera",
            };
            return Err(Error::argument(
                at,
                "not a perspective projection (no eye point)",
            ));
        }
        let eye = eye.truncate() / eye.w;
        let (r0, r1, r2, r3) = (m.row(0), m.row(1), m.row(2), m.row(3));
        let planes = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r3 + r2, r3 - r2];
        Ok(View {
            planes,
            plane_count: if use_far { 6 } else { 5 },
            eye,
            r: pixel_error * 2.0 * tan_half_fov / f64::from(viewport.height),
        })
    }

    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// The angle (radians) of the pixel-error budget: a cluster is fine when
    /// `delta_c(t) / distance < r`.
    pub fn r(&self) -> f64 {
        self.r
    }

    /// True when the box lies wholly outside one of the frustum planes (the
    /// usual conservative test: a box near a corner may pass while outside).
    #[inline]
    pub fn outside(&self, b: &Aabb) -> bool {
        self.planes[..self.plane_count].iter().any(|p| {
            let n = p.truncate();
            let far_corner = DVec3::select(n.cmpge(DVec3::ZERO), b.max, b.min);
            n.dot(far_corner) + p.w < 0.0
        })
    }

    /// Distance from the eye to the nearest point of the box (0 inside).
    #[inline]
    pub fn distance(&self, b: &Aabb) -> f64 {
        (self.eye.clamp(b.min, b.max) - self.eye).length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn look(position: [f64; 3], target: [f64; 3]) -> CameraSpec {
        CameraSpec {
            position: Some(position),
            target: Some(target),
            far: Some(1000.0),
            ..Default::default()
        }
    }

    #[test]
    fn matrix_and_look_at_agree() {
        let vp = Viewport {
            width: 800,
            height: 600,
        };
        let a = View::new(&look([1.0, 2.0, 30.0], [0.0, 0.0, 0.0]), vp, 2.0, DVec3::Y).unwrap();
        let m = glam::dcamera::rh::proj::opengl::perspective(
            60f64.to_radians(),
            800.0 / 600.0,
            0.1,
            1000.0,
        ) * glam::dcamera::rh::view::look_at_mat4(
            DVec3::new(1.0, 2.0, 30.0),
            DVec3::ZERO,
            DVec3::Y,
        );
        // A uniform scale of the matrix changes nothing.
        let cols = (m * 3.0).to_cols_array().to_vec();
        let spec = CameraSpec {
            view_projection: Some(cols),
            ..Default::default()
        };
        let b = View::new(&spec, vp, 2.0, DVec3::Y).unwrap();
        assert!(a.eye().abs_diff_eq(DVec3::new(1.0, 2.0, 30.0), 1e-9));
        assert!(b.eye().abs_diff_eq(a.eye(), 1e-6));
        assert!((a.r() - b.r()).abs() < 1e-12);
        assert!((a.r() - 2.0 * 2.0 * 30f64.to_radians().tan() / 600.0).abs() < 1e-12);
    }

    #[test]
    fn culls_and_measures() {
        let v = View::new(
            &look([0.0, 0.0, 10.0], [0.0, 0.0, 0.0]),
            Viewport::default(),
            1.0,
            DVec3::Y,
        )
        .unwrap();
        let unit = |c: DVec3| Aabb::new(c - 0.5, c + 0.5);
        assert!(!v.outside(&unit(DVec3::ZERO)));
        assert!(
            v.outside(&unit(DVec3::new(0.0, 0.0, 20.0))),
            "behind the eye"
        );
        assert!(
            v.outside(&unit(DVec3::new(50.0, 0.0, 0.0))),
            "far to the right"
        );
        assert!(
            v.outside(&unit(DVec3::new(0.0, 0.0, -2000.0))),
            "beyond far"
        );
        assert!((v.distance(&unit(DVec3::ZERO)) - 9.5).abs() < 1e-12);
        assert_eq!(v.distance(&unit(DVec3::new(0.0, 0.0, 10.0))), 0.0);
    }

    #[test]
    fn names_the_bad_field() {
        let vp = Viewport::default();
        let err = |c: CameraSpec| View::new(&c, vp, 1.0, DVec3::Y).unwrap_err().to_string();
        assert!(err(CameraSpec::default()).starts_with("camera.position"));
        let mut c = look([0.0; 3], [0.0, 0.0, -1.0]);
        c.fov_y_deg = Some(200.0);
        assert!(err(c).starts_with("camera.fov_y_deg"));
        let mut c = look([0.0; 3], [0.0, 0.0, -1.0]);
        c.far = Some(0.01);
        assert!(err(c).starts_with("camera.far"));
        assert!(err(look([0.0; 3], [0.0; 3])).starts_with("camera.target"));
        let c = CameraSpec {
            view_projection: Some(vec![1.0; 15]),
            ..Default::default()
        };
        assert!(err(c).starts_with("camera.view_projection"));
        let c = CameraSpec {
            view_projection: Some(vec![0.0; 16]),
            ..Default::default()
        };
        assert!(err(c).starts_with("camera.view_projection"));
        let e = View::new(&look([0.0; 3], [0.0, 0.0, -1.0]), vp, -1.0, DVec3::Y).unwrap_err();
        assert!(e.to_string().starts_with("pixel_error"));
    }
}
