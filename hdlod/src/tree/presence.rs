//! Which children of the root can be present at a time. The root holds
//! one child per dynamic object (docs/method.md section 2: each dynamic object
//! gets its own cluster, all roots hang under one virtual root): 15,000 on
//! the paper scene, most of them on site for a few hours of a two-year
//! period. Testing every one's visibility made a cut of 30 clusters visit
//! 15,700; this index answers, from the one time bucket `t` falls in, the
//! children that are present somewhere in that bucket, in the children's
//! order, so the cut visits what it would emit or refine and little else.
//!
//! A bucketed interval index (one list per slice of the period, each
//! interval filed in every slice it overlaps) rather than an interval tree:
//! the query is one array lookup, and the lists keep the children's order,
//! which the cut's output order follows.

use super::{Steps, Tree};

/// Slices of the span of the children's breakpoints.
const BUCKETS: usize = 512;

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Presence {
    start: f64,
    width: f64,
    /// Per bucket, the root's children with `v > 0` at some time in it (the
    /// first bucket also holds those present before `start`, the last those
    /// present after its end), in the order of `root.children`.
    buckets: Vec<Vec<u32>>,
}

impl Presence {
    pub(super) fn new(tree: &Tree) -> Presence {
        let children = tree.children_of(tree.root);
        let visibility: Vec<Steps> = children
            .iter()
            .map(|&c| Steps::from_checked(tree.facts(c).steps.collect()))
            .collect();
        let times = || {
            visibility
                .iter()
                .flat_map(|v| v.steps().iter().map(|s| s.0))
        };
        let start = times().fold(f64::INFINITY, f64::min);
        let end = times().fold(f64::NEG_INFINITY, f64::max);
        if start >= end {
            // One breakpoint or none: one bucket holds every child.
            return Presence {
                start: 0.0,
                width: 1.0,
                buckets: vec![children.to_vec()],
            };
        }
        let mut out = Presence {
            start,
            width: (end - start) / BUCKETS as f64,
            buckets: vec![Vec::new(); BUCKETS],
        };
        for (&c, v) in children.iter().zip(&visibility) {
            for (a, b) in present(v) {
                // b's own bucket too when b is its edge: a superset is fine.
                let first = out.bucket(a);
                let last = if b.is_finite() {
                    out.bucket(b)
                } else {
                    BUCKETS - 1
                };
                for bucket in &mut out.buckets[first..=last] {
                    if bucket.last() != Some(&c) {
                        bucket.push(c);
                    }
                }
            }
        }
        out
    }

    fn bucket(&self, t: f64) -> usize {
        let k = ((t - self.start) / self.width).floor();
        if k.is_nan() || k < 0.0 {
            0
        } else {
            (k as usize).min(self.buckets.len() - 1)
        }
    }

    /// The root's children that may be present at `t`: every one that is,
    /// and some that are not.
    pub fn candidates(&self, t: f64) -> &[u32] {
        &self.buckets[self.bucket(t)]
    }
}

/// The intervals `[a, b)` where `v > 0`; `b` infinite when the last step is
/// present.
fn present(steps: &Steps) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut open: Option<f64> = None;
    for &(t, v) in steps.steps() {
        match (open, v > 0.0) {
            (None, true) => open = Some(t),
            (Some(a), false) => {
                out.push((a, t));
                open = None;
            }
            _ => {}
        }
    }
    if let Some(a) = open {
        out.push((a, f64::INFINITY));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_of_presence() {
        let s = Steps::new(vec![
            (0.0, 0.0),
            (1.0, 1.0),
            (2.0, 0.5),
            (3.0, 0.0),
            (5.0, 1.0),
        ])
        .unwrap();
        assert_eq!(present(&s), vec![(1.0, 3.0), (5.0, f64::INFINITY)]);
        assert!(present(&Steps::constant(0.0)).is_empty());
    }
}
