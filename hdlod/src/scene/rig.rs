//! Articulated models: a glTF node hierarchy whose animations (clips) are
//! placed on the scene's timeline, and each mesh node's world transform over
//! time composed down the hierarchy and kept as keyframes (docs/formats.md,
//! "Clips").
//!
//! A node's local transform is its rest transform with its animated
//! properties (translation, rotation, scale) replaced by the clip's values
//! at the clip time the timeline maps the scene time to. Its world
//! transform is its parents' after its own (glTF 2.0 specification,
//! sections 3.5 "Nodes and hierarchy" and 3.11 "Animations", including
//! appendix C for cubic-spline interpolation).
//!
//! The scene keeps motions as keyframes interpolated linearly (slerp for
//! rotations), so the composed transform is sampled: at every key time of
//! the channels above the node and at the ends of the clip's placements,
//! then cut between two samples until the keyframes' interpolation lies
//! within a tolerance ([`TOLERANCE`] for `scene.json` clips) of the exact
//! composed transform at the corners of the node's mesh box (a jib that
//! slews moves a hook on an arc, which linear interpolation of its world
//! position would cut short).

use glam::{Mat4, Quat, Vec3};

use super::Keyframe;

/// The largest distance, in scene units (metres), between a resampled
/// keyframe motion and the exact composed transform, at the corners of the
/// part's mesh box, for clips placed by `scene.json`.
pub const TOLERANCE: f32 = 1e-3;

/// Cuts of one interval between key times at most, one inside another.
const MAX_DEPTH: u32 = 8;

/// One cut makes at most this many pieces.
const MAX_PIECES: usize = 64;

/// A resampled motion has at most this many keyframes.
pub const MAX_KEYFRAMES: usize = 1_000_000;

/// A jump of the clip time (a clip played again from its start) is kept as
/// a held pose until this many seconds before the jump: keyframes need
/// distinct times.
const JUMP: f64 = 1e-3;

/// How a channel interpolates between its keys (glTF `sampler.interpolation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    Linear,
    Step,
    /// Each key holds an in-tangent, a value and an out-tangent.
    CubicSpline,
}

/// The values of one channel, one per key (three per key, in-tangent,
/// value, out-tangent, for cubic splines).
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    Translation(Vec<Vec3>),
    Rotation(Vec<Quat>),
    Scale(Vec<Vec3>),
}

/// One animated property of one node.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    pub node: usize,
    pub interpolation: Interpolation,
    /// Clip seconds, increasing (`f32` in glTF; a clip made in code may
    /// run in scene seconds over years).
    pub times: Vec<f64>,
    pub values: Values,
}

/// A glTF animation.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    pub name: Option<String>,
    pub channels: Vec<Channel>,
}

impl Clip {
    /// The clip's length: its last key time.
    pub fn duration(&self) -> f64 {
        self.channels
            .iter()
            .filter_map(|c| c.times.last())
            .fold(0.0, |a, &b| a.max(b))
    }
}

/// A node's transform as translation, rotation and scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trs {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Trs {
    /// A translation alone.
    pub fn from_translation(translation: Vec3) -> Trs {
        Trs {
            translation,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
        }
    }
}

/// The node hierarchy of a model and its clips.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Rig {
    pub parent: Vec<Option<usize>>,
    /// Each node's local transform at rest.
    pub rest: Vec<Mat4>,
    /// The same, decomposed: what an animated property replaces a part of.
    pub rest_trs: Vec<Trs>,
    pub clips: Vec<Clip>,
}

/// Where a placement's clip time runs: from `tau.0` at scene time `start`
/// to `tau.1` at `end`, linearly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    pub start: f64,
    pub end: f64,
    pub tau: (f64, f64),
}

/// The map from scene time to a clip's time: sorted segments that do not
/// overlap; before the first the clip time is the first's start, between
/// two and after the last it holds where the segment before ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    segments: Vec<Segment>,
}

