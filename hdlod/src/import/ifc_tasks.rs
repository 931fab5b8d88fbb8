//! IFC4 schedules inside a model: `IfcTask` with its `IfcTaskTime`, the
//! products it makes through `IfcRelAssignsToProduct` (outputs) and those it
//! acts on through `IfcRelAssignsToProcess` (inputs). The task's type is its
//! `PredefinedType` (or `ObjectType` when USERDEFINED), mapped by
//! [`TaskType::parse`] as docs/method.md section 1 says.
//!
//! Outputs take the task's type. Inputs are what the task uses up or acts
//! on: a construct task consumes its inputs (they disappear at its finish,
//! IfcOpenShell's default "consumed" input), any other task acts on them
//! with its own type.
//!
//! The planned dates are the schedule dates (else the early, else the
//! actual ones); `ActualStart`/`ActualFinish` are the actual dates. Tasks
//! nested in a task (`IfcRelNests`, the IFC4 work breakdown) have it as
//! their parent; a summary task without times of its own spans the tasks
//! nested in it.
//!
//! The logic links are `IfcRelSequence`s (the relating process is the
//! predecessor; `SequenceType` START_START, FINISH_START, ...; the lag an
//! `IfcLagTime` whose `LagValue` is an ISO 8601 duration in IFC4, seconds
//! in IFC2x3; a ratio lag reads as none). A task assigned to a work
//! schedule or work plan (`IfcRelAssignsToControl` to an
//! `IfcWorkSchedule`/`IfcWorkPlan`), itself or through the task it is
//! nested in, has its name as the field `work_schedule` (`work_plan`), for
//! the linking rules.
//!
//! IFC2x3 tasks keep their times in an `IfcScheduleTimeControl`, assigned
//! to them with an `IfcRelAssignsTasks`; its dates are `IfcDateAndTime`
//! (an `IfcCalendarDate` and an `IfcLocalTime`, read as UTC) or a bare
//! `IfcCalendarDate` (midnight).
//!
//! Reference: IFC 4.0 ADD2 TC1, IfcTask (attributes 0..12), IfcTaskTime
//! (ScheduleStart 5, ScheduleFinish 6, EarlyStart 7, EarlyFinish 8,
//! ActualStart 16, ActualFinish 17; 0 to 2 are those of
//! IfcSchedulingTime), IfcRelAssignsToProduct (RelatedObjects 4,
//! RelatingProduct 6), IfcRelAssignsToProcess (RelatedObjects 4,
//! RelatingProcess 6), IfcRelNests (RelatingObject 4, RelatedObjects 5),
//! IfcRelSequence (RelatingProcess 4, RelatedProcess 5, TimeLag 6,
//! SequenceType 7), IfcLagTime (LagValue 3), IfcRelAssignsToControl
//! (RelatedObjects 4, RelatingControl 6), IfcWorkSchedule and IfcWorkPlan
//! (Name 2). IFC2x3 TC1: IfcTask (TaskId 5, no times), IfcRelAssignsTasks
//! (RelatedObjects 4, RelatingControl 6, TimeForTask 7),
//! IfcScheduleTimeControl (ActualStart 5, EarlyStart 6, LateStart 7,
//! ScheduleStart 8, ActualFinish 9, EarlyFinish 10, LateFinish 11,
//! ScheduleFinish 12), IfcDateAndTime (DateComponent 0, TimeComponent 1),
//! IfcCalendarDate (DayComponent 0, MonthComponent 1, YearComponent 2),
//! IfcLocalTime (HourComponent 0, MinuteComponent 1, SecondComponent 2),
//! IfcRelSequence (TimeLag 6, an IfcTimeMeasure).

use std::collections::{HashMap, HashSet};
use std::path::Path;

use chrono::{DateTime, Utc};
use ifc_lite_core::{DecodedEntity, EntityDecoder, EntityScanner, IfcType};

use super::{Recorded, ScheduleTask, check_links};
use crate::error::{Error, Result};
use crate::scene::{LinkType, NamedType, Predecessor, TaskType};
use crate::time::parse_date;

/// A task's dates as its `IfcTaskTime` gives them, or as the tasks nested
/// in it span them.
#[derive(Debug, Clone, Copy)]
struct Times {
    start: DateTime<Utc>,
    finish: DateTime<Utc>,
    actual: Recorded,
    early: Option<(DateTime<Utc>, DateTime<Utc>)>,
    late: Option<(DateTime<Utc>, DateTime<Utc>)>,
}

