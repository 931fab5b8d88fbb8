//! Fractional visibility `v_c(t)` as a step function (docs/method.md section 2):
//! `v_c = sum w_c' v_c' / sum w_c'` over the children, simplified to at most
//! K steps, and the L1 distances from which the temporal error `gamma_c` is
//! computed.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::scene::Visibility;

/// `v(t) = values[i]` for the last `times[i] <= t`; the first step is at
/// `t = 0`, so the function is defined on the whole span `[0, T]`.
/// Consecutive values differ (the representation is canonical). The
/// builder computes in `f64`; the tree stores the `f32` form
/// ([`crate::tree::Steps`], made by [`StepFunction::to_tree`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StepFunction {
    points: Vec<(f64, f64)>,
}

impl StepFunction {
    pub fn constant(v: f64) -> StepFunction {
        StepFunction {
            points: vec![(0.0, v)],
        }
    }

    /// The 0/1 function of an object over `[0, span]`.
    pub fn of_visibility(visibility: &Visibility, span: f64) -> StepFunction {
        let mut raw = vec![(0.0, if visibility.at(0.0) { 1.0 } else { 0.0 })];
        for t in visibility.breakpoints(span) {
            raw.push((t, if visibility.at(t) { 1.0 } else { 0.0 }));
        }
        StepFunction::canonical(raw)
    }

    fn canonical(raw: Vec<(f64, f64)>) -> StepFunction {
        let mut points: Vec<(f64, f64)> = Vec::with_capacity(raw.len());
        for (t, v) in raw {
            match points.last_mut() {
                Some(last) if last.0 == t => last.1 = v,
                Some(last) if last.1 == v => {}
                _ => points.push((t, v)),
            }
        }
        // A change that lands on the previous value (t equal) can leave two
        // equal neighbours; fold them.
        points.dedup_by(|b, a| a.1 == b.1);
        StepFunction { points }
    }

    pub fn points(&self) -> &[(f64, f64)] {
        &self.points
    }

    pub fn at(&self, t: f64) -> f64 {
        let i = self.points.partition_point(|p| p.0 <= t);
        if i == 0 { 0.0 } else { self.points[i - 1].1 }
    }

    pub fn from_tree(steps: &crate::tree::Steps) -> StepFunction {
        StepFunction::canonical(
            steps
                .steps()
                .iter()
                .map(|&(t, v)| (t, f64::from(v)))
                .collect(),
        )
    }

    /// The stored form (single-precision values, as the tree keeps them).
    pub fn to_tree(&self) -> crate::tree::Steps {
        crate::tree::Steps::new(self.points.iter().map(|&(t, v)| (t, v as f32)).collect())
            .expect("canonical steps are sorted, finite and within [0, 1]")
    }

    /// `sum w_i f_i / sum w_i`, exact (every breakpoint of every input kept).
    pub fn weighted_mean(parts: &[(f64, &StepFunction)]) -> StepFunction {
        let total: f64 = parts.iter().map(|p| p.0).sum();
        if total <= 0.0 {
            return StepFunction::constant(0.0);
        }
        let mut events: Vec<(f64, f64)> = Vec::new();
        for &(w, f) in parts {
            let mut prev = 0.0;
            for &(t, v) in &f.points {
                events.push((t, w * (v - prev) / total));
                prev = v;
            }
        }
        events.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut raw: Vec<(f64, f64)> = Vec::with_capacity(events.len());
        let mut acc = 0.0;
        for (t, dv) in events {
            acc += dv;
            // Rounding must not leave the function outside [0, 1].
            let v = acc.clamp(0.0, 1.0);
            match raw.last_mut() {
                Some(last) if last.0 == t => last.1 = v,
                _ => raw.push((t, v)),
            }
        }
        // Snap values within rounding of 0 or 1, so that "wholly present"
        // compares equal to 1 in the cut.
        for p in &mut raw {
            if p.1 < 1e-12 {
                p.1 = 0.0;
            } else if p.1 > 1.0 - 1e-12 {
                p.1 = 1.0;
            }
        }
        StepFunction::canonical(raw)
    }

    /// `integral_0^span |self - other| dt`.
    pub fn l1_distance(&self, other: &StepFunction, span: f64) -> f64 {
        let (a, b) = (&self.points, &other.points);
        let (mut i, mut j) = (0, 0);
        let (mut va, mut vb) = (0.0f64, 0.0f64);
        let mut t = 0.0;
        let mut sum = 0.0;
        loop {
            let ta = a.get(i).map_or(f64::INFINITY, |p| p.0);
            let tb = b.get(j).map_or(f64::INFINITY, |p| p.0);
            let next = ta.min(tb).min(span);
            sum += (va - vb).abs() * (next - t).max(0.0);
            t = next;
            if t >= span {
                return sum;
            }
            if ta == next {
                va = a[i].1;
                i += 1;
            }
            if tb == next {
                vb = b[j].1;
                j += 1;
            }
        }
    }