impl Timeline {
    /// Errors when the segments overlap or one runs backwards in scene time.
    pub fn new(mut segments: Vec<Segment>) -> Result<Timeline, String> {
        if segments.is_empty() {
            return Err("places the clip nowhere".into());
        }
        segments.sort_by(|a, b| a.start.total_cmp(&b.start));
        for s in &segments {
            let finite = [s.start, s.end, s.tau.0, s.tau.1]
                .iter()
                .all(|x| x.is_finite());
            if !finite || s.end <= s.start {
                return Err(format!(
                    "a piece from {} s to {} s is empty or not finite",
                    s.start, s.end
                ));
            }
        }
        if let Some(w) = segments.windows(2).find(|w| w[1].start < w[0].end) {
            return Err(format!(
                "the clip plays twice at once: from {} s and from {} s",
                w[0].start, w[1].start
            ));
        }
        Ok(Timeline { segments })
    }

    /// A clip whose time is the scene's from its start: a clip made in
    /// scene seconds.
    pub fn scene_time() -> Timeline {
        const END: f64 = super::format::MAX_SECONDS;
        Timeline {
            segments: vec![Segment {
                start: 0.0,
                end: END,
                tau: (0.0, END),
            }],
        }
    }

    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// The clip time at scene time `t`.
    pub fn tau(&self, t: f64) -> f64 {
        let i = self.segments.partition_point(|s| s.start <= t);
        if i == 0 {
            return self.segments[0].tau.0;
        }
        let s = &self.segments[i - 1];
        if t >= s.end {
            return s.tau.1;
        }
        s.tau.0 + (s.tau.1 - s.tau.0) * (t - s.start) / (s.end - s.start)
    }

    /// The scene times within `window` at which the clip time is one of
    /// `times` (sorted; inside a segment), with the segments' ends: where
    /// a composed motion must have a keyframe.
    fn breakpoints(&self, times: &[f64], (from, to): (f64, f64), out: &mut Vec<f64>) {
        for s in &self.segments {
            if s.end < from || s.start > to {
                continue;
            }
            out.push(s.start);
            out.push(s.end);
            let (a, b) = (s.start.max(from), s.end.min(to));
            let at = |t: f64| s.tau.0 + (s.tau.1 - s.tau.0) * (t - s.start) / (s.end - s.start);
            let (lo, hi) = (at(a).min(at(b)), at(a).max(at(b)));
            if hi <= lo {
                continue;
            }
            let first = times.partition_point(|&k| k <= lo);
            let last = times.partition_point(|&k| k < hi);
            for &k in &times[first..last] {
                out.push(s.start + (s.end - s.start) * (k - s.tau.0) / (s.tau.1 - s.tau.0));
            }
        }
    }
}

/// A clip placed on the timeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Placed<'a> {
    pub clip: &'a Clip,
    pub timeline: Timeline,
    /// The clip's channels of each node it animates.
    by_node: std::collections::HashMap<usize, Vec<usize>>,
}

impl<'a> Placed<'a> {
    pub fn new(clip: &'a Clip, timeline: Timeline) -> Placed<'a> {
        let mut by_node: std::collections::HashMap<usize, Vec<usize>> = Default::default();
        for (k, c) in clip.channels.iter().enumerate() {
            by_node.entry(c.node).or_default().push(k);
        }
        Placed {
            clip,
            timeline,
            by_node,
        }
    }

    /// The channels that animate `node`.
    fn channels(&self, node: usize) -> impl Iterator<Item = &Channel> {
        self.by_node
            .get(&node)
            .into_iter()
            .flatten()
            .map(|&k| &self.clip.channels[k])
    }
}

impl Channel {
    /// The channel's value at clip time `tau`, clamped to its keys.
    fn sample(&self, tau: f64) -> Sampled {
        let n = self.times.len();
        let i = self.times.partition_point(|&k| k <= tau);
        let (a, b, s) = if i == 0 {
            (0, 0, 0.0)
        } else if i == n {
            (n - 1, n - 1, 0.0)
        } else {
            let (t0, t1) = (self.times[i - 1], self.times[i]);
            (i - 1, i, ((tau - t0) / (t1 - t0)) as f32)
        };
        let dt = if a == b {
            0.0
        } else {
            (self.times[b] - self.times[a]) as f32
        };
        match &self.values {
            Values::Translation(v) => Sampled::Translation(self.vec(v, a, b, s, dt)),
            Values::Scale(v) => Sampled::Scale(self.vec(v, a, b, s, dt)),
            Values::Rotation(v) => Sampled::Rotation(match self.interpolation {
                Interpolation::Step => v[a],
                // On a key, its value exactly: slerp at 0 need not give it.
                Interpolation::Linear if s == 0.0 => v[a],
                Interpolation::Linear => v[a].slerp(v[b], s),
                Interpolation::CubicSpline => {
                    let [p0, m0, p1, m1] =
                        [v[3 * a + 1], v[3 * a + 2], v[3 * b + 1], v[3 * b]].map(glam::Vec4::from);
                    crate::scene::unit(Quat::from_vec4(hermite(p0, m0 * dt, p1, m1 * dt, s)))
                }
            }),
        }
    }

