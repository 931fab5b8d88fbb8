//! The scene format `hdlod-scene/1` (docs/formats.md, schemas/scene.schema.json):
//! a `scene.json` with the schedule, the motion and per-object properties,
//! beside the glTF/GLB files that hold the geometry. Every mesh node of the
//! models is an object; its id is `extras.id`, else the node name.
//!
//! Loading checks everything a later stage would trip over and names the
//! file and the task, object or field at fault; saving writes into a
//! temporary directory beside the target and renames it into place, so a
//! failed save leaves nothing half-written.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::appearance::{Profile, ProfileFile};
use super::links::{LinkType, find_cycle, show_cycle};
use super::rig::{Placed, Segment, TOLERANCE, Timeline};
use super::{
    Actual, Georeference, Keyframe, Motion, NamedType, Object, ObjectSkin, Predecessor, Scene,
    ScheduleOptions, Span, Task, TaskType, Up, Visibility,
};
use crate::error::{Error, Result};
use crate::io::glb::GlbBuilder;
use crate::io::gltf::read_model;
use crate::time::{TimeSpan, TimeValue, format_date, parse_date};

/// The value of the `format` field.
pub const FORMAT: &str = "hdlod-scene/1";
/// The scene file inside a scene directory.
pub const SCENE_FILE: &str = "scene.json";

/// Times further than this from the scene's start (about 300 years) are
/// taken for mistakes (and would overflow date arithmetic long before
/// `f64` does).
pub(crate) const MAX_SECONDS: f64 = 1e10;

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    format: String,
    name: String,
    #[serde(default)]
    up: Up,
    time: TimeFile,
    models: Vec<String>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    objects: BTreeMap<String, ObjectEntry>,
    #[serde(default)]
    tasks: Vec<TaskFile>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    motion: BTreeMap<String, Vec<KeyframeFile>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    schedule_options: Option<ScheduleOptions>,
    /// The scene's appearance profile (`hdlod-appearance/1`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    appearance: Option<ProfileFile>,
    /// Its place on Earth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    georeference: Option<Georeference>,
    /// The models' animations placed on the timeline.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    clips: Vec<ClipFile>,
}

/// A model's animation placed on the timeline: played at given times,
/// looped over an interval, or driven by keyframes of its clip time.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClipFile {
    /// The model (an entry of `models`) whose animation this is; needed
    /// only when several models have an animation of that name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    model: Option<String>,
    /// The glTF animation's name, or its index.
    animation: AnimationRef,
    /// Clip seconds per scene second, for `play` and `loop`.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    speed: f64,
    /// Times at which the clip plays once from its start.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    play: Vec<TimeValue>,
    /// An interval over which the clip plays again and again.
    #[serde(rename = "loop", default, skip_serializing_if = "Option::is_none")]
    repeat: Option<LoopFile>,
    /// The clip time at scene times, interpolated linearly between them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    keys: Vec<ClipKeyFile>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(untagged)]
enum AnimationRef {
    Index(usize),
    Name(String),
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LoopFile {
    from: TimeValue,
    to: TimeValue,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClipKeyFile {
    t: TimeValue,
    /// Seconds into the clip.
    clip_time: f64,
}

fn one() -> f64 {
    1.0
}

fn is_one(x: &f64) -> bool {
    *x == 1.0
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TimeFile {
    start: String,
    end: TimeValue,
}

#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectEntry {
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    properties: BTreeMap<String, String>,
    /// Leaves the mesh node out of the scene.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    skip: bool,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskFile {
    id: String,
    #[serde(default)]
    name: String,
    #[serde(rename = "type")]
    kind: String,
    start: TimeValue,
    finish: TimeValue,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    actual_start: Option<TimeValue>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    actual_finish: Option<TimeValue>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    baseline_start: Option<TimeValue>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    baseline_finish: Option<TimeValue>,
    /// The id of its summary task.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    parent: Option<String>,
    /// The tasks it follows.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    predecessors: Vec<PredecessorFile>,
    objects: Vec<String>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PredecessorFile {
    task: String,
    #[serde(rename = "type", default)]
    kind: LinkType,
    /// Seconds.
    #[serde(default, skip_serializing_if = "is_zero")]
    lag: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeFile {
    t: TimeValue,
    #[serde(default = "zero3", deserialize_with = "f32s")]
    translation: [f32; 3],
    #[serde(default = "identity_rotation", deserialize_with = "f32s")]
    rotation: [f32; 4],
    #[serde(default = "one3", deserialize_with = "f32s")]
    scale: [f32; 3],
}

/// `N` numbers kept as `f32`, each read by [`F32`].
fn f32s<'de, D: serde::Deserializer<'de>, const N: usize>(d: D) -> Result<[f32; N], D::Error>
where
    [F32; N]: Deserialize<'de>,
{
    Ok(<[F32; N]>::deserialize(d)?.map(|F32(x)| x))
}

/// A number kept as `f32`, read as `f64` first: serde would turn one
/// beyond the `f32` range into an infinity, which a later check would call
/// non-finite although the file holds a finite number. The error comes
/// from the element itself, so that its path names the index.
struct F32(f32);

impl<'de> Deserialize<'de> for F32 {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let wide = f64::deserialize(d)?;
        if wide.abs() > f64::from(f32::MAX) {
            return Err(serde::de::Error::custom(format!(
                "{wide:e} is out of range: a 32-bit float is at most {:e} in magnitude",
                f32::MAX
            )));
        }
        Ok(F32(wide as f32))
    }
}

fn zero3() -> [f32; 3] {
    [0.0; 3]
}
fn one3() -> [f32; 3] {
    [1.0; 3]
}
fn identity_rotation() -> [f32; 4] {
    [0.0, 0.0, 0.0, 1.0]
}

/// The longest scene name.
pub const MAX_NAME: usize = 128;

/// Why `name` cannot name a scene, if it cannot: a scene's name is its
/// URL (`/api/v1/scenes/NAME`) and its GLB's file name, so it is 1 to
/// [`MAX_NAME`] characters a URL path segment and a file name take as they
/// are (letters, digits, `-`, `_`, `.`, `~`: RFC 3986's unreserved), not
/// starting with a dot.
pub fn name_problem(name: &str) -> Option<String> {
    let quoted = crate::input::quote(name);
    if name.is_empty() {
        return Some("the name is empty".into());
    }
    if name.len() > MAX_NAME {
        return Some(format!("{quoted} is longer than {MAX_NAME} characters"));
    }
    if name.starts_with('.') {
        return Some(format!("{quoted} starts with a dot"));
    }
    if let Some(c) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | '~')))
    {
        return Some(format!(
            "{quoted} holds {c:?}: a scene name is letters, digits, '-', '_', '.' and '~'"
        ));
    }
    None
}

