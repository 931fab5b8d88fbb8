//! Cut requests (`schemas/api/cut-request.schema.json`) from a JSON body
//! (`POST .../cut`, the stream's messages), from query pairs (`GET
//! .../cut`) or from `hdlod cut`'s flags, and their preparation: the
//! request's time and view, checked against the tree.

use glam::DVec3;
use hdlod::input::quote;
use hdlod::scene::Up;
use hdlod::time::TimeValue;
use hdlod::tree::cut::{Lod, Presence};
use hdlod::tree::{CameraSpec, Tree, View, Viewport};
use serde::{Deserialize, Serialize};

use super::ProtocolError;

/// Dates are computed in milliseconds; times are kept far from their
/// overflow.
const MAX_SECONDS: f64 = 1e12;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutRequest {
    /// ISO 8601 or seconds since the scene's start.
    pub time: TimeValue,
    pub camera: CameraSpec,
    #[serde(default)]
    pub viewport: Viewport,
    #[serde(default = "one")]
    pub pixel_error: f64,
    /// `paper` (the default: clusters with `v_c(t) >= 0.5`) or `exact`
    /// (every cluster with `v_c(t) > 0`; the client hides absent features).
    #[serde(default)]
    pub presence: Presence,
    /// `hdlod` (the default: the cut) or `none` (every present leaf at full
    /// detail, in view or not: drawing without levels of detail).
    #[serde(default)]
    pub lod: Lod,
}

/// `hdlod` or `none`; `field` names it in errors.
pub fn parse_lod(field: &str, text: &str) -> Result<Lod, ProtocolError> {
    match text.trim() {
        "hdlod" => Ok(Lod::Hdlod),
        "none" => Ok(Lod::None),
        other => Err(ProtocolError::new(
            field,
            format!("{} is neither hdlod nor none", quote(other)),
        )),
    }
}

/// `paper` or `exact`; `field` names it in errors.
pub fn parse_presence(field: &str, text: &str) -> Result<Presence, ProtocolError> {
    match text.trim() {
        "paper" => Ok(Presence::Paper),
        "exact" => Ok(Presence::Exact),
        other => Err(ProtocolError::new(
            field,
            format!("{} is not a presence rule (paper or exact)", quote(other)),
        )),
    }
}

fn one() -> f64 {
    1.0
}

pub fn parse_json(bytes: &[u8]) -> Result<CutRequest, ProtocolError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let request: CutRequest =
        serde_path_to_error::deserialize(&mut de).map_err(ProtocolError::from_json)?;
    de.end()
        .map_err(|e| ProtocolError::new("body", e.to_string()))?;
    Ok(request)
}

fn numbers(name: &str, text: &str, count: usize) -> Result<Vec<f64>, ProtocolError> {
    let values: Result<Vec<f64>, _> = text.split(',').map(|x| x.trim().parse::<f64>()).collect();
    match values {
        Ok(v) if v.len() == count => Ok(v),
        _ => Err(ProtocolError::new(
            name,
            format!("must be {count} comma-separated numbers"),
        )),
    }
}

fn vec3(name: &str, text: &str) -> Result<[f64; 3], ProtocolError> {
    let v = numbers(name, text, 3)?;
    Ok([v[0], v[1], v[2]])
}

fn number(name: &str, text: &str) -> Result<f64, ProtocolError> {
    text.trim()
        .parse()
        .map_err(|_| ProtocolError::new(name, format!("{} is not a number", quote(text))))
}

fn dimension(name: &str, text: &str) -> Result<u32, ProtocolError> {
    text.trim().parse().map_err(|_| {
        ProtocolError::new(name, format!("{} is not a whole number >= 0", quote(text)))
    })
}

/// A `WxH` size such as `1920x1080`.
fn parse_viewport(name: &str, text: &str) -> Result<Viewport, ProtocolError> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| ProtocolError::new(name, format!("{} is not WIDTHxHEIGHT", quote(text))))?;
    Ok(Viewport {
        width: dimension(&format!("{name}.width"), w)?,
        height: dimension(&format!("{name}.height"), h)?,
    })
}

/// A time given as text: a number is seconds, anything else an ISO 8601 date.
pub fn parse_time(text: &str) -> TimeValue {
    match text.trim().parse::<f64>() {
        Ok(s) => TimeValue::Seconds(s),
        Err(_) => TimeValue::Iso(text.to_owned()),
    }
}