    fn vec(&self, v: &[Vec3], a: usize, b: usize, s: f32, dt: f32) -> Vec3 {
        match self.interpolation {
            Interpolation::Step => v[a],
            Interpolation::Linear => v[a].lerp(v[b], s),
            Interpolation::CubicSpline => hermite(
                v[3 * a + 1],
                v[3 * a + 2] * dt,
                v[3 * b + 1],
                v[3 * b] * dt,
                s,
            ),
        }
    }
}

/// The cubic Hermite spline through `p0` and `p1` with tangents `m0` and
/// `m1` (already scaled by the key interval) at `s` in `[0, 1]`.
fn hermite<T>(p0: T, m0: T, p1: T, m1: T, s: f32) -> T
where
    T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    let (s2, s3) = (s * s, s * s * s);
    p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + m0 * (s3 - 2.0 * s2 + s)
        + p1 * (-2.0 * s3 + 3.0 * s2)
        + m1 * (s3 - s2)
}

enum Sampled {
    Translation(Vec3),
    Rotation(Quat),
    Scale(Vec3),
}

impl Rig {
    /// A rig whose nodes' rest transforms are all translations, rotations
    /// and scales (a glTF node may give a matrix instead, kept as it is by
    /// the reader).
    pub fn from_trs(parent: Vec<Option<usize>>, rest: Vec<Trs>, clips: Vec<Clip>) -> Rig {
        Rig {
            parent,
            rest: rest
                .iter()
                .map(|r| Mat4::from_scale_rotation_translation(r.scale, r.rotation, r.translation))
                .collect(),
            rest_trs: rest,
            clips,
        }
    }

    /// The nodes from `node` up to its root, `node` first.
    fn chain(&self, node: usize) -> Vec<usize> {
        let mut chain = vec![node];
        while let Some(p) = self.parent[*chain.last().expect("not empty")] {
            chain.push(p);
        }
        chain
    }

    /// Whether any of `placed` animates `node` or a node above it.
    pub fn moves(&self, node: usize, placed: &[Placed]) -> bool {
        let chain = self.chain(node);
        placed
            .iter()
            .any(|p| chain.iter().any(|&n| p.channels(n).next().is_some()))
    }

    /// Node `n`'s transform relative to its parent at scene time `t`, when
    /// `placed` animates it.
    fn local(&self, n: usize, placed: &[Placed], t: f64) -> Option<Trs> {
        let mut trs: Option<Trs> = None;
        for p in placed {
            let tau = p.timeline.tau(t);
            for c in p.channels(n) {
                let v = trs.get_or_insert(self.rest_trs[n]);
                match c.sample(tau) {
                    Sampled::Translation(x) => v.translation = x,
                    Sampled::Rotation(x) => v.rotation = crate::scene::unit(x),
                    Sampled::Scale(x) => v.scale = x,
                }
            }
        }
        trs
    }

