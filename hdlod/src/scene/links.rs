//! The logic of a schedule: a task's predecessors, each link with its type
//! (finish-to-start, start-to-start, finish-to-finish, start-to-finish) and
//! its lag, as planners' tools keep them (P6's `TASKPRED`, Project's
//! `PredecessorLink`, IFC's `IfcRelSequence`). A schedule's links form no
//! cycle: a task that must wait for itself can never be scheduled, and
//! every planning tool refuses one ("circular logic").

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

/// How a task depends on its predecessor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum LinkType {
    /// It starts once the predecessor has finished.
    #[default]
    #[serde(rename = "FS")]
    FinishStart,
    /// It starts once the predecessor has started.
    #[serde(rename = "SS")]
    StartStart,
    /// It finishes once the predecessor has finished.
    #[serde(rename = "FF")]
    FinishFinish,
    /// It finishes once the predecessor has started.
    #[serde(rename = "SF")]
    StartFinish,
}

impl LinkType {
    /// The planners' abbreviation: `FS`, `SS`, `FF`, `SF`.
    pub fn name(self) -> &'static str {
        match self {
            LinkType::FinishStart => "FS",
            LinkType::StartStart => "SS",
            LinkType::FinishFinish => "FF",
            LinkType::StartFinish => "SF",
        }
    }

    /// Parses the abbreviations and the spelled-out names in any case and
    /// spacing (`FS`, `Finish to Start`, `finish-start`, P6's `PR_FS`, IFC's
    /// `FINISH_START`).
    pub fn parse(text: &str) -> Option<LinkType> {
        let key: String = text
            .to_ascii_uppercase()
            .trim_start_matches("PR_")
            .chars()
            .filter(char::is_ascii_alphabetic)
            .collect();
        Some(match key.as_str() {
            "FS" | "FINISHSTART" | "FINISHTOSTART" => LinkType::FinishStart,
            "SS" | "STARTSTART" | "STARTTOSTART" => LinkType::StartStart,
            "FF" | "FINISHFINISH" | "FINISHTOFINISH" => LinkType::FinishFinish,
            "SF" | "STARTFINISH" | "STARTTOFINISH" => LinkType::StartFinish,
            _ => return None,
        })
    }
}

/// A link from a predecessor to the task that holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct Predecessor {
    /// The predecessor's task id.
    pub task: String,
    pub kind: LinkType,
    /// Seconds between the predecessor's date and the task's (negative: a
    /// lead), as the schedule gives it; working time in the tools that
    /// count lags on a calendar.
    pub lag: f64,
}

impl Predecessor {
    /// A finish-to-start link without lag.
    pub fn finish_start(task: impl Into<String>) -> Predecessor {
        Predecessor {
            task: task.into(),
            kind: LinkType::FinishStart,
            lag: 0.0,
        }
    }
}

/// A cycle of the links among `ids`, if there is one: the indices of its
/// tasks in link order from the first of them in `ids`, repeated at the
/// end (`a -> b -> a`).
/// `predecessors(i)` gives the ids of task `i`'s predecessors; ids that
/// name no task are skipped. Iterative depth-first search, linear in tasks
/// and links.
pub fn find_cycle<'a, F, I>(ids: &[&'a str], predecessors: F) -> Option<Vec<usize>>
where
    F: Fn(usize) -> I,
    I: Iterator<Item = &'a str>,
{
    let index: HashMap<&str, usize> = ids.iter().enumerate().map(|(i, id)| (*id, i)).collect();
    let edges: Vec<Vec<usize>> = (0..ids.len())
        .map(|i| {
            predecessors(i)
                .filter_map(|p| index.get(p).copied())
                .collect()
        })
        .collect();
    // 0: not visited, 1: on the current path, 2: done.
    let mut state = vec![0u8; ids.len()];
    for root in 0..ids.len() {
        if state[root] != 0 {
            continue;
        }
        let mut path: Vec<(usize, usize)> = vec![(root, 0)];
        state[root] = 1;
        while let Some(&mut (node, ref mut next)) = path.last_mut() {
            if let Some(&p) = edges[node].get(*next) {
                *next += 1;
                match state[p] {
                    0 => {
                        state[p] = 1;
                        path.push((p, 0));
                    }
                    1 => {
                        let from = path.iter().position(|&(n, _)| n == p).unwrap_or(0);
                        // The path runs from successors to predecessors:
                        // reversed, it reads in link order.
                        let mut cycle: Vec<usize> = path[from..].iter().map(|&(n, _)| n).collect();
                        cycle.reverse();
                        // From its first task in file order, for a stable
                        // message.
                        let first = (0..cycle.len()).min_by_key(|&k| cycle[k]).unwrap_or(0);
                        cycle.rotate_left(first);
                        cycle.push(cycle[0]);
                        return Some(cycle);
                    }
                    _ => {}
                }
            } else {
                state[node] = 2;
                path.pop();
            }
        }
    }
    None
}

/// A cycle as a message: `"A -> B -> A"`.
pub fn show_cycle(ids: &[&str], cycle: &[usize]) -> String {
    cycle
        .iter()
        .map(|&i| ids[i])
        .collect::<Vec<_>>()
        .join(" -> ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_types_parse_every_spelling() {
        for (text, kind) in [
            ("FS", LinkType::FinishStart),
            ("PR_SS", LinkType::StartStart),
            ("Finish to Finish", LinkType::FinishFinish),
            ("START_FINISH", LinkType::StartFinish),
            ("finish-start", LinkType::FinishStart),
        ] {
            assert_eq!(LinkType::parse(text), Some(kind), "{text}");
        }
        assert_eq!(LinkType::parse("USERDEFINED"), None);
    }

    #[test]
    fn cycles_are_found_in_link_order() {
        let ids = ["a", "b", "c", "d"];
        // b after a, c after b, a after c; d after a.
        let preds: [&[&str]; 4] = [&["c"], &["a"], &["b"], &["a"]];
        let cycle = find_cycle(&ids, |i| preds[i].iter().copied()).unwrap();
        assert_eq!(show_cycle(&ids, &cycle), "a -> b -> c -> a");
        let preds: [&[&str]; 4] = [&[], &["a", "x"], &["b", "a"], &["a"]];
        assert_eq!(find_cycle(&ids, |i| preds[i].iter().copied()), None);
        let own: [&[&str]; 1] = [&["a"]];
        assert_eq!(
            find_cycle(&ids[..1], |i| own[i].iter().copied()),
            Some(vec![0, 0])
        );
    }
}
