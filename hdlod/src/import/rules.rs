//! Linking rules (`hdlod-links/1`, schemas/links.schema.json): attach objects
//! to schedule tasks by what they are, the way Navisworks TimeLiner's rules
//! and Synchro's auto-matching do for schedules without element links. A
//! rule selects objects by source file, storey, IFC class, name or any
//! property, and assigns them to a task (by id, or by a unique name) with a
//! type. Every rule applies to every object it selects, so an object may
//! get several tasks (built, then demolished).
//!
//! Patterns are globs (`*`, `?`, `[a-z]`, `{a,b}`; globset), case-insensitive,
//! matched against the whole value, or `{"regex": "..."}` (regex crate,
//! searched anywhere in the value unless anchored), or a list of them (any
//! may match).

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use serde::Deserialize;

use super::ScheduleTask;
use super::xlsx::{FIELDS, Mapping};
use crate::error::{Error, Result};
use crate::scene::{NamedType, Object, TaskType};

/// The value of the `format` field.
pub const FORMAT: &str = "hdlod-links/1";

/// A rules file as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RulesFile {
    format: String,
    /// Free text for the reader of the file.
    #[serde(default, rename = "description")]
    _description: Option<serde::de::IgnoredAny>,
    /// The columns of a spreadsheet schedule.
    #[serde(default)]
    spreadsheet: Option<Mapping>,
    rules: Vec<RuleFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RuleFile {
    name: String,
    select: SelectFile,
    #[serde(default)]
    task: Option<String>,
    #[serde(default)]
    task_name: Option<String>,
    /// Tasks by what they are, instead of one task.
    #[serde(default)]
    tasks: Option<TaskSelectFile>,
    /// Object property -> task attribute: each object goes to the selected
    /// tasks whose attribute equals its property.
    #[serde(default, rename = "match")]
    join: BTreeMap<String, String>,
    #[serde(rename = "type", default)]
    kind: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct TaskSelectFile {
    id: Option<PatternFile>,
    name: Option<PatternFile>,
    wbs: Option<PatternFile>,
    #[serde(default)]
    codes: BTreeMap<String, PatternFile>,
    #[serde(default)]
    fields: BTreeMap<String, PatternFile>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct SelectFile {
    file: Option<PatternFile>,
    storey: Option<PatternFile>,
    class: Option<PatternFile>,
    name: Option<PatternFile>,
    #[serde(default)]
    properties: BTreeMap<String, PatternFile>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum PatternFile {
    Glob(String),
    Regex { regex: String },
    Any(Vec<PatternFile>),
}

/// A compiled pattern.
#[derive(Debug)]
enum Pattern {
    Glob(globset::GlobMatcher),
    Regex(regex::Regex),
    Any(Vec<Pattern>),
}

impl Pattern {
    fn compile(p: &PatternFile) -> std::result::Result<Pattern, String> {
        Ok(match p {
            PatternFile::Glob(g) => Pattern::Glob(
                globset::GlobBuilder::new(g)
                    .case_insensitive(true)
                    .literal_separator(false)
                    .build()
                    .map_err(|e| format!("bad glob {g:?}: {e}"))?
                    .compile_matcher(),
            ),
            PatternFile::Regex { regex } => Pattern::Regex(
                regex::Regex::new(regex).map_err(|e| format!("bad regex {regex:?}: {e}"))?,
            ),
            PatternFile::Any(list) => Pattern::Any(
                list.iter()
                    .map(Pattern::compile)
                    .collect::<std::result::Result<_, _>>()?,
            ),
        })
    }

    fn matches(&self, value: &str) -> bool {
        match self {
            Pattern::Glob(g) => g.is_match(value),
            Pattern::Regex(r) => r.is_match(value),
            Pattern::Any(list) => list.iter().any(|p| p.matches(value)),
        }
    }
}

/// One compiled rule.
#[derive(Debug)]
pub struct Rule {
    pub name: String,
    /// Object property -> pattern; all must match.
    select: Vec<(String, Pattern)>,
    /// Indices of its tasks in the schedule: one, or those its task
    /// selector matched, in schedule order.
    pub tasks: Vec<usize>,
    /// The object property a selected object's tasks are matched on, and
    /// its tasks by their value of the task attribute (normalised).
    join: Option<(String, HashMap<String, Vec<usize>>)>,
    /// The type the rule gives, else the task's own, else construct.
    pub kind: Option<NamedType>,
}

impl Rule {
    pub fn selects(&self, object: &Object) -> bool {
        self.select.iter().all(|(key, pattern)| {
            object
                .properties
                .get(key)
                .is_some_and(|v| pattern.matches(v))
        })
    }

    /// The tasks the rule gives `object`: none unless it selects it; with a
    /// `match`, those whose attribute equals the object's property.
    pub fn tasks_of(&self, object: &Object) -> &[usize] {
        if !self.selects(object) {
            return &[];
        }
        match &self.join {
            None => &self.tasks,
            Some((key, by_value)) => object
                .properties
                .get(key)
                .and_then(|v| by_value.get(&normalise(v)))
                .map_or(&[], Vec::as_slice),
        }
    }
}

/// Values compared by a `match`: trimmed, in any case.
fn normalise(value: &str) -> String {
    value.trim().to_lowercase()
}

/// A task's attribute as rules name it: `id`, `name`, `wbs`, `code:TYPE`
/// (an activity code) or `field:NAME` (a user or custom field, or one of
/// the CPM dates `early_start`, `early_finish`, `late_start`,
/// `late_finish`).
fn task_attribute(task: &ScheduleTask, key: &str) -> Option<String> {
    if let Some(code) = key.strip_prefix("code:") {
        return task.codes.get(code).cloned();
    }
    if let Some(field) = key.strip_prefix("field:") {
        return task.field(field);
    }
    match key {
        "id" => Some(task.id.clone()),
        "name" => Some(task.name.clone()),
        "wbs" => task.wbs.clone(),
        _ => None,
    }
}

/// Whether `key` names a task attribute (see [`task_attribute`]).
fn is_task_attribute(key: &str) -> bool {
    matches!(key, "id" | "name" | "wbs")
        || key.strip_prefix("code:").is_some_and(|k| !k.is_empty())
        || key.strip_prefix("field:").is_some_and(|k| !k.is_empty())
}

/// The property names the selectors `file`, `storey`, `class` and `name`
/// stand for.
pub use crate::scene::property::{CLASS, FILE, NAME, STOREY};

/// The rules file, parsed and its format checked.
fn parse(path: &Path) -> Result<RulesFile> {
    let text = crate::input::read_to_string(path)?;
    let de = &mut serde_json::Deserializer::from_str(&text);
    let file: RulesFile = serde_path_to_error::deserialize(de)
        .map_err(|e| Error::invalid(path, e.path().to_string(), e.inner().to_string()))?;
    if file.format != FORMAT {
        return Err(Error::invalid(
            path,
            "format",
            format!("{:?} is not {FORMAT:?}", file.format),
        ));
    }
    Ok(file)
}

/// The property-set properties the rules name (`Pset_WallCommon.FireRating`
/// in `select.properties` or as a `match` property): the IFC reader
/// imports their values.
pub fn property_sets(path: &Path) -> Result<std::collections::HashSet<String>> {
    let file = parse(path)?;
    Ok(file
        .rules
        .iter()
        .flat_map(|r| r.select.properties.keys().chain(r.join.keys()))
        .filter(|k| k.contains('.'))
        .cloned()
        .collect())
}

/// The rules file's spreadsheet mapping, if it has one: an unknown column
/// name is an error naming it.
pub fn read_mapping(path: &Path) -> Result<Option<Mapping>> {
    let file = parse(path)?;
    if let Some(m) = &file.spreadsheet
        && let Some(key) = m.columns.keys().find(|k| !FIELDS.contains(&k.as_str()))
    {
        return Err(Error::invalid(
            path,
            format!("spreadsheet.columns.{key}"),
            format!("not a column of a task; use {}", FIELDS.join(", ")),
        ));
    }
    Ok(file.spreadsheet)
}

/// A task selector compiled: task attribute -> pattern; the error names
/// the field.
fn task_selector(
    s: &TaskSelectFile,
) -> std::result::Result<Vec<(String, Pattern)>, (String, String)> {
    let mut select = Vec::new();
    for (key, p) in [("id", &s.id), ("name", &s.name), ("wbs", &s.wbs)] {
        if let Some(p) = p {
            let compiled = Pattern::compile(p).map_err(|m| (format!("tasks.{key}"), m))?;
            select.push((key.to_string(), compiled));
        }
    }
    for (prefix, group, map) in [
        ("code:", "codes", &s.codes),
        ("field:", "fields", &s.fields),
    ] {
        for (key, p) in map {
            let compiled = Pattern::compile(p).map_err(|m| (format!("tasks.{group}.{key}"), m))?;
            select.push((format!("{prefix}{key}"), compiled));
        }
    }
    if select.is_empty() {
        return Err((
            "tasks".into(),
            "an empty task selector; give id, name, wbs, codes or fields".into(),
        ));
    }
    Ok(select)
}

/// Reads and compiles a rules file against the schedule's tasks: an unknown
/// task id, an ambiguous task name or a bad pattern is an error naming the
/// rule.
pub fn read(path: &Path, tasks: &[ScheduleTask]) -> Result<Vec<Rule>> {
    let file = parse(path)?;
    let mut rules = Vec::with_capacity(file.rules.len());
    for (i, r) in file.rules.iter().enumerate() {
        let bad = |field: &str, m: String| {
            Error::invalid(path, format!("rules[{i}].{field} (rule {:?})", r.name), m)
        };
        let chosen = match (&r.task, &r.task_name, &r.tasks) {
            (Some(id), None, None) => {
                vec![tasks.iter().position(|t| &t.id == id).ok_or_else(|| {
                    bad("task", format!("no task with id {id:?} in the schedule"))
                })?]
            }
            (None, Some(name), None) => {
                let found: Vec<usize> = (0..tasks.len())
                    .filter(|&k| tasks[k].name == *name)
                    .collect();
                match found[..] {
                    [k] => vec![k],
                    [] => return Err(bad("task_name", format!("no task named {name:?}"))),
                    _ => {
                        let ids: Vec<&str> = found.iter().map(|&k| tasks[k].id.as_str()).collect();
                        return Err(bad(
                            "task_name",
                            format!(
                                "{} tasks are named {name:?} (ids {}); give the task id",
                                found.len(),
                                ids.join(", ")
                            ),
                        ));
                    }
                }
            }
            (None, None, Some(select)) => {
                let select = task_selector(select).map_err(|(field, m)| bad(&field, m))?;
                let found: Vec<usize> = (0..tasks.len())
                    .filter(|&k| {
                        select.iter().all(|(key, p)| {
                            task_attribute(&tasks[k], key).is_some_and(|v| p.matches(&v))
                        })
                    })
                    .collect();
                if found.is_empty() {
                    return Err(bad("tasks", "selects no task of the schedule".into()));
                }
                found
            }
            _ => {
                return Err(bad(
                    "task",
                    "give exactly one of \"task\" (an id), \"task_name\" and \"tasks\" (a \
                     task selector)"
                        .into(),
                ));
            }
        };
        let join = match r.join.len() {
            0 => None,
            1 => {
                let (property, attribute) = r.join.iter().next().expect("one entry");
                if !is_task_attribute(attribute) {
                    return Err(bad(
                        &format!("match.{property}"),
                        format!(
                            "{attribute:?} is not a task attribute; use id, name, wbs, \
                             code:TYPE or field:NAME"
                        ),
                    ));
                }
                let mut by_value: HashMap<String, Vec<usize>> = HashMap::new();
                for &k in &chosen {
                    if let Some(v) = task_attribute(&tasks[k], attribute) {
                        by_value.entry(normalise(&v)).or_default().push(k);
                    }
                }
                Some((property.clone(), by_value))
            }
            _ => {
                return Err(bad(
                    "match",
                    "give one object property and one task attribute".into(),
                ));
            }
        };
        let kind = match &r.kind {
            Some(k) => Some(NamedType::parse(k).ok_or_else(|| {
                bad(
                    "type",
                    format!("unknown type {k:?}; expected {}", TaskType::NAMES),
                )
            })?),
            None => None,
        };
        let s = &r.select;
        let mut select = Vec::new();
        for (key, field, p) in [
            (FILE, "file", &s.file),
            (STOREY, "storey", &s.storey),
            (CLASS, "class", &s.class),
            (NAME, "name", &s.name),
        ] {
            if let Some(p) = p {
                let compiled =
                    Pattern::compile(p).map_err(|m| bad(&format!("select.{field}"), m))?;
                select.push((key.to_string(), compiled));
            }
        }
        for (key, p) in &s.properties {
            let compiled =
                Pattern::compile(p).map_err(|m| bad(&format!("select.properties.{key}"), m))?;
            select.push((key.clone(), compiled));
        }
        rules.push(Rule {
            name: r.name.clone(),
            select,
            tasks: chosen,
            join,
            kind,
        });
    }
    Ok(rules)
}