    /// The world transform of `node` at scene time `t`.
    fn world(&self, chain: &[usize], placed: &[Placed], t: f64) -> Mat4 {
        let mut world = Mat4::IDENTITY;
        for &n in chain.iter().rev() {
            let local = self.local(n, placed, t).map_or(self.rest[n], |v| {
                Mat4::from_scale_rotation_translation(v.scale, v.rotation, v.translation)
            });
            world *= local;
        }
        world
    }

    /// The keyframe of the world transform of `chain` at `t`. Where one
    /// animated node is all that moves it (the nodes above it rest at
    /// identity, as a saved skeleton's root does), it is that node's
    /// sampled transform as it is: through a matrix it would move in the
    /// last bits, and a scene saved with the keyframes as a clip and loaded
    /// again must give back the same keyframes.
    fn key_at(&self, chain: &[usize], placed: &[Placed], t: f64) -> (Keyframe, Mat4) {
        let world = self.world(chain, placed, t);
        let animated = |n: usize| placed.iter().any(|p| p.channels(n).next().is_some());
        let mut moving = chain
            .iter()
            .filter(|&&n| animated(n) || self.rest[n] != Mat4::IDENTITY);
        if let (Some(&n), None) = (moving.next(), moving.next())
            && let Some(v) = self.local(n, placed, t)
        {
            let key = Keyframe {
                t,
                translation: v.translation,
                rotation: v.rotation,
                scale: v.scale,
            };
            return (key, world);
        }
        (Keyframe::of_matrix(t, &world), world)
    }

    /// The keyframes of `node`'s world transform under the clips `placed`
    /// over the scene times `window`, within `tolerance` of it at the
    /// corners of `(lo, hi)` (the node's mesh box). Before and after the
    /// window, a motion made of them holds its first and last pose.
    pub fn keyframes(
        &self,
        node: usize,
        placed: &[Placed],
        (lo, hi): (Vec3, Vec3),
        window: (f64, f64),
        tolerance: f32,
    ) -> Result<Vec<Keyframe>, String> {
        let chain = self.chain(node);
        let mut times = vec![window.0, window.1];
        for p in placed {
            let mut animated = false;
            for &n in &chain {
                for c in p.channels(n) {
                    p.timeline.breakpoints(&c.times, window, &mut times);
                    animated = true;
                }
            }
            if !animated {
                continue;
            }
            // A jump of the clip time between two segments: the pose held
            // until just before the next one starts.
            for w in p.timeline.segments.windows(2) {
                if w[0].tau.1 != w[1].tau.0 && w[1].start - w[0].end > 2.0 * JUMP {
                    times.push(w[1].start - JUMP);
                }
            }
        }
        times.retain(|t| (window.0..=window.1).contains(t));
        times.sort_by(f64::total_cmp);
        times.dedup_by(|a, b| (*a - *b).abs() < JUMP / 2.0);

        let corners: Vec<Vec3> = (0..8)
            .map(|k| {
                Vec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        let key = |t: f64| -> Result<Keyframe, String> {
            let (k, m) = self.key_at(&chain, placed, t);
            let off = far(&corners, &m, &k.matrix());
            if off.is_nan() || off > tolerance {
                return Err(format!(
                    "its world transform at {t} s is not a translation, rotation and scale \
                     (a non-uniform scale above a rotation shears it {off} m): it cannot move \
                     as a rigid part"
                ));
            }
            Ok(k)
        };
        let fit = Fit {
            chain: &chain,
            placed,
            corners: &corners,
            tolerance,
        };
        let mut out = vec![key(times[0])?];
        for w in times.windows(2) {
            let end = key(w[1])?;
            self.refine(&fit, *out.last().expect("not empty"), end, 0, &mut out);
            out.push(end);
            if out.len() > MAX_KEYFRAMES {
                return Err(format!(
                    "its motion needs more than {MAX_KEYFRAMES} keyframes to stay within \
                     {tolerance} m"
                ));
            }
        }
        Ok(out)
    }

    /// Adds the keyframes between `a` and `b` that keep the interpolation
    /// within the tolerance of the composed transform. An interval that
    /// strays is cut into `n` equal pieces with `n` the square root of its
    /// error over the tolerance, rounded up: a swing's deviation from its
    /// chord falls with the square of the piece (an arc of angle `d` and
    /// radius `r` strays `r d^2 / 8`), so one cut usually suffices where
    /// halving would overshoot to the next power of two.
    fn refine(&self, fit: &Fit, a: Keyframe, b: Keyframe, depth: u32, out: &mut Vec<Keyframe>) {
        // Three probes: a motion can return to the midpoint's pose (a full
        // turn) and still stray between.
        let error = [0.25, 0.5, 0.75]
            .iter()
            .map(|s| {
                let t = a.t + (b.t - a.t) * s;
                let exact = self.world(fit.chain, fit.placed, t);
                far(
                    fit.corners,
                    &exact,
                    &super::Motion::between(a, b, t).matrix(),
                )
            })
            .fold(0.0, f32::max);
        // Past the keyframes' cap the caller reports the motion too long:
        // a wild curve must not be cut 64 ways at every depth first.
        if error <= fit.tolerance
            || depth >= MAX_DEPTH
            || b.t - a.t < 2.0 * JUMP
            || out.len() > MAX_KEYFRAMES
        {
            return;
        }
        let n = ((error / fit.tolerance).sqrt().ceil() as usize).clamp(2, MAX_PIECES);
        let mut from = a;
        for k in 1..=n {
            let to = if k == n {
                b
            } else {
                let t = a.t + (b.t - a.t) * k as f64 / n as f64;
                self.key_at(fit.chain, fit.placed, t).0
            };
            self.refine(fit, from, to, depth + 1, out);
            if k < n {
                out.push(to);
            }
            from = to;
        }
    }
}

/// What [`Rig::refine`] holds a resampled motion to.
struct Fit<'a> {
    chain: &'a [usize],
    placed: &'a [Placed<'a>],
    corners: &'a [Vec3],
    tolerance: f32,
}