/// The query parameters of `GET .../cut`: `time`, `position`, `target`,
/// `up` (`x,y,z`), `fov_y_deg`, `aspect`, `near`, `far`, `view_projection`
/// (16 numbers), `viewport` (`WxH`) or `width` and `height`, `pixel_error`,
/// `presence`, `lod`.
pub fn parse_query(pairs: &[(String, String)]) -> Result<CutRequest, ProtocolError> {
    let mut time = None;
    let mut camera = CameraSpec::default();
    let mut viewport = Viewport::default();
    let mut pixel_error = 1.0;
    let mut presence = Presence::default();
    let mut lod = Lod::default();
    for (key, value) in pairs {
        let k = key.as_str();
        match k {
            "time" => time = Some(parse_time(value)),
            "position" => camera.position = Some(vec3(k, value)?),
            "target" => camera.target = Some(vec3(k, value)?),
            "up" => camera.up = Some(vec3(k, value)?),
            "fov_y_deg" => camera.fov_y_deg = Some(number(k, value)?),
            "aspect" => camera.aspect = Some(number(k, value)?),
            "near" => camera.near = Some(number(k, value)?),
            "far" => camera.far = Some(number(k, value)?),
            "view_projection" => camera.view_projection = Some(numbers(k, value, 16)?),
            "viewport" => viewport = parse_viewport(k, value)?,
            "width" => viewport.width = dimension(k, value)?,
            "height" => viewport.height = dimension(k, value)?,
            "pixel_error" => pixel_error = number(k, value)?,
            "presence" => presence = parse_presence(k, value)?,
            "lod" => lod = parse_lod(k, value)?,
            _ => return Err(ProtocolError::new(k, "unknown query parameter")),
        }
    }
    Ok(CutRequest {
        time: time.ok_or_else(|| ProtocolError::new("time", "is required"))?,
        camera,
        viewport,
        pixel_error,
        presence,
        lod,
    })
}

/// A query whose one parameter is `time` (the tiles' `tileset.json`).
pub fn parse_time_query(pairs: &[(String, String)]) -> Result<TimeValue, ProtocolError> {
    let mut time = None;
    for (key, value) in pairs {
        match key.as_str() {
            "time" => time = Some(parse_time(value)),
            other => return Err(ProtocolError::new(other, "unknown query parameter")),
        }
    }
    time.ok_or_else(|| ProtocolError::new("time", "is required"))
}

/// The flags of `hdlod cut`. `camera` is the whole camera when given
/// (`--camera-json`, which excludes the other camera flags); otherwise the
/// camera is `position`, `target` and `up` as `x,y,z` text, named in errors
/// as the query names them, and `fov_y_deg`.
pub struct Flags<'a> {
    pub time: &'a str,
    pub camera: Option<CameraSpec>,
    pub position: Option<&'a str>,
    pub target: Option<&'a str>,
    pub up: Option<&'a str>,
    pub fov_y_deg: Option<f64>,
    /// `WxH`, named `--viewport` in errors.
    pub viewport: &'a str,
    pub pixel_error: f64,
    /// Named `--presence` in errors.
    pub presence: &'a str,
    /// Named `--lod` in errors.
    pub lod: &'a str,
}

pub fn parse_flags(flags: Flags) -> Result<CutRequest, ProtocolError> {
    let point = |name, text: Option<&str>| text.map(|t| vec3(name, t)).transpose();
    let camera = match flags.camera {
        Some(camera) => camera,
        None => CameraSpec {
            position: point("position", flags.position)?,
            target: point("target", flags.target)?,
            up: point("up", flags.up)?,
            fov_y_deg: flags.fov_y_deg,
            ..CameraSpec::default()
        },
    };
    Ok(CutRequest {
        time: parse_time(flags.time),
        camera,
        viewport: parse_viewport("--viewport", flags.viewport)?,
        pixel_error: flags.pixel_error,
        presence: parse_presence("--presence", flags.presence)?,
        lod: parse_lod("--lod", flags.lod)?,
    })
}

/// `time` in seconds since the scene's start, checked by
/// [`within_period`]; `field` names it in errors.
pub fn resolve_time(tree: &Tree, field: &str, time: &TimeValue) -> Result<f64, ProtocolError> {
    let t = tree
        .time
        .resolve(time)
        .map_err(|m| ProtocolError::new(field, m.to_string()))?;
    within_period(field, t)
}

/// `t` if its date can be written, else an error naming `field`.
pub fn within_period(field: &str, t: f64) -> Result<f64, ProtocolError> {
    if t.abs() > MAX_SECONDS {
        return Err(ProtocolError::new(
            field,
            "is too far from the scene's period",
        ));
    }
    Ok(t)
}

pub(super) fn up_vector(up: Up) -> DVec3 {
    match up {
        Up::Y => DVec3::Y,
        Up::Z => DVec3::Z,
    }
}

/// The view and time of a request, checked against the tree.
pub fn prepare(tree: &Tree, request: &CutRequest) -> Result<(View, f64), ProtocolError> {
    let t = resolve_time(tree, "time", &request.time)?;
    let view = View::new(
        &request.camera,
        request.viewport,
        request.pixel_error,
        up_vector(tree.up),
    )?;
    Ok((view, t))
}