/// A start and a finish, each given or not.
type Pair = [Option<DateTime<Utc>>; 2];

impl Times {
    /// The dates an IFC2x3 `IfcScheduleTimeControl` or an IFC4
    /// `IfcTaskTime` gives: planned from the schedule dates, else the early,
    /// else the actual ones. `entity` (`#12 (IfcTaskTime)`) names the record
    /// in errors.
    fn given(
        path: &Path,
        entity: &str,
        schedule: Pair,
        early: Pair,
        late: Pair,
        actual: Pair,
    ) -> Result<Times> {
        let at = |field: &str| format!("{entity} {field}");
        let (Some(start), Some(finish)) = (
            schedule[0].or(early[0]).or(actual[0]),
            schedule[1].or(early[1]).or(actual[1]),
        ) else {
            return Err(Error::invalid(
                path,
                entity.to_string(),
                "no ScheduleStart/ScheduleFinish (nor early or actual dates)",
            ));
        };
        if finish < start {
            return Err(Error::invalid(
                path,
                at("ScheduleFinish"),
                "the task finishes before it starts",
            ));
        }
        let actual = Recorded::new(actual[0], actual[1])
            .map_err(|m| Error::invalid(path, at("ActualFinish"), m))?;
        let both = |[a, b]: Pair| a.zip(b);
        Ok(Times {
            start,
            finish,
            actual,
            early: both(early),
            late: both(late),
        })
    }
}

/// An ISO 8601 duration, compiled once.
static DURATION: std::sync::LazyLock<regex::Regex> = std::sync::LazyLock::new(|| {
    regex::Regex::new(r"^(-)?P(?:([\d.]+)Y)?(?:([\d.]+)M)?(?:([\d.]+)W)?(?:([\d.]+)D)?(?:T(?:([\d.]+)H)?(?:([\d.]+)M)?(?:([\d.]+)S)?)?$").expect("a valid pattern")
});

/// An ISO 8601 duration in seconds (`P2D`, `PT8H30M`, `-P1W`; a year is
/// 365 days, a month 30).
fn iso_duration(text: &str) -> Option<f64> {
    let m = DURATION.captures(text.trim())?;
    let units = [
        365.0 * 86400.0,
        30.0 * 86400.0,
        7.0 * 86400.0,
        86400.0,
        3600.0,
        60.0,
        1.0,
    ];
    let mut seconds = 0.0;
    for (k, unit) in units.iter().enumerate() {
        if let Some(v) = m.get(k + 2) {
            seconds += v.as_str().parse::<f64>().ok()? * unit;
        }
    }
    Some(if m.get(1).is_some() {
        -seconds
    } else {
        seconds
    })
}

/// The dates of an IFC2x3 `IfcScheduleTimeControl`: planned from the
/// schedule dates, else the early, else the actual ones.
fn schedule_time_control(path: &Path, d: &mut EntityDecoder, id: u32) -> Result<Times> {
    let c = d
        .decode_by_id(id)
        .map_err(|e| Error::invalid(path, format!("#{id}"), e.to_string()))?;
    let at = |field: &str| format!("#{id} (IfcScheduleTimeControl) {field}");
    let mut date = |i: usize, field: &str| -> Result<Option<DateTime<Utc>>> {
        match c.get_ref(i) {
            Some(r) => date_time_2x3(d, r)
                .map(Some)
                .map_err(|m| Error::invalid(path, at(field), m)),
            None => Ok(None),
        }
    };
    let actual_start = date(5, "ActualStart")?;
    let early_start = date(6, "EarlyStart")?;
    let late_start = date(7, "LateStart")?;
    let schedule_start = date(8, "ScheduleStart")?;
    let actual_finish = date(9, "ActualFinish")?;
    let early_finish = date(10, "EarlyFinish")?;
    let late_finish = date(11, "LateFinish")?;
    let schedule_finish = date(12, "ScheduleFinish")?;
    Times::given(
        path,
        &format!("#{id} (IfcScheduleTimeControl)"),
        [schedule_start, schedule_finish],
        [early_start, early_finish],
        [late_start, late_finish],
        [actual_start, actual_finish],
    )
}