/// Loads a scene from its directory or its `scene.json`, reads the models,
/// checks the schedule and motion, and applies the schedule.
pub fn load(path: &Path) -> Result<Scene> {
    let file = if path.is_dir() {
        path.join(SCENE_FILE)
    } else {
        path.to_path_buf()
    };
    let text = crate::input::read_to_string(&file)?;
    // Tracking the path slows the parse of a large scene (the paper's has
    // 43 MB of JSON): only a file that fails is parsed again to say where.
    let parsed: SceneFile = match serde_json::from_str(&text) {
        Ok(parsed) => parsed,
        Err(_) => {
            let de = &mut serde_json::Deserializer::from_str(&text);
            serde_path_to_error::deserialize(de).map_err(|e| {
                let at = e.path().to_string();
                let at = if at == "." { "JSON".to_owned() } else { at };
                Error::invalid(&file, at, e.into_inner().to_string())
            })?
        }
    };
    Loader {
        file: &file,
        base: file.parent().unwrap_or(Path::new(".")),
    }
    .scene(parsed)
}

struct Loader<'a> {
    file: &'a Path,
    base: &'a Path,
}

impl Loader<'_> {
    fn err(&self, at: impl Into<String>, message: impl Into<String>) -> Error {
        Error::invalid(self.file, at, message)
    }

    fn time(&self, span: &TimeSpan, value: &TimeValue, at: &str) -> Result<f64> {
        let t = span
            .resolve(value)
            .map_err(|m| self.err(at, m.to_string()))?;
        if t.abs() > MAX_SECONDS {
            return Err(self.err(
                at,
                format!(
                    "{} is more than {MAX_SECONDS:e} s from the scene start",
                    show(value)
                ),
            ));
        }
        Ok(t)
    }

    fn scene(&self, f: SceneFile) -> Result<Scene> {
        if f.format != FORMAT {
            return Err(self.err(
                "format",
                format!(
                    "{} is not supported (expected {FORMAT:?})",
                    crate::input::quote(&f.format)
                ),
            ));
        }
        if let Some(why) = name_problem(&f.name) {
            return Err(self.err("name", why));
        }
        let start = parse_date(&f.time.start).map_err(|m| self.err("time.start", m.to_string()))?;
        let mut time = TimeSpan {
            start,
            seconds: 0.0,
        };
        time.seconds = self.time(&time, &f.time.end, "time.end")?;
        if time.seconds <= 0.0 {
            return Err(self.err(
                "time.end",
                format!(
                    "{} is not after the start {}",
                    show(&f.time.end),
                    f.time.start
                ),
            ));
        }

        let (meshes, mut objects, rigs) = self.objects(&f)?;
        let index: HashMap<String, usize> = objects
            .iter()
            .enumerate()
            .map(|(i, o)| (o.id.clone(), i))
            .collect();
        let lookup = |id: &str, at: &str| -> Result<usize> {
            index.get(id).copied().ok_or_else(|| {
                let why = if f.objects.get(id).is_some_and(|o| o.skip) {
                    "is skipped (objects.skip)"
                } else {
                    "does not exist in the models"
                };
                self.err(at, format!("object {id:?} {why}"))
            })
        };

        let mut tasks = Vec::with_capacity(f.tasks.len());
        let mut task_ids = HashMap::new();
        for (i, t) in f.tasks.iter().enumerate() {
            let at = format!("tasks[{i}] {:?}", t.id);
            if let Some(first) = task_ids.insert(t.id.as_str(), i) {
                return Err(self.err(at, format!("the id is also the id of tasks[{first}]")));
            }
            let named = NamedType::parse(&t.kind).ok_or_else(|| {
                self.err(
                    format!("{at}.type"),
                    format!("{:?} is not a task type; use {}", t.kind, TaskType::NAMES),
                )
            })?;
            let start = self.time(&time, &t.start, &format!("{at}.start"))?;
            let finish = self.time(&time, &t.finish, &format!("{at}.finish"))?;
            if finish < start {
                return Err(self.err(
                    at,
                    format!(
                        "finish {} is before start {}",
                        show(&t.finish),
                        show(&t.start)
                    ),
                ));
            }
            for (k, id) in t.objects.iter().enumerate() {
                lookup(id, &format!("{at}.objects"))?;
                if let Some(first) = t.objects[..k].iter().position(|o| o == id) {
                    return Err(self.err(
                        format!("{at}.objects[{k}]"),
                        format!("object {id:?} is also objects[{first}]"),
                    ));
                }
            }
            if t.objects.is_empty() && !f.tasks.iter().any(|c| c.parent.as_ref() == Some(&t.id)) {
                return Err(self.err(
                    format!("{at}.objects"),
                    "is empty, and no task names this one its parent: only a summary task \
                     has no objects",
                ));
            }
            let opt = |v: &Option<TimeValue>, field: &str| {
                v.as_ref()
                    .map(|v| self.time(&time, v, &format!("{at}.{field}")))
                    .transpose()
            };
            let actual = Actual {
                start: opt(&t.actual_start, "actual_start")?,
                finish: opt(&t.actual_finish, "actual_finish")?,
            };
            match (actual.start, actual.finish) {
                (None, Some(_)) => {
                    return Err(self.err(
                        format!("{at}.actual_finish"),
                        "an actual finish needs an actual start",
                    ));
                }
                (Some(a), Some(b)) if b < a => {
                    return Err(
                        self.err(format!("{at}.actual_finish"), "is before the actual start")
                    );
                }
                _ => {}
            }
            let baseline = match (
                opt(&t.baseline_start, "baseline_start")?,
                opt(&t.baseline_finish, "baseline_finish")?,
            ) {
                (None, None) => None,
                (Some(start), Some(finish)) if finish >= start => Some(Span { start, finish }),
                (Some(_), Some(_)) => {
                    return Err(self.err(
                        format!("{at}.baseline_finish"),
                        "is before the baseline start",
                    ));
                }
                _ => {
                    return Err(self.err(
                        at,
                        "a baseline needs both baseline_start and baseline_finish",
                    ));
                }
            };
            tasks.push(Task {
                id: t.id.clone(),
                name: t.name.clone(),
                kind: named.kind,
                ifc_type: named.ifc,
                start,
                finish,
                actual,
                baseline,
                parent: t.parent.clone(),
                predecessors: t
                    .predecessors
                    .iter()
                    .map(|p| Predecessor {
                        task: p.task.clone(),
                        kind: p.kind,
                        lag: p.lag,
                    })
                    .collect(),
                objects: t.objects.clone(),
            });
        }
        // Links name other tasks, and form no cycle.
        for (i, t) in f.tasks.iter().enumerate() {
            for (j, p) in t.predecessors.iter().enumerate() {
                let at = format!("tasks[{i}] {:?}.predecessors[{j}]", t.id);
                if !task_ids.contains_key(p.task.as_str()) {
                    return Err(self.err(at, format!("{:?} is not the id of a task", p.task)));
                }
                if p.task == t.id {
                    return Err(self.err(at, "a task cannot follow itself"));
                }
                if !p.lag.is_finite() || p.lag.abs() > MAX_SECONDS {
                    return Err(self.err(format!("{at}.lag"), format!("{} is out of range", p.lag)));
                }
            }
        }
        let ids: Vec<&str> = f.tasks.iter().map(|t| t.id.as_str()).collect();
        if let Some(cycle) = find_cycle(&ids, |i| {
            f.tasks[i].predecessors.iter().map(|p| p.task.as_str())
        }) {
            return Err(self.err(
                format!("tasks[{}] {:?}.predecessors", cycle[0], ids[cycle[0]]),
                format!("the links form a cycle: {}", show_cycle(&ids, &cycle)),
            ));
        }
        // Parents name tasks, and no task is its own ancestor.
        for (i, t) in f.tasks.iter().enumerate() {
            let mut seen = 0;
            let mut at = t.parent.as_deref();
            while let Some(p) = at {
                let Some(&k) = task_ids.get(p) else {
                    return Err(self.err(
                        format!("tasks[{i}] {:?}.parent", t.id),
                        format!("{p:?} is not the id of a task"),
                    ));
                };
                seen += 1;
                if seen > f.tasks.len() {
                    return Err(self.err(
                        format!("tasks[{i}] {:?}.parent", t.id),
                        "the parents form a cycle",
                    ));
                }
                at = f.tasks[k].parent.as_deref();
            }
        }
        if let Some(g) = &f.georeference {
            g.validate()
                .map_err(|(field, m)| self.err(format!("georeference.{field}"), m))?;
        }
        let appearance = f
            .appearance
            .map(|p| Profile::from_file(p, self.file, "appearance."))
            .transpose()?;

        for (id, keys) in &f.motion {
            let at = format!("motion.{id:?}");
            let i = lookup(id, &at)?;
            let mut frames: Vec<Keyframe> = Vec::with_capacity(keys.len());
            for (k, key) in keys.iter().enumerate() {
                let t = self.time(&time, &key.t, &format!("{at}[{k}].t"))?;
                // Keyframes in file order: a list out of order is more
                // likely a mistake than a wish to have it sorted.
                if let Some(before) = frames.last()
                    && t <= before.t
                {
                    return Err(self.err(
                        format!("{at}[{k}].t"),
                        format!(
                            "{} is not after keyframe {} ({} s): keyframes go forward in time",
                            show(&key.t),
                            k - 1,
                            before.t
                        ),
                    ));
                }
                if key.scale.iter().any(|s| *s <= 0.0) {
                    return Err(self.err(
                        format!("{at}[{k}].scale"),
                        format!(
                            "{:?} has a component <= 0: an object cannot shrink to nothing or \
                             turn inside out",
                            key.scale
                        ),
                    ));
                }
                frames.push(Keyframe {
                    t,
                    translation: Vec3::from(key.translation),
                    rotation: Quat::from_array(key.rotation),
                    scale: Vec3::from(key.scale),
                });
            }
            objects[i].motion = Some(
                Motion::new(frames)
                    .map_err(|m| self.err(format!("object {id:?}"), m.to_string()))?,
            );
        }

        self.clips(&f.clips, &f.models, &time, &rigs, &meshes, &mut objects)?;

        let mut scene = Scene {
            name: f.name,
            up: f.up,
            time,
            meshes,
            objects,
            tasks,
            schedule_options: f.schedule_options.unwrap_or_default(),
            appearance,
            georeference: f.georeference,
        };
        scene.apply_schedule();
        Ok(scene)
    }

    /// Places the models' animations on the timeline (`clips`): every
    /// object whose node or a node above it is animated moves with its
    /// composed world transform (`rig`).
    fn clips(
        &self,
        clips: &[ClipFile],
        models: &[String],
        time: &TimeSpan,
        rigs: &Rigs,
        meshes: &[crate::geometry::Mesh],
        objects: &mut [Object],
    ) -> Result<()> {
        if clips.is_empty() {
            return Ok(());
        }
        // The placed clips of each model.
        let mut placed: Vec<Vec<Placed>> = vec![Vec::new(); rigs.rigs.len()];
        for (i, c) in clips.iter().enumerate() {
            let at = format!("clips[{i}]");
            let models: Vec<usize> = match &c.model {
                Some(name) => vec![models.iter().position(|m| m == name).ok_or_else(|| {
                    self.err(
                        format!("{at}.model"),
                        format!("{:?} is not one of models", name),
                    )
                })?],
                None => (0..models.len()).collect(),
            };
            let found: Vec<(usize, usize)> = models
                .iter()
                .flat_map(|&m| {
                    let clips = &rigs.rigs[m].clips;
                    let k = match &c.animation {
                        AnimationRef::Index(k) => (*k < clips.len()).then_some(*k),
                        AnimationRef::Name(name) => {
                            clips.iter().position(|a| a.name.as_deref() == Some(name))
                        }
                    };
                    k.map(|k| (m, k))
                })
                .collect();
            let animation = match &c.animation {
                AnimationRef::Index(k) => format!("animation {k}"),
                AnimationRef::Name(name) => format!("animation {name:?}"),
            };
            let (m, k) = match found[..] {
                [one] => one,
                [] => {
                    return Err(self.err(
                        format!("{at}.animation"),
                        format!("no model has {animation}"),
                    ));
                }
                _ => {
                    return Err(self.err(
                        format!("{at}.model"),
                        format!("{} models have {animation}: name the model", found.len()),
                    ));
                }
            };
            let clip = &rigs.rigs[m].clips[k];
            let timeline = self.timeline(c, time, clip.duration(), &at)?;
            placed[m].push(Placed::new(clip, timeline));
        }
        // Two placements animating one node at once cannot both hold.
        for (m, list) in placed.iter().enumerate() {
            for (a, first) in list.iter().enumerate() {
                for second in &list[a + 1..] {
                    let shared = first
                        .clip
                        .channels
                        .iter()
                        .find(|x| second.clip.channels.iter().any(|y| y.node == x.node));
                    let overlap = first.timeline.segments().iter().any(|s| {
                        second
                            .timeline
                            .segments()
                            .iter()
                            .any(|r| r.start < s.end && s.start < r.end)
                    });
                    if let (Some(channel), true) = (shared, overlap) {
                        return Err(self.err(
                            "clips",
                            format!(
                                "two clips of {:?} animate node {} at the same time",
                                models[m], channel.node
                            ),
                        ));
                    }
                }
            }
        }
        for ((o, &(m, node)), joints) in objects.iter_mut().zip(&rigs.nodes).zip(&rigs.joints) {
            let rig = &rigs.rigs[m];
            if let Some(skin) = &mut o.skin {
                move_joints(skin, &meshes[o.mesh], joints, rig, &placed[m], time.seconds)
                    .map_err(|(k, m)| self.err(format!("object {:?} joint {k}", o.id), m))?;
            }
            if placed[m].is_empty() || !rig.moves(node, &placed[m]) {
                continue;
            }
            let at = format!("object {:?}", o.id);
            if o.motion.is_some() {
                return Err(self.err(
                    format!("motion.{:?}", o.id),
                    "the object also moves with a clip: give it one or the other",
                ));
            }
            let bounds = meshes[o.mesh]
                .bounds()
                .unwrap_or((glam::Vec3::ZERO, glam::Vec3::ZERO));
            let keys = rig
                .keyframes(node, &placed[m], bounds, (0.0, time.seconds), TOLERANCE)
                .map_err(|m| self.err(&at, m))?;
            o.motion = Some(Motion::new(keys).map_err(|e| self.err(&at, e.to_string()))?);
        }
        Ok(())
    }

    /// The timeline of clip placement `c` (at `at`) for a clip of
    /// `duration` seconds.
    fn timeline(&self, c: &ClipFile, time: &TimeSpan, duration: f64, at: &str) -> Result<Timeline> {
        let given = [!c.play.is_empty(), c.repeat.is_some(), !c.keys.is_empty()];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(self.err(at.to_owned(), "give exactly one of play, loop and keys"));
        }
        if !(c.speed.is_finite() && c.speed > 0.0) {
            return Err(self.err(format!("{at}.speed"), format!("{} is not above 0", c.speed)));
        }
        let length = duration / c.speed;
        let mut segments = Vec::new();
        if !c.play.is_empty() {
            if duration <= 0.0 {
                return Err(self.err(
                    format!("{at}.animation"),
                    "the animation has no length: it can only be placed by keys",
                ));
            }
            for (k, t) in c.play.iter().enumerate() {
                let start = self.time(time, t, &format!("{at}.play[{k}]"))?;
                segments.push(Segment {
                    start,
                    end: start + length,
                    tau: (0.0, duration),
                });
            }
        } else if let Some(l) = &c.repeat {
            let from = self.time(time, &l.from, &format!("{at}.loop.from"))?;
            let to = self.time(time, &l.to, &format!("{at}.loop.to"))?;
            if to <= from {
                return Err(self.err(format!("{at}.loop.to"), "is not after loop.from"));
            }
            if duration <= 0.0 {
                return Err(self.err(
                    format!("{at}.animation"),
                    "the animation has no length: it can only be placed by keys",
                ));
            }
            let cycles = ((to - from) / length).ceil();
            if cycles > MAX_CYCLES as f64 {
                return Err(self.err(
                    format!("{at}.loop"),
                    format!(
                        "plays the {duration} s clip {cycles} times; at most {MAX_CYCLES} \
                         (a longer loop is a motion of its own: give keys)"
                    ),
                ));
            }
            let mut start = from;
            while start < to {
                let end = (start + length).min(to);
                segments.push(Segment {
                    start,
                    end,
                    tau: (0.0, (end - start) * c.speed),
                });
                start = end;
            }
        } else {
            let mut keys: Vec<(f64, f64)> = Vec::with_capacity(c.keys.len());
            for (k, key) in c.keys.iter().enumerate() {
                let t = self.time(time, &key.t, &format!("{at}.keys[{k}].t"))?;
                if !key.clip_time.is_finite() {
                    return Err(self.err(format!("{at}.keys[{k}].clip_time"), "is not finite"));
                }
                if let Some(&(before, _)) = keys.last()
                    && t <= before
                {
                    return Err(self.err(
                        format!("{at}.keys[{k}].t"),
                        "is not after the key before: keys go forward in time",
                    ));
                }
                keys.push((t, key.clip_time));
            }
            if let [(t, tau)] = keys[..] {
                // One key: the pose at that clip time, throughout.
                segments.push(Segment {
                    start: t,
                    end: t + 1.0,
                    tau: (tau, tau),
                });
            }
            for w in keys.windows(2) {
                segments.push(Segment {
                    start: w[0].0,
                    end: w[1].0,
                    tau: (w[0].1, w[1].1),
                });
            }
        }
        Timeline::new(segments).map_err(|m| self.err(at.to_owned(), m))
    }

    /// Reads the models: the meshes (only those some object uses, in order
    /// of first use), one object per mesh node not skipped, and the models'
    /// node hierarchies and animations.
    fn objects(&self, f: &SceneFile) -> Result<(Vec<crate::geometry::Mesh>, Vec<Object>, Rigs)> {
        let mut rigs = Rigs::default();
        let mut meshes = Vec::new();
        let mut objects: Vec<Object> = Vec::new();
        let mut seen: HashMap<String, String> = HashMap::new();
        // Skipped ids seen in the models: an `objects` key must name a
        // mesh node, skipped or not.
        let mut skipped: std::collections::HashSet<String> = Default::default();
        for (m, name) in f.models.iter().enumerate() {
            let path = crate::input::inside(self.base, name)
                .map_err(|why| self.err(format!("models[{m}]"), why))?;
            let model = read_model(&path).map_err(|e| match e {
                Error::Io { source, .. } => self.err(
                    format!("models[{m}]"),
                    format!("cannot read {}: {source}", path.display()),
                ),
                other => other,
            })?;
            // Model mesh index -> scene mesh index, filled on first use.
            let mut remap: Vec<Option<usize>> = vec![None; model.meshes.len()];
            let mut model_meshes: Vec<Option<crate::geometry::Mesh>> =
                model.meshes.into_iter().map(Some).collect();
            rigs.rigs.push(model.rig);
            for node in model.nodes {
                let id = node.id.clone().ok_or_else(|| {
                    Error::invalid(
                        &path,
                        node.describe(),
                        "has a mesh but neither extras.id nor a name, so it cannot be an object",
                    )
                })?;
                let entry = f.objects.get(&id);
                if entry.is_some_and(|e| e.skip) {
                    skipped.insert(id);
                    continue;
                }
                let here = format!("{} {}", path.display(), node.describe());
                if let Some(first) = seen.insert(id.clone(), here) {
                    return Err(Error::invalid(
                        &path,
                        node.describe(),
                        format!("object id {id:?} is also the id of {first}"),
                    ));
                }
                let mesh = *remap[node.mesh].get_or_insert_with(|| {
                    meshes.push(model_meshes[node.mesh].take().expect("taken once"));
                    meshes.len() - 1
                });
                rigs.nodes.push((m, node.index));
                let (joints, skin) = node
                    .skin
                    .map(|s| (s.nodes, Some(Box::new(s.skin))))
                    .unwrap_or_default();
                rigs.joints.push(joints);
                objects.push(Object {
                    id,
                    mesh,
                    transform: node.transform,
                    color: node.color,
                    visibility: Visibility::always(),
                    motion: None,
                    skin,
                    properties: entry.map(|e| e.properties.clone()).unwrap_or_default(),
                });
            }
        }
        let named = |id: &str| seen.contains_key(id) || skipped.contains(id);
        if let Some(id) = f.objects.keys().find(|id| !named(id)) {
            return Err(self.err(
                format!("objects.{id:?}"),
                "names no mesh node in the models",
            ));
        }
        Ok((meshes, objects, rigs))
    }
}

