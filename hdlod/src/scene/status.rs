//! Where a task stands at a time, and how its execution compares with its
//! plan: the status a 4D review colours elements by (docs/method.md
//! section 1, "Planned and actual dates, status, appearance"). Planned dates are the task's `start` and `finish`; actual
//! dates are what was recorded of its execution (a start once it began, a
//! finish once it ended); the baseline is an earlier plan, kept for
//! reference.
//!
//! The viewer works the same status out in JavaScript
//! (`server/viewer/appearance.js`); the browser tests hold the two to the
//! same colours.

use serde::{Deserialize, Serialize};

/// Which dates a build's presence follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Dates {
    /// The planned start and finish.
    #[default]
    Planned,
    /// The recorded actual dates; a task with none has not started, one
    /// with a start and no finish is still running.
    Actual,
}

impl Dates {
    pub fn name(self) -> &'static str {
        match self {
            Dates::Planned => "planned",
            Dates::Actual => "actual",
        }
    }
}

/// A task's recorded execution, seconds since the scene's start.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Actual {
    pub start: Option<f64>,
    /// Only with a start.
    pub finish: Option<f64>,
}

impl Actual {
    pub fn is_recorded(&self) -> bool {
        self.start.is_some()
    }
}

/// A start and a finish (a baseline's dates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    pub start: f64,
    pub finish: f64,
}

/// A task's dates: planned, and what else is known of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskDates {
    pub start: f64,
    pub finish: f64,
    pub actual: Actual,
    pub baseline: Option<Span>,
}

/// Where a task stands at a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Progress {
    NotStarted,
    /// `in_progress` in files and answers.
    #[serde(rename = "in_progress")]
    Active,
    Finished,
}

/// A task's execution against its plan at a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Deviation {
    Early,
    OnTime,
    Late,
}

impl Progress {
    /// The name files and answers use.
    pub fn name(self) -> &'static str {
        match self {
            Progress::NotStarted => "not_started",
            Progress::Active => "in_progress",
            Progress::Finished => "finished",
        }
    }
}

impl Deviation {
    pub fn name(self) -> &'static str {
        match self {
            Deviation::Early => "early",
            Deviation::OnTime => "on_time",
            Deviation::Late => "late",
        }
    }
}

impl TaskDates {
    /// The interval the task runs over under `dates`: `[start, finish)`,
    /// the finish infinite while a recorded task is still running, both
    /// infinite for one not started by the record (so it never acts).
    pub fn running(&self, dates: Dates) -> (f64, f64) {
        match dates {
            Dates::Planned => (self.start, self.finish),
            Dates::Actual => match self.actual.start {
                Some(start) => (start, self.actual.finish.unwrap_or(f64::INFINITY)),
                None => (f64::INFINITY, f64::INFINITY),
            },
        }
    }

    /// Not started before the start, active until the finish, finished
    /// from it on (a task of no duration is finished from its start).
    pub fn progress(&self, t: f64, dates: Dates) -> Progress {
        let (start, finish) = self.running(dates);
        if t < start {
            Progress::NotStarted
        } else if t < finish {
            Progress::Active
        } else {
            Progress::Finished
        }
    }

    /// Against the plan at `t`, for a task with a recorded start (`None`
    /// otherwise): late while it should have started and has not, or
    /// should have finished and has not; early while it has started or
    /// finished before the plan says; on time otherwise. Lateness wins when
    /// a task is both (it started early but runs past its planned finish).
    pub fn deviation(&self, t: f64) -> Option<Deviation> {
        let started = self.actual.start?;
        let finished = self.actual.finish.unwrap_or(f64::INFINITY);
        let late = (t >= self.start && t < started) || (t >= self.finish && t < finished);
        let early = (t >= started && t < self.start) || (t >= finished && t < self.finish);
        Some(if late {
            Deviation::Late
        } else if early {
            Deviation::Early
        } else {
            Deviation::OnTime
        })
    }

    /// How much later than planned the task finished (negative: earlier),
    /// once it has.
    pub fn finish_variance(&self) -> Option<f64> {
        self.actual.finish.map(|f| f - self.finish)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn task(start: f64, finish: f64, actual: (Option<f64>, Option<f64>)) -> TaskDates {
        TaskDates {
            start,
            finish,
            actual: Actual {
                start: actual.0,
                finish: actual.1,
            },
            baseline: None,
        }
    }

    #[test]
    fn progress_follows_the_chosen_dates() {
        let t = task(10.0, 20.0, (Some(15.0), Some(30.0)));
        assert_eq!(t.progress(12.0, Dates::Planned), Progress::Active);
        assert_eq!(t.progress(12.0, Dates::Actual), Progress::NotStarted);
        assert_eq!(t.progress(25.0, Dates::Planned), Progress::Finished);
        assert_eq!(t.progress(25.0, Dates::Actual), Progress::Active);
        let never = task(10.0, 20.0, (None, None));
        assert_eq!(never.progress(1e9, Dates::Actual), Progress::NotStarted);
        let running = task(10.0, 20.0, (Some(5.0), None));
        assert_eq!(running.progress(1e9, Dates::Actual), Progress::Active);
    }

    #[test]
    fn late_and_early_last_while_the_record_differs_from_the_plan() {
        // Started late, finished late.
        let t = task(10.0, 20.0, (Some(15.0), Some(30.0)));
        assert_eq!(t.deviation(5.0), Some(Deviation::OnTime));
        assert_eq!(t.deviation(12.0), Some(Deviation::Late));
        assert_eq!(t.deviation(17.0), Some(Deviation::OnTime));
        assert_eq!(t.deviation(25.0), Some(Deviation::Late));
        assert_eq!(t.deviation(30.0), Some(Deviation::OnTime));
        assert_eq!(t.finish_variance(), Some(10.0));
        // Started and finished early.
        let t = task(10.0, 20.0, (Some(5.0), Some(12.0)));
        assert_eq!(t.deviation(7.0), Some(Deviation::Early));
        assert_eq!(t.deviation(11.0), Some(Deviation::OnTime));
        assert_eq!(t.deviation(15.0), Some(Deviation::Early));
        // Early start but a late finish: late wins while both hold.
        let t = task(10.0, 20.0, (Some(5.0), None));
        assert_eq!(t.deviation(7.0), Some(Deviation::Early));
        assert_eq!(t.deviation(25.0), Some(Deviation::Late));
        assert_eq!(task(10.0, 20.0, (None, None)).deviation(15.0), None);
    }
}
