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
//! Reference: IFC 4.0 ADD2 TC1, IfcTask (attributes 0..12), IfcTaskTime
//! (ScheduleStart 5, ScheduleFinish 6, EarlyStart 7, EarlyFinish 8,
//! ActualStart 16, ActualFinish 17), IfcRelAssignsToProduct (RelatedObjects
//! 4, RelatingProduct 6), IfcRelAssignsToProcess (RelatedObjects 4,
//! RelatingProcess 6). IFC2x3 tasks carry no times (those sit in
//! IfcScheduleTimeControl) and are not read.

use std::collections::HashMap;
use std::path::Path;

use ifc_lite_core::{EntityDecoder, EntityScanner, IfcType};

use super::ScheduleTask;
use crate::error::{Error, Result};
use crate::scene::TaskType;
use crate::time::parse_date;

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
            IfcType::IfcTask | IfcType::IfcRelAssignsToProduct | IfcType::IfcRelAssignsToProcess
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

    let mut tasks = Vec::new();
    let mut index = HashMap::new();
    for id in task_ids {
        let t = decode(&mut d, id)?;
        let at = |field: &str| format!("#{id} (IfcTask) {field}");
        let Some(time_id) = t.get_ref(11) else {
            // A task without times (a summary or a note) places nothing.
            continue;
        };
        let time = decode(&mut d, time_id)?;
        let date = |pairs: &[usize]| pairs.iter().find_map(|&i| time.get_string(i));
        let (Some(start), Some(finish)) = (date(&[5, 7, 16]), date(&[6, 8, 17])) else {
            return Err(Error::invalid(
                path,
                format!("#{time_id} (IfcTaskTime)"),
                "no ScheduleStart/ScheduleFinish (nor early or actual dates)",
            ));
        };
        let parse = |text: &str, field: &str| {
            parse_date(text)
                .map_err(|m| Error::invalid(path, format!("#{time_id} {field}"), m.to_string()))
        };
        let (start, finish) = (parse(start, "start")?, parse(finish, "finish")?);
        if finish < start {
            return Err(Error::invalid(
                path,
                at("TaskTime"),
                "finishes before it starts",
            ));
        }
        let predefined = t.get(12).and_then(|v| v.as_enum()).unwrap_or("NOTDEFINED");
        let kind =
            TaskType::parse(predefined).or_else(|| t.get_string(4).and_then(TaskType::parse));
        index.insert(id, tasks.len());
        tasks.push(ScheduleTask {
            id: t
                .get_string(5)
                .filter(|s| !s.is_empty())
                .or(t.get_string(0))
                .unwrap_or_default()
                .to_string(),
            name: t.get_string(2).unwrap_or_default().to_string(),
            kind,
            start,
            finish,
            objects: Vec::new(),
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