/// Each joint of `skin` (at the nodes `joints` of `rig`) that `placed`
/// animates, or a node above it, gets its world transform over the scene's
/// `[0, end]` as keyframes, held within the tolerance at the corners of the
/// box, in the joint's frame, of the vertices it moves (its origin when it
/// moves none). An error names the joint.
fn move_joints(
    skin: &mut crate::scene::ObjectSkin,
    mesh: &crate::geometry::Mesh,
    joints: &[usize],
    rig: &crate::scene::rig::Rig,
    placed: &[Placed],
    end: f64,
) -> std::result::Result<(), (usize, String)> {
    for (k, (joint, &node)) in skin.joints.iter_mut().zip(joints).enumerate() {
        if placed.is_empty() || !rig.moves(node, placed) {
            continue;
        }
        let inverse = skin.inverse_bind[k];
        let moved = skin
            .vertices
            .joints
            .iter()
            .zip(&skin.vertices.weights)
            .zip(&mesh.positions)
            .filter(|((j, w), _)| (0..4).any(|i| usize::from(j[i]) == k && w[i] > 0.0))
            .map(|(_, p)| inverse.transform_point3(*p));
        let bounds = moved.fold(None, |b: Option<(Vec3, Vec3)>, p| {
            Some(b.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))))
        });
        let keys = rig
            .keyframes(
                node,
                placed,
                bounds.unwrap_or((Vec3::ZERO, Vec3::ZERO)),
                (0.0, end),
                TOLERANCE,
            )
            .map_err(|m| (k, m))?;
        joint.motion = Some(Motion::new(keys).map_err(|e| (k, e.to_string()))?);
    }
    Ok(())
}