    /// Merges neighbouring steps until at most `max_steps` remain, each time
    /// the pair whose merge adds the least L1 error (the merged value is the
    /// time-weighted mean, which minimises the L2 error and keeps the
    /// integral). The error this adds is measured by the caller as part of
    /// `gamma_c`, against the original objects.
    pub fn simplified(&self, max_steps: usize, span: f64) -> StepFunction {
        let n = self.points.len();
        if n <= max_steps.max(1) {
            return self.clone();
        }
        #[derive(Clone, Copy)]
        struct Seg {
            t: f64,
            dur: f64,
            v: f64,
            prev: usize,
            next: usize,
            alive: bool,
            version: u32,
        }
        const NONE: usize = usize::MAX;
        let mut segs: Vec<Seg> = self
            .points
            .iter()
            .enumerate()
            .map(|(i, &(t, v))| Seg {
                t,
                dur: self.points.get(i + 1).map_or(span, |p| p.0).max(t) - t,
                v,
                prev: if i == 0 { NONE } else { i - 1 },
                next: if i + 1 == n { NONE } else { i + 1 },
                alive: true,
                version: 0,
            })
            .collect();
        let cost = |a: &Seg, b: &Seg| {
            let d = a.dur + b.dur;
            if d <= 0.0 {
                return 0.0;
            }
            let m = (a.v * a.dur + b.v * b.dur) / d;
            a.dur * (a.v - m).abs() + b.dur * (b.v - m).abs()
        };
        // Min-heap of (cost, left segment, versions of both) with lazy deletion.
        #[derive(PartialEq)]
        struct Cand(f64, usize, u32, u32);
        impl Eq for Cand {}
        impl PartialOrd for Cand {
            fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for Cand {
            fn cmp(&self, o: &Self) -> Ordering {
                o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
            }
        }
        let mut heap = BinaryHeap::new();
        for i in 0..n - 1 {
            heap.push(Cand(cost(&segs[i], &segs[i + 1]), i, 0, 0));
        }
        let mut alive = n;
        while alive > max_steps.max(1) {
            let Some(Cand(_, i, vi, vj)) = heap.pop() else {
                break;
            };
            let j = segs[i].next;
            if !segs[i].alive || j == NONE || segs[i].version != vi || segs[j].version != vj {
                continue;
            }
            let d = segs[i].dur + segs[j].dur;
            if d > 0.0 {
                segs[i].v = (segs[i].v * segs[i].dur + segs[j].v * segs[j].dur) / d;
            }
            segs[i].dur = d;
            segs[i].version += 1;
            segs[j].alive = false;
            segs[i].next = segs[j].next;
            if segs[j].next != NONE {
                let k = segs[j].next;
                segs[k].prev = i;
                heap.push(Cand(
                    cost(&segs[i], &segs[k]),
                    i,
                    segs[i].version,
                    segs[k].version,
                ));
            }
            if segs[i].prev != NONE {
                let p = segs[i].prev;
                heap.push(Cand(
                    cost(&segs[p], &segs[i]),
                    p,
                    segs[p].version,
                    segs[i].version,
                ));
            }
            alive -= 1;
        }
        StepFunction::canonical(
            segs.iter()
                .filter(|s| s.alive)
                .map(|s| (s.t, s.v))
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(p: &[(f64, f64)]) -> StepFunction {
        StepFunction::canonical(p.to_vec())
    }

    #[test]
    fn from_visibility() {
        let v = Visibility::from_intervals(vec![(2.0, 5.0), (7.0, f64::INFINITY)]);
        let s = StepFunction::of_visibility(&v, 10.0);
        assert_eq!(
            s.points(),
            &[(0.0, 0.0), (2.0, 1.0), (5.0, 0.0), (7.0, 1.0)]
        );
        assert_eq!(
            StepFunction::of_visibility(&Visibility::always(), 10.0).points(),
            &[(0.0, 1.0)]
        );
    }

    #[test]
    fn weighted_mean_and_distance() {
        let a = steps(&[(0.0, 0.0), (2.0, 1.0)]);
        let b = steps(&[(0.0, 1.0), (6.0, 0.0)]);
        let m = StepFunction::weighted_mean(&[(1.0, &a), (3.0, &b)]);
        assert_eq!(m.points(), &[(0.0, 0.75), (2.0, 1.0), (6.0, 0.25)]);
        // |m - a| = 0.75 on [0,2), 0 on [2,6), 0.75 on [6,10).
        assert!((m.l1_distance(&a, 10.0) - 4.5).abs() < 1e-12);
        assert_eq!(a.l1_distance(&a, 10.0), 0.0);
    }

    #[test]
    fn simplification_keeps_the_integral_and_bounds() {
        let raw: Vec<(f64, f64)> = (0..100).map(|i| (i as f64, (i % 3) as f64 / 2.0)).collect();
        let f = steps(&raw);
        let g = f.simplified(10, 100.0);
        assert!(g.points().len() <= 10);
        let integral = |s: &StepFunction| s.l1_distance(&StepFunction::constant(0.0), 100.0);
        assert!((integral(&f) - integral(&g)).abs() < 1e-9);
        assert!(g.points().iter().all(|p| (0.0..=1.0).contains(&p.1)));
        assert_eq!(g.points()[0].0, 0.0);
    }
}
