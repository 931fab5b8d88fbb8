//! Visibility `v_s(t) -> {0, 1}` of an object, stored as sorted, disjoint,
//! non-touching half-open intervals `[a, b)` of seconds since the start.

use serde::{Deserialize, Serialize};

///
/// The first interval may start at minus infinity and the last end at plus
/// infinity: "present before the schedule starts / after it ends".
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Visibility {
    intervals: Vec<(f64, f64)>,
}

/// The typical visibility functions of the paper, named by the state at the
/// start and end of the span and the number of present intervals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VisibilityType {
    /// Present on the whole span.
    Static,
    /// Never present.
    Absent,
    /// Absent, then present to the end.
    Appearing,
    /// Present from the start, then absent.
    Disappearing,
    /// Absent, present once, absent again.
    Temporary,
    /// Absent at both ends, present several times in between.
    Skipped,
    /// Present at the end after at least one gap.
    Reappearing,
    /// Present at the start, absent at the end, with at least one gap.
    ReDisappearing,
}

impl VisibilityType {
    pub const ALL: [VisibilityType; 8] = [
        VisibilityType::Static,
        VisibilityType::Absent,
        VisibilityType::Appearing,
        VisibilityType::Disappearing,
        VisibilityType::Temporary,
        VisibilityType::Skipped,
        VisibilityType::Reappearing,
        VisibilityType::ReDisappearing,
    ];
}

impl Visibility {
    /// Present on `[0, span]` (the end is included by extending the last
    /// interval to infinity, so `at(span)` is true).
    pub fn always() -> Self {
        Visibility {
            intervals: vec![(f64::NEG_INFINITY, f64::INFINITY)],
        }
    }

    pub fn never() -> Self {
        Visibility::default()
    }

    /// Normalises arbitrary intervals: drops empty ones, sorts, merges
    /// overlapping and touching ones.
    pub fn from_intervals(mut raw: Vec<(f64, f64)>) -> Self {
        raw.retain(|(a, b)| a < b);
        raw.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut intervals: Vec<(f64, f64)> = Vec::with_capacity(raw.len());
        for (a, b) in raw {
            match intervals.last_mut() {
                Some(last) if a <= last.1 => last.1 = last.1.max(b),
                _ => intervals.push((a, b)),
            }
        }
        Visibility { intervals }
    }

    /// Intervals that are already normalised (each non-empty, sorted,
    /// apart), kept as they are; `None` for any others.
    pub fn from_normalised(intervals: Vec<(f64, f64)>) -> Option<Self> {
        let normalised =
            intervals.iter().all(|(a, b)| a < b) && intervals.windows(2).all(|w| w[0].1 < w[1].0);
        normalised.then_some(Visibility { intervals })
    }

    pub fn intervals(&self) -> &[(f64, f64)] {
        &self.intervals
    }

    pub fn at(&self, t: f64) -> bool {
        let i = self.intervals.partition_point(|&(a, _)| a <= t);
        i > 0 && t < self.intervals[i - 1].1
    }

    /// The intervals clipped to `[0, span]`, the end counted as present when
    /// the object is present at `span`.
    pub fn clipped(&self, span: f64) -> Vec<(f64, f64)> {
        self.intervals
            .iter()
            .map(|&(a, b)| (a.max(0.0), b.min(span)))
            .filter(|(a, b)| a < b)
            .collect()
    }

    /// The visibility restricted to `[from, to)`.
    pub fn clipped_to(&self, from: f64, to: f64) -> Visibility {
        Visibility::from_intervals(
            self.intervals
                .iter()
                .map(|&(a, b)| (a.max(from), b.min(to)))
                .collect(),
        )
    }

    /// Seconds present within `[0, span]`.
    pub fn present_seconds(&self, span: f64) -> f64 {
        self.clipped(span).iter().map(|(a, b)| b - a).sum()
    }

    /// The instants within `(0, span)` at which the visibility changes.
    pub fn breakpoints(&self, span: f64) -> Vec<f64> {
        self.intervals
            .iter()
            .flat_map(|&(a, b)| [a, b])
            .filter(|t| *t > 0.0 && *t < span)
            .collect()
    }

    pub fn kind(&self, span: f64) -> VisibilityType {
        let parts = self.clipped(span);
        if parts.is_empty() {
            return VisibilityType::Absent;
        }
        let at_start = self.at(0.0);
        let at_end = self.at(span) || parts.last().is_some_and(|p| p.1 >= span);
        match (at_start, at_end, parts.len()) {
            (true, true, 1) => VisibilityType::Static,
            (false, true, 1) => VisibilityType::Appearing,
            (true, false, 1) => VisibilityType::Disappearing,
            (false, false, 1) => VisibilityType::Temporary,
            (false, false, _) => VisibilityType::Skipped,
            (_, true, _) => VisibilityType::Reappearing,
            (true, false, _) => VisibilityType::ReDisappearing,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use VisibilityType::*;

    #[test]
    fn normalises_and_answers() {
        let v = Visibility::from_intervals(vec![(5.0, 6.0), (1.0, 2.0), (2.0, 3.0), (4.0, 4.0)]);
        assert_eq!(v.intervals(), &[(1.0, 3.0), (5.0, 6.0)]);
        assert!(!v.at(0.5));
        assert!(v.at(1.0));
        assert!(v.at(2.5));
        assert!(!v.at(3.0));
        assert!(v.at(5.5));
        assert_eq!(v.present_seconds(10.0), 3.0);
        assert_eq!(v.breakpoints(10.0), vec![1.0, 3.0, 5.0, 6.0]);
        assert_eq!(Visibility::from_normalised(v.intervals().to_vec()), Some(v));
        for bad in [
            vec![(2.0, 1.0)],
            vec![(1.0, 2.0), (2.0, 3.0)],
            vec![(3.0, 4.0), (1.0, 2.0)],
            vec![(f64::NAN, 1.0)],
        ] {
            assert_eq!(Visibility::from_normalised(bad), None);
        }
    }

    #[test]
    fn names_every_type_of_the_paper() {
        let t = 10.0;
        let inf = f64::INFINITY;
        let case = |iv: Vec<(f64, f64)>| Visibility::from_intervals(iv).kind(t);
        assert_eq!(Visibility::always().kind(t), Static);
        assert_eq!(Visibility::never().kind(t), Absent);
        assert_eq!(case(vec![(3.0, inf)]), Appearing);
        assert_eq!(case(vec![(-inf, 3.0)]), Disappearing);
        assert_eq!(case(vec![(2.0, 3.0)]), Temporary);
        assert_eq!(case(vec![(2.0, 3.0), (5.0, 6.0)]), Skipped);
        assert_eq!(case(vec![(2.0, 3.0), (5.0, inf)]), Reappearing);
        assert_eq!(case(vec![(-inf, 3.0), (5.0, inf)]), Reappearing);
        assert_eq!(case(vec![(-inf, 3.0), (5.0, 6.0)]), ReDisappearing);
        assert_eq!(case(vec![(12.0, 13.0)]), Absent);
    }
}
