//! A Primavera P6 work breakdown (XER's `PROJWBS`, PMXML's `WBS`): each
//! node's code path from the project's node (`TWR.L01.FRM`, as P6 shows
//! a WBS code) and its names, and the nodes below the project's as summary
//! tasks spanning the activities below them, the bands a P6 Gantt chart
//! groups activities under.

use std::collections::HashMap;

use chrono::{DateTime, Utc};

use super::{Recorded, ScheduleTask};

/// One WBS node as a file gives it.
pub(super) struct RawNode<'a> {
    pub id: &'a str,
    /// The id of its parent node (or of the project).
    pub parent: &'a str,
    /// Its code (P6's short name) and its name.
    pub short: &'a str,
    pub name: &'a str,
    /// The project's own node, the root of the code paths.
    pub root: bool,
}

/// One WBS node of the project.
#[derive(Debug, Clone, Default)]
pub(super) struct Node {
    /// Its code path from the project's node (`TWR.L01`).
    pub code: String,
    /// Its names below the project's node (`Level 1 / Frame`).
    pub names: String,
    /// A node below the project's root, which becomes a summary task.
    pub summary: bool,
    /// Its parent node's code path when that is a summary task.
    pub parent: Option<String>,
}

/// The project's work breakdown: `wbs_id` -> node.
#[derive(Default)]
pub(super) struct Wbs {
    nodes: HashMap<String, Node>,
    /// Node ids in file order.
    order: Vec<String>,
}

impl Wbs {
    /// The nodes' code paths, names and parents; a cycle of parents is an
    /// error naming a node of it.
    pub(super) fn new(list: &[RawNode]) -> std::result::Result<Wbs, String> {
        // id -> (parent, short name, name, is the project's node).
        let raw: HashMap<&str, (&str, &str, &str, bool)> = list
            .iter()
            .map(|n| (n.id, (n.parent, n.short, n.name, n.root)))
            .collect();
        let order: Vec<String> = list.iter().map(|n| n.id.to_string()).collect();
        let mut nodes = HashMap::new();
        for key in &order {
            // The chain up to the project's node or to a parent outside
            // the project; a cycle of parents is an error.
            let mut chain = Vec::new();
            let mut at = key.as_str();
            while let Some(&(up, ..)) = raw.get(at) {
                if chain.contains(&at) {
                    return Err(key.clone());
                }
                chain.push(at);
                if raw[at].3 {
                    break;
                }
                at = up;
            }
            chain.reverse();
            let code: Vec<&str> = chain.iter().map(|k| raw[k].1).collect();
            let names: Vec<&str> = chain
                .iter()
                .filter(|k| !raw[**k].3)
                .map(|k| raw[k].2)
                .collect();
            let summary = !raw[key.as_str()].3;
            let parent = (chain.len() >= 2 && !raw[chain[chain.len() - 2]].3)
                .then(|| code[..code.len() - 1].join("."));
            nodes.insert(
                key.clone(),
                Node {
                    code: code.join("."),
                    names: names.join(" / "),
                    summary,
                    parent,
                },
            );
        }
        Ok(Wbs { nodes, order })
    }

    pub(super) fn node(&self, wbs_id: &str) -> Option<&Node> {
        self.nodes.get(wbs_id)
    }

    /// The summary tasks: each node below the project's, spanning the
    /// activities below it (actual: from their first actual start,
    /// finished once all have finished). Nodes with no activity below are
    /// left out.
    pub(super) fn summaries(&self, tasks: &[ScheduleTask]) -> Vec<ScheduleTask> {
        let by_code: HashMap<&str, &Node> =
            self.nodes.values().map(|n| (n.code.as_str(), n)).collect();
        let mut span: HashMap<&str, Span> = HashMap::new();
        for t in tasks {
            let mut at = t.parent.as_deref();
            while let Some(code) = at {
                span.entry(code).or_default().add(t);
                at = by_code.get(code).and_then(|n| n.parent.as_deref());
            }
        }
        self.order
            .iter()
            .filter_map(|k| {
                let n = &self.nodes[k];
                let s = span.get(n.code.as_str())?;
                let (start, finish) = s.planned?;
                let name = n.names.clone();
                Some(ScheduleTask {
                    actual: s.actual(),
                    parent: n.parent.clone(),
                    wbs: Some(n.code.clone()),
                    ..ScheduleTask::planned(n.code.clone(), name, start, finish)
                })
            })
            .collect()
    }
}

/// What a summary spans of the activities below it.
#[derive(Default)]
struct Span {
    planned: Option<(DateTime<Utc>, DateTime<Utc>)>,
    actual_start: Option<DateTime<Utc>>,
    actual_finish: Option<DateTime<Utc>>,
    all_finished: bool,
    count: usize,
}

impl Span {
    fn add(&mut self, t: &ScheduleTask) {
        self.planned = Some(match self.planned {
            Some((s, f)) => (s.min(t.start), f.max(t.finish)),
            None => (t.start, t.finish),
        });
        if let Some(s) = t.actual.start {
            self.actual_start = Some(self.actual_start.map_or(s, |a| a.min(s)));
        }
        let finished = t.actual.finish;
        if let Some(f) = finished {
            self.actual_finish = Some(self.actual_finish.map_or(f, |a| a.max(f)));
        }
        self.all_finished = (self.count == 0 || self.all_finished) && finished.is_some();
        self.count += 1;
    }

    fn actual(&self) -> Recorded {
        Recorded {
            start: self.actual_start,
            finish: self.actual_finish.filter(|_| self.all_finished),
        }
    }
}