/// An IFC2x3 `IfcDateAndTime`, or an `IfcCalendarDate` (its midnight).
fn date_time_2x3(d: &mut EntityDecoder, id: u32) -> std::result::Result<DateTime<Utc>, String> {
    let e = d.decode_by_id(id).map_err(|e| format!("#{id}: {e}"))?;
    let int = |e: &DecodedEntity, i: usize| e.get(i).and_then(|v| v.as_int());
    let (date, time) = match e.get_ref(0) {
        Some(date) => (
            d.decode_by_id(date).map_err(|e| format!("#{date}: {e}"))?,
            e.get_ref(1)
                .map(|t| d.decode_by_id(t).map_err(|e| format!("#{t}: {e}")))
                .transpose()?,
        ),
        None => (e, None),
    };
    let (Some(day), Some(month), Some(year)) = (int(&date, 0), int(&date, 1), int(&date, 2)) else {
        return Err(format!(
            "#{}: not an IfcCalendarDate (day, month, year)",
            date.id
        ));
    };
    let (hour, minute, second) = match &time {
        Some(t) => (
            int(t, 0).unwrap_or(0),
            int(t, 1).unwrap_or(0),
            t.get(2).and_then(|v| v.as_float()).unwrap_or(0.0),
        ),
        None => (0, 0, 0.0),
    };
    chrono::NaiveDate::from_ymd_opt(year as i32, month as u32, day as u32)
        .and_then(|d| d.and_hms_opt(hour as u32, minute as u32, second as u32))
        .filter(|d| super::xer::YEARS.contains(&chrono::Datelike::year(d)))
        .map(|d| d.and_utc())
        .ok_or_else(|| {
            format!(
                "{year}-{month:02}-{day:02} {hour:02}:{minute:02}:{second:02} is not a date in \
                 the years {} to {}",
                super::xer::YEARS.start(),
                super::xer::YEARS.end()
            )
        })
}

/// The entities of the work schedules read by keyword: IFC2x3's are not
/// in the decoder's IFC4 type list.
const SCHEDULING: [&str; 5] = [
    "IFCRELSEQUENCE",
    "IFCRELASSIGNSTOCONTROL",
    "IFCRELASSIGNSTASKS",
    "IFCWORKSCHEDULE",
    "IFCWORKPLAN",
];