/// The models' rigs, and each object's model and node, and its skin's
/// joints' nodes (none for an object without a skin).
#[derive(Default)]
struct Rigs {
    rigs: Vec<crate::scene::rig::Rig>,
    nodes: Vec<(usize, usize)>,
    joints: Vec<Vec<usize>>,
}

/// A loop plays its clip at most this many times.
const MAX_CYCLES: usize = 100_000;

/// A time as the user wrote it, for messages.
fn show(value: &TimeValue) -> String {
    match value {
        TimeValue::Seconds(s) if s.abs() < 1e15 => format!("{s} s"),
        TimeValue::Seconds(s) => format!("{s:e} s"),
        TimeValue::Iso(text) => text.clone(),
    }
}

/// Writes `dir/scene.json` and `dir/<name>.glb`. The files are written into
/// a temporary directory beside `dir` which then replaces `dir`, so on any
/// error nothing is left half-written and an existing `dir` is untouched.
pub fn save(scene: &Scene, dir: &Path) -> Result<()> {
    check(scene)?;
    let model = format!("{}.glb", scene.name);
    let glb = scene_glb(scene)?;
    // Compact: a paper-size scene has 150,000 keyframes, which pretty printing
    // would spread over millions of lines.
    let json = serde_json::to_vec(&scene_file(scene, &model))
        .map_err(|e| Error::argument("scene", e.to_string()))?;

    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let leaf = dir
        .file_name()
        .ok_or_else(|| {
            Error::argument("output directory", format!("{} has no name", dir.display()))
        })?
        .to_string_lossy()
        .into_owned();
    std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
    crate::debris::remove_stale(dir);
    let tmp = parent.join(format!(".{leaf}.tmp-{}", std::process::id()));
    let write = || -> Result<()> {
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
        }
        std::fs::create_dir(&tmp).map_err(|e| Error::io(&tmp, e))?;
        for (name, bytes) in [(SCENE_FILE, &json), (model.as_str(), &glb)] {
            let p = tmp.join(name);
            std::fs::write(&p, bytes).map_err(|e| Error::io(&p, e))?;
        }
        Ok(())
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    replace_dir(&tmp, dir).inspect_err(|_| {
        let _ = std::fs::remove_dir_all(&tmp);
    })
}

