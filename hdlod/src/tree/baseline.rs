//! The baseline the cut is measured against: every original object present
//! at `t`, drawn at full detail (the paper's "no HDLOD" column, Semenov et
//! al. 2020, table 2). A leaf counts while its visibility is at least 0.5,
//! as in [`super::paper::baseline`]. That function scans every cluster; the
//! server answers it with each cut, so here it is precomputed once as a step
//! function over the leaves' visibility changes and looked up by binary
//! search.

use super::Tree;

/// Present triangles and objects as a step function of time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Baseline {
    /// Strictly increasing times at which the present set changes.
    times: Vec<f64>,
    /// `(triangles, objects)` from `times[i]` on; nothing before `times[0]`.
    values: Vec<(u64, u64)>,
}

impl Baseline {
    pub fn of(tree: &Tree) -> Baseline {
        // (time, triangles, objects) deltas at each change of a leaf.
        let mut events: Vec<(f64, i64, i64)> = Vec::new();
        for c in tree
            .clusters
            .iter()
            .filter(|c| c.is_leaf() && c.geometry.is_some())
        {
            let (tri, obj) = (c.triangles as i64, c.objects.len() as i64);
            let mut present = false;
            for &(t, v) in c.visibility.steps() {
                let now = v >= 0.5;
                if now != present {
                    let sign = if now { 1 } else { -1 };
                    events.push((t, sign * tri, sign * obj));
                    present = now;
                }
            }
        }
        events.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut baseline = Baseline::default();
        let (mut tri, mut obj) = (0i64, 0i64);
        for (t, dt, dobj) in events {
            tri += dt;
            obj += dobj;
            // Every removal follows its own addition, so the sums stay >= 0.
            let value = (tri.max(0) as u64, obj.max(0) as u64);
            if baseline.times.last() == Some(&t) {
                *baseline.values.last_mut().expect("same length") = value;
            } else {
                baseline.times.push(t);
                baseline.values.push(value);
            }
        }
        baseline
    }

    /// `(triangles, objects)` present at `t`.
    pub fn at(&self, t: f64) -> (u64, u64) {
        let i = self.times.partition_point(|&x| x <= t);
        if i == 0 { (0, 0) } else { self.values[i - 1] }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::paper::baseline;
    use crate::tree::sample::write_sample_tree;

    #[test]
    fn matches_the_scan_over_every_leaf() {
        let dir = tempfile::tempdir().unwrap();
        let tree = write_sample_tree(&dir.path().join("t"), 5, 6).unwrap();
        let steps = Baseline::of(&tree);
        let span = tree.time.seconds;
        let mut changes = 0;
        let mut last = None;
        for i in -5..=205 {
            let t = span * f64::from(i) / 200.0;
            let (tri, draws) = baseline(&tree, t);
            let (stri, sobj) = steps.at(t);
            assert_eq!(stri, tri, "triangles at {t}");
            let objects: u64 = tree
                .clusters
                .iter()
                .filter(|c| c.is_leaf() && c.geometry.is_some() && c.visibility.at(t) >= 0.5)
                .map(|c| c.objects.len() as u64)
                .sum();
            assert_eq!(sobj, objects, "objects at {t}");
            assert!(draws <= tri);
            changes += usize::from(last.is_some_and(|l| l != tri));
            last = Some(tri);
        }
        // The sample tree's schedule makes the present set change.
        assert!(changes > 2, "{changes} changes");
        // Exactly at a step time the new value holds (half-open steps).
        for (&t, &value) in steps.times.iter().zip(&steps.values) {
            assert_eq!(steps.at(t), value);
            assert_eq!(baseline(&tree, t).0, value.0);
        }
    }
}