/// The tasks of an IFC4 or IFC2x3 file with their linked products (by
/// GlobalId), links and work schedules. Files without tasks give none.
pub fn read(path: &Path, schema: &str, step: &[u8]) -> Result<Vec<ScheduleTask>> {
    let ifc4 = schema.starts_with("IFC4");
    let mut scanner = EntityScanner::new(step);
    let mut wanted: HashMap<IfcType, Vec<u32>> = HashMap::new();
    let mut scheduling: HashMap<&str, Vec<u32>> = HashMap::new();
    while let Some((id, keyword, _, _)) = scanner.next_entity() {
        if let Some(k) = SCHEDULING.iter().find(|k| keyword.eq_ignore_ascii_case(k)) {
            scheduling.entry(*k).or_default().push(id);
        }
        let ty = IfcType::from_str(keyword);
        if matches!(
            ty,
            IfcType::IfcTask
                | IfcType::IfcRelAssignsToProduct
                | IfcType::IfcRelAssignsToProcess
                | IfcType::IfcRelNests
        ) {
            wanted.entry(ty).or_default().push(id);
        }
    }
    let task_ids = wanted.remove(&IfcType::IfcTask).unwrap_or_default();
    if task_ids.is_empty() {
        return Ok(Vec::new());
    }
    let mut d = EntityDecoder::new(step);
    let decode = |d: &mut EntityDecoder, id: u32| {
        d.decode_by_id(id)
            .map_err(|e| Error::invalid(path, format!("#{id}"), e.to_string()))
    };
    let guid = |d: &mut EntityDecoder, id: u32| -> Result<Option<String>> {
        Ok(decode(d, id)?.get_string(0).map(str::to_string))
    };

    // The work breakdown: task -> the task it is nested in.
    let is_task: HashSet<u32> = task_ids.iter().copied().collect();
    let mut parent_of: HashMap<u32, u32> = HashMap::new();
    for rel in wanted.remove(&IfcType::IfcRelNests).unwrap_or_default() {
        let r = decode(&mut d, rel)?;
        let Some(whole) = r.get_ref(4).filter(|w| is_task.contains(w)) else {
            continue;
        };
        for part in r.get_refs(5).unwrap_or_default() {
            if is_task.contains(&part) {
                parent_of.entry(part).or_insert(whole);
            }
        }
    }

    // Work schedules and plans by name; IFC2x3 task times by task.
    let mut controls: HashMap<u32, (&str, String)> = HashMap::new();
    for (keyword, field) in [
        ("IFCWORKSCHEDULE", "work_schedule"),
        ("IFCWORKPLAN", "work_plan"),
    ] {
        for &id in scheduling.get(keyword).into_iter().flatten() {
            let name = decode(&mut d, id)?
                .get_string(2)
                .unwrap_or_default()
                .to_string();
            controls.insert(id, (field, name));
        }
    }
    let mut assigned: HashMap<u32, Vec<(&str, String)>> = HashMap::new();
    let mut time_control: HashMap<u32, u32> = HashMap::new();
    for keyword in ["IFCRELASSIGNSTOCONTROL", "IFCRELASSIGNSTASKS"] {
        for &rel in scheduling.get(keyword).into_iter().flatten() {
            let r = decode(&mut d, rel)?;
            let related: Vec<u32> = r
                .get_refs(4)
                .unwrap_or_default()
                .into_iter()
                .filter(|t| is_task.contains(t))
                .collect();
            if let Some(control) = r.get_ref(6).and_then(|c| controls.get(&c)) {
                for &t in &related {
                    assigned.entry(t).or_default().push(control.clone());
                }
            }
            if let Some(time) = r.get_ref(7) {
                for &t in &related {
                    time_control.entry(t).or_insert(time);
                }
            }
        }
    }

    // Each task's attributes and own times, in file order.
    let mut read = Vec::with_capacity(task_ids.len());
    for &id in &task_ids {
        let t = decode(&mut d, id)?;
        let times = match (ifc4, t.get_ref(11), time_control.get(&id)) {
            (true, Some(time_id), _) => Some(task_time(path, &decode(&mut d, time_id)?, time_id)?),
            (false, _, Some(&control)) => Some(schedule_time_control(path, &mut d, control)?),
            _ => None,
        };
        let predefined = t.get(12).and_then(|v| v.as_enum()).unwrap_or("NOTDEFINED");
        let kind =
            NamedType::parse(predefined).or_else(|| t.get_string(4).and_then(NamedType::parse));
        let task_id = t
            .get_string(5)
            .filter(|s| !s.is_empty())
            .or(t.get_string(0))
            .unwrap_or_default()
            .to_string();
        let name = t.get_string(2).unwrap_or_default().to_string();
        read.push((id, task_id, name, kind, times));
    }
    let own: HashMap<u32, Times> = read
        .iter()
        .filter_map(|(id, .., times)| times.map(|t| (*id, t)))
        .collect();
    let spans = nested_spans(&own, &parent_of);
    let ids: HashMap<u32, &str> = read.iter().map(|(id, t, ..)| (*id, t.as_str())).collect();

    let mut tasks = Vec::new();
    let mut index = HashMap::new();
    for (id, task_id, name, kind, times) in &read {
        // A task without times, and none nested in it, places nothing.
        let Some(times) = times.or_else(|| spans.get(id).copied()) else {
            continue;
        };
        index.insert(*id, tasks.len());
        // Its work schedule: its own, else that of the task it is nested in.
        let mut fields = std::collections::BTreeMap::new();
        let mut at = Some(*id);
        for _ in 0..=parent_of.len() {
            let Some(a) = at else { break };
            for (field, name) in assigned.get(&a).into_iter().flatten() {
                fields
                    .entry(field.to_string())
                    .or_insert_with(|| name.clone());
            }
            at = parent_of.get(&a).copied();
        }
        tasks.push(ScheduleTask {
            kind: *kind,
            actual: times.actual,
            early: times.early,
            late: times.late,
            parent: parent_of
                .get(id)
                .and_then(|p| ids.get(p))
                .map(|p| p.to_string()),
            fields,
            ..ScheduleTask::planned(task_id.clone(), name.clone(), times.start, times.finish)
        });
    }

    // The logic links between tasks with dates.
    for &rel in scheduling.get("IFCRELSEQUENCE").into_iter().flatten() {
        let r = decode(&mut d, rel)?;
        let (Some(&pred), Some(&succ)) = (
            r.get_ref(4).and_then(|p| index.get(&p)),
            r.get_ref(5).and_then(|p| index.get(&p)),
        ) else {
            continue;
        };
        let kind = r
            .get(7)
            .and_then(|v| v.as_enum())
            .and_then(LinkType::parse)
            .unwrap_or_default();
        let lag = match (ifc4, r.get_ref(6)) {
            (true, Some(lag_id)) => {
                let l = decode(&mut d, lag_id)?;
                match l.get(3).and_then(|v| v.as_string()) {
                    Some(text) => iso_duration(text).ok_or_else(|| {
                        Error::invalid(
                            path,
                            format!("#{lag_id} (IfcLagTime) LagValue"),
                            format!("{text:?} is not an ISO 8601 duration (P2D, PT8H)"),
                        )
                    })?,
                    // A ratio of the predecessor's duration.
                    None => 0.0,
                }
            }
            (false, _) => r.get_float(6).unwrap_or(0.0),
            (true, None) => 0.0,
        };
        let task = tasks[pred].id.clone();
        tasks[succ]
            .predecessors
            .push(Predecessor { task, kind, lag });
    }
    check_links(path, "IfcRelSequence", &tasks)?;

    let mut consumed: Vec<(usize, String)> = Vec::new();
    for rel in wanted
        .remove(&IfcType::IfcRelAssignsToProduct)
        .unwrap_or_default()
    {
        let r = decode(&mut d, rel)?;
        let Some(product) = r.get_ref(6) else {
            continue;
        };
        let Some(product) = guid(&mut d, product)? else {
            continue;
        };
        for related in r.get_refs(4).unwrap_or_default() {
            if let Some(&k) = index.get(&related) {
                tasks[k].objects.push(product.clone());
            }
        }
    }
    for rel in wanted
        .remove(&IfcType::IfcRelAssignsToProcess)
        .unwrap_or_default()
    {
        let r = decode(&mut d, rel)?;
        let Some(&k) = r.get_ref(6).and_then(|p| index.get(&p)) else {
            continue;
        };
        for related in r.get_refs(4).unwrap_or_default() {
            let Some(product) = guid(&mut d, related)? else {
                continue;
            };
            if tasks[k].kind.map_or(TaskType::Construct, |t| t.kind) == TaskType::Construct {
                consumed.push((k, product));
            } else {
                tasks[k].objects.push(product);
            }
        }
    }
    // Consumed inputs: a demolish task of their own, ending with the task.
    for (k, product) in consumed {
        let t = &tasks[k];
        let id = format!("{}:consumed", t.id);
        let existing = tasks.iter().position(|x| x.id == id);
        match existing {
            Some(j) => tasks[j].objects.push(product),
            None => {
                let t = tasks[k].clone();
                tasks.push(ScheduleTask {
                    id,
                    name: format!("{} (consumed inputs)", t.name),
                    kind: Some(TaskType::Demolish.into()),
                    objects: vec![product],
                    ..t
                });
            }
        }
    }
    Ok(tasks)
}