/// Moves `tmp` to `dir`, replacing an existing `dir` only once the new one
/// is in place.
fn replace_dir(tmp: &Path, dir: &Path) -> Result<()> {
    if !dir.exists() {
        return std::fs::rename(tmp, dir).map_err(|e| Error::io(dir, e));
    }
    let old = tmp.with_extension("old");
    std::fs::rename(dir, &old).map_err(|e| Error::io(dir, e))?;
    if let Err(e) = std::fs::rename(tmp, dir) {
        let _ = std::fs::rename(&old, dir);
        return Err(Error::io(dir, e));
    }
    std::fs::remove_dir_all(&old).map_err(|e| Error::io(&old, e))
}

/// Rejects what `load` would reject, before anything is written.
fn check(scene: &Scene) -> Result<()> {
    let bad = |at: String, m: String| Err(Error::argument(at, m));
    if let Some(why) = name_problem(&scene.name) {
        return bad("scene name".into(), why);
    }
    let in_range = |t: f64| t.abs() <= MAX_SECONDS;
    let task_ids: Vec<&str> = scene.tasks.iter().map(|t| t.id.as_str()).collect();
    let is_task: std::collections::HashSet<&str> = task_ids.iter().copied().collect();
    if !(in_range(scene.time.seconds) && scene.time.seconds > 0.0) {
        return bad(
            "scene time".into(),
            format!("span of {} s", scene.time.seconds),
        );
    }
    let mut ids = HashMap::new();
    for (i, o) in scene.objects.iter().enumerate() {
        let at = format!("object {:?}", o.id);
        if o.id.is_empty() {
            return bad(format!("objects[{i}]"), "the id is empty".into());
        }
        if let Some(first) = ids.insert(o.id.as_str(), i) {
            return bad(
                at,
                format!("objects[{first}] and objects[{i}] share the id"),
            );
        }
        let Some(mesh) = scene.meshes.get(o.mesh) else {
            return bad(at, format!("mesh {} does not exist", o.mesh));
        };
        if mesh.is_empty() {
            return bad(at, format!("mesh {} has no triangles", o.mesh));
        }
        if !o.transform.is_finite() {
            return bad(at, "the transform is not finite".into());
        }
        if !o.color.iter().all(|c| (0.0..=1.0).contains(c)) {
            return bad(at, format!("colour {:?} is not within [0, 1]", o.color));
        }
        let skin = o.skin.as_deref();
        let motions = o.motion.iter().chain(
            skin.iter()
                .flat_map(|s| s.joints.iter().flat_map(|j| &j.motion)),
        );
        if let Some(k) = motions
            .clone()
            .flat_map(|m| m.keyframes())
            .find(|k| !in_range(k.t))
        {
            return bad(at, format!("keyframe time {} is out of range", k.t));
        }
        if let Some(k) = motions
            .flat_map(|m| m.keyframes())
            .find(|k| k.scale.cmple(glam::Vec3::ZERO).any())
        {
            return bad(
                at,
                format!("keyframe scale {} has a component <= 0", k.scale),
            );
        }
        if let Some(skin) = skin
            && let Some(why) = skin_problem(skin, mesh)
        {
            return bad(at, format!("skin: {why}"));
        }
    }
    for (m, mesh) in scene.meshes.iter().enumerate() {
        mesh.validate()
            .map_err(|e| Error::argument(format!("mesh {m}"), e.to_string()))?;
    }
    for t in &scene.tasks {
        let at = format!("task {:?}", t.id);
        if !(in_range(t.start) && in_range(t.finish) && t.start <= t.finish) {
            return bad(at, format!("start {} and finish {}", t.start, t.finish));
        }
        let a = t.actual;
        let actual_ok = match (a.start, a.finish) {
            (None, None) => true,
            (Some(s), None) => in_range(s),
            (Some(s), Some(f)) => in_range(s) && in_range(f) && s <= f,
            (None, Some(_)) => false,
        };
        if !actual_ok {
            return bad(
                at,
                format!("actual start {:?} and finish {:?}", a.start, a.finish),
            );
        }
        if let Some(b) = t.baseline
            && !(in_range(b.start) && in_range(b.finish) && b.start <= b.finish)
        {
            return bad(
                at,
                format!("baseline start {} and finish {}", b.start, b.finish),
            );
        }
        if let Some(p) = &t.parent
            && !is_task.contains(p.as_str())
        {
            return bad(at, format!("parent {p:?} is not a task"));
        }
        if let Some(id) = t.objects.iter().find(|id| !ids.contains_key(id.as_str())) {
            return bad(at, format!("object {id:?} does not exist"));
        }
        if let Some(k) = (1..t.objects.len()).find(|&k| t.objects[..k].contains(&t.objects[k])) {
            return bad(at, format!("object {:?} is named twice", t.objects[k]));
        }
        if t.objects.is_empty() && !scene.tasks.iter().any(|c| c.parent.as_ref() == Some(&t.id)) {
            return bad(
                at,
                "has no objects and is no task's parent (only a summary task has none)".into(),
            );
        }
        for p in &t.predecessors {
            if p.task == t.id || !is_task.contains(p.task.as_str()) {
                return bad(at, format!("predecessor {:?} is not another task", p.task));
            }
            if !in_range(p.lag) {
                return bad(at, format!("lag {} is out of range", p.lag));
            }
        }
    }
    if let Some(cycle) = find_cycle(&task_ids, |i| {
        scene.tasks[i].predecessors.iter().map(|p| p.task.as_str())
    }) {
        return bad(
            "tasks".into(),
            format!("the links form a cycle: {}", show_cycle(&task_ids, &cycle)),
        );
    }
    Ok(())
}

