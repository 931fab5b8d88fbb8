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

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use super::ScheduleTask;
use crate::error::{Error, Result};
use crate::scene::{Object, TaskType};

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
    #[serde(rename = "type", default)]
    kind: Option<String>,
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
    /// Index of the task in the schedule.
    pub task: usize,
    /// The type the rule gives, else the task's own, else construct.
    pub kind: Option<TaskType>,
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
}

/// The property names the selectors `file`, `storey`, `class` and `name`
/// stand for.
pub use crate::scene::property::{CLASS, FILE, NAME, STOREY};

/// Reads and compiles a rules file against the schedule's tasks: an unknown
/// task id, an ambiguous task name or a bad pattern is an error naming the
/// rule.
pub fn read(path: &Path, tasks: &[ScheduleTask]) -> Result<Vec<Rule>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
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
    let mut rules = Vec::with_capacity(file.rules.len());
    for (i, r) in file.rules.iter().enumerate() {
        let bad = |field: &str, m: String| {
            Error::invalid(path, format!("rules[{i}].{field} (rule {:?})", r.name), m)
        };
        let task = match (&r.task, &r.task_name) {
            (Some(id), None) => tasks
                .iter()
                .position(|t| &t.id == id)
                .ok_or_else(|| bad("task", format!("no task with id {id:?} in the schedule")))?,
            (None, Some(name)) => {
                let found: Vec<usize> = (0..tasks.len())
                    .filter(|&k| tasks[k].name == *name)
                    .collect();
                match found[..] {
                    [k] => k,
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
            _ => {
                return Err(bad(
                    "task",
                    "give exactly one of \"task\" (an id) and \"task_name\"".into(),
                ));
            }
        };
        let kind = match &r.kind {
            Some(k) => Some(TaskType::parse(k).ok_or_else(|| {
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
            task,
            kind,
        });
    }
    Ok(rules)
}