/// The planned and actual dates of an `IfcTaskTime`.
fn task_time(path: &Path, time: &DecodedEntity, time_id: u32) -> Result<Times> {
    let entity = format!("#{time_id} (IfcTaskTime)");
    let parse = |i: usize, field: &str| {
        time.get_string(i)
            .map(|text| {
                parse_date(text)
                    .map_err(|m| Error::invalid(path, format!("{entity} {field}"), m.to_string()))
            })
            .transpose()
    };
    Times::given(
        path,
        &entity,
        [parse(5, "ScheduleStart")?, parse(6, "ScheduleFinish")?],
        [parse(7, "EarlyStart")?, parse(8, "EarlyFinish")?],
        [parse(9, "LateStart")?, parse(10, "LateFinish")?],
        [parse(16, "ActualStart")?, parse(17, "ActualFinish")?],
    )
}

/// The dates of each task without times of its own that has tasks with
/// times nested in it (at any depth): planned from the first start to the
/// last finish below it; actual from the first actual start, finished when
/// everything below it has finished.
fn nested_spans(own: &HashMap<u32, Times>, parent_of: &HashMap<u32, u32>) -> HashMap<u32, Times> {
    let mut spans: HashMap<u32, Times> = HashMap::new();
    for (&task, times) in own {
        let mut at = task;
        // At most one step per nesting: a cycle in a broken file ends it.
        for _ in 0..parent_of.len() {
            let Some(&whole) = parent_of.get(&at) else {
                break;
            };
            at = whole;
            if own.contains_key(&whole) {
                continue;
            }
            spans
                .entry(whole)
                .and_modify(|s| {
                    s.start = s.start.min(times.start);
                    s.finish = s.finish.max(times.finish);
                    s.actual = Recorded {
                        start: match (s.actual.start, times.actual.start) {
                            (Some(a), Some(b)) => Some(a.min(b)),
                            (a, b) => a.or(b),
                        },
                        finish: s
                            .actual
                            .finish
                            .zip(times.actual.finish)
                            .map(|(a, b)| a.max(b)),
                    };
                })
                .or_insert(Times {
                    early: None,
                    late: None,
                    ..*times
                });
        }
    }
    spans
}
