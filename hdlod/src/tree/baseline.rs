//! The baseline the cut is measured against: every original object present
//! at `t`, drawn at full detail (the paper's "no HDLOD" column, Semenov et
//! al. 2020, table 2). A leaf counts while its visibility is at least 0.5.
//! The server answers it with each cut and the table of the paper at many
//! times, so it is precomputed once as a step function over the leaves'
//! visibility changes and looked up by binary search.

use super::Tree;

/// What drawing every present original object costs at one time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Present {
    pub triangles: u64,
    pub objects: u64,
    /// Present leaves: one draw each.
    pub draws: u64,
}

/// [`Present`] as a step function of time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Baseline {
    /// Strictly increasing times at which the present set changes.
    times: Vec<f64>,
    /// What is present from `times[i]` on; nothing before `times[0]`.
    values: Vec<Present>,
}

impl Baseline {
    pub fn of(tree: &Tree) -> Baseline {
        Baseline::of_leaves(tree, |_| true)
    }

    /// The baseline of the leaves `counted` keeps: a part of the scene,
    /// such as one site of a district.
    pub fn of_leaves(tree: &Tree, counted: impl Fn(u32) -> bool) -> Baseline {
        // (time, [triangles, objects, draws]) deltas at each change of a leaf.
        let mut events: Vec<(f64, [i64; 3])> = Vec::new();
        for id in 0..tree.cluster_count() as u32 {
            let c = tree.facts(id);
            if !c.leaf || !c.geometry || !counted(id) {
                continue;
            }
            let (tri, obj) = (c.triangles as i64, c.objects as i64);
            let mut present = false;
            for (t, v) in c.steps {
                let now = v >= 0.5;
                if now != present {
                    let sign = if now { 1 } else { -1 };
                    events.push((t, [sign * tri, sign * obj, sign]));
                    present = now;
                }
            }
        }
        events.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut baseline = Baseline::default();
        let mut sum = [0i64; 3];
        for (t, delta) in events {
            for (s, d) in sum.iter_mut().zip(delta) {
                *s += d;
            }
            // Every removal follows its own addition, so the sums stay >= 0.
            let [triangles, objects, draws] = sum.map(|s| s.max(0) as u64);
            let value = Present {
                triangles,
                objects,
                draws,
            };
            if baseline.times.last() == Some(&t) {
                *baseline.values.last_mut().expect("same length") = value;
            } else {
                baseline.times.push(t);
                baseline.values.push(value);
            }
        }
        baseline
    }

    /// The steps: what is present from each time on.
    pub(crate) fn steps(&self) -> impl Iterator<Item = (f64, Present)> + '_ {
        self.times.iter().copied().zip(self.values.iter().copied())
    }

    /// The baseline of `steps` (as [`Baseline::steps`] gives them: times
    /// strictly increasing).
    pub(crate) fn from_steps(steps: impl Iterator<Item = (f64, Present)>) -> Baseline {
        let (times, values) = steps.unzip();
        Baseline { times, values }
    }

    /// What is present at `t`.
    pub fn present(&self, t: f64) -> Present {
        let i = self.times.partition_point(|&x| x <= t);
        if i == 0 {
            Present::default()
        } else {
            self.values[i - 1]
        }
    }

    /// `(triangles, objects)` present at `t`.
    pub fn at(&self, t: f64) -> (u64, u64) {
        let p = self.present(t);
        (p.triangles, p.objects)
    }
}
