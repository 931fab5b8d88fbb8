//! Cut requests and answers (`schemas/api/cut-request.schema.json`,
//! `cut-response.schema.json`), shared by `POST`/`GET .../cut`, the
//! WebSocket stream and `hdlod cut`. The HDLOD work is `hdlod::tree::cut`.

use std::time::Instant;

use glam::DVec3;
use hdlod::scene::Up;
use hdlod::time::{TimeValue, format_date};
use hdlod::tree::cut::cut_into;
use hdlod::tree::{Baseline, CameraSpec, Cut, Tree, View, Viewport};
use serde::{Deserialize, Serialize};

use super::error::ApiError;

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
}

fn one() -> f64 {
    1.0
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClusterOut {
    pub id: u32,
    pub class: &'static str,
    pub level: u32,
    /// The geometry's URL path (content-addressed, immutable).
    pub geometry: String,
    /// Column-major 4x4 pose at the requested time (dynamic clusters).
    pub transform: Option<[f32; 16]>,
    pub triangles: u64,
    /// `delta_c(t)` in world units.
    pub error: f64,
    /// `v_c(t)`.
    pub visibility: f32,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StatsOut {
    pub clusters: usize,
    pub triangles: u64,
    pub visited: usize,
    pub micros: f64,
    /// Every original object present at the time, at full detail.
    pub baseline_triangles: u64,
    pub baseline_objects: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CutResponse {
    /// Seconds since the scene's start.
    pub time: f64,
    /// The same instant as an ISO 8601 date.
    pub date: String,
    pub clusters: Vec<ClusterOut>,
    pub stats: StatsOut,
}

pub fn parse_json(bytes: &[u8]) -> Result<CutRequest, ApiError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let request: CutRequest =
        serde_path_to_error::deserialize(&mut de).map_err(ApiError::from_json)?;
    de.end().map_err(|e| ApiError::bad("body", e.to_string()))?;
    Ok(request)
}

fn numbers(name: &str, text: &str, count: usize) -> Result<Vec<f64>, ApiError> {
    let values: Result<Vec<f64>, _> = text.split(',').map(|x| x.trim().parse::<f64>()).collect();
    match values {
        Ok(v) if v.len() == count => Ok(v),
        _ => Err(ApiError::bad(
            name,
            format!("must be {count} comma-separated numbers"),
        )),
    }
}

fn vec3(name: &str, text: &str) -> Result<[f64; 3], ApiError> {
    let v = numbers(name, text, 3)?;
    Ok([v[0], v[1], v[2]])
}

fn number(name: &str, text: &str) -> Result<f64, ApiError> {
    text.trim()
        .parse()
        .map_err(|_| ApiError::bad(name, format!("{text:?} is not a number")))
}

fn dimension(name: &str, text: &str) -> Result<u32, ApiError> {
    text.trim()
        .parse()
        .map_err(|_| ApiError::bad(name, format!("{text:?} is not a whole number >= 0")))
}

/// A `WxH` size such as `1920x1080`.
pub fn parse_viewport(name: &str, text: &str) -> Result<Viewport, ApiError> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| ApiError::bad(name, format!("{text:?} is not WIDTHxHEIGHT")))?;
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
/// (16 numbers), `viewport` (`WxH`) or `width` and `height`, `pixel_error`.
pub fn parse_query(pairs: &[(String, String)]) -> Result<CutRequest, ApiError> {
    let mut time = None;
    let mut camera = CameraSpec::default();
    let mut viewport = Viewport::default();
    let mut pixel_error = 1.0;
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
            _ => return Err(ApiError::bad(k, "unknown query parameter")),
        }
    }
    Ok(CutRequest {
        time: time.ok_or_else(|| ApiError::bad("time", "is required"))?,
        camera,
        viewport,
        pixel_error,
    })
}

pub fn up_vector(up: Up) -> DVec3 {
    match up {
        Up::Y => DVec3::Y,
        Up::Z => DVec3::Z,
    }
}

/// The view and time of a request, checked against the tree.
pub fn prepare(tree: &Tree, request: &CutRequest) -> Result<(View, f64), ApiError> {
    let t = tree
        .time
        .resolve(&request.time)
        .map_err(|m| ApiError::bad("time", m))?;
    // Dates are computed in milliseconds; keep far from their overflow.
    if t.abs() > 1e12 {
        return Err(ApiError::bad("time", "is too far from the scene's period"));
    }
    let view = View::new(
        &request.camera,
        request.viewport,
        request.pixel_error,
        up_vector(tree.up),
    )?;
    Ok((view, t))
}

/// Runs the cut into reused buffers and returns its duration in microseconds.
pub fn run(tree: &Tree, view: &View, t: f64, cut: &mut Cut, stack: &mut Vec<u32>) -> f64 {
    let start = Instant::now();
    cut_into(tree, view, t, cut, stack);
    start.elapsed().as_secs_f64() * 1e6
}

/// URL path prefix of a scene, its name percent-encoded.
pub fn scene_path(scene: &str) -> String {
    // RFC 3986 unreserved characters stay as they are.
    const SEGMENT: &percent_encoding::AsciiSet = &percent_encoding::NON_ALPHANUMERIC
        .remove(b'-')
        .remove(b'_')
        .remove(b'.')
        .remove(b'~');
    let name = percent_encoding::utf8_percent_encode(scene, SEGMENT);
    format!("/api/v1/scenes/{name}")
}

pub fn cluster_out(tree: &Tree, prefix: &str, item: &hdlod::tree::CutItem) -> ClusterOut {
    let c = &tree.clusters[item.id as usize];
    ClusterOut {
        id: c.id,
        class: c.class.name(),
        level: c.level,
        geometry: format!(
            "{prefix}/geometry/{}.glb",
            c.geometry.as_deref().unwrap_or_default()
        ),
        transform: item.transform.map(|m| m.to_cols_array()),
        triangles: c.triangles,
        error: item.error,
        visibility: item.visibility,
    }
}

pub fn response(tree: &Tree, baseline: &Baseline, t: f64, cut: &Cut, micros: f64) -> CutResponse {
    let (baseline_triangles, baseline_objects) = baseline.at(t);
    let prefix = scene_path(&tree.scene);
    CutResponse {
        time: t,
        date: format_date(tree.time.date_at(t)),
        clusters: cut
            .items
            .iter()
            .map(|i| cluster_out(tree, &prefix, i))
            .collect(),
        stats: StatsOut {
            clusters: cut.stats.clusters,
            triangles: cut.stats.triangles,
            visited: cut.stats.visited,
            micros,
            baseline_triangles,
            baseline_objects,
        },
    }
}

/// The whole request: check, cut, answer.
pub fn answer(
    tree: &Tree,
    baseline: &Baseline,
    request: &CutRequest,
) -> Result<CutResponse, ApiError> {
    let (view, t) = prepare(tree, request)?;
    let (mut cut, mut stack) = (Cut::default(), Vec::new());
    let micros = run(tree, &view, t, &mut cut, &mut stack);
    Ok(response(tree, baseline, t, &cut, micros))
}