/// Why `skin` cannot deform `mesh` in a saved scene, if it cannot.
fn skin_problem(skin: &ObjectSkin, mesh: &crate::geometry::Mesh) -> Option<String> {
    let n = skin.joints.len();
    if n == 0 || n > usize::from(u16::MAX) + 1 {
        return Some(format!("{n} joints (1 to 65536)"));
    }
    if skin.inverse_bind.len() != n {
        return Some(format!(
            "{} inverse bind matrices for {n} joints",
            skin.inverse_bind.len()
        ));
    }
    if let Some(k) = skin.inverse_bind.iter().position(|m| !m.is_finite()) {
        return Some(format!("inverse bind matrix {k} is not finite"));
    }
    if let Some(k) = skin.joints.iter().position(|j| !j.transform.is_finite()) {
        return Some(format!("joint {k}'s transform is not finite"));
    }
    // Every joint index is written, also under a zero weight.
    if let Some(v) = skin
        .vertices
        .joints
        .iter()
        .position(|j| j.iter().any(|&k| usize::from(k) >= n))
    {
        return Some(format!("vertex {v} names a joint beyond the {n} joints"));
    }
    skin.vertices.problem(mesh, n)
}

/// One GLB for the whole scene: each mesh written once, a glTF mesh per
/// (mesh, colour) pair over the same accessors, a node per object. A
/// skinned object has a primitive of its own with its joints and weights,
/// its skin, and an animation of its joints when they move, in the order
/// of the objects ([`ObjectSkin::times`]).
fn scene_glb(scene: &Scene) -> Result<Vec<u8>> {
    let mut glb = GlbBuilder::new();
    let mut accessors = vec![None; scene.meshes.len()];
    let mut primitives = HashMap::new();
    let mut nodes = Vec::with_capacity(scene.objects.len());
    let mut skeletons = Vec::new();
    for o in &scene.objects {
        let acc = *accessors[o.mesh].get_or_insert_with(|| glb.add_mesh(&scene.meshes[o.mesh]));
        if let Some(skin) = &o.skin {
            let skinned = glb.with_influences(&acc, &skin.vertices);
            let material = glb.material(o.color);
            let mesh = glb.add_primitive(&skinned, Some(material));
            let node = glb.add_node(mesh, &o.transform, Some(&o.id));
            let (index, skeleton) = glb.add_skin(&o.id, skin, &skin.times());
            glb.set_skin(node, index);
            nodes.push(node);
            skeletons.push(skeleton);
            continue;
        }
        let key = (o.mesh, o.color.map(f32::to_bits));
        let mesh = match primitives.get(&key) {
            Some(&m) => m,
            None => {
                let material = glb.material(o.color);
                let m = glb.add_primitive(&acc, Some(material));
                primitives.insert(key, m);
                m
            }
        };
        nodes.push(glb.add_node(mesh, &o.transform, Some(&o.id)));
    }
    // GLB lengths are 32-bit.
    if glb.bin_len() > (u32::MAX as usize) - (64 << 20) {
        return Err(Error::argument(
            "scene",
            format!(
                "{} bytes of geometry exceed the 4 GiB of a GLB",
                glb.bin_len()
            ),
        ));
    }
    nodes.extend(skeletons);
    Ok(glb.finish(nodes))
}

