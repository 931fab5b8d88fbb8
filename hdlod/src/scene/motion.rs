//! Position `p_s(t) -> 4x4 matrix` of a moving object, stored as keyframes:
//! translation and scale interpolate linearly, rotation by slerp; before the
//! first keyframe and after the last the pose is held (clamped).

use glam::{Mat4, Quat, Vec3};

use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Seconds since the scene's start.
    pub t: f64,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Keyframe {
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// The keyframe at `t` of the transform `m`, decomposed (exact for a
    /// translation, rotation and scale; a shear is lost).
    pub fn of_matrix(t: f64, m: &Mat4) -> Keyframe {
        let (scale, rotation, translation) = m.to_scale_rotation_translation();
        Keyframe {
            t,
            translation,
            rotation,
            scale,
        }
    }
}

/// `q` normalised if it is off the unit sphere by more than `f32`
/// rounding, else `q` itself: normalising a unit quaternion again can move
/// its last bit, and a motion read back from a file must equal the one
/// written.
pub(crate) fn unit(q: Quat) -> Quat {
    if (q.length_squared() - 1.0).abs() > 1e-6 {
        q.normalize()
    } else {
        q
    }
}

/// Keyframes sorted by time, at least one.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    keys: Vec<Keyframe>,
}

impl Motion {
    /// Sorts the keyframes by time. Errors on an empty list, on two
    /// keyframes at the same time and on non-finite values.
    pub fn new(mut keys: Vec<Keyframe>) -> Result<Self> {
        if keys.is_empty() {
            return Err(Error::value("a motion needs at least one keyframe"));
        }
        for (i, k) in keys.iter().enumerate() {
            if !k.t.is_finite()
                || !k.translation.is_finite()
                || !k.rotation.is_finite()
                || !k.scale.is_finite()
            {
                return Err(Error::value(format!("keyframe {i} has a non-finite value")));
            }
            if k.rotation.length_squared() < 1e-12 {
                return Err(Error::value(format!(
                    "keyframe {i} has a zero rotation quaternion"
                )));
            }
        }
        keys.sort_by(|a, b| a.t.total_cmp(&b.t));
        if let Some(w) = keys.windows(2).find(|w| w[0].t == w[1].t) {
            return Err(Error::value(format!("two keyframes at t = {}", w[0].t)));
        }
        for k in &mut keys {
            k.rotation = unit(k.rotation);
        }
        Ok(Motion { keys })
    }

    pub fn keyframes(&self) -> &[Keyframe] {
        &self.keys
    }

    /// True when the pose changes at some time (more than one distinct pose).
    pub fn moves(&self) -> bool {
        let first = self.keys[0];
        self.keys.iter().any(|k| {
            !k.translation.abs_diff_eq(first.translation, 1e-6)
                || !k.scale.abs_diff_eq(first.scale, 1e-6)
                || k.rotation.dot(first.rotation).abs() < 1.0 - 1e-9
        })
    }

    /// The interpolated keyframe at `t`.
    pub fn sample(&self, t: f64) -> Keyframe {
        let i = keys_until(self.keys.len(), t, |k| self.keys[k].t);
        if i == 0 {
            return self.keys[0];
        }
        if i == self.keys.len() {
            return self.keys[i - 1];
        }
        Motion::between(self.keys[i - 1], self.keys[i], t)
    }

    /// The keyframe at `t` between keyframes `a` and `b` (`a.t <= t < b.t`).
    pub(crate) fn between(a: Keyframe, b: Keyframe, t: f64) -> Keyframe {
        let s = ((t - a.t) / (b.t - a.t)) as f32;
        Keyframe {
            t,
            translation: a.translation.lerp(b.translation, s),
            rotation: a.rotation.slerp(b.rotation, s),
            scale: a.scale.lerp(b.scale, s),
        }
    }

    pub fn at(&self, t: f64) -> Mat4 {
        self.sample(t).matrix()
    }
}

