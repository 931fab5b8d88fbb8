//! Cut answers (`schemas/api/cut-response.schema.json`): the response as
//! a value (`hdlod cut` prints it), and the same JSON written straight
//! into a buffer with the tree's [`Fragments`] (`POST`/`GET .../cut`; the
//! stream writes its added clusters with them).

use std::borrow::Cow;

use hdlod::time::format_date;
use hdlod::tree::{Baseline, Cut, CutStats, Tree};
use rustc_hash::FxHashMap;
use serde::Serialize;

use super::{CutRequest, ProtocolError, prepare, run};

/// Borrows from the tree: an answer of thousands of clusters allocates
/// nothing per cluster.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClusterOut<'a> {
    pub id: u32,
    pub class: &'static str,
    pub level: u32,
    /// The geometry's URL path (content-addressed, immutable).
    pub geometry: GeometryUrl<'a>,
    /// The object a dynamic cluster is (its GLB, shared by the model's
    /// instances, carries no feature ids); `Tree::dynamic_object`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub object: Option<u32>,
    /// Column-major 4x4 pose at the requested time (dynamic clusters).
    pub transform: Option<[f32; 16]>,
    /// A skinned cluster's joint matrices at the requested time, each
    /// column-major, in the order of its GLB's `JOINTS_0` indices.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joints: Option<Vec<[f32; 16]>>,
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
#[derive(Debug, Clone, PartialEq)]
pub struct GeometryUrl<'a> {
    pub scene: &'a str,
    /// Borrowed from a built tree, decoded from a mapped one.
    pub hash: Cow<'a, str>,
}

impl std::fmt::Display for GeometryUrl<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "/api/v1/scenes/{}/geometry/{}.glb",
            segment(self.scene),
            self.hash
        )
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

/// What a name keeps unencoded in a URL path: RFC 3986's
/// unreserved characters.
const SEGMENT: &percent_encoding::AsciiSet = &percent_encoding::NON_ALPHANUMERIC
    .remove(b'-')
    .remove(b'_')
    .remove(b'.')
    .remove(b'~');

/// A name (of a scene, an object, a task) as one URL path segment,
/// percent-encoded.
pub fn segment(name: &str) -> percent_encoding::PercentEncode<'_> {
    percent_encoding::utf8_percent_encode(name, SEGMENT)
}

/// URL path prefix of a scene, its name percent-encoded.
pub fn scene_path(scene: &str) -> String {
    format!("/api/v1/scenes/{}", segment(scene))
}

fn cluster_out<'a>(tree: &'a Tree, cut: &Cut, item: &hdlod::tree::CutItem) -> ClusterOut<'a> {
    let id = item.id;
    ClusterOut {
        id,
        class: tree.class_of(id).name(),
        level: tree.level_of(id),
        geometry: GeometryUrl {
            scene: &tree.scene,
            hash: tree.geometry_of(id).unwrap_or_default(),
        },
        object: tree.dynamic_object(id),
        transform: item.transform.map(|m| m.to_cols_array()),
        joints: item.joints.map(|_| {
            cut.joints_of(item)
                .iter()
                .map(|m| m.to_cols_array())
                .collect()
        }),
        triangles: tree.triangles_of(id),
        error: item.error,
        visibility: item.visibility,
    }
}

fn response<'a>(
    tree: &'a Tree,
    baseline: &Baseline,
    t: f64,
    cut: &Cut,
    micros: f64,
) -> CutResponse<'a> {
    CutResponse {
        time: t,
        date: format_date(tree.time.date_at(t)),
        clusters: cut
            .items
            .iter()
            .map(|i| cluster_out(tree, cut, i))
            .collect(),
        stats: stats_out(cut, micros, baseline, t),
    }
}

/// What the cut answers of a loaded tree share: the scene's geometry URL
/// prefix, percent-encoded once, and each dynamic cluster's object. The
/// rest is read from the tree per emitted cluster (a mapped tree's pages
/// are then touched only by the clusters cuts emit).
pub struct Fragments {
    geometry: String,
    /// [`Tree::dynamic_object`] of every dynamic cluster that has one,
    /// found once: its lookup by the object's id (a search of the object
    /// table's strings) took about 7% of a server answering cuts at the
    /// 1/16 view under load.
    dynamic_objects: FxHashMap<u32, u32>,
}