/// The largest distance between `corners` placed by `a` and by `b`.
fn far(corners: &[Vec3], a: &Mat4, b: &Mat4) -> f32 {
    corners
        .iter()
        .map(|&c| a.transform_point3(c).distance(b.transform_point3(c)))
        .fold(0.0, f32::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(
        node: usize,
        interpolation: Interpolation,
        times: &[f64],
        values: Values,
    ) -> Channel {
        Channel {
            node,
            interpolation,
            times: times.to_vec(),
            values,
        }
    }

    /// A two-node arm: node 0 turns about Y through a quarter turn over
    /// one second, node 1 sits 10 m out along X on it.
    fn arm() -> Rig {
        Rig::from_trs(
            vec![None, Some(0)],
            vec![
                Trs::from_translation(Vec3::ZERO),
                Trs::from_translation(Vec3::X * 10.0),
            ],
            vec![Clip {
                name: Some("slew".into()),
                channels: vec![channel(
                    0,
                    Interpolation::Linear,
                    &[0.0, 1.0],
                    Values::Rotation(vec![
                        Quat::IDENTITY,
                        Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
                    ]),
                )],
            }],
        )
    }

    #[test]
    fn a_child_moves_on_the_arc_of_its_parent_within_the_tolerance() {
        let rig = arm();
        let timeline = Timeline::new(vec![Segment {
            start: 100.0,
            end: 200.0,
            tau: (0.0, 1.0),
        }])
        .unwrap();
        let placed = [Placed::new(&rig.clips[0], timeline)];
        let bounds = (Vec3::splat(-0.5), Vec3::splat(0.5));
        let keys = rig
            .keyframes(1, &placed, bounds, (0.0, 300.0), TOLERANCE)
            .unwrap();
        // Two keys would cut the arc's chord 2.9 m inside it.
        assert!(keys.len() > 8, "{}", keys.len());
        let motion = super::super::Motion::new(keys).unwrap();
        for i in 0..=300 {
            let t = f64::from(i);
            let angle = std::f32::consts::FRAC_PI_2 * ((t - 100.0) / 100.0).clamp(0.0, 1.0) as f32;
            let exact = Quat::from_rotation_y(angle) * (Vec3::X * 10.0);
            let got = motion.at(t).transform_point3(Vec3::ZERO);
            assert!(
                got.distance(exact) <= TOLERANCE * 1.01,
                "t {t}: {got} vs {exact}"
            );
        }
        // Held before and after the placement.
        assert!(
            motion
                .at(0.0)
                .transform_point3(Vec3::ZERO)
                .distance(Vec3::X * 10.0)
                < 1e-5
        );
    }

    #[test]
    fn step_and_cubic_spline_follow_the_specification() {
        let step = channel(
            0,
            Interpolation::Step,
            &[0.0, 1.0],
            Values::Translation(vec![Vec3::ZERO, Vec3::ONE]),
        );
        let Sampled::Translation(v) = step.sample(0.99) else {
            panic!()
        };
        assert_eq!(v, Vec3::ZERO);
        // A cubic spline with zero tangents eases in and out: at a quarter
        // of the interval, 3 s^2 - 2 s^3 of the way.
        let cubic = channel(
            0,
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            Values::Translation(vec![
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::X * 8.0,
                Vec3::ZERO,
            ]),
        );
        let Sampled::Translation(v) = cubic.sample(0.5) else {
            panic!()
        };
        let s: f32 = 0.25;
        assert!(
            (v.x - 8.0 * (3.0 * s * s - 2.0 * s * s * s)).abs() < 1e-5,
            "{v}"
        );
        // Tangents scale with the key interval: out-tangent 1 m/s over 2 s.
        let sloped = channel(
            0,
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            Values::Translation(vec![
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::X,
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::ZERO,
            ]),
        );
        let Sampled::Translation(v) = sloped.sample(1.0) else {
            panic!()
        };
        // s = 0.5: m0 * dt * (s^3 - 2 s^2 + s) = 2 * 0.125.
        assert!((v.x - 0.25).abs() < 1e-5, "{v}");
    }

    #[test]
    fn a_timeline_holds_outside_its_pieces_and_refuses_overlaps() {
        let t = Timeline::new(vec![
            Segment {
                start: 10.0,
                end: 20.0,
                tau: (0.0, 2.0),
            },
            Segment {
                start: 30.0,
                end: 40.0,
                tau: (0.0, 2.0),
            },
        ])
        .unwrap();
        assert_eq!(t.tau(0.0), 0.0);
        assert_eq!(t.tau(15.0), 1.0);
        assert_eq!(t.tau(25.0), 2.0);
        assert_eq!(t.tau(35.0), 1.0);
        assert_eq!(t.tau(50.0), 2.0);
        let overlap = Timeline::new(vec![
            Segment {
                start: 10.0,
                end: 20.0,
                tau: (0.0, 2.0),
            },
            Segment {
                start: 15.0,
                end: 25.0,
                tau: (0.0, 2.0),
            },
        ]);
        assert!(overlap.unwrap_err().contains("twice at once"));
    }

    #[test]
    fn a_replayed_clip_jumps_back_just_before_it_starts_again() {
        let rig = arm();
        let piece = |start: f64| Segment {
            start,
            end: start + 10.0,
            tau: (0.0, 1.0),
        };
        let placed = [Placed::new(
            &rig.clips[0],
            Timeline::new(vec![piece(10.0), piece(50.0)]).unwrap(),
        )];
        let keys = rig
            .keyframes(
                1,
                &placed,
                (Vec3::ZERO, Vec3::ZERO),
                (0.0, 100.0),
                TOLERANCE,
            )
            .unwrap();
        let motion = super::super::Motion::new(keys).unwrap();
        let at = |t: f64| motion.at(t).transform_point3(Vec3::ZERO);
        let turned = Vec3::new(0.0, 0.0, -10.0);
        assert!(at(49.99).distance(turned) < 1e-4, "{}", at(49.99));
        assert!(at(50.0).distance(Vec3::X * 10.0) < 1e-4, "{}", at(50.0));
    }
}
