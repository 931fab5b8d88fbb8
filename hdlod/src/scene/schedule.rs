//! Schedule-driven visibility: tasks of four types act on objects, and the
//! visibility of an object is composed from all its tasks (docs/method.md
//! section 1, the profiles of Navisworks TimeLiner, Synchro and IfcOpenShell).

use serde::{Deserialize, Serialize};

use super::status::Dates;
use super::visibility::Visibility;

/// What a task does to the objects it acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskType {
    /// Absent before the task, present from it on.
    Construct,
    /// Present until the task's finish, absent after.
    Demolish,
    /// Present from the task's start to its finish.
    Temporary,
    /// Present throughout.
    Maintain,
}

/// The IFC task types (`IfcTaskTypeEnum`) that name one of ours.
const IFC_NAMES: [(&str, TaskType); 11] = [
    ("CONSTRUCTION", TaskType::Construct),
    ("INSTALLATION", TaskType::Construct),
    ("DEMOLITION", TaskType::Demolish),
    ("DISMANTLE", TaskType::Demolish),
    ("DISPOSAL", TaskType::Demolish),
    ("REMOVAL", TaskType::Demolish),
    ("MAINTENANCE", TaskType::Maintain),
    ("OPERATION", TaskType::Maintain),
    ("ATTENDANCE", TaskType::Maintain),
    ("LOGISTIC", TaskType::Maintain),
    ("MOVE", TaskType::Maintain),
];

impl TaskType {
    /// Parses our names and the IFC `IfcTaskTypeEnum` names (any case).
    pub fn parse(name: &str) -> Option<TaskType> {
        NamedType::parse(name).map(|t| t.kind)
    }

    pub const ALL: [TaskType; 4] = [
        TaskType::Construct,
        TaskType::Demolish,
        TaskType::Temporary,
        TaskType::Maintain,
    ];

    /// Its place in [`TaskType::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The name files use (`construct`, ...).
    pub fn name(self) -> &'static str {
        match self {
            TaskType::Construct => "construct",
            TaskType::Demolish => "demolish",
            TaskType::Temporary => "temporary",
            TaskType::Maintain => "maintain",
        }
    }

    /// All accepted names, for error messages.
    pub const NAMES: &'static str = "construct, demolish, temporary, maintain (or the IFC names \
         CONSTRUCTION, INSTALLATION, DEMOLITION, DISMANTLE, DISPOSAL, REMOVAL, MAINTENANCE, \
         OPERATION, ATTENDANCE, LOGISTIC, MOVE)";
}

/// A task type as its schedule names it: what the task does and, when the
/// schedule gave an IFC task type, that name. Several IFC types do the same
/// (INSTALLATION and CONSTRUCTION both construct), and planners colour them
/// apart, so the name is kept beside the type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NamedType {
    pub kind: TaskType,
    /// The IFC name, upper case, as in [`IFC_NAMES`].
    pub ifc: Option<&'static str>,
}

impl NamedType {
    /// Our names and the IFC names, any case.
    pub fn parse(name: &str) -> Option<NamedType> {
        if let Some(&kind) = TaskType::ALL
            .iter()
            .find(|k| k.name().eq_ignore_ascii_case(name))
        {
            return Some(kind.into());
        }
        let &(ifc, kind) = IFC_NAMES
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))?;
        Some(NamedType {
            kind,
            ifc: Some(ifc),
        })
    }

    /// The name files use: the IFC name if there is one, else ours.
    pub fn name(self) -> &'static str {
        self.ifc.unwrap_or(self.kind.name())
    }
}

impl From<TaskType> for NamedType {
    fn from(kind: TaskType) -> NamedType {
        NamedType { kind, ifc: None }
    }
}

/// The instant inside a task at which its effect happens.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Instant {
    Start,
    Finish,
}

/// Build options of the schedule: which dates it follows, when a
/// constructed element appears and when a demolished one disappears.
/// Defaults follow docs/method.md section 1: the planned dates, present from
/// the start of its construct task, present until the finish of its
/// demolish task. Written as an object of these fields (each optional) or,
/// for the dates alone, as `"planned"` or `"actual"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "OptionsFile")]
pub struct ScheduleOptions {
    pub dates: Dates,
    pub construct_at: Instant,
    pub demolish_at: Instant,
}

impl Default for ScheduleOptions {
    fn default() -> Self {
        ScheduleOptions {
            dates: Dates::Planned,
            construct_at: Instant::Start,
            demolish_at: Instant::Finish,
        }
    }
}

#[derive(Deserialize)]
#[serde(untagged)]
enum OptionsFile {
    Dates(Dates),
    Fields(OptionFields),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OptionFields {
    #[serde(default)]
    dates: Dates,
    #[serde(default = "start")]
    construct_at: Instant,
    #[serde(default = "finish")]
    demolish_at: Instant,
}

fn start() -> Instant {
    Instant::Start
}

fn finish() -> Instant {
    Instant::Finish
}

impl From<OptionsFile> for ScheduleOptions {
    fn from(f: OptionsFile) -> Self {
        match f {
            OptionsFile::Dates(dates) => ScheduleOptions {
                dates,
                ..ScheduleOptions::default()
            },
            OptionsFile::Fields(f) => ScheduleOptions {
                dates: f.dates,
                construct_at: f.construct_at,
                demolish_at: f.demolish_at,
            },
        }
    }
}

/// One task as it applies to an object, times in seconds since the start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Action {
    pub kind: TaskType,
    pub start: f64,
    pub finish: f64,
}