fn scene_file(scene: &Scene, model: &str) -> SceneFile {
    let span = &scene.time;
    let whole_start = span.start.timestamp_subsec_nanos() == 0;
    // ISO dates where they are exact (whole seconds), seconds otherwise, so
    // that a saved scene loads back identical.
    let time = |t: f64| {
        if whole_start && t.fract() == 0.0 {
            TimeValue::Iso(format_date(span.date_at(t)))
        } else {
            TimeValue::Seconds(t)
        }
    };
    let start = span
        .start
        .to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true);
    SceneFile {
        format: FORMAT.into(),
        name: scene.name.clone(),
        up: scene.up,
        time: TimeFile {
            start,
            end: time(span.seconds),
        },
        models: vec![model.into()],
        objects: scene
            .objects
            .iter()
            .filter(|o| !o.properties.is_empty())
            .map(|o| {
                (
                    o.id.clone(),
                    ObjectEntry {
                        properties: o.properties.clone(),
                        skip: false,
                    },
                )
            })
            .collect(),
        tasks: scene
            .tasks
            .iter()
            .map(|t| TaskFile {
                id: t.id.clone(),
                name: t.name.clone(),
                kind: t.ifc_type.unwrap_or(t.kind.name()).into(),
                start: time(t.start),
                finish: time(t.finish),
                actual_start: t.actual.start.map(time),
                actual_finish: t.actual.finish.map(time),
                baseline_start: t.baseline.map(|b| time(b.start)),
                baseline_finish: t.baseline.map(|b| time(b.finish)),
                parent: t.parent.clone(),
                predecessors: t
                    .predecessors
                    .iter()
                    .map(|p| PredecessorFile {
                        task: p.task.clone(),
                        kind: p.kind,
                        lag: p.lag,
                    })
                    .collect(),
                objects: t.objects.clone(),
            })
            .collect(),
        motion: scene
            .objects
            .iter()
            .filter_map(|o| {
                let keys = o.motion.as_ref()?.keyframes().iter().map(|k| KeyframeFile {
                    t: TimeValue::Seconds(k.t),
                    translation: k.translation.to_array(),
                    rotation: k.rotation.to_array(),
                    scale: k.scale.to_array(),
                });
                Some((o.id.clone(), keys.collect()))
            })
            .collect(),
        schedule_options: Some(scene.schedule_options),
        appearance: scene.appearance.as_ref().map(Profile::to_file),
        georeference: scene.georeference,
        // The clips of the models are saved as the motions they make,
        // above; only the joints of skins move with clips, one animation
        // per skinned object whose joints move, which plays keyframe `k`
        // at clip time `k`.
        clips: scene
            .objects
            .iter()
            .filter_map(|o| o.skin.as_deref())
            .map(|s| s.times())
            .filter(|times| !times.is_empty())
            .enumerate()
            .map(|(animation, times)| ClipFile {
                model: None,
                animation: AnimationRef::Index(animation),
                speed: 1.0,
                play: Vec::new(),
                repeat: None,
                keys: times
                    .iter()
                    .enumerate()
                    .map(|(k, &t)| ClipKeyFile {
                        t: time(t),
                        clip_time: k as f64,
                    })
                    .collect(),
            })
            .collect(),
    }
}