/// How many of `n` keyframes, at the increasing times `time(0..n)`, are at
/// or before `t`: `partition_point(|k| k.t <= t)`. A few keyframes are
/// searched; many (a crane's motion over two years has 16,000, 770 kB,
/// and a cut samples it at a new time each frame) are entered where `t`
/// would fall were they evenly spaced, then bracketed by doubling steps
/// and searched within the bracket: two to four reads for evenly spaced
/// keyframes where a binary search waits on fourteen misses one after the
/// other. The answer is the same whatever the spacing.
pub(crate) fn keys_until(n: usize, t: f64, time: impl Fn(usize) -> f64) -> usize {
    let search = |lo: usize, hi: usize| {
        let (mut lo, mut hi) = (lo, hi);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if time(mid) <= t {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo
    };
    if n <= GUESSED_FROM {
        return search(0, n);
    }
    let (first, last) = (time(0), time(n - 1));
    // NaN is before every keyframe, as the comparison says.
    if t < first || t.is_nan() {
        return 0;
    }
    if last <= t {
        return n;
    }
    // first <= t < last: time(lo) <= t < time(hi) from here on.
    let guess = ((t - first) / (last - first) * (n - 1) as f64) as usize;
    let guess = guess.min(n - 2);
    let (mut lo, mut hi);
    let mut step = 1;
    if time(guess) <= t {
        lo = guess;
        loop {
            let h = (lo + step).min(n - 1);
            if time(h) > t {
                hi = h;
                break;
            }
            lo = h;
            step *= 2;
        }
    } else {
        hi = guess;
        loop {
            let l = hi.saturating_sub(step);
            if time(l) <= t {
                lo = l;
                break;
            }
            hi = l;
            step *= 2;
        }
    }
    search(lo + 1, hi)
}

/// The fewest keyframes [`keys_until`] enters by a guess.
const GUESSED_FROM: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_until_is_the_partition_point() {
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for n in [1, 2, 5, 63, 64, 65, 100, 1000, 16105] {
            for spacing in 0..3 {
                let mut times = Vec::with_capacity(n);
                let mut at = -50.0;
                for _ in 0..n {
                    // Even, random, and bunched: most keyframes in a burst.
                    at += match spacing {
                        0 => 10.0,
                        1 => 0.1 + 20.0 * next(),
                        _ => {
                            if next() < 0.9 {
                                1e-3
                            } else {
                                1e4 * next() + 1e-3
                            }
                        }
                    };
                    times.push(at);
                }
                let (a, b) = (times[0], times[n - 1]);
                let mut probes = vec![f64::NAN, f64::NEG_INFINITY, f64::INFINITY, a - 1.0, b + 1.0];
                probes.extend(times.iter().copied());
                probes.extend(times.iter().map(|x| x + 1e-4));
                probes.extend(times.iter().map(|x| x - 1e-4));
                probes.extend((0..200).map(|_| a - 5.0 + (b - a + 10.0) * next()));
                for t in probes {
                    assert_eq!(
                        keys_until(n, t, |k| times[k]),
                        times.partition_point(|&x| x <= t),
                        "n {n}, spacing {spacing}, t {t}"
                    );
                }
            }
        }
    }

    fn key(t: f64, x: f32, angle: f32) -> Keyframe {
        Keyframe {
            t,
            translation: Vec3::new(x, 0.0, 0.0),
            rotation: Quat::from_rotation_z(angle),
            scale: Vec3::ONE,
        }
    }

    #[test]
    fn interpolates_and_clamps() {
        let m = Motion::new(vec![key(10.0, 10.0, 1.0), key(0.0, 0.0, 0.0)]).unwrap();
        assert!(m.moves());
        let mid = m.sample(5.0);
        assert!(mid.translation.abs_diff_eq(Vec3::new(5.0, 0.0, 0.0), 1e-5));
        assert!((mid.rotation.angle_between(Quat::IDENTITY) - 0.5).abs() < 1e-5);
        assert_eq!(m.sample(-1.0).translation.x, 0.0);
        assert_eq!(m.sample(99.0).translation.x, 10.0);
    }

    #[test]
    fn rejects_bad_keyframes() {
        assert!(Motion::new(vec![]).is_err());
        assert!(Motion::new(vec![key(1.0, 0.0, 0.0), key(1.0, 2.0, 0.0)]).is_err());
        assert!(Motion::new(vec![key(f64::NAN, 0.0, 0.0)]).is_err());
        assert!(
            !Motion::new(vec![key(1.0, 3.0, 0.0), key(2.0, 3.0, 0.0)])
                .unwrap()
                .moves()
        );
    }
}
