//! The scene model: objects `s = (g_s, v_s, p_s)` with triangle geometry,
//! visibility and position functions over the time span `[0, T]`, the
//! schedule that drives visibility, and the classification of docs/method.md
//! section 1.

pub mod appearance;
pub mod format;
mod georef;
pub mod links;
mod motion;
pub mod rig;
mod schedule;
pub mod status;
mod summary;
mod visibility;

use std::collections::BTreeMap;

use glam::Mat4;
use serde::{Deserialize, Serialize};

use crate::geometry::Mesh;
use crate::geometry::skin::Skin;
use crate::time::TimeSpan;

pub use appearance::Profile;
pub use georef::{Geographic, Georeference, Projected, epsg_code};
pub use links::{LinkType, Predecessor};
pub use motion::{Keyframe, Motion};
pub(crate) use motion::{keys_until, unit};
pub use schedule::{Action, Instant, NamedType, ScheduleOptions, TaskType, compose};
pub use status::{Actual, Dates, Span, TaskDates};
pub use summary::{Bounds, Counts, SceneSummary, ScheduleSummary, TimeSummary};
pub use visibility::{Visibility, VisibilityType};

/// The names of the properties the IFC import gives an element (the
/// linking rules select by them, the object table of a tree reads its
/// name and class from them); other scenes may use them too.
pub mod property {
    /// The model file the element came from.
    pub const FILE: &str = "source_file";
    pub const STOREY: &str = "storey";
    /// The element's class: its IFC entity, such as `IfcWall`.
    pub const CLASS: &str = "ifc_class";
    pub const NAME: &str = "name";
}

/// Which axis points up in the scene's world frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Up {
    #[default]
    Y,
    Z,
}

/// The classes of docs/method.md section 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// Visible on all of `[0, T]`, never moves.
    Static,
    /// Appears and/or disappears, never moves.
    PseudoDynamic,
    /// Moves (and may appear and disappear).
    Dynamic,
    /// Never visible: dropped by the build.
    Absent,
}

impl Class {
    pub const ALL: [Class; 4] = [
        Class::Static,
        Class::PseudoDynamic,
        Class::Dynamic,
        Class::Absent,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Class::Static => "static",
            Class::PseudoDynamic => "pseudo_dynamic",
            Class::Dynamic => "dynamic",
            Class::Absent => "absent",
        }
    }
}

/// A schedule task, times in seconds since the scene's start.
#[derive(Debug, Clone, PartialEq)]
pub struct Task {
    pub id: String,
    pub name: String,
    pub kind: TaskType,
    /// The IFC task type its schedule named, if any (`INSTALLATION`): a
    /// profile may give it looks of its own.
    pub ifc_type: Option<&'static str>,
    /// The planned start and finish.
    pub start: f64,
    pub finish: f64,
    /// What was recorded of its execution.
    pub actual: Actual,
    /// An earlier plan's dates.
    pub baseline: Option<Span>,
    /// The id of its summary task in the work breakdown, if any.
    pub parent: Option<String>,
    /// The tasks it follows (the schedule's logic links).
    pub predecessors: Vec<Predecessor>,
    /// Ids of the objects the task acts on.
    pub objects: Vec<String>,
}

impl Task {
    /// A planned task with no actual or baseline dates, no parent and no
    /// predecessors.
    pub fn planned(
        id: impl Into<String>,
        name: impl Into<String>,
        kind: TaskType,
        start: f64,
        finish: f64,
        objects: Vec<String>,
    ) -> Task {
        Task {
            id: id.into(),
            name: name.into(),
            kind,
            ifc_type: None,
            start,
            finish,
            actual: Actual::default(),
            baseline: None,
            parent: None,
            predecessors: Vec::new(),
            objects,
        }
    }

    pub fn dates(&self) -> TaskDates {
        TaskDates {
            start: self.start,
            finish: self.finish,
            actual: self.actual,
            baseline: self.baseline,
        }
    }
}

/// One object of the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    pub id: String,
    /// Index into [`Scene::meshes`]; objects sharing a mesh are instances.
    pub mesh: usize,
    /// World placement of the mesh when the object has no motion.
    pub transform: Mat4,
    /// Linear RGBA colour, used where the mesh has no vertex colours.
    pub color: [f32; 4],
    pub visibility: Visibility,
    /// Keyframed world transform; replaces `transform` when present.
    pub motion: Option<Motion>,
    /// The joints that deform the mesh, when it is skinned. `transform`
    /// and `motion` still place the mesh in its bind pose, as the stages
    /// that do not skin draw it; the build poses an object whose joints
    /// move by its joints alone (`build::skinned`).
    pub skin: Option<Box<ObjectSkin>>,
    /// Free-form properties (storey, IFC class, source file, ...).
    pub properties: BTreeMap<String, String>,
}

