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

/// Borrows from the tree: an answer of thousands of clusters allocates
/// nothing per cluster.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClusterOut<'a> {
    pub id: u32,
    pub class: &'static str,
    pub level: u32,
    /// The geometry's URL path (content-addressed, immutable).
    pub geometry: GeometryUrl<'a>,
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

/// `/api/v1/scenes/{scene}/geometry/{hash}.glb`, written out only when
/// serialised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeometryUrl<'a> {
    pub scene: &'a str,
    pub hash: &'a str,
}

impl std::fmt::Display for GeometryUrl<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = percent_encoding::utf8_percent_encode(self.scene, SEGMENT);
        write!(f, "/api/v1/scenes/{name}/geometry/{}.glb", self.hash)
    }
}

impl Serialize for GeometryUrl<'_> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CutResponse<'a> {
    /// Seconds since the scene's start.
    pub time: f64,
    /// The same instant as an ISO 8601 date.
    pub date: String,
    pub clusters: Vec<ClusterOut<'a>>,
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

/// What a scene name keeps unencoded in a URL path: RFC 3986's
/// unreserved characters.
const SEGMENT: &percent_encoding::AsciiSet = &percent_encoding::NON_ALPHANUMERIC
    .remove(b'-')
    .remove(b'_')
    .remove(b'.')
    .remove(b'~');

/// URL path prefix of a scene, its name percent-encoded.
pub fn scene_path(scene: &str) -> String {
    let name = percent_encoding::utf8_percent_encode(scene, SEGMENT);
    format!("/api/v1/scenes/{name}")
}

pub fn cluster_out<'a>(tree: &'a Tree, item: &hdlod::tree::CutItem) -> ClusterOut<'a> {
    let c = &tree.clusters[item.id as usize];
    ClusterOut {
        id: c.id,
        class: c.class.name(),
        level: c.level,
        geometry: GeometryUrl {
            scene: &tree.scene,
            hash: c.geometry.as_deref().unwrap_or_default(),
        },
        transform: item.transform.map(|m| m.to_cols_array()),
        triangles: c.triangles,
        error: item.error,
        visibility: item.visibility,
    }
}

pub fn response<'a>(
    tree: &'a Tree,
    baseline: &Baseline,
    t: f64,
    cut: &Cut,
    micros: f64,
) -> CutResponse<'a> {
    CutResponse {
        time: t,
        date: format_date(tree.time.date_at(t)),
        clusters: cut.items.iter().map(|i| cluster_out(tree, i)).collect(),
        stats: stats_out(cut, micros, baseline, t),
    }
}

/// Each cluster's JSON in a cut answer up to its transform, and from its
/// triangle count to its error, made once per loaded tree: an answer is
/// then mostly copies, with only the transform, error and visibility
/// written per request (thousands of clusters per answer).
pub struct Fragments {
    text: String,
    /// Per cluster: where its head starts, its tail starts and ends.
    spans: Vec<(u32, u32, u32)>,
}

impl Fragments {
    pub fn of(tree: &Tree) -> Fragments {
        let mut text = String::new();
        let mut spans = Vec::with_capacity(tree.clusters.len());
        let mut head = Vec::new();
        for c in &tree.clusters {
            let item = hdlod::tree::CutItem {
                id: c.id,
                transform: None,
                visibility: 0.0,
                error: 0.0,
            };
            let out = cluster_out(tree, &item);
            head.clear();
            serde_json::to_writer(&mut head, &out).expect("plain data serialises");
            let json = std::str::from_utf8(&head).expect("JSON is UTF-8");
            // The serialised cluster is `HEAD null,"triangles":N,"error":
            // 0.0,"visibility":0.0}`: keep the parts around the numbers.
            let (before, after) = json
                .split_once("null,")
                .expect("a cluster without transform serialises it as null");
            let tail = &after[..after.find("0.0,").expect("the error is 0.0")];
            let start = text.len() as u32;
            text.push_str(before);
            let middle = text.len() as u32;
            text.push(',');
            text.push_str(tail);
            spans.push((start, middle, text.len() as u32));
        }
        Fragments { text, spans }
    }