/// Composes the visibility of an object from the tasks acting on it. An
/// object with no task is present throughout (an unscheduled element is
/// shown, as 4D tools do).
///
/// Construct and demolish tasks are events in time order: the object starts
/// absent if its first event is a construct and present otherwise, each
/// construct makes it present, each demolish absent. Temporary tasks add
/// their interval, a maintain task makes the object present throughout.
/// This expresses every visibility type of the paper: construct then
/// demolish is temporary, demolish then construct reappearing, several
/// temporary tasks skipped.
pub fn compose(actions: &[Action], options: &ScheduleOptions) -> Visibility {
    if actions.is_empty() || actions.iter().any(|a| a.kind == TaskType::Maintain) {
        return Visibility::always();
    }
    let at = |a: &Action, i: Instant| match i {
        Instant::Start => a.start,
        Instant::Finish => a.finish,
    };
    let mut events: Vec<(f64, bool)> = actions
        .iter()
        .filter_map(|a| match a.kind {
            TaskType::Construct => Some((at(a, options.construct_at), true)),
            TaskType::Demolish => Some((at(a, options.demolish_at), false)),
            _ => None,
        })
        .collect();
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut intervals: Vec<(f64, f64)> = actions
        .iter()
        .filter(|a| a.kind == TaskType::Temporary)
        .map(|a| (a.start, a.finish))
        .collect();
    if let Some(&(_, first_is_construct)) = events.first() {
        let mut present_since = (!first_is_construct).then_some(f64::NEG_INFINITY);
        for (t, construct) in events {
            match (construct, present_since) {
                (true, None) => present_since = Some(t),
                (false, Some(since)) => {
                    intervals.push((since, t));
                    present_since = None;
                }
                _ => {}
            }
        }
        if let Some(since) = present_since {
            intervals.push((since, f64::INFINITY));
        }
    }
    Visibility::from_intervals(intervals)
}

#[cfg(test)]
mod tests {
    use super::super::visibility::VisibilityType::{self, *};
    use super::*;

    fn act(kind: TaskType, start: f64, finish: f64) -> Action {
        Action {
            kind,
            start,
            finish,
        }
    }

    #[test]
    fn composes_every_type() {
        use TaskType::*;
        let o = ScheduleOptions::default();
        let kind = |a: &[Action]| compose(a, &o).kind(100.0);
        assert_eq!(kind(&[]), Static);
        assert_eq!(kind(&[act(Maintain, 10.0, 20.0)]), Static);
        assert_eq!(kind(&[act(Construct, 10.0, 20.0)]), Appearing);
        assert_eq!(kind(&[act(Demolish, 10.0, 20.0)]), Disappearing);
        assert_eq!(
            kind(&[act(Temporary, 10.0, 20.0)]),
            VisibilityType::Temporary
        );
        assert_eq!(
            kind(&[act(Construct, 10.0, 20.0), act(Demolish, 30.0, 40.0)]),
            VisibilityType::Temporary
        );
        assert_eq!(
            kind(&[act(Temporary, 10.0, 20.0), act(Temporary, 30.0, 40.0)]),
            Skipped
        );
        assert_eq!(
            kind(&[act(Demolish, 10.0, 20.0), act(Construct, 30.0, 40.0)]),
            Reappearing
        );
        assert_eq!(
            kind(&[
                act(Demolish, 10.0, 20.0),
                act(Construct, 30.0, 40.0),
                act(Demolish, 50.0, 60.0)
            ]),
            ReDisappearing
        );
        assert_eq!(kind(&[act(Construct, 200.0, 300.0)]), Absent);
    }

    #[test]
    fn instants_are_options() {
        let a = [
            act(TaskType::Construct, 10.0, 20.0),
            act(TaskType::Demolish, 30.0, 40.0),
        ];
        let v = compose(&a, &ScheduleOptions::default());
        assert_eq!(v.intervals(), &[(10.0, 40.0)]);
        let v = compose(
            &a,
            &ScheduleOptions {
                construct_at: Instant::Finish,
                demolish_at: Instant::Start,
                ..ScheduleOptions::default()
            },
        );
        assert_eq!(v.intervals(), &[(20.0, 30.0)]);
    }

    #[test]
    fn parses_ifc_aliases() {
        assert_eq!(TaskType::parse("INSTALLATION"), Some(TaskType::Construct));
        assert_eq!(TaskType::parse("dismantle"), Some(TaskType::Demolish));
        assert_eq!(TaskType::parse("temporary"), Some(TaskType::Temporary));
        assert_eq!(TaskType::parse("OPERATION"), Some(TaskType::Maintain));
        assert_eq!(TaskType::parse("party"), None);
        let installation = NamedType::parse("installation").unwrap();
        assert_eq!(installation.kind, TaskType::Construct);
        assert_eq!(installation.name(), "INSTALLATION");
        assert_eq!(NamedType::parse("Construct").unwrap().name(), "construct");
    }
}
