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
//! Reference: IFC 4.0 ADD2 TC1, IfcTask (attributes 0..12), IfcTaskTime
//! (ScheduleStart 5, ScheduleFinish 6, EarlyStart 7, EarlyFinish 8,
//! ActualStart 16, ActualFinish 17; 0 to 2 are those of
//! IfcSchedulingTime), IfcRelAssignsToProduct (RelatedObjects 4,
//! RelatingProduct 6), IfcRelAssignsToProcess (RelatedObjects 4,
//! RelatingProcess 6), IfcRelNests (RelatingObject 4, RelatedObjects 5).
//! IFC2x3 tasks carry no times (those sit in IfcScheduleTimeControl) and
//! are not read.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use chrono::{DateTime, Utc};
use ifc_lite_core::{DecodedEntity, EntityDecoder, EntityScanner, IfcType};

use super::{Recorded, ScheduleTask};
use crate::error::{Error, Result};
use crate::scene::TaskType;
use crate::time::parse_date;

/// A task's dates as its `IfcTaskTime` gives them, or as the tasks nested
/// in it span them.
#[derive(Debug, Clone, Copy)]
struct Times {
    start: DateTime<Utc>,
    finish: DateTime<Utc>,
    actual: Recorded,
}

/// The tasks of an IFC4 file with their linked products (by GlobalId).
/// Files of other schemas, or without tasks, give none.
pub fn read(path: &Path, schema: &str, step: &[u8]) -> Result<Vec<ScheduleTask>> {
    if !schema.starts_with("IFC4") {
        return Ok(Vec::new());
    }
    let mut scanner = EntityScanner::new(step);
    let mut wanted: HashMap<IfcType, Vec<u32>> = HashMap::new();
    while let Some((id, keyword, _, _)) = scanner.next_entity() {
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

    // Each task's attributes and own times, in file order.
    let mut read = Vec::with_capacity(task_ids.len());
    for &id in &task_ids {
        let t = decode(&mut d, id)?;
        let times = match t.get_ref(11) {
            Some(time_id) => Some(task_time(path, &decode(&mut d, time_id)?, time_id)?),
            None => None,
        };
        let predefined = t.get(12).and_then(|v| v.as_enum()).unwrap_or("NOTDEFINED");
        let kind =
            TaskType::parse(predefined).or_else(|| t.get_string(4).and_then(TaskType::parse));
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
        tasks.push(ScheduleTask {
            kind: *kind,
            actual: times.actual,
            parent: parent_of
                .get(id)
                .and_then(|p| ids.get(p))
                .map(|p| p.to_string()),
            ..ScheduleTask::planned(task_id.clone(), name.clone(), times.start, times.finish)
        });
    }

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
            if tasks[k].kind.unwrap_or(TaskType::Construct) == TaskType::Construct {
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
                    kind: Some(TaskType::Demolish),
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
    let at = |field: &str| format!("#{time_id} (IfcTaskTime) {field}");
    let parse = |i: usize, field: &str| {
        time.get_string(i)
            .map(|text| {
                parse_date(text).map_err(|m| Error::invalid(path, at(field), m.to_string()))
            })
            .transpose()
    };
    let first = |fields: &[(usize, &str)]| -> Result<Option<DateTime<Utc>>> {
        for &(i, field) in fields {
            if let Some(d) = parse(i, field)? {
                return Ok(Some(d));
            }
        }
        Ok(None)
    };
    let actual_start = parse(16, "ActualStart")?;
    let actual_finish = parse(17, "ActualFinish")?;
    let (Some(start), Some(finish)) = (
        first(&[(5, "ScheduleStart"), (7, "EarlyStart"), (16, "ActualStart")])?,
        first(&[
            (6, "ScheduleFinish"),
            (8, "EarlyFinish"),
            (17, "ActualFinish"),
        ])?,
    ) else {
        return Err(Error::invalid(
            path,
            format!("#{time_id} (IfcTaskTime)"),
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
    let actual = Recorded::new(actual_start, actual_finish)
        .map_err(|m| Error::invalid(path, at("ActualFinish"), m))?;
    Ok(Times {
        start,
        finish,
        actual,
    })
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
                .or_insert(*times);
        }
    }
    spans
}