impl Fragments {
    pub fn of(tree: &Tree) -> Fragments {
        let dynamic_objects = (0..tree.cluster_count() as u32)
            .filter_map(|id| Some((id, tree.dynamic_object(id)?)))
            .collect();
        Fragments {
            geometry: format!("{}/geometry/", scene_path(&tree.scene)),
            dynamic_objects,
        }
    }

    /// The JSON of `cluster_out(tree, cut, item)`, byte for byte.
    pub fn write_cluster(
        &self,
        tree: &Tree,
        cut: &Cut,
        item: &hdlod::tree::CutItem,
        out: &mut Vec<u8>,
    ) {
        let id = item.id;
        out.extend_from_slice(b"{\"id\":");
        write_number(out, &id);
        out.extend_from_slice(b",\"class\":\"");
        out.extend_from_slice(tree.class_of(id).name().as_bytes());
        out.extend_from_slice(b"\",\"level\":");
        write_number(out, &tree.level_of(id));
        // Percent-encoded and hexadecimal: nothing to escape.
        out.extend_from_slice(b",\"geometry\":\"");
        out.extend_from_slice(self.geometry.as_bytes());
        tree.push_geometry_of(id, out);
        out.extend_from_slice(b".glb\"");
        if let Some(object) = self.dynamic_objects.get(&id) {
            out.extend_from_slice(b",\"object\":");
            write_number(out, object);
        }
        out.extend_from_slice(b",\"transform\":");
        write_transform(out, item.transform.map(|m| m.to_cols_array()).as_ref());
        if item.joints.is_some() {
            out.extend_from_slice(b",\"joints\":[");
            for (k, m) in cut.joints_of(item).iter().enumerate() {
                if k > 0 {
                    out.push(b',');
                }
                write_transform(out, Some(&m.to_cols_array()));
            }
            out.push(b']');
        }
        out.extend_from_slice(b",\"triangles\":");
        write_number(out, &tree.triangles_of(id));
        out.extend_from_slice(b",\"error\":");
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
fn write_response(
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
        fragments.write_cluster(tree, cut, item, out);
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

/// Bytes a cluster takes in a cut answer, about: the buffer is sized once.
const CLUSTER_JSON_BYTES: usize = 256;

/// The whole request as the API answers it: checked, cut, and its JSON
/// written into `out` from the tree's `fragments`. Returns the cut's stats.
pub fn write_answer(
    tree: &Tree,
    baseline: &Baseline,
    fragments: &Fragments,
    request: &CutRequest,
    out: &mut Vec<u8>,
) -> Result<CutStats, ProtocolError> {
    let (view, t) = prepare(tree, request)?;
    let (mut cut, mut stack) = (Cut::default(), Vec::new());
    let micros = run(
        tree,
        &view,
        t,
        (request.presence, request.lod),
        &mut cut,
        &mut stack,
    );
    out.reserve((cut.items.len() + 1) * CLUSTER_JSON_BYTES);
    write_response(tree, baseline, fragments, t, &cut, micros, out);
    Ok(cut.stats)
}

/// The whole request as a value: checked, cut, answered.
pub fn answer<'a>(
    tree: &'a Tree,
    baseline: &Baseline,
    request: &CutRequest,
) -> Result<CutResponse<'a>, ProtocolError> {
    let (view, t) = prepare(tree, request)?;
    let (mut cut, mut stack) = (Cut::default(), Vec::new());
    let micros = run(
        tree,
        &view,
        t,
        (request.presence, request.lod),
        &mut cut,
        &mut stack,
    );
    Ok(response(tree, baseline, t, &cut, micros))
}

#[cfg(test)]
mod tests {
    use hdlod::tree::View;
    use hdlod::tree::cut::Presence;
    use hdlod_fixtures::paper;

    use super::*;
    use crate::protocol::request::up_vector;

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
                let micros = run(
                    &tree,
                    &view,
                    t,
                    (Presence::Paper, Default::default()),
                    &mut cut,
                    &mut stack,
                );
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