/// A skinned object's deformation (glTF 2.0 section 3.7.3 "Skins"): kept
/// beside its mesh rather than baked into keyframed copies of it, so that
/// the mesh stays one bind-pose mesh and its pose at any time is its
/// vertices blended by the joints' world transforms then.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectSkin {
    /// Each vertex's four joints (indices into `joints`) and weights,
    /// which sum to 1.
    pub vertices: Skin,
    /// Each joint's inverse bind matrix: from the mesh's frame to the
    /// joint's frame in the bind pose.
    pub inverse_bind: Vec<Mat4>,
    pub joints: Vec<Joint>,
}

/// A joint of a skin: a node of the model's hierarchy, whose world
/// transform the clips move as they move an articulated part.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// The node's name in its model, if it has one.
    pub name: Option<String>,
    /// World transform when the joint has no motion.
    pub transform: Mat4,
    /// Keyframed world transform; replaces `transform` when present.
    pub motion: Option<Motion>,
}

impl Joint {
    /// The world transform at `t`.
    pub fn pose(&self, t: f64) -> Mat4 {
        self.motion.as_ref().map_or(self.transform, |m| m.at(t))
    }
}

/// Appends the joint matrices at `t` to `out`: each joint's world transform
/// after its inverse bind matrix (glTF 2.0 section 3.7.3).
pub fn joint_matrices_into(joints: &[Joint], inverse_bind: &[Mat4], t: f64, out: &mut Vec<Mat4>) {
    out.extend(
        joints
            .iter()
            .zip(inverse_bind)
            .map(|(j, inverse)| j.pose(t) * *inverse),
    );
}

impl ObjectSkin {
    /// The joint matrices at `t`: each joint's world transform after its
    /// inverse bind matrix.
    pub fn matrices(&self, t: f64) -> Vec<Mat4> {
        let mut out = Vec::with_capacity(self.joints.len());
        joint_matrices_into(&self.joints, &self.inverse_bind, t, &mut out);
        out
    }

    /// True when some joint's pose changes over time.
    pub fn moves(&self) -> bool {
        self.joints
            .iter()
            .any(|j| j.motion.as_ref().is_some_and(Motion::moves))
    }

    /// The times of every keyframe of the joints, sorted and distinct:
    /// where the joints' poses are given, linear between them (a clip that
    /// moves them has one key at each). Empty when no joint moves.
    pub fn times(&self) -> Vec<f64> {
        let mut times: Vec<f64> = self
            .joints
            .iter()
            .filter_map(|j| j.motion.as_ref())
            .flat_map(|m| m.keyframes().iter().map(|k| k.t))
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        times
    }

    /// `mesh` (the object's, in its bind pose) posed at `t`, in world
    /// coordinates. The object's own transform plays no part: the joints
    /// place a skinned mesh (glTF 2.0 section 3.7.3.1).
    pub fn pose(&self, mesh: &Mesh, t: f64) -> Mesh {
        self.vertices.pose(mesh, &self.matrices(t))
    }
}

impl Object {
    /// The world transform at `t`.
    pub fn pose(&self, t: f64) -> Mat4 {
        self.motion.as_ref().map_or(self.transform, |m| m.at(t))
    }

    pub fn class(&self, span: f64) -> Class {
        if self.visibility.present_seconds(span) <= 0.0 {
            Class::Absent
        } else if self.motion.as_ref().is_some_and(Motion::moves)
            || self.skin.as_ref().is_some_and(|s| s.moves())
        {
            Class::Dynamic
        } else if self.visibility.kind(span) == VisibilityType::Static {
            Class::Static
        } else {
            Class::PseudoDynamic
        }
    }
}

/// A whole 4D scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub name: String,
    pub up: Up,
    pub time: TimeSpan,
    /// Shared geometry in each mesh's own frame.
    pub meshes: Vec<Mesh>,
    pub objects: Vec<Object>,
    pub tasks: Vec<Task>,
    pub schedule_options: ScheduleOptions,
    /// The scene's own appearance profile, if it has one.
    pub appearance: Option<Profile>,
    /// Its place on Earth, if known.
    pub georeference: Option<Georeference>,
}

impl Scene {
    /// Recomputes every object's visibility from the tasks, on the dates
    /// the schedule options choose. Objects without a task are present
    /// throughout.
    pub fn apply_schedule(&mut self) {
        let index: BTreeMap<&str, usize> = self
            .objects
            .iter()
            .enumerate()
            .map(|(i, o)| (o.id.as_str(), i))
            .collect();
        let mut actions: Vec<Vec<Action>> = vec![Vec::new(); self.objects.len()];
        for task in &self.tasks {
            for id in &task.objects {
                if let Some(&i) = index.get(id.as_str()) {
                    let (start, finish) = task.dates().running(self.schedule_options.dates);
                    actions[i].push(Action {
                        kind: task.kind,
                        start,
                        finish,
                    });
                }
            }
        }
        for (object, actions) in self.objects.iter_mut().zip(actions) {
            object.visibility = compose(&actions, &self.schedule_options);
        }
    }

    pub fn class_of(&self, object: &Object) -> Class {
        object.class(self.time.seconds)
    }
}