    /// The JSON of `cluster_out(tree, item)`, byte for byte.
    pub fn write_cluster(&self, item: &hdlod::tree::CutItem, out: &mut Vec<u8>) {
        let (start, middle, end) = self.spans[item.id as usize];
        let text = self.text.as_bytes();
        out.extend_from_slice(&text[start as usize..middle as usize]);
        write_transform(out, item.transform.map(|m| m.to_cols_array()).as_ref());
        out.extend_from_slice(&text[middle as usize..end as usize]);
        write_number(out, &item.error);
        out.extend_from_slice(b",\"visibility\":");
        write_number(out, &item.visibility);
        out.push(b'}');
    }
}

/// A transform as serde_json writes `Option<[f32; 16]>`.
pub fn write_transform(out: &mut Vec<u8>, transform: Option<&[f32; 16]>) {
    match transform {
        Some(m) => serde_json::to_writer(&mut *out, m).expect("numbers"),
        None => out.extend_from_slice(b"null"),
    }
}

/// Writes the JSON of `response(tree, baseline, t, cut, micros)` into `out`, from the
/// tree's `fragments`; the same text as serialising that response.
pub fn write_response(
    tree: &Tree,
    baseline: &Baseline,
    fragments: &Fragments,
    t: f64,
    cut: &Cut,
    micros: f64,
    out: &mut Vec<u8>,
) {
    out.extend_from_slice(b"{\"time\":");
    write_number(out, &t);
    out.extend_from_slice(b",\"date\":");
    serde_json::to_writer(&mut *out, &format_date(tree.time.date_at(t))).expect("a string");
    out.extend_from_slice(b",\"clusters\":[");
    for (k, item) in cut.items.iter().enumerate() {
        if k > 0 {
            out.push(b',');
        }
        fragments.write_cluster(item, out);
    }
    out.extend_from_slice(b"],\"stats\":");
    serde_json::to_writer(&mut *out, &stats_out(cut, micros, baseline, t))
        .expect("plain data serialises");
    out.push(b'}');
}

/// A number as serde_json writes it (non-finite as null).
pub fn write_number(out: &mut Vec<u8>, x: &impl Serialize) {
    serde_json::to_writer(out, x).expect("a number serialises");
}

pub fn stats_out(cut: &Cut, micros: f64, baseline: &Baseline, t: f64) -> StatsOut {
    let (baseline_triangles, baseline_objects) = baseline.at(t);
    StatsOut {
        clusters: cut.stats.clusters,
        triangles: cut.stats.triangles,
        visited: cut.stats.visited,
        micros,
        baseline_triangles,
        baseline_objects,
    }
}

/// The whole request: check, cut, answer.
pub fn answer<'a>(
    tree: &'a Tree,
    baseline: &Baseline,
    request: &CutRequest,
) -> Result<CutResponse<'a>, ApiError> {
    let (view, t) = prepare(tree, request)?;
    let (mut cut, mut stack) = (Cut::default(), Vec::new());
    let micros = run(tree, &view, t, &mut cut, &mut stack);
    Ok(response(tree, baseline, t, &cut, micros))
}

#[cfg(test)]
mod tests {
    use hdlod_fixtures::paper;

    use super::*;

    /// The answer written from fragments is the serialised response, byte
    /// for byte, over views near and far and times across the period
    /// (dynamic clusters with transforms included).
    #[test]
    fn fragments_write_the_serialised_response() {
        let dir = tempfile::tempdir().unwrap();
        let tree = hdlod_fixtures::sample::write_sample_tree(&dir.path().join("t"), 3, 6).unwrap();
        let fragments = Fragments::of(&tree);
        let baseline = Baseline::of(&tree);
        let mut compared = 0;
        for factor in [0.6, 1.0, 4.0] {
            for k in 0..=6 {
                let t = tree.time.seconds * f64::from(k) / 6.0;
                let view = View::new(
                    &paper::camera(&tree, factor),
                    paper::VIEWPORT,
                    1.0,
                    up_vector(tree.up),
                )
                .unwrap();
                let (mut cut, mut stack) = (Cut::default(), Vec::new());
                let micros = run(&tree, &view, t, &mut cut, &mut stack);
                let mut fast = Vec::new();
                write_response(&tree, &baseline, &fragments, t, &cut, micros, &mut fast);
                let serde =
                    serde_json::to_vec(&response(&tree, &baseline, t, &cut, micros)).unwrap();
                assert_eq!(
                    String::from_utf8(fast).unwrap(),
                    String::from_utf8(serde).unwrap()
                );
                compared += cut.items.len();
            }
        }
        assert!(compared > 100, "{compared} clusters compared");
    }
}
